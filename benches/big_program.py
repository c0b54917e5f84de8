#!/usr/bin/env python3
"""Write a five-axis program of N motion blocks, like benches/gcode.rs's
`target/gcode-bench-1M.nc` (a seeded random walk of X Y Z A C, every 1000th
block inverse-time), for memory and time measurements at any length:

    python3 benches/big_program.py 10000000 target/bench-10M.nc
    /usr/bin/time -v target/release/volcomp predict machines/ref-trt.toml \
        target/bench-10M.nc --extrapolate hold --report target/bench-10M.json

(`--extrapolate hold`: the walk leaves ref-trt's Y and Z tables now and then.)
"""
import random
import sys


def main():
    blocks = int(sys.argv[1])
    path = sys.argv[2]
    rng = random.Random(2016)
    x = y = z = a = c = 0.0
    with open(path + ".tmp", "w", buffering=1 << 20) as w:
        w.write("%\nO1000 (BENCH: FIVE-AXIS BLOCKS)\nN1 G21 G90 G94 G17\n")
        w.write("N2 G0 X0. Y0. Z20. A0. C0.\nN3 G1 Z0. F800.\n")
        for i in range(blocks):
            x = min(max(x + rng.uniform(-0.8, 0.8), -200.0), 200.0)
            y = min(max(y + rng.uniform(-0.8, 0.8), -200.0), 200.0)
            z = min(max(z + rng.uniform(-0.2, 0.2), -50.0), 50.0)
            a = min(max(a + rng.uniform(-0.3, 0.3), -90.0), 90.0)
            c += rng.uniform(-0.2, 0.6)
            n = 10 * (i + 4)
            if i % 1000 == 999:
                w.write(f"N{n} G93 G1 X{x:.4f} Y{y:.4f} Z{z:.4f} A{a:.4f} C{c:.4f} "
                        f"F{rng.uniform(50.0, 5000.0):.4f}\nG94 F800.\n")
            else:
                w.write(f"N{n} X{x:.4f} Y{y:.4f} Z{z:.4f} A{a:.4f} C{c:.4f}\n")
        w.write("G0 Z50.\nM30\n%\n")
    import os
    os.replace(path + ".tmp", path)


if __name__ == "__main__":
    main()
