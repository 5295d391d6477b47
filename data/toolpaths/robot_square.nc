%
(A 100 mm square pocket pass for the bundled UR10, data/robots/ur10/ur10.yaml, in its home configuration.)
(Coordinates in the robot's base frame, mm: the square x 750..850, y 110..210 at z 250, tool axis down;)
(run with a 150 mm spindle: vjm path ... --tool 0,0,150.  8 mm end mill, corners rounded to 4 mm.)
(This program is part of vjm, written for its demo; licence MIT, as the project.)
G21 G90 G17 (mm, absolute, XY plane)
T1 M6
S18000 M3
G0 X754.000 Y110.000 Z260.000
G1 Z250.000 F300 (plunge)
G1 X846.000 F1200
G3 X850.000 Y114.000 I0 J4.000
G1 Y206.000
G3 X846.000 Y210.000 I-4.000 J0
G1 X754.000
G3 X750.000 Y206.000 I0 J-4.000
G1 Y114.000
G3 X754.000 Y110.000 I4.000 J0
G0 Z260.000
M5
M30
%
