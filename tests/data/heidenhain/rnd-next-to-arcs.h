0 BEGIN PGM RNDARCS MM
1 ; RND next to arcs, worked by hand in tests/it/heidenhain.rs (rnd_next_to_arcs_by_hand)
2 ; (TNC 620 Klartext user's manual 01/2022 p. 157: an arc tangent to the elements before and after).
3 TOOL CALL 1 Z S1000
4 L X+0 Y+0 Z+0 R0 F500
5 CC X+20 Y+0
6 L X+10
7 RND R2
8 C X+30 Y+0 DR+
9 RND R1
10 L X+40 Y+10
11 END PGM RNDARCS MM
