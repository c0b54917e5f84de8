n10 g21 g90 g94 ; metric, absolute
n20 g0 x1.5 y-2. z10 ; rapid
n30 g1 z-.5 f250 (plunge) ; comment after comment
n40 x+10 y.25
n50 X-0.5 Y5. a-12.25 c33.3333
; a whole-line comment
(another one)

n60 m5 m9 s0
n70 m30
