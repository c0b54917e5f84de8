#!/usr/bin/env python3
"""Writes the laser fixtures of tests/data/laser/ from the reference tables in
machines/ref-trt/: each target's mean bidirectional deviation is the table's value,
the reversal is known (B_i below), the run-to-run noise is seeded Gaussian.

    python3 tests/data/laser/make.py            # the fixtures (deterministic)
    python3 tests/data/laser/make.py --rows N OUT.csv   # a long-form file of >= N rows (bench)
"""
import csv, math, os, random, sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", "..", ".."))

def table(axis):
    with open(os.path.join(ROOT, "machines", "ref-trt", axis + ".csv")) as f:
        rows = [r for r in csv.reader(l for l in f if not l.startswith("#"))]
    head = rows[0]
    return head, [[float(v) for v in r] for r in rows[1:]]

def column(axis, name):
    head, rows = table(axis)
    k = head.index(name)
    return [(r[0], r[k]) for r in rows]

# Known reversal per fixture (µm or µrad): B_i = REV0 + REV1 * target / span.
def runs(points, reversal, sigma, n, seed, unit=1.0):
    """[(run, up, target, deviation)] in measuring order: run j goes up the
    targets, then down from the far end (descending)."""
    rnd = random.Random(seed)
    out = []
    for j in range(1, n + 1):
        for up in (True, False):
            seq = points if up else list(reversed(points))
            for t, e in seq:
                b = reversal(t)
                d = e + (b / 2 if up else -b / 2) + rnd.gauss(0.0, sigma)
                out.append((j, up, t, d * unit))
    return out

def fmt(v, decimals):
    return f"{v:.{decimals}f}"

def write(name, text):
    with open(os.path.join(HERE, name), "w", encoding="utf-8", newline="") as f:
        f.write(text)

def x_reversal(t):
    return 6.0 + 1.0 * t / 200.0     # 5 µm at X-200 to 7 µm at X200

