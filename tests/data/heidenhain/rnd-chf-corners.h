0 BEGIN PGM CORNERS MM
1 ; RND and CHF between straight lines, worked by hand (TNC 620 Klartext user's manual 01/2022,
2 ; "Corner rounding RND" p. 157: an arc tangent to the lines before and after it;
3 ; "Chamfer CHF" p. 156: the chamfer side length is measured from the corner along each line).
4 TOOL CALL 1 Z S1000
5 L X+0 Y+0 Z+0 R0 F500
6 ; the line to the corner X+20 Y+0 ends 5 mm early (R5 at a right angle: 5·tan 45°):
7 L X+20
8 ; the rounding: centre X+15 Y+5, counter-clockwise, from X+15 Y+0 to X+20 Y+5
9 RND R5
10 ; ends 4 mm before the corner X+20 Y+20: at X+20 Y+16
11 L Y+20
12 ; the chamfer from X+20 Y+16 to X+16 Y+20
13 CHF 4
14 L X+0
15 END PGM CORNERS MM
