0 BEGIN PGM POLAR MM
1 ; Polar blocks whose ends compensate moves (hand-written for volcomp's closed loop):
2 ; LP absolute and incremental, CP with PA, a CP helix of a quarter turn (IPA+90 IZ-0.5,
3 ; as hyperMILL writes it), one of 450 degrees and one of two whole turns (IPA+720 IZ-4)
4 TOOL CALL 1 Z S8000 F1200
5 L X+24 Y+20 Z+10 R0 FMAX M3
6 CC X+20 Y+20
7 L Z-2 F300
8 CP PA+60 DR+ F900
9 LP PR+3 PA+90
10 LP IPR-1 IPA+30
11 CP IPA+90 IZ-0.5 DR+
12 CP IPA-450 IZ-1.5 DR- F700
13 LP PR+3.5 PA+0 F900
14 CC X+22 Y+21
15 CP IPA+720 IZ-4 DR+
16 L Z+10 FMAX
17 END PGM POLAR MM