def main():
    x = column("x", "EXX")
    # 1. Long form, comma separated, µm, the contract's header.
    rows = runs(x, x_reversal, 0.3, 5, 1)
    text = "# X positioning, 5 bidirectional runs; made by make.py from machines/ref-trt/x.csv\n"
    text += "target,run,direction,deviation\n"
    text += "".join(f"{fmt(t,3)},{j},{'+' if up else '-'},{fmt(d,4)}\n" for j, up, t, d in rows)
    write("x-long.csv", text)
    # 2. Semicolon, decimal comma, deviation in mm, up/down words.
    rows = runs(x, x_reversal, 0.3, 5, 2, unit=1e-3)
    text = "target [mm];run;direction;deviation [mm]\n"
    text += "".join(f"{fmt(t,3).replace('.',',')};{j};{'up' if up else 'down'};{fmt(d,7).replace('.',',')}\n"
                    for j, up, t, d in rows)
    write("x-semicolon.csv", text)
    # 3. Paired: a target and run a row, forward and reverse deviations (um).
    rows = runs(x, x_reversal, 0.3, 5, 3)
    pair = {}
    for j, up, t, d in rows:
        pair.setdefault((j, t), {})[up] = d
    text = "target [mm],run,fwd [um],rev [um]\n"
    text += "".join(f"{fmt(t,3)},{j},{fmt(p[True],4)},{fmt(p[False],4)}\n"
                    for (j, t), p in sorted(pair.items(), key=lambda kv: (kv[0][0], -kv[0][1])))
    write("x-paired.csv", text)
    # 4. Wide, tab separated, µm: the spreadsheet export; targets descending.
    y = column("y", "EYY")
    rows = runs(y, lambda t: 4.0, 0.25, 3, 4)
    wide = {}
    for j, up, t, d in rows:
        wide.setdefault(t, {})[(j, up)] = d
    cols = [(j, up) for j in range(1, 4) for up in (True, False)]
    text = "target [mm]\t" + "\t".join(f"Run {j} {'+' if up else '-'} [µm]" for j, up in cols) + "\n"
    text += "".join(fmt(t, 3) + "\t" + "\t".join(fmt(wide[t][c], 3) for c in cols) + "\n"
                    for t in sorted(wide, reverse=True))
    write("y-wide.tsv", text)
    # 5. Straightness EYX (µm) and pitch EBX (arcsec) of X, long form, no reversal.
    rows = runs(column("x", "EYX"), lambda t: 0.0, 0.2, 3, 5)
    text = "target,run,direction,EYX [µm]\n"
    text += "".join(f"{fmt(t,3)},{j},{'+' if up else '-'},{fmt(d,4)}\n" for j, up, t, d in rows)
    write("x-straightness-eyx.csv", text)
    arcsec = math.pi / (180 * 3600) * 1e6
    rows = runs(column("x", "EBX"), lambda t: 0.0, 0.5, 3, 6, unit=1 / arcsec)
    text = "target;run;direction;deviation [arcsec]\n"
    text += "".join(f"{fmt(t,3).replace('.',',')};{j};{'fwd' if up else 'rev'};{fmt(d,5).replace('.',',')}\n"
                    for j, up, t, d in rows)
    write("x-pitch-ebx.csv", text)
    # 6. A axis positioning, deviations in arcsec, reversal 10 µrad.
    rows = runs(column("a", "EAA"), lambda t: 10.0, 1.0, 5, 7, unit=1 / arcsec)
    text = "target [deg],run,direction,deviation [arcsec]\n"
    text += "".join(f"{fmt(t,3)},{j},{'+' if up else '-'},{fmt(d,5)}\n" for j, up, t, d in rows)
    write("a-long.csv", text)

    # 7. As CARTO-style software exports: metadata lines without '#', the long
    #    form with arrows, per-reading environment columns and a comment column.
    rows = runs(x, x_reversal, 0.3, 5, 11)
    text = ("Renishaw CARTO Explore export\nMachine,ref-trt (volcomp fixture)\nAxis,X\n"
            "Date,2026-11-20 09:14\nOperator,make.py\n\n")
    text += "Target (mm),Run,Direction,Error (µm),Air temp (°C),Material temp (°C),Pressure (mbar),Comment\n"
    for k, (j, up, t, d) in enumerate(rows):
        note = "restart after door open" if k == 17 else ""
        text += (f"{fmt(t,3)},{j},{'↑' if up else '↓'},{fmt(d,4)},{fmt(20.1 + 0.0004 * k,2)},"
                 f"{fmt(20.4 + 0.0003 * k,2)},{fmt(1012.5 - 0.002 * k,1)},{note}\n")
    write("x-carto-preamble.csv", text)
    # 8. German, Latin-1 (as Windows software saves it), ';' and decimal commas,
    #    vorwärts/rückwärts, a temperature and a remark column; Z, B_i = 3 µm.
    z = column("z", "EZZ")
    rows = runs(z, lambda t: 3.0, 0.3, 4, 12)
    text = "Messung Z-Achse;Positionierung nach ISO 230-2\nMaschine;ref-trt\n"
    text += "Sollposition [mm];Lauf;Richtung;Abweichung [µm];Lufttemperatur [°C];Bemerkung\n"
    text += "".join(f"{fmt(t,3).replace('.',',')};{j};{'vorwärts' if up else 'rückwärts'};"
                    f"{fmt(d,4).replace('.',',')};{fmt(20.2,1).replace('.',',')};\n"
                    for j, up, t, d in rows)
    with open(os.path.join(HERE, "z-german-latin1.csv"), "w", encoding="latin-1", newline="") as f:
        f.write(text)
    # 9. German wide, tab separated, decimal commas, hin/rück, units in a
    #    units line under the header; Y, B_i = 4 µm.
    rows = runs(y, lambda t: 4.0, 0.25, 3, 13)
    wide = {}
    for j, up, t, d in rows:
        wide.setdefault(t, {})[(j, up)] = d
    cols = [(j, up) for j in range(1, 4) for up in (True, False)]
    text = "Sollposition\t" + "\t".join(f"Lauf {j} {'hin' if up else 'rück'}" for j, up in cols) + "\n"
    text += "mm\t" + "\t".join("µm" for _ in cols) + "\n"
    text += "".join(fmt(t, 3).replace('.', ',') + "\t" + "\t".join(fmt(wide[t][c], 3).replace('.', ',') for c in cols) + "\n"
                    for t in sorted(wide))
    write("y-german-wide.tsv", text)
    # 10. Inch: targets in inches, deviations in microinches, paired
    #     forward/reverse columns; Y, B_i = 4 µm.
    rows = runs(y, lambda t: 4.0, 0.25, 3, 14, unit=1 / 0.0254)
    pair = {}
    for j, up, t, d in rows:
        pair.setdefault((j, t), {})[up] = d
    text = "Target [in],Run,Forward [µin],Reverse [µin]\n"
    text += "".join(f"{t / 25.4:.7f},{j},{fmt(p[True],1)},{fmt(p[False],1)}\n"
                    for (j, t), p in sorted(pair.items()))
    write("y-inch-paired.csv", text)
    # 11. A units line in brackets, mils, up/down; Z, B_i = 3 µm.
    rows = runs(z, lambda t: 3.0, 0.3, 3, 15, unit=1 / 25.4)
    text = "Position,Run,Dir,Error\n[mm],,,[mil]\n"
    text += "".join(f"{fmt(t,3)},{j},{'up' if up else 'down'},{fmt(d,5)}\n" for j, up, t, d in rows)
    write("z-units-line-mil.csv", text)

def bench(rows_wanted, out):
    x = column("x", "EXX")
    n = max(1, -(-rows_wanted // (2 * len(x))))
    rows = runs(x, x_reversal, 0.3, n, 9)
    with open(out, "w") as f:
        f.write("target,run,direction,deviation\n")
        for j, up, t, d in rows:
            f.write(f"{t:.3f},{j},{'+' if up else '-'},{d:.4f}\n")

if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--rows":
        bench(int(sys.argv[2]), sys.argv[3])
    else:
        main()
