#!/usr/bin/env python3
"""Write the same five-axis path of N blocks in the three dialects, for the
speed comparison of docs/dialects.md ("SINUMERIK: speed", Heidenhain
"Measured"): TAG.ngc (LinuxCNC: `X Y Z A C` lines), TAG.mpf (SINUMERIK:
`%_N_BIG_MPF`, `G71`, `N… G1 X Y Z A C F800` lines) and TAG.h (Klartext:
`BEGIN PGM BIG MM`, `n L X+… Y+… Z+… A+… C+…` blocks), TAG-words.ngc
(LinuxCNC with the words of the SINUMERIK lines: `N… G1 X Y Z A C F800`,
the fair yardstick for the words read per line) and TAG-bare.mpf
(SINUMERIK with the LinuxCNC lines: `X Y Z A C`), a helix-like path:

    python3 benches/dialect_programs.py 1000000 big1m
    volcomp check big1m.mpf        # and big1m.ngc, big1m.h, in turn
"""
import math
import sys


def main():
    blocks = int(sys.argv[1])
    tag = sys.argv[2]
    ngc = open(f"{tag}.ngc", "w", buffering=1 << 20)
    mpf = open(f"{tag}.mpf", "w", buffering=1 << 20)
    h = open(f"{tag}.h", "w", buffering=1 << 20)
    words = open(f"{tag}-words.ngc", "w", buffering=1 << 20)
    bare = open(f"{tag}-bare.mpf", "w", buffering=1 << 20)
    ngc.write("%\nG21 G90 G94 G17\nG0 X0 Y0 Z20 A0 C0\nG1 Z0 F800\n")
    mpf.write("%_N_BIG_MPF\nG71 G90 G94 G17\nG0 X0 Y0 Z20 A0 C0\nG1 Z0 F800\n")
    words.write("%\nG21 G90 G94 G17\nG0 X0 Y0 Z20 A0 C0\nG1 Z0 F800\n")
    bare.write("%_N_BIG_MPF\nG71 G90 G94 G17\nG0 X0 Y0 Z20 A0 C0\nG1 Z0 F800\n")
    h.write("0 BEGIN PGM BIG MM\n1 L X+0 Y+0 Z+20 A+0 C+0 R0 FMAX\n2 L Z+0 F800\n")
    for i in range(blocks):
        t = i * 0.001
        x = 50 * math.cos(t)
        y = 50 * math.sin(t)
        z = -10 + 5 * math.sin(t * 0.1)
        a = 20 * math.sin(t * 0.3)
        c = (i * 0.01) % 360
        point = f"X{x:.4f} Y{y:.4f} Z{z:.4f} A{a:.4f} C{c:.4f}\n"
        ngc.write(point)
        bare.write(point)
        line = f"N{10 * (i + 1)} G1 X{x:.4f} Y{y:.4f} Z{z:.4f} A{a:.4f} C{c:.4f} F800\n"
        mpf.write(line)
        words.write(line)
        h.write(f"{i + 3} L X{x:+.4f} Y{y:+.4f} Z{z:+.4f} A{a:+.4f} C{c:+.4f}\n")
    ngc.write("M30\n%\n")
    words.write("M30\n%\n")
    mpf.write("M30\n")
    bare.write("M30\n")
    h.write(f"{blocks + 3} END PGM BIG MM\n")
    for f in (ngc, mpf, h, words, bare):
        f.close()


if __name__ == "__main__":
    main()
