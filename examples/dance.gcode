; A joint-space dance: every joint swings within its range (M21: X Y Z A B C = J1..J6, degrees).
;
;   mirobot run examples/dance.gcode
M21 G90 G21                   ; joint angles, absolute, degrees (G21)
G0 X0 Y0 Z0 A0 B0 C0          ; start straight
G0 X45 Y20 Z-20               ; lean left
G0 X-45 Y20 Z-20              ; lean right
G0 X0 Y0 Z0                   ; back to the middle
G1 A90 B-60 C120 F3000        ; wrist twist at 3000 deg/min
G1 A-90 B20 C-120             ; and the other way
G1 A0 B0 C0                   ; straighten the wrist
G91                           ; relative: small nods
G0 Y15 Z-15
G0 Y-15 Z15
G0 Y15 Z-15
G0 Y-15 Z15
G90                           ; absolute again
G0 X0 Y0 Z0 A0 B0 C0          ; bow out
