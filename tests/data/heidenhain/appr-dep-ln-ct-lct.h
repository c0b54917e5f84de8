0 BEGIN PGM APPRDEP MM
1 ; APPR/DEP LN, CT, LCT with R0, worked by hand in tests/it/heidenhain.rs (appr_dep_ln_ct_lct_by_hand).
2 ; The side of the contour: the starting point's (here every start is right of the contour, -Y of +X).
3 TOOL CALL 1 Z S8000
4 L X+0 Y-20 Z+5 R0 FMAX
5 APPR LN X+10 Y+0 Z-2 LEN5 R0 F300
6 L X+40
7 L Y+30
8 DEP CT CCA90 R+4 F600
9 L Z+5 FMAX
10 L X+60 Y-20 FMAX
11 APPR CT X+50 Y+0 Z-2 CCA90 R+4 R0 F300
12 L X+80
13 DEP LN LEN5
14 L Z+5 FMAX
15 L X+100 Y-16 FMAX
16 APPR LCT X+100 Y+0 Z-2 R4 R0 F300
17 L X+130
18 DEP LCT X+140 Y-10 Z+5 R4 F600
19 END PGM APPRDEP MM
