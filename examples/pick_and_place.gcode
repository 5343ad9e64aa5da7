; Pick and place with the suction cup (air pump on PWM 1: S1000 suck, S500 blow, S0 off).
; Moves a part from (200, -100) to (200, 100) on the table at Z = 60 mm, tool pointing down.
;
;   mirobot run examples/pick_and_place.gcode             (embedded virtual Mirobot, homed first)
;   mirobot run examples/pick_and_place.gcode --port /dev/ttyUSB0 --home
;
; The arm must be homed (or unlocked) first. Check offline with: mirobot check FILE
M20 G90 G21                   ; Cartesian coordinates, absolute, millimetres
G0 X200 Y0 Z230 A0 B0 C0      ; start above the table, tool pointing down
G0 X200 Y-100 Z120            ; above the part
G1 X200 Y-100 Z60 F2000       ; straight down onto it (linear, 2000 mm/min)
M3 S1000                      ; suck
G4 P0.5                       ; let the vacuum build up
G1 X200 Y-100 Z120 F2000      ; lift straight up
G0 X200 Y100 Z120             ; carry it over
G1 X200 Y100 Z60 F2000        ; put it down
M3 S500                       ; blow to release it
G4 P0.3
M3 S0                         ; pump off
G1 X200 Y100 Z120 F2000       ; back up
G0 X200 Y0 Z230               ; and away
