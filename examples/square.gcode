; Draw a 60 mm square with straight lines (G1 in Cartesian mode M20), pen tip at Z = 120 mm.
;
;   mirobot run examples/square.gcode --trace square.csv
;   mirobot plot square.csv -o square.png
M20 G90 G21                   ; Cartesian coordinates, absolute, millimetres
G0 X170 Y-30 Z150 A0 B0 C0    ; above the first corner
G1 Z120 F1500                 ; pen down (1500 mm/min)
G1 X230 Y-30                  ; side 1
G1 X230 Y30                   ; side 2
G1 X170 Y30                   ; side 3
G1 X170 Y-30                  ; side 4: closed
G1 Z150                       ; pen up
G0 X200 Y0 Z230               ; park
