( xyzac-trt style demo: tool-tip control with M428, inverse time, spaces in words )
g21 g90 g94 g17
g0 x0 y0 z 20 a0 c0
M428 (switch to tool-tip: X Y Z are the tool tip in part coordinates)
G93
G1 X  16.339 Y -2.5 Z 5.0 A 10 C 20 F 159
G1 X 1 0.5 Y 3 Z 4.25 A 1 2.5 C 4 0 F 2 10.25
g1 x-5 y 6 z 3 a 15 c 60 f 95.5
G1 X0 Y0 Z2 A0 C 90 F 60
G94
M429 (back to joint mode)
G0 Z 50
M2
