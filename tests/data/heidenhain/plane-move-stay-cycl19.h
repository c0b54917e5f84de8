0 BEGIN PGM POSITIONING MM
1 ; How PLANE and CYCL DEF 19 position the rotary axes, worked by hand on head-table
2 ; (TNC 640 user's manual, "Specifying the positioning behavior of the PLANE function";
3 ; TNC 620 Klartext user's manual 10/2017 p. 556: MOVE with DIST tilts about the point DIST
4 ; below the tip; STAY leaves the axes to the program, their values in Q120-Q122).
5 TOOL CALL 1 Z S1000
6 L X+0 Y+0 Z+50 R0 FMAX
7 ; MOVE DIST+50 about X+0 Y+0 Z+0: the tip goes to 50·(sin 30°, 0, cos 30°) = X+25 Y+0 Z+43.3013,
8 ; B to +30; the program position there is Z+50 in the tilted frame
9 PLANE SPATIAL SPA+0 SPB+30 SPC+0 MOVE DIST+50 F2000
10 ; the tip at Ry(30°)·(0, 0, 10) = X+5 Y+0 Z+8.6603
11 L Z+10 F500
12 PLANE RESET TURN FMAX
13 ; STAY with SEQ-: B-30 C+180 (or C-180) left in Q121 Q122; the program turns the axes
14 PLANE SPATIAL SPA+0 SPB+30 SPC+0 STAY SEQ-
15 L B+Q121 C+Q122 R0 FMAX
16 ; the tip at Ry(30°)·(10, 0, 0) = X+8.6603 Y+0 Z-5
17 L X+10 Y+0 Z+0 F500
18 PLANE RESET TURN FMAX
19 ; CYCL DEF 19 with spatial angles (as PLANE SPATIAL), the axes in Q120-Q122
20 CYCL DEF 19.0 WORKING PLANE
21 CYCL DEF 19.1 A+0 B+30 C+0
22 L B+Q121 C+Q122 R0 FMAX
23 ; the tip at X+8.6603 Y+0 Z-5, B+30 C+0
24 L X+10 Y+0 Z+0 F500
25 CYCL DEF 19.0 WORKING PLANE
26 CYCL DEF 19.1 A+0 B+0 C+0
27 L B+Q121 C+Q122 R0 FMAX
28 END PGM POSITIONING MM
