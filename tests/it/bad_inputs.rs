//! The bad-input matrix: every kind of file a user hands over, malformed in
//! the ways files are, through the command that reads it. Each case states
//! the exit code, what the message must say (file, line, column where they
//! apply) and that no output file is left. `docs/bad-inputs.md` is this table;
//! the test fails when the two differ (`VOLCOMP_WRITE_BAD_INPUTS=1` rewrites it).
use crate::compensate::ref_trt;
use crate::support::{root, volcomp};
use std::path::Path;

/// A good five-axis program, small.
const PROGRAM: &str =
    "%\nG21 G90 G94\nG0 X0 Y0 Z10 A10 C0\nG1 X5 Y5 Z2 A12 C30 F500\nG1 X10 Y2 Z1 A15 C60\nM30\n%\n";

struct Case {
    /// What the user hands over.
    input: &'static str,
    /// How it is malformed.
    what: &'static str,
    /// Files written into the scratch folder (name, bytes).
    files: Vec<(&'static str, Vec<u8>)>,
    /// Command line; `{d}` is the scratch folder.
    args: &'static str,
    code: i32,
    /// What stderr (or, for accepted inputs, stdout) must contain; `{d}` as above.
    expect: Vec<&'static str>,
}

fn case(
    input: &'static str,
    what: &'static str,
    files: Vec<(&'static str, Vec<u8>)>,
    args: &'static str,
    code: i32,
    expect: &[&'static str],
) -> Case {
    Case {
        input,
        what,
        files,
        args,
        code,
        expect: expect.to_vec(),
    }
}

const COMPENSATE: &str = "compensate {d}/ok.toml {d}/bad.nc -o {d}/out.nc --model {d}/fit.json";
const SINUMERIK: &str = "compensate {d}/ok.toml {d}/bad.mpf -o {d}/out.mpf --model {d}/fit.json";
const SINUMERIK_TOOLS: &str =
    "compensate {d}/ok.toml {d}/bad.mpf -o {d}/out.mpf --model {d}/fit.json --tools {d}/named.tbl";
const SINUMERIK_OFFSET: &str =
    "compensate {d}/ok.toml {d}/ok.nc -o {d}/out.nc --model {d}/fit.json --offset G600=1,2,3";
const SINUMERIK_SYSVAR: &str =
    "compensate {d}/ok.toml {d}/ok.nc -o {d}/out.nc --model {d}/fit.json --sysvar AA_IW=1";
const MACHINE: &str = "compensate {d}/bad.toml {d}/ok.nc -o {d}/out.nc --model {d}/fit.json";
const TABLE: &str = "compensate {d}/table.toml {d}/ok.nc -o {d}/out.nc";
const PLAN: &str =
    "predict {d}/ok.toml {d}/ok.nc --plan {d}/bad.csv --report {d}/out.json --model {d}/fit.json";
const MEASURED: &str =
    "diagnose {d}/ok.toml {d}/ok.nc {d}/bad.csv --report {d}/out.json --model {d}/fit.json";
const MODEL: &str = "compensate {d}/ok.toml {d}/ok.nc -o {d}/out.nc --model {d}/bad.json";
const TOOLS: &str =
    "compensate {d}/ok.toml {d}/ok.nc -o {d}/out.nc --model {d}/fit.json --tools {d}/bad.tbl";
const OFFSETS: &str = "compensate {d}/ok.toml {d}/ok.nc -o {d}/out.nc --model {d}/fit.json --offset G54=0,0,0 --offset G54=1,0,0";
const FOLLOWUP: &str = "diagnose {d}/ok.toml {d}/ok.nc {d}/ok.csv --report {d}/out.json --model {d}/fit.json --followup {d}/bad.csv";
const WRITE_MACHINE_INPUT: &str = "diagnose {d}/ok.toml {d}/ok.nc {d}/ok.csv --report {d}/out.json --model {d}/fit.json --write-machine {d}/ok.toml";
const WRITE_MACHINE_MEASUREMENT: &str = "diagnose {d}/ok.toml {d}/ok.nc {d}/ok.csv --report {d}/out.json --model {d}/fit.json --write-machine {d}/ok.csv";
const WRITE_MACHINE_NO_FOLDER: &str = "diagnose {d}/ok.toml {d}/ok.nc {d}/ok.csv --report {d}/out.json --model {d}/fit.json --write-machine {d}/ok.nc/out.toml";
const WRITE_MACHINE_STDOUT: &str = "diagnose {d}/ok.toml {d}/ok.nc {d}/ok.csv --report {d}/out.json --model {d}/fit.json --write-machine -";
const SIMULATE: &str = "simulate {d}/ok.toml {d}/saddle.nc {d}/plan.csv -o {d}/out.csv --model {d}/fit.json --effect tool_wear:w=1e308";
const LOOP: &str =
    "compensate {d}/ok.toml {d}/bad.nc -o {d}/out.nc --model {d}/fit.json --max-loop-lines 100000";
const LENIENT_LOOP: &str = "compensate {d}/ok.toml {d}/bad.nc -o {d}/out.nc --model {d}/fit.json --lenient --max-loop-lines 100000";
const MOVES: &str =
    "compensate {d}/ok.toml {d}/bad.nc -o {d}/out.nc --model {d}/fit.json --max-moves 1000";
const LASER: &str = "import-laser {d}/bad.csv --axis X -o {d}/out.csv --report {d}/out.json";
const VAR: &str =
    "compensate {d}/ok.toml {d}/ok.nc -o {d}/out.nc --model {d}/fit.json --var {d}/bad.var";

fn text(s: &str) -> Vec<u8> {
    s.as_bytes().to_vec()
}

fn binary() -> Vec<u8> {
    // Deterministic noise with NUL and high bytes.
    (0u32..3000)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect()
}

/// The reference machine text with `from` replaced by `to`.
fn machine(from: &str, to: &str) -> Vec<u8> {
    let text = std::fs::read_to_string(root().join("machines/ref-trt.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    text.replacen(from, to, 1).into_bytes()
}

/// The reference machine text with `[reversal]` and `entries` appended.
fn with_reversal(entries: &str) -> Vec<u8> {
    let text = std::fs::read_to_string(root().join("machines/ref-trt.toml")).unwrap();
    format!("{text}\n[reversal]\n{entries}\n").into_bytes()
}

/// The X table with line `line` (1-based) replaced (`None`: removed from
/// there on), and a machine file `table.toml` reading it.
fn table(edit: impl Fn(&mut Vec<String>)) -> Vec<(&'static str, Vec<u8>)> {
    let text = std::fs::read_to_string(root().join("machines/ref-trt/x.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    edit(&mut lines);
    vec![
        ("table.toml", machine("\"ref-trt/x.csv\"", "\"bad-x.csv\"")),
        ("bad-x.csv", (lines.join("\n") + "\n").into_bytes()),
    ]
}

/// `row` with its field `k` replaced by `nan`.
fn nan_at(row: &str, k: usize) -> String {
    let mut f: Vec<&str> = row.split(',').collect();
    f[k] = "nan";
    f.join(",")
}

fn plan_rows(rows: &[&str]) -> Vec<u8> {
    let mut s = String::from("id,x,y,z,i,j,k\n");
    for r in rows {
        s.push_str(r);
        s.push('\n');
    }
    s.into_bytes()
}

/// A follow-up measurement: the header and `rows`.
fn followup_rows(rows: &[&str]) -> Vec<u8> {
    let mut s = String::from("id,x,y,z,i,j,k,a,c,t_min,mx,my,mz\n");
    for r in rows {
        s.push_str(r);
        s.push('\n');
    }
    s.into_bytes()
}

/// A measurement: rows `id,x,y,z,i,j,k,mx,my,mz` on a 6 × 5 grid near the
/// program's path, with `extra` appended.
fn measured(extra: &[&str], rows: usize) -> Vec<u8> {
    let mut s = String::from("id,x,y,z,i,j,k,mx,my,mz\n");
    for n in 0..rows {
        let (x, y) = ((n % 6) as f64, (n / 6) as f64);
        s.push_str(&format!("{},{x},{y},1,0,0,1,{x},{y},1.001\n", n + 1));
    }
    for r in extra {
        s.push_str(r);
        s.push('\n');
    }
    s.into_bytes()
}

fn cases() -> Vec<Case> {
    let p = |s: &str| vec![("bad.nc", text(s))];
    let mut long_comment = b"%\nG21 G90\n(".to_vec();
    long_comment.extend(std::iter::repeat_n(b'x', 50 << 20));
    long_comment.extend(b") \x01\nG1 X1 Y1 Z1 A10 C0 F100\nM30\n%\n");
    let mut fair_comment = b"%\nG21 G90\n(".to_vec();
    fair_comment.extend(std::iter::repeat_n(b'x', 60_000));
    fair_comment.extend(b")\nG1 X1 Y1 Z1 A10 C0 F100\nM30\n%\n");
    let nested = |n: usize, open: &str, inner: &str, close: &str| {
        let mut s = String::from("%\nG21 G90 F100\n#1 = 1\nG1 X");
        for _ in 0..n {
            s.push_str(open);
        }
        s.push_str(inner);
        for _ in 0..n {
            s.push_str(close);
        }
        s.push_str(" Y1 Z1 A10 C0\nM30\n%\n");
        vec![("bad.nc", s.into_bytes())]
    };
    let terms = {
        let sum = vec!["1"; 20_000].join("+");
        vec![(
            "bad.nc",
            format!("%\nG21 G90 F100\nG1 X[{sum}] Y1 Z1 A10 C0\nM30\n%\n").into_bytes(),
        )]
    };
    let many_tools: String = (1..=2000).map(|t| format!("T{t} P{t} Z50 D6\n")).collect();
    let mut long_number = b"%\nG21 G90\nG1 X".to_vec();
    long_number.extend(std::iter::repeat_n(b'1', 50 << 20));
    long_number.extend(b" F100\nM30\n%\n");
    vec![
        // Programs.
        case(
            "program",
            "empty file",
            p(""),
            COMPENSATE,
            1,
            &[
                "File ended with no percent sign or program end",
                "{d}/bad.nc:1:1",
            ],
        ),
        case(
            "program",
            "binary file",
            vec![("bad.nc", binary())],
            COMPENSATE,
            1,
            &["{d}/bad.nc:1:"],
        ),
        case(
            "program",
            "non-UTF-8 byte in a word",
            vec![("bad.nc", b"%\nG21\nG1 X1\xff Y0 F100\nM30\n%\n".to_vec())],
            COMPENSATE,
            1,
            &["unexpected character", "{d}/bad.nc:3:6"],
        ),
        case(
            "program",
            "non-UTF-8 byte in a comment (accepted, kept byte for byte)",
            vec![(
                "bad.nc",
                b"%\nG21 G90\n(caf\xe9)\nG1 X1 Y1 Z1 A10 C0 F100\nM30\n%\n".to_vec(),
            )],
            COMPENSATE,
            0,
            &["blocks read"],
        ),
        case(
            "program",
            "CR-only (classic Mac) line ends",
            p("%\rG21 G90\rG1 X1 Y1 Z1 A10 C0 F100\rM30\r%\r"),
            COMPENSATE,
            1,
            &["carriage return inside the line", "{d}/bad.nc:1:2"],
        ),
        case(
            "program",
            "a 50 MB comment line, a bad character at its end",
            vec![("bad.nc", long_comment)],
            COMPENSATE,
            1,
            &[
                "line of 52428804 bytes, longer than volcomp's limit of 65536 bytes",
                "{d}/bad.nc:3:1",
            ],
        ),
        case(
            "program",
            "a 60 000-byte comment line (accepted)",
            vec![("bad.nc", fair_comment)],
            COMPENSATE,
            0,
            &["blocks read"],
        ),
        case(
            "program",
            "20 000 nested brackets `[[[…1…]]]`",
            nested(20_000, "[", "1", "]"),
            COMPENSATE,
            1,
            &[
                "expression nested more than 256 levels deep",
                "{d}/bad.nc:4:",
            ],
        ),
        case(
            "program",
            "10 000 nested functions `abs[abs[…]]`",
            nested(10_000, "abs[", "1", "]"),
            COMPENSATE,
            1,
            &[
                "expression nested more than 256 levels deep",
                "{d}/bad.nc:4:",
            ],
        ),
        case(
            "program",
            "20 000 nested references `##…#1`",
            nested(20_000, "#", "1", ""),
            COMPENSATE,
            1,
            &[
                "expression nested more than 256 levels deep",
                "{d}/bad.nc:4:",
            ],
        ),
        case(
            "program",
            "an expression of 20 000 terms",
            terms,
            COMPENSATE,
            1,
            &[
                "expression of more than 4096 terms and operations",
                "{d}/bad.nc:3:",
            ],
        ),
        case(
            "SINUMERIK program",
            "an IF without its ENDIF",
            vec![("bad.mpf", text("G0 X0 Y0 Z10\nIF R1>0\nG1 X1 F100\nM30\n"))],
            SINUMERIK,
            1,
            &["IF is never closed: no ENDIF follows", "{d}/bad.mpf:2:1"],
        ),
        case(
            "SINUMERIK program",
            "a GOTOF to no label",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nGOTOF SKIP\nG1 X1 F100\nM30\n"),
            )],
            SINUMERIK,
            1,
            &[
                "jump destination `SKIP` not found (GOTOF searches forward)",
                "{d}/bad.mpf:2:1",
            ],
        ),
        case(
            "SINUMERIK program",
            "a recursive PROC",
            vec![
                ("bad.mpf", text("G0 X0 Y0 Z10\nDEEP(1)\nM30\n")),
                (
                    "DEEP.SPF",
                    text("PROC DEEP(REAL N)\nG1 X=N F100\nDEEP(N+1)\nRET\n"),
                ),
            ],
            SINUMERIK,
            1,
            &["recursive call of `DEEP`", "DEEP.SPF:3:1"],
        ),
        case(
            "SINUMERIK program",
            "a DEF after the first motion block",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nDEF REAL LATE=1\nG1 X=LATE F100\nM30\n"),
            )],
            SINUMERIK,
            1,
            &["DEF after the first motion block", "{d}/bad.mpf:2:1"],
        ),
        case(
            "SINUMERIK program",
            "a rounding `RND=` too large for its elements",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nG1 X10 RND=20 F100\nY10\nM30\n"),
            )],
            SINUMERIK,
            1,
            &["too large for its elements", "{d}/bad.mpf:2:8"],
        ),
        case(
            "SINUMERIK program",
            "a rounding `RND=` on the last motion block",
            vec![("bad.mpf", text("G0 X0 Y0 Z10\nG1 X10 RND=2 F100\nM30\n"))],
            SINUMERIK,
            1,
            &["on the last motion block", "{d}/bad.mpf:2:8"],
        ),
        case(
            "SINUMERIK program",
            "an orientation vector of length 0 (`A3=0 B3=0 C3=0`)",
            vec![(
                "bad.mpf",
                text("TRAORI\nG1 X0 Y0 Z10 A3=0 B3=0 C3=0 F100\nM30\n"),
            )],
            SINUMERIK,
            1,
            &[
                "orientation vector A3 B3 C3 of length 0",
                "{d}/bad.mpf:2:14",
            ],
        ),
        case(
            "SINUMERIK program",
            "an orientation vector without `TRAORI` (`A3= B3= C3=`)",
            vec![("bad.mpf", text("G1 X0 Y0 Z10 A3=0 B3=0.5 C3=1 F100\nM30\n"))],
            SINUMERIK,
            1,
            &["needs TRAORI", "{d}/bad.mpf:1:14"],
        ),
        case(
            "SINUMERIK program",
            "a `CIP` whose intermediate point is on the line from start to end",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nCIP X10 Y0 I1=5 J1=0 F100\nM30\n"),
            )],
            SINUMERIK,
            1,
            &["lie on one line: no circle passes", "{d}/bad.mpf:2:1"],
        ),
        case(
            "SINUMERIK program",
            "a tool turned by 180° in one block under `ORIVECT` (no great circle)",
            vec![(
                "bad.mpf",
                text("TRAORI\nG1 X0 Y0 Z10 A3=0 B3=1 C3=0 F100\nG1 X1 A3=0 B3=-1 C3=0\nM30\n"),
            )],
            SINUMERIK,
            1,
            &["turns by 180° in one block", "{d}/bad.mpf:3:7"],
        ),
        case(
            "SINUMERIK program",
            "a circle in a tilted plane (`ROT Y30`) that also turns the tool without TRAORI",
            vec![(
                "bad.mpf",
                text("ROT Y30\nG1 X10 Y0 Z0 F100\nG3 X0 Y10 I-10 J0 C10\nM30\n"),
            )],
            SINUMERIK,
            1,
            &["also turns the tool without TRAORI", "{d}/bad.mpf:3:19"],
        ),
        case(
            "SINUMERIK program",
            "a circle of opening angle 0 (`AR=0`)",
            vec![("bad.mpf", text("G0 X0 Y0 Z10\nG2 X10 Y0 AR=0 F100\nM30\n"))],
            SINUMERIK,
            1,
            &["AR=0: a circle's opening angle", "{d}/bad.mpf:2:11"],
        ),
        case(
            "SINUMERIK program",
            "a `REPEAT` to no label",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nG1 X1 F100\nREPEAT START P=2\nM30\n"),
            )],
            SINUMERIK,
            1,
            &["REPEAT: the label `START` is not in", "{d}/bad.mpf:3:8"],
        ),
        case(
            "SINUMERIK program",
            "a `REPEAT` of a later label with no `ENDLABEL`",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nREPEAT LATER P=2\nLATER: G1 X1 F100\nM30\n"),
            )],
            SINUMERIK,
            1,
            &[
                "the label follows the statement, and no ENDLABEL closes the section",
                "{d}/bad.mpf:2:8",
            ],
        ),
        case(
            "SINUMERIK program",
            "a value passed to a `VAR` parameter",
            vec![
                ("bad.mpf", text("G0 X0 Y0 Z10\nDOWN(2)\nM30\n")),
                (
                    "DOWN.SPF",
                    text("PROC DOWN(VAR REAL DEPTH)\nG1 Z=DEPTH F100\nRET\n"),
                ),
            ],
            SINUMERIK,
            1,
            &["`DEPTH` of DOWN is a VAR parameter", "{d}/bad.mpf:2:1"],
        ),
        case(
            "SINUMERIK program",
            "a tool by name (`T=\"…\"`) that no tool table entry names",
            vec![
                ("bad.mpf", text("G0 X0 Y0 Z10\nT=\"DRILL 9\" M6\nM30\n")),
                ("named.tbl", text("T1 P1 Z100 D6 ;MILL 6\n")),
            ],
            SINUMERIK_TOOLS,
            1,
            &[
                "tool \"DRILL 9\" is not in the tool table",
                "{d}/bad.mpf:2:1",
            ],
        ),
        case(
            "SINUMERIK settable frame",
            "`--offset G600=…` (G505–G599 are the settable frames)",
            vec![],
            SINUMERIK_OFFSET,
            2,
            &["`G600` is not a work coordinate system"],
        ),
        case(
            "SINUMERIK program",
            "a system variable the control knows only at run time (`$AA_IW[X]`), not given",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nR1=$AA_IW[X]\nG1 X=R1 F100\nM30\n"),
            )],
            SINUMERIK,
            1,
            &[
                "system variable `$AA_IW[X]` has no value offline",
                "--sysvar '$AA_IW[X]=VALUE'",
                "{d}/bad.mpf:2:4",
            ],
        ),
        case(
            "SINUMERIK program",
            "a B spline point weight out of the manual's range (`PW=4`)",
            vec![(
                "bad.mpf",
                text("G0 X0 Y0 Z10\nG1 X0 F100\nBSPLINE X10 Y5 PW=4\nX20 Y0\nM30\n"),
            )],
            SINUMERIK,
            1,
            &[
                "PW=4: a point weight is more than 0 and at most 3",
                "{d}/bad.mpf:3:16",
            ],
        ),
        case(
            "SINUMERIK program",
            "a `VAR` array parameter given an array of another size",
            vec![
                (
                    "bad.mpf",
                    text("DEF REAL V[4]\nG0 X0 Y0 Z10\nFILL(V)\nM30\n"),
                ),
                ("FILL.SPF", text("PROC FILL(VAR REAL A[3])\nA[0]=1\nRET\n")),
            ],
            SINUMERIK,
            1,
            &[
                "`V` has dimensions [4]; `A` of FILL takes [3]",
                "{d}/bad.mpf:3:1",
            ],
        ),
        case(
            "SINUMERIK system variable",
            "`--sysvar AA_IW=1` (no `$`)",
            vec![],
            SINUMERIK_SYSVAR,
            2,
            &["a system variable's name starts with `$`"],
        ),
        case(
            "program",
            "an endless `while [1]` (--max-loop-lines 100000)",
            p(
                "%\nG21 G90 G94 F500\no1 while [1]\nG1 X1 Y1 Z1 A10 C0\nG1 X2 Y1 Z1 A10 C0\no1 endwhile\nM30\n%\n",
            ),
            LOOP,
            1,
            &[
                "more than 100000 lines in loops and calls, in `o1 while` (line 3)",
                "{d}/bad.nc:",
            ],
        ),
        case(
            "program",
            "an error inside a loop under --lenient (the counter never grows)",
            p(
                "%\nG21 G90 G94 F500\n#1 = 0\no1 while [#1 LT 10]\nG1 X#1 Y1 Z1 A10 C0\n#1 = [#1 + 1)\no1 endwhile\nM30\n%\n",
            ),
            LENIENT_LOOP,
            1,
            &[
                "more than 100000 lines in loops and calls, in `o1 while` (line 4)",
                "{d}/bad.nc:",
            ],
        ),
        case(
            "program",
            "a canned cycle of 62 000 holes in a `repeat [1000000]` (1.9e11 moves)",
            p(
                "%\nG21 G90 G94 F500\nG0 X0 Y0 Z10 A10 C0\no1 repeat [1000000]\nG91 G81 X1 Y0 Z-1 R1 L62000\nG90\no1 endrepeat\nM30\n%\n",
            ),
            COMPENSATE,
            1,
            &[
                "this block would generate about 1.860e11 moves (186001 per execution × 1000000 executions of `o1 repeat` (line 4))",
                "{d}/bad.nc:5:1",
            ],
        ),
        case(
            "program",
            "a loop generating moves past --max-moves 1000",
            p(
                "%\nG21 G90 G94 F500\n#1 = 0\no1 while [#1 LT 100000]\nG1 X[#1 / 1000] Y1 Z1 A10 C0\n#1 = [#1 + 1]\no1 endwhile\nM30\n%\n",
            ),
            MOVES,
            1,
            &[
                "more than 1000 generated moves (loops, calls, canned cycles, splines), in `o1 while` (line 4)",
                "{d}/bad.nc:5:1",
            ],
        ),
        case(
            "program",
            "a 50 MB number",
            vec![("bad.nc", long_number)],
            COMPENSATE,
            1,
            &[
                "longer than volcomp's limit of 65536 bytes",
                "{d}/bad.nc:3:1",
            ],
        ),
        case(
            "program",
            "`X1e400` (X1 and an E word)",
            p("%\nG21\nG1 X1e400 F100\nM30\n%\n"),
            COMPENSATE,
            1,
            &["E word with no G or M code that uses it", "{d}/bad.nc:3:6"],
        ),
        case(
            "program",
            "`Xnan`",
            p("%\nG21\nG1 Xnan F100\nM30\n%\n"),
            COMPENSATE,
            1,
            &["word `X` has no number", "{d}/bad.nc:3:4"],
        ),
        case(
            "program",
            "an expression overflowing to infinity",
            p("%\nG21\nG1 X[10**400] F100\nM30\n%\n"),
            COMPENSATE,
            1,
            &["Calculation resulted in 'infinity'", "{d}/bad.nc:3:5"],
        ),
        case(
            "program",
            "division by zero",
            p("%\nG21\nG1 X[1/0] F100\nM30\n%\n"),
            COMPENSATE,
            1,
            &["Attempt to divide by zero", "{d}/bad.nc:3:5"],
        ),
        case(
            "program",
            "a byte order mark at the start (LinuxCNC: Bad character)",
            vec![(
                "bad.nc",
                [b"\xEF\xBB\xBF".as_slice(), PROGRAM.as_bytes()].concat(),
            )],
            COMPENSATE,
            1,
            &["Bad character '\\357' used", "{d}/bad.nc:1:1"],
        ),
        case(
            "program",
            "assigning a read-only parameter (`#<_vmajor>=1`)",
            p("%\n#<_vmajor>=1\nG21 G90 G94\nG1 X5 Y5 Z2 A12 C30 F500\nM30\n%\n"),
            COMPENSATE,
            1,
            &["#<_vmajor> is read-only", "{d}/bad.nc:2:"],
        ),
        case(
            "program",
            "a rotary word in a canned cycle (named by its own letter)",
            p("%\nG21 G90 G17 G98\nG0 X0 Y0 Z20 A0 C0\nG81 X10 Y10 Z-5 R2 C10 F100\nM30\n%\n"),
            COMPENSATE,
            1,
            &["Cannot put a c in canned cycle", "{d}/bad.nc:4:"],
        ),
        case(
            "program",
            "a B word in a canned cycle (`check`, X Y Z A B C as rs274 reads)",
            p("%\nG21 G90 G17 G98\nG0 X0 Y0 Z20\nG81 X10 Y10 Z-5 R2 B10 F100\nM30\n%\n"),
            "check {d}/bad.nc",
            1,
            &["Cannot put a b in canned cycle", "{d}/bad.nc:4:"],
        ),
        case(
            "program",
            "an arc `P` beyond an int (LinuxCNC: not an integer)",
            p("%\nG21 G90 G17\nG0 X10 Y0 Z0 A10 C0\nG2 X10 Y0 I-10 J0 P2147483648 F500\nM30\n%\n"),
            COMPENSATE,
            1,
            &["P value not an integer with G2 or G3", "{d}/bad.nc:4:19"],
        ),
        case(
            "program",
            "an arc of 100,001 turns (more straight pieces than volcomp writes)",
            p(
                "%\nG21 G90 G17\nG0 X-50 Y0 Z10 A0 C0\nG1 X-40 Z0 F500\nG2 X-40 Y0 I40 J0 P100001\nM30\n%\n",
            ),
            COMPENSATE,
            1,
            &[
                "{d}/bad.nc:5: the correction varies along this arc",
                "more than the 100000 volcomp writes for one arc",
            ],
        ),
        case(
            "program",
            "a spline that needs more than 100,000 straight pieces (`--tol 1e-6`)",
            p("%\nG21 G90 G17 F600\nG0 X0 Y0 Z0 A10 C0\nG5 I10 J0 P-10 Q0 X30 Y20\nM30\n%\n"),
            "compensate {d}/ok.toml {d}/bad.nc -o {d}/out.nc --model {d}/fit.json --tol 1e-6",
            1,
            &[
                "the curve needs more than 100000 straight pieces to stay within the tolerance of it",
                "{d}/bad.nc:4:1",
            ],
        ),
        case(
            "program",
            "Heidenhain: a jump to a label the program does not define",
            p(
                "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 L X+1 Y+1 Z+1 A+10 C+0 R0 F100\n3 FN 9: IF +0 EQU +0 GOTO LBL 7\n4 END PGM T MM\n",
            ),
            COMPENSATE,
            1,
            &[
                "jump to LBL 7, which the program does not define",
                "{d}/bad.nc:4:3",
            ],
        ),
        case(
            "program",
            "Heidenhain: END PGM missing",
            p("0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 L X+1 Y+1 Z+1 A+10 C+0 R0 F100\n"),
            COMPENSATE,
            1,
            &["the program bad ends without END PGM", "{d}/bad.nc:3:"],
        ),
        case(
            "program",
            "Heidenhain: C with no CC before it",
            p(
                "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 L X+1 Y+1 Z+1 A+10 C+0 R0 F100\n3 C X+0 Y+2 DR+\n4 END PGM T MM\n",
            ),
            COMPENSATE,
            1,
            &[
                "no circle centre: program CC before C, CP or LP",
                "{d}/bad.nc:4:3",
            ],
        ),
        case(
            "program",
            "Heidenhain: a PLANE the machine cannot reach (A 120° on an A ±110° table)",
            p(
                "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 PLANE SPATIAL SPA+0 SPB+120 SPC+0 TURN FMAX\n3 L X+1 Y+1 Z+1 R0 F100\n4 END PGM T MM\n",
            ),
            COMPENSATE,
            1,
            &[
                "the machine cannot reach this working plane",
                "{d}/bad.nc:3:",
            ],
        ),
        case(
            "program",
            "Heidenhain: RND with a radius too large for its corner",
            p(
                "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 L X+0 Y+0 Z+1 R0 F100\n3 L X+10\n4 RND R20\n5 L Y+10\n6 END PGM T MM\n",
            ),
            COMPENSATE,
            1,
            &["RND 20: too large for the corner", "{d}/bad.nc:5:3"],
        ),
        case(
            "program",
            "Heidenhain: LN with a zero vector",
            p(
                "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 M128\n3 LN X+1 Y+1 Z+1 NX+0 NY+0 NZ+0 R0 F100\n4 END PGM T MM\n",
            ),
            COMPENSATE,
            1,
            &["LN with a zero normal vector", "{d}/bad.nc:4:3"],
        ),
        case(
            "program",
            "Heidenhain: a block number out of order",
            p(
                "0 BEGIN PGM T MM\n2 TOOL CALL 1 Z\n1 L X+1 Y+1 Z+1 A+10 C+0 R0 F100\n3 END PGM T MM\n",
            ),
            COMPENSATE,
            1,
            &[
                "block number 1 out of order: after block 2",
                "{d}/bad.nc:3:1",
            ],
        ),
        case(
            "program",
            "a target outside the machine's travel",
            p("%\nG21\nG1 X900 Y0 Z0 A0 C0 F100\nM30\n%\n"),
            COMPENSATE,
            1,
            &["{d}/bad.nc:3: X = 900 is outside the X error table"],
        ),
        // Machine files.
        case(
            "machine file",
            "empty file",
            vec![("bad.toml", text(""))],
            MACHINE,
            1,
            &["{d}/bad.toml:1:1: missing field `name`"],
        ),
        case(
            "machine file",
            "binary file",
            vec![("bad.toml", binary())],
            MACHINE,
            1,
            &["{d}/bad.toml", "line 1, column", "not UTF-8 text"],
        ),
        case(
            "machine file",
            "NaN geometry",
            vec![(
                "bad.toml",
                machine("x_rot_point = 0.0", "x_rot_point = nan"),
            )],
            MACHINE,
            1,
            &["{d}/bad.toml:6:15: `geometry.x_rot_point`: must be a finite number"],
        ),
        case(
            "machine file",
            "1e400",
            vec![("bad.toml", machine("length = 100.0", "length = 1e400"))],
            MACHINE,
            1,
            &["{d}/bad.toml:13:10", "overflowed"],
        ),
        case(
            "machine file",
            "duplicate key",
            vec![(
                "bad.toml",
                machine("z_offset = 0.0", "z_offset = 0.0\nz_offset = 1.0"),
            )],
            MACHINE,
            1,
            &["{d}/bad.toml:11:1: duplicate key"],
        ),
        case(
            "machine file",
            "a tool listed twice in [[tools]]",
            vec![("bad.toml", machine("number = 2", "number = 1"))],
            MACHINE,
            1,
            &[
                "{d}/bad.toml:",
                "tool 1 is listed twice (first at {d}/bad.toml:",
            ],
        ),
        case(
            "machine file",
            "[reversal] of an axis the machine lacks",
            vec![("bad.toml", with_reversal("B = 8.0"))],
            MACHINE,
            1,
            &["{d}/bad.toml:73:5: `reversal.B`: the machine has no axis B (its axes: XYZAC)"],
        ),
        case(
            "machine file",
            "[reversal] not a finite number",
            vec![("bad.toml", with_reversal("X = nan"))],
            MACHINE,
            1,
            &["{d}/bad.toml:73:5: `reversal.X`: must be a finite number"],
        ),
        case(
            "machine file",
            "[reversal] of one axis twice",
            vec![("bad.toml", with_reversal("X = 8.0\nx = 6.0"))],
            MACHINE,
            1,
            &[
                "{d}/bad.toml:",
                "`reversal.",
                "the reversal of X is given twice",
            ],
        ),
        case(
            "machine file",
            "[reversal] and a REVERSAL column for the same axis",
            {
                let mut files = table(|l| {
                    for (i, line) in l.iter_mut().enumerate() {
                        line.push_str(if i == 0 { ",REVERSAL" } else { ",6.0" });
                    }
                });
                let text = String::from_utf8(files[0].1.clone()).unwrap();
                files[0].1 = format!("{text}\n[reversal]\nX = 8.0\n").into_bytes();
                files
            },
            TABLE,
            1,
            &[
                "{d}/table.toml:73:5: `reversal.X`: X already has a REVERSAL column in {d}/bad-x.csv: give the reversal of X in one place only",
            ],
        ),
        // Error tables.
        case(
            "error table (CSV)",
            "one row",
            table(|l| l.truncate(2)),
            TABLE,
            1,
            &[
                "{d}/table.toml:26:5: `errors.x`",
                "{d}/bad-x.csv: line 2: 1 rows, but at least 8 are needed",
            ],
        ),
        case(
            "error table (CSV)",
            "NaN",
            table(|l| l[3] = nan_at(&l[3], 1)),
            TABLE,
            1,
            &["{d}/bad-x.csv: line 4, column 2 (EXX): `nan` is not a finite number"],
        ),
        case(
            "error table (CSV)",
            "a repeated position",
            table(|l| l[4] = l[3].clone()),
            TABLE,
            1,
            &[
                "{d}/bad-x.csv: line 5, column 1 (position)",
                "strictly increasing",
            ],
        ),
        case(
            "error table (CSV)",
            "non-UTF-8 byte",
            table(|l| l[3].push('\u{0}'))
                .into_iter()
                .map(|(n, b)| {
                    (
                        n,
                        if n == "bad-x.csv" {
                            [b.as_slice(), b"\xff"].concat()
                        } else {
                            b
                        },
                    )
                })
                .collect(),
            TABLE,
            1,
            &["{d}/bad-x.csv", "not UTF-8 text"],
        ),
        case(
            "error table (CSV)",
            "empty file",
            vec![
                ("table.toml", machine("\"ref-trt/x.csv\"", "\"bad-x.csv\"")),
                ("bad-x.csv", vec![]),
            ],
            TABLE,
            1,
            &["{d}/bad-x.csv: line 1: empty table"],
        ),
        // Plans.
        case(
            "plan (CSV)",
            "duplicate ids",
            vec![("bad.csv", plan_rows(&["1,0,0,1,0,0,1", "1,1,0,1,0,0,1"]))],
            PLAN,
            1,
            &["{d}/bad.csv:3: column `id`: expected unique ids"],
        ),
        case(
            "plan (CSV)",
            "zero normal",
            vec![("bad.csv", plan_rows(&["1,0,0,1,0,0,0"]))],
            PLAN,
            1,
            &["{d}/bad.csv:2: column `i,j,k`: expected a non-zero surface normal"],
        ),
        case(
            "plan (CSV)",
            "NaN",
            vec![("bad.csv", plan_rows(&["1,nan,0,1,0,0,1"]))],
            PLAN,
            1,
            &["{d}/bad.csv:2: column `x`: expected a finite number, found `nan`"],
        ),
        case(
            "plan (CSV)",
            "a normal whose length overflows (1e300,1e300,1e300)",
            vec![("bad.csv", plan_rows(&["1,0,0,1,1e300,1e300,1e300"]))],
            PLAN,
            1,
            &[
                "{d}/bad.csv:2: column `i,j,k`: expected a unit surface normal",
                "overflows",
            ],
        ),
        case(
            "plan (CSV)",
            "no move reaches it",
            vec![(
                "bad.csv",
                plan_rows(&["1,500,0,1,0,0,1", "2,0,500,1,0,0,1"]),
            )],
            PLAN,
            1,
            &["{d}/bad.csv: none of its 2 plan points is cut by {d}/ok.nc"],
        ),
        case(
            "plan (CSV)",
            "a byte order mark before the header (accepted)",
            vec![(
                "bad.csv",
                [b"\xEF\xBB\xBF".as_slice(), &plan_rows(&["1,0,0,1,0,0,1"])].concat(),
            )],
            PLAN,
            0,
            &["over 1 of 1 plan points"],
        ),
        case(
            "plan (CSV)",
            "empty file",
            vec![("bad.csv", vec![])],
            PLAN,
            1,
            &["{d}/bad.csv:1: header lacks column `id`"],
        ),
        // Measurements.
        case(
            "measurement (CSV)",
            "duplicate ids",
            vec![("bad.csv", measured(&["3,0,0,1,0,0,1,0,0,1"], 30))],
            MEASURED,
            1,
            &["{d}/bad.csv:32: column `id`: expected unique ids"],
        ),
        case(
            "measurement (CSV)",
            "NaN",
            vec![("bad.csv", measured(&["99,0,0,1,0,0,1,nan,0,1"], 30))],
            MEASURED,
            1,
            &["{d}/bad.csv:32: column `mx`: expected a finite number"],
        ),
        case(
            "measurement (CSV)",
            "one row",
            vec![("bad.csv", measured(&[], 1))],
            MEASURED,
            1,
            &["{d}/bad.csv: 1 measured point was cut", "at least 20"],
        ),
        case(
            "follow-up measurement (CSV)",
            "a probe before the program started (t_min = -5)",
            vec![
                ("ok.csv", measured(&[], 30)),
                (
                    "bad.csv",
                    followup_rows(&["F01,1,1,1,0,0,1,12,30,-5,1,1,1.001"]),
                ),
            ],
            FOLLOWUP,
            1,
            &[
                "{d}/bad.csv:2: column `t_min`: expected minutes since the part program's start (≥ 0), found -5",
            ],
        ),
        case(
            "follow-up measurement (CSV)",
            "a probed point far from its plan point (my = 1e6)",
            vec![
                ("ok.csv", measured(&[], 30)),
                (
                    "bad.csv",
                    followup_rows(&["F01,1,1,1,0,0,1,12,30,0.5,1,1e6,1.001"]),
                ),
            ],
            FOLLOWUP,
            1,
            &["{d}/bad.csv:2: column `mx,my,mz`", "from the plan point"],
        ),
        // `diagnose --write-machine` (issue 26): checked before anything is computed.
        case(
            "`diagnose --write-machine` output",
            "the machine file itself (`--write-machine ok.toml`)",
            vec![("ok.csv", measured(&[], 30))],
            WRITE_MACHINE_INPUT,
            2,
            &["--write-machine {d}/ok.toml is the machine file {d}/ok.toml (the same file)"],
        ),
        case(
            "`diagnose --write-machine` output",
            "the measurement (`--write-machine ok.csv`)",
            vec![("ok.csv", measured(&[], 30))],
            WRITE_MACHINE_MEASUREMENT,
            2,
            &["--write-machine {d}/ok.csv is the measurement {d}/ok.csv (the same file)"],
        ),
        case(
            "`diagnose --write-machine` output",
            "in a folder that is a file (`--write-machine ok.nc/out.toml`)",
            vec![("ok.csv", measured(&[], 30))],
            WRITE_MACHINE_NO_FOLDER,
            1,
            &[
                "cannot write {d}/ok.nc/out.toml: {d}/ok.nc is not a folder, so the output's folder cannot be created",
            ],
        ),
        case(
            "`diagnose --write-machine` output",
            "standard output (`--write-machine -`)",
            vec![("ok.csv", measured(&[], 30))],
            WRITE_MACHINE_STDOUT,
            2,
            &["--write-machine -: give a file name"],
        ),
        // Effects.
        case(
            "effect (command line)",
            "a parameter whose displacement overflows (tool_wear:w=1e308)",
            vec![
                (
                    "saddle.nc",
                    std::fs::read(root().join("samples/saddle.nc")).unwrap(),
                ),
                (
                    "plan.csv",
                    std::fs::read(root().join("samples/saddle-plan.csv")).unwrap(),
                ),
            ],
            SIMULATE,
            1,
            &["the simulated measured point (the effects' displacement overflows"],
        ),
        // Fitted-model files.
        case(
            "model file (JSON)",
            "not a model file",
            vec![("bad.json", text("{\"garbage\": 1}"))],
            MODEL,
            1,
            &["{d}/bad.json:1:14: not a fitted-model file"],
        ),
        case(
            "model file (JSON)",
            "empty file",
            vec![("bad.json", vec![])],
            MODEL,
            1,
            &["{d}/bad.json:1:0: not a fitted-model file"],
        ),
        case(
            "model file (JSON)",
            "stale (a table changed since the fit)",
            vec![("bad.json", b"STALE".to_vec())],
            MODEL,
            1,
            &[
                "{d}/bad.json: EXX: was fitted to different data",
                "refit with volcomp fit",
            ],
        ),
        case(
            "model file (JSON)",
            "a curve edited after the fit",
            vec![("bad.json", b"EDITED".to_vec())],
            MODEL,
            1,
            &["{d}/bad.json: EXX: its curve was changed after the fit"],
        ),
        case(
            "model file (JSON)",
            "a curve edited and its hash removed",
            vec![("bad.json", b"EDITED-NO-HASH".to_vec())],
            MODEL,
            1,
            &[
                "{d}/bad.json: EXX: its curve departs from the table by up to",
                "the file was edited",
            ],
        ),
        // Tool tables.
        case(
            "tool table",
            "negative length",
            vec![("bad.tbl", text("T1 P1 Z-5 D6\n"))],
            TOOLS,
            1,
            &["{d}/bad.tbl:1:7: `Z-5`: a tool length must be ≥ 0 mm"],
        ),
        case(
            "tool table",
            "a tool listed twice",
            vec![("bad.tbl", text("T1 Z5\nT1 Z6\n"))],
            TOOLS,
            1,
            &["{d}/bad.tbl:2:1: tool T1 is listed twice (first at {d}/bad.tbl:1)"],
        ),
        case(
            "tool table",
            "not a tool table",
            vec![("bad.tbl", text("garbage here\n"))],
            TOOLS,
            1,
            &["{d}/bad.tbl:1:1: `garbage`: not a tool table word"],
        ),
        case(
            "tool table",
            "2000 tools (LinuxCNC holds 1000)",
            vec![("bad.tbl", many_tools.into_bytes())],
            TOOLS,
            1,
            &["{d}/bad.tbl:1001:1: more than 1000 tools"],
        ),
        case(
            "tool table",
            "a word given twice (`Z100 Z200`)",
            vec![("bad.tbl", text("T1 Z100 Z200\n"))],
            TOOLS,
            1,
            &["{d}/bad.tbl:1:9: `Z200`: Z is given twice on the line (first at column 4)"],
        ),
        // The command line.
        case(
            "work offsets (command line)",
            "one system given twice (`--offset G54=… --offset G54=…`)",
            vec![],
            OFFSETS,
            2,
            &["--offset `G54=1,0,0`: that work coordinate system is already given"],
        ),
        // Parameter files.
        case(
            "parameter file (.var)",
            "not a .var line",
            vec![("bad.var", text("#5221 = abc\n"))],
            VAR,
            1,
            &["{d}/bad.var:1:", "expected `NUMBER VALUE`"],
        ),
        // Plans in work coordinates (--plan-frame work).
        case(
            "plan (work coordinates)",
            "a program cutting in two work offsets (G54, then G55)",
            vec![
                (
                    "bad.nc",
                    text(
                        "%\nG21 G90 G94\nG0 X0 Y0 Z10 A10 C0\nG1 X5 Y5 Z2 A12 C30 F500\nG55\nG1 X10 Y2 Z1 A15 C60\nM30\n%\n",
                    ),
                ),
                ("plan.csv", plan_rows(&["1,5,5,2,0,0,1"])),
            ],
            "predict {d}/ok.toml {d}/bad.nc --plan {d}/plan.csv --plan-frame work --report {d}/out.json --model {d}/fit.json --offset G55=1,0,0",
            1,
            &[
                "{d}/bad.nc: --plan-frame work is ambiguous: the program cuts in 2 work frames: line 4",
                "line 6",
            ],
        ),
        case(
            "plan (work coordinates)",
            "a joint-frame program cutting with A turned under a work offset",
            vec![("plan.csv", plan_rows(&["1,5,5,2,0,0,1"]))],
            "predict {d}/ok.toml {d}/ok.nc --plan {d}/plan.csv --plan-frame work --report {d}/out.json --model {d}/fit.json --offset G54=1,0,0",
            1,
            &[
                "{d}/ok.nc: --plan-frame work: the program cuts in joint coordinates (no tool-tip control) with a rotary axis turned (first at line 4, 2 moves)",
            ],
        ),
        case(
            "plan (work coordinates)",
            "a work offset that turns C",
            vec![
                ("ok2.nc", text(PROGRAM)),
                ("plan.csv", plan_rows(&["1,5,5,2,0,0,1"])),
            ],
            "predict {d}/ok.toml {d}/ok2.nc --plan {d}/plan.csv --plan-frame work --report {d}/out.json --model {d}/fit.json --offset G54=0,0,0,0,15",
            1,
            &["{d}/ok2.nc: --plan-frame work: the program's work offset turns C (15°)"],
        ),
        // Controller export.
        case(
            "machine file (export linuxcnc)",
            "no linear axis has a positioning table",
            vec![(
                "bad.toml",
                machine(
                    "x = \"ref-trt/x.csv\"\ny = \"ref-trt/y.csv\"\nz = \"ref-trt/z.csv\"\n",
                    "",
                ),
            )],
            "export linuxcnc {d}/bad.toml -o {d}/out.dir",
            1,
            &["{d}/bad.toml: no linear axis has a positioning table (EXX, EYY, EZZ)"],
        ),
        case(
            "command line (export linuxcnc)",
            "`--max-lines 300` (LinuxCNC takes 256)",
            vec![],
            "export linuxcnc {d}/ok.toml -o {d}/out.dir --max-lines 300",
            2,
            &["--max-lines 300: LinuxCNC takes 2 to 256 lines a joint"],
        ),
        // Laser positioning runs (import-laser).
        case(
            "laser runs (CSV)",
            "empty file",
            vec![("bad.csv", text(""))],
            LASER,
            1,
            &["{d}/bad.csv:1:1: empty file"],
        ),
        case(
            "laser runs (CSV)",
            "binary file",
            vec![("bad.csv", binary())],
            LASER,
            1,
            &["{d}/bad.csv:1:1: byte 0x00 is not text"],
        ),
        case(
            "laser runs (CSV)",
            "a column that is not a reading, its cells left out (accepted, named)",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation,temperature", &[]),
            )],
            "import-laser {d}/bad.csv --axis X -o {d}/out.csv",
            0,
            &["not readings (kept in the report): `temperature`"],
        ),
        case(
            "laser runs (CSV)",
            "a header mixing layouts",
            vec![("bad.csv", laser_rows("target,run,direction,+,-", &[]))],
            LASER,
            1,
            &["{d}/bad.csv:1:1: cannot tell the layout"],
        ),
        case(
            "laser runs (CSV)",
            "an empty cell",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,2,-,"]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:18:8: empty cell in column `deviation`"],
        ),
        case(
            "laser runs (CSV)",
            "a row with a cell missing",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,2,-"]),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:18:7: 3 fields, but the header (line 1) has 4 columns; the cell of `deviation` is missing",
            ],
        ),
        case(
            "laser runs (CSV)",
            "`nan` deviation",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,2,-,nan"]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:18:8: `nan` in column `deviation` is not a finite number"],
        ),
        case(
            "laser runs (CSV)",
            "a quoted decimal comma among decimal points",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,2,-,\"1,5\""]),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:18:8: `1,5` writes a decimal comma, but this file writes a decimal point (first `1.5` at line 2, column 7)",
            ],
        ),
        case(
            "laser runs (CSV)",
            "`1.030` in a `;` file of decimal commas",
            vec![(
                "bad.csv",
                text("target;run;direction;deviation\n0;1;+;0,0012\n10;1;+;1.030\n"),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:3:8: `1.030` writes a decimal point, but this file writes a decimal comma (first `0,0012` at line 2, column 7)",
            ],
        ),
        case(
            "laser runs (CSV)",
            "a deviation of 1e308",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,2,-,1e308"]),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:18:8: deviation `1e308` in column `deviation` is beyond a machine tool's positioning error (|deviation| ≤ 100000 µm = 100 mm)",
            ],
        ),
        case(
            "laser runs (CSV)",
            "the same file twice",
            vec![("bad.csv", laser_rows("target,run,direction,deviation", &[]))],
            "import-laser {d}/bad.csv {d}/./bad.csv --axis X -o {d}/out.csv --report {d}/out.json",
            1,
            &[
                "{d}/./bad.csv (file 2) is the same file as {d}/bad.csv (file 1): one measurement counts once",
            ],
        ),
        case(
            "laser runs (CSV)",
            "a 100 000-byte line",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &[&"7".repeat(100_000)]),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:18:65537: line of 100000 bytes: volcomp reads laser lines of at most 65536 bytes",
            ],
        ),
        case(
            "laser runs (CSV)",
            "a 20 000-byte cell (echoed cut)",
            vec![(
                "bad.csv",
                laser_rows(
                    "target,run,direction,deviation",
                    &[&format!("30,2,-,{}x", "1".repeat(20_000))],
                ),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:18:8: `1111",
                "… (20001 bytes)` in column `deviation` is not a finite number",
            ],
        ),
        case(
            "laser runs (CSV)",
            "an unknown direction",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,2,left,1"]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:18:6: direction `left`"],
        ),
        case(
            "laser runs (CSV)",
            "run 0",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,0,-,1"]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:18:4: run `0` is not a whole number from 1"],
        ),
        case(
            "laser runs (CSV)",
            "an angle unit on a length",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation [arcsec]", &[]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:1:22: deviation unit `arcsec`: EXX is a length"],
        ),
        case(
            "laser runs (CSV)",
            "an unknown target unit",
            vec![(
                "bad.csv",
                laser_rows("target [ft],run,direction,deviation", &[]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:1:1: target unit `ft`: axis X takes mm or inch (`in`)"],
        ),
        case(
            "laser runs (CSV)",
            "the same run and approach twice",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["30,1,+,1"]),
            )],
            LASER,
            1,
            &[
                "{d}/bad.csv:18:8: run 1 approaches target 30 from below (+) a second time (first at {d}/bad.csv:8:8)",
            ],
        ),
        case(
            "laser runs (CSV)",
            "a target approached from one side only",
            vec![(
                "bad.csv",
                laser_rows("target,run,direction,deviation", &["95,1,+,1"]),
            )],
            LASER,
            1,
            &["{d}/bad.csv:18:1: EXX at target 95 has no reading approached from above (-)"],
        ),
        case(
            "laser runs (CSV)",
            "fewer than 5 targets",
            vec![(
                "bad.csv",
                text("target,run,direction,deviation\n0,1,+,1\n0,1,-,1\n"),
            )],
            LASER,
            1,
            &["{d}/bad.csv: EXX has 1 targets, but an error table needs at least 5"],
        ),
        case(
            "laser runs (CSV)",
            "a parameter of another axis (`EYY=` with --axis X)",
            vec![("bad.csv", laser_rows("target,run,direction,deviation", &[]))],
            "import-laser EYY={d}/bad.csv --axis X -o {d}/out.csv",
            2,
            &["EYY is not an error parameter of axis X"],
        ),
    ]
}

