#!/usr/bin/env python3
"""Write an error table of N rows (one column, EXX, over -200...200 mm): a
trend, a ripple and a bump plus N(0, 0.3 um) noise, like a laser run with N
points. For the time and peak memory of the default fit at any length:

    python3 benches/long_table.py 100000 target/x-100k.csv
    /usr/bin/time -v target/release/volcomp fit target/x-100k.csv

(benches/smem.rs fits the same shape in process: its "cv fit, N rows" rows.)
"""
import math
import random
import sys


def truth(x):
    return (0.02 * x - 2e-5 * x * x + 3.0 * math.sin(x / 40.0)
            + 4.0 * math.exp(-((x - 35.0) / 20.0) ** 2))


def main():
    rows = int(sys.argv[1])
    path = sys.argv[2]
    rng = random.Random(25)
    with open(path, "w") as w:
        w.write("position,EXX\n")
        for i in range(rows):
            x = -200.0 + 400.0 * i / (rows - 1)
            w.write(f"{x:.6f},{truth(x) + rng.gauss(0.0, 0.3):.5f}\n")


if __name__ == "__main__":
    main()
