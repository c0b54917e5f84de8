"""Per-block positions of SINUMERIK programs read by CEAD's nc-gcode-interpreter.

The reference side of volcomp's SINUMERIK differential test
(tests/it/sinumerik_differential.rs, docs/sinumerik-differential.md): one
Python process reads every program named on the command line and prints one
JSON object per program on standard output, in order:

  {"file": ..., "ok": true, "moves": [[line, motion, x, y, z, a, b, c], ...]}
  {"file": ..., "ok": false, "kind": ..., "line": ..., "message": ...}

`moves` are the blocks that program an axis (X Y Z A B C), in execution
order, with every axis's position after the block (the interpreter's
positions after frames; an axis never programmed is 0, where the control
starts) and the modal motion (G0 G1 G2 G3 ..., "G0" before any). The one
change to a program's text: a `%_N_..._MPF` / `_SPF` header line, which the
interpreter refuses, is read as an empty comment line (line numbers stay).
"""

import json
import pathlib
import sys

from nc_gcode_interpreter import NcError, nc_to_dataframe

AXES = ["X", "Y", "Z", "A", "B", "C"]


def program_text(path: pathlib.Path) -> str:
    text = path.read_text(encoding="utf-8", errors="replace")
    first, sep, rest = text.partition("\n")
    if first.lstrip().startswith("%_N_"):
        return ";" + sep + rest
    return text


def moves(text: str) -> list:
    df, _state = nc_to_dataframe(
        text,
        extra_axes=["A", "B", "C"],
        disable_forward_fill=True,
        include_line_numbers=True,
    )
    columns = set(df.columns)
    position = {axis: 0.0 for axis in AXES}
    motion = "G0"
    out = []
    for row in df.iter_rows(named=True):
        if row.get("gg01_motion") is not None:
            motion = row["gg01_motion"]
        programmed = [a for a in AXES if a in columns and row[a] is not None]
        for axis in programmed:
            position[axis] = float(row[axis])
        if programmed:
            out.append([row["line_no"], motion] + [position[a] for a in AXES])
    return out


def main() -> None:
    for name in sys.argv[1:]:
        path = pathlib.Path(name)
        try:
            result = {"file": name, "ok": True, "moves": moves(program_text(path))}
        except NcError as e:
            # The message's "Details:" line (its first sentence), else its first line.
            lines = [line.strip() for line in str(e).splitlines() if line.strip()]
            details = [line[len("Details:"):].strip() for line in lines if line.startswith("Details:")]
            message = (details or lines or [""])[0]
            result = {
                "file": name,
                "ok": False,
                "kind": e.kind,
                "line": e.line,
                "message": message[:200],
            }
        except Exception as e:  # the interpreter's other refusals (ValueError…)
            result = {
                "file": name,
                "ok": False,
                "kind": type(e).__name__,
                "line": None,
                "message": " ".join(str(e).split())[:300],
            }
        print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