/// The head-table chain machine's text with `from` replaced by `to`.
fn chain_machine(from: &str, to: &str) -> Vec<u8> {
    let text = std::fs::read_to_string(root().join("machines/head-table.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    text.replacen(from, to, 1).into_bytes()
}

/// Issue 38: the numbers a user gives within what a machine tool can have,
/// the outputs of `import-laser` and `export` checked against the inputs,
/// `--lenient` words passed through as written, echoes cut.
fn issue_38_cases() -> Vec<Case> {
    let long_cell = "9".repeat(1000);
    let long_line = "9".repeat(100_000);
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };
    vec![
        case(
            "machine file (TOML)",
            "`[reversal] X = 1e6` (µm)",
            vec![("bad.toml", with_reversal("X = 1e6"))],
            MACHINE,
            1,
            &[
                "`reversal.X`: 1e6 µm is beyond what a machine tool can have: the range is -1000 to 1000 µm",
            ],
        ),
        case(
            "machine file (TOML)",
            "`[reversal] X = 1e300`",
            vec![("bad.toml", with_reversal("X = 1e300"))],
            MACHINE,
            1,
            &["is beyond what a machine tool can have"],
        ),
        case(
            "machine file (TOML)",
            "a location error of 1e20 µm",
            vec![("bad.toml", machine("EY0A = 12.7", "EY0A = 1e20"))],
            MACHINE,
            1,
            &[
                "`location.EY0A`: 1e20 µm is beyond what a machine tool can have: the range is -10000 to 10000 µm",
            ],
        ),
        case(
            "machine file (TOML)",
            "a squareness of 1e9 µrad",
            vec![("bad.toml", machine("s_xy = -39.9", "s_xy = 1e9"))],
            MACHINE,
            1,
            &["`squareness.s_xy`: 1e9 µrad is beyond what a machine tool can have"],
        ),
        case(
            "machine file (TOML)",
            "a tool length of 1e300 mm",
            vec![("bad.toml", machine("length = 100.0", "length = 1e300"))],
            MACHINE,
            1,
            &[
                "`tool.length`: 1e300 mm is beyond what a machine tool can have: the range is -5000 to 5000 mm",
            ],
        ),
        case(
            "machine file (TOML)",
            "a chain `direction` of 4 numbers",
            vec![(
                "bad.toml",
                chain_machine(
                    "direction = [0.0, 1.0, 0.0]",
                    "direction = [0.0, 1.0, 0.0, 7.0]",
                ),
            )],
            MACHINE,
            1,
            &["`axes.B.direction`: expected 3 numbers [x, y, z], got 4"],
        ),
        case(
            "machine file (TOML)",
            "a chain `point` of 2 numbers",
            vec![(
                "bad.toml",
                chain_machine("point = [0.0, 0.0, 150.0]", "point = [0.0, 150.0]"),
            )],
            MACHINE,
            1,
            &["`axes.B.point`: expected 3 numbers [x, y, z], got 2"],
        ),
        case(
            "machine file (TOML)",
            "a chain `point` at 1e20 mm",
            vec![(
                "bad.toml",
                chain_machine("point = [0.0, 0.0, 150.0]", "point = [0.0, 0.0, 1e20]"),
            )],
            MACHINE,
            1,
            &[
                "`axes.B.point`: 1e20 mm is beyond what a machine tool can have: the range is -100000 to 100000 mm",
            ],
        ),
        case(
            "machine file (TOML)",
            "a chain `direction` too large to normalise (1e300 × 3)",
            vec![(
                "bad.toml",
                chain_machine(
                    "direction = [0.0, 1.0, 0.0]",
                    "direction = [1e300, 1e300, 1e300]",
                ),
            )],
            MACHINE,
            1,
            &["too large to normalise"],
        ),
        case(
            "machine file (TOML)",
            "a 100 000-byte string where a number goes (the message cut)",
            vec![(
                "bad.toml",
                machine("length = 100.0", leak(format!("length = \"{long_line}\""))),
            )],
            MACHINE,
            1,
            &["bytes)"],
        ),
        case(
            "error table (CSV)",
            "a value of 1e300 µm",
            table(|l| l[3] = "-100,1e300,0.4,-0.2,1.2,0.9,-0.3".into()),
            TABLE,
            1,
            &[
                "EXX = 1e300 µm is beyond what a machine tool can have: the range is -10000 to 10000 µm",
            ],
        ),
        case(
            "error table (CSV)",
            "a 1000-byte cell (the message cut)",
            table(|l| l[3] = format!("-100,{}x,0.4,-0.2,1.2,0.9,-0.3", long_cell)),
            TABLE,
            1,
            &["… (1001 bytes)` is not a finite number"],
        ),
        case(
            "error table (CSV)",
            "a 100 000-byte line",
            table(|l| l[3] = long_line.clone()),
            TABLE,
            1,
            &["line of 100000 bytes, longer than volcomp's limit of 65536 bytes"],
        ),
        case(
            "inspection plan (CSV)",
            "a 1000-byte cell (the message cut)",
            vec![(
                "bad.csv",
                plan_rows(&[leak(format!("p1,{long_cell}x,0,0,0,0,1"))]),
            )],
            PLAN,
            1,
            &["… (1001 bytes)`"],
        ),
        case(
            "inspection plan (CSV)",
            "a 100 000-byte line",
            vec![("bad.csv", plan_rows(&[leak(long_line.clone())]))],
            PLAN,
            1,
            &["line of 100000 bytes, longer than volcomp's limit of 65536 bytes"],
        ),
        case(
            "parameter file (.var)",
            "a 1000-byte value (the message cut)",
            vec![("bad.var", text(leak(format!("5220 {long_cell}x\n"))))],
            VAR,
            1,
            &["… (1001 bytes)` is not a finite number"],
        ),
        case(
            "laser runs (CSV)",
            "`-o` naming the laser file itself",
            vec![("bad.csv", laser_rows("target,run,direction,deviation", &[]))],
            "import-laser {d}/bad.csv --axis X -o {d}/bad.csv",
            2,
            &["-o {d}/bad.csv is the laser file {d}/bad.csv (the same file)"],
        ),
        case(
            "laser runs (CSV)",
            "`-o` and `--report` the same file",
            vec![("bad.csv", laser_rows("target,run,direction,deviation", &[]))],
            "import-laser {d}/bad.csv --axis X -o {d}/out.csv --report {d}/out.csv",
            2,
            &["-o {d}/out.csv and --report {d}/out.csv are the same file"],
        ),
        case(
            "export folder",
            "`export tables -o` the folder of the machine's tables",
            vec![],
            "export tables {d}/ok.toml -o {d}/ref-trt --model {d}/fit.json",
            2,
            &["(-o) {d}/ref-trt/x.csv is the error table"],
        ),
        case(
            "export setting",
            "`export tables --step 1e300`",
            vec![],
            "export tables {d}/ok.toml -o {d}/out.d --model {d}/fit.json --step 1e300",
            2,
            &[
                "--step = 1e300 mm is beyond what a machine tool can have: the range is more than 0 and at most 100000 mm",
            ],
        ),
        case(
            "program",
            "`B45 U3 V4 W10 W-7.5` on an X Y Z A C machine under --lenient (accepted, words kept as written)",
            vec![(
                "bad.nc",
                text(
                    "%\nG21 G90 G94\nG0 X0 Y0 Z10 A10 C0\nG1 X5 B45 F500\nG1 X6 U3 V4 W10\nG1 X7 W-7.5\nM30\n%\n",
                ),
            )],
            "compensate {d}/ok.toml {d}/bad.nc -o {d}/out.nc --model {d}/fit.json --lenient",
            0,
            &["8 blocks read"],
        ),
    ]
}

/// A laser file: `header`, then targets 0, 10, … 70 with run 1 up and down
/// (lines 2-17), then `extra` rows.
fn laser_rows(header: &str, extra: &[&str]) -> Vec<u8> {
    let mut s = format!("{header}\n");
    for t in 0..8 {
        s.push_str(&format!("{},1,+,1.5\n{},1,-,-1.5\n", t * 10, t * 10));
    }
    for r in extra {
        s.push_str(r);
        s.push('\n');
    }
    s.into_bytes()
}

/// The scratch folder every case runs in: the reference machine, its tables,
/// its fitted model and a good program.
fn scratch() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let (machine, model) = ref_trt();
    let fit = serde_json::to_string(&model.to_model_file(machine).unwrap()).unwrap();
    std::fs::write(dir.path().join("fit.json"), &fit).unwrap();
    std::fs::create_dir(dir.path().join("ref-trt")).unwrap();
    for axis in ["x", "y", "z", "a", "c"] {
        std::fs::copy(
            root().join(format!("machines/ref-trt/{axis}.csv")),
            dir.path().join(format!("ref-trt/{axis}.csv")),
        )
        .unwrap();
    }
    std::fs::copy(
        root().join("machines/ref-trt.toml"),
        dir.path().join("ok.toml"),
    )
    .unwrap();
    std::fs::write(dir.path().join("ok.nc"), PROGRAM).unwrap();
    dir
}

