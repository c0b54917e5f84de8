0 BEGIN PGM HEIDENHAIN-M128 MM
1 ; M128 under a datum shift on ref-trt: the tool tip and axis in the workpiece frame
2 ; hand-checked rows in tests/it/workpiece_targets.rs; run with --offset PRESET=100,50,-200
3 TOOL CALL 1 Z S8000
4 CYCL DEF 7.0 DATUM SHIFT
5 CYCL DEF 7.1 X+10
6 CYCL DEF 7.2 Y-5
7 M128
8 L X+5 Y-5 Z+12 A+30 C+90 R0 F500
9 L X+6 A+45 C+180 R0
10 M129
11 L Z+50 R0 FMAX
12 L Z+0 R0 FMAX M91
13 END PGM HEIDENHAIN-M128 MM