/// A model file fitted to other tables than the machine's (one X value changed).
fn stale_model(dir: &Path) -> Vec<u8> {
    let fit = std::fs::read_to_string(dir.join("fit.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&fit).unwrap();
    let text = serde_json::to_string(&v).unwrap();
    // Each curve records the hash of the table it was fitted to.
    let hash = text
        .split("\"table_hash\":\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .expect("model files hash their tables")
        .to_string();
    let stale = text.replace(&hash, "0123456789abcdef");
    v = serde_json::from_str(&stale).unwrap();
    serde_json::to_vec(&v).unwrap()
}

/// The model file with a control point of EXX moved by 499 µm (issue 23:
/// such a file compensated with 499 µm corrections); its curve hash kept, or
/// removed as in files written before it.
fn edited_model(dir: &Path, keep_hash: bool) -> Vec<u8> {
    let fit = std::fs::read_to_string(dir.join("fit.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&fit).unwrap();
    let p = &mut v["parameters"][0];
    assert_eq!(p["parameter"], "EXX");
    let y = p["points"][3][1].as_f64().unwrap();
    p["points"][3][1] = serde_json::json!(y + 499.0);
    if !keep_hash {
        p.as_object_mut().unwrap().remove("curve_hash");
    }
    serde_json::to_vec(&v).unwrap()
}

#[test]
fn every_bad_input_is_refused_with_its_place_and_leaves_no_output() {
    let dir = scratch();
    let d = dir.path().display().to_string();
    let mut rows = Vec::new();
    for c in cases().into_iter().chain(issue_38_cases()) {
        for (name, bytes) in &c.files {
            let bytes = match bytes.as_slice() {
                b"STALE" => stale_model(dir.path()),
                b"EDITED" => edited_model(dir.path(), true),
                b"EDITED-NO-HASH" => edited_model(dir.path(), false),
                _ => bytes.clone(),
            };
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let args: Vec<String> = c.args.split(' ').map(|a| a.replace("{d}", &d)).collect();
        let out = volcomp().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        let shown = if c.code == 0 {
            String::from_utf8_lossy(&out.stdout).into_owned()
        } else {
            stderr.clone()
        };
        let label = format!("{} / {}", c.input, c.what);
        assert_eq!(out.status.code(), Some(c.code), "{label}: {stderr}");
        assert!(!stderr.contains("panicked"), "{label}: {stderr}");
        for e in &c.expect {
            let e = e.replace("{d}", &d);
            assert!(shown.contains(&e), "{label}: expected `{e}` in:\n{shown}");
        }
        let outputs: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("out.") || n.contains(".tmp"))
            .collect();
        if c.code == 0 {
            // The command's one output, whole.
            assert_eq!(outputs.len(), 1, "{label}: {outputs:?}");
            assert!(!outputs[0].contains(".tmp"), "{label}: {outputs:?}");
        } else {
            assert!(outputs.is_empty(), "{label}: left {outputs:?}");
        }
        for f in outputs {
            std::fs::remove_file(dir.path().join(f)).unwrap();
        }
        for (name, _) in &c.files {
            std::fs::remove_file(dir.path().join(name)).unwrap();
        }
        // The message, and where it points for program errors (` --> file:line:col`).
        // The dialect note (`note: … read as Heidenhain …`) comes before the message.
        let mut lines = shown
            .lines()
            .skip_while(|l| l.starts_with("note: ") && l.contains(": read as "));
        let mut first = lines.next().unwrap_or("").to_string();
        if let Some(at) = lines.next().and_then(|l| l.trim().strip_prefix("--> ")) {
            first.push_str(&format!(" (at {at})"));
        }
        let first = first
            .replace(&d, "…")
            .replace(&root().display().to_string(), "<project>")
            .replace('|', "\\|");
        let first: String = first.chars().take(260).collect();
        rows.push(format!(
            "| {} | {} | `volcomp {}` | {} | {} |",
            c.input,
            c.what,
            c.args.split(' ').next().unwrap_or(""),
            c.code,
            first
        ));
    }
    let doc = format!(
        "# Bad inputs: what the user gets\n\n\
Generated by `tests/it/bad_inputs.rs` (`VOLCOMP_WRITE_BAD_INPUTS=1 cargo test --release --locked bad_inputs` \
rewrites it; the test fails when it is stale). Every case runs the command that reads the input, in a \
scratch folder (shown as `…`), and checks the exit code, the located message, and that no output file \
(nor a temporary one) is left. Exit 1 is bad input, 2 a usage error; accepted inputs (exit 0) show the \
first line of the summary.\n\n\
| input | case | command | exit | first line of the message |\n|---|---|---|---|---|\n{}\n",
        rows.join("\n")
    );
    let path = root().join("docs/bad-inputs.md");
    if std::env::var_os("VOLCOMP_WRITE_BAD_INPUTS").is_some() {
        std::fs::write(&path, &doc).unwrap();
    } else {
        let committed = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            committed == doc,
            "docs/bad-inputs.md is stale: run VOLCOMP_WRITE_BAD_INPUTS=1 cargo test --release --locked bad_inputs"
        );
    }
}

/// Under `--lenient`, a word of a letter the machine lacks (B45, U3 V4 W10,
/// W-7.5 on an X Y Z A C machine) is written as it was read, byte for byte,
/// never as a rewritten zero.
#[test]
fn lenient_words_of_letters_the_machine_lacks_are_written_as_read() {
    let dir = scratch();
    let program = "%\nG21 G90 G94\nG0 X0 Y0 Z10 A10 C0\nG1 X5 B45 F500\nG1 X6 U3 V4 W10\nG1 X7 w-7.5\nM30\n%\n";
    std::fs::write(dir.path().join("bad.nc"), program).unwrap();
    let d = dir.path();
    let out = volcomp()
        .args(["compensate", "--lenient", "--model"])
        .arg(d.join("fit.json"))
        .arg(d.join("ok.toml"))
        .arg(d.join("bad.nc"))
        .arg("-o")
        .arg(d.join("out.nc"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let written = std::fs::read_to_string(d.join("out.nc")).unwrap();
    for word in [" B45 ", " U3 V4 W10", " w-7.5"] {
        assert!(written.contains(word), "`{word}` not kept in:\n{written}");
    }
    assert!(
        !written.contains("B0.0") && !written.contains("W0.0"),
        "{written}"
    );
}
