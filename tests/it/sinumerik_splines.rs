//! SINUMERIK `BSPLINE` (docs/dialects.md, "B splines"; Siemens, *Job
//! planning*, "Spline interpolation"): the fixture `bspline.mpf` holds
//! three sections, each checked by hand.
//! - `SD=1`: the control polygon, one move per block to its point.
//! - `SD=2` with weights 1, 1/√2, 1 on (30, 0), (30, 10), (20, 10): the
//!   quarter circle of radius 10 about (20, 0) (the rational quadratic
//!   Bézier form of a circle); its first block ends at the curve's
//!   parameter 10 of 20, the 45° point (20 + 5√2, 5√2).
//! - `SD=3`, equal weights, then `PW=3` on its third point: the block ends
//!   against an independent evaluation (the Cox–de Boor recursion of the
//!   basis functions below, not the de Boor triangle volcomp runs), with
//!   the values a Python script of the same recursion printed written
//!   down; every chord within 0.5 µm of the curve.
use crate::sinumerik::targets;
use crate::support::{assert_success, program_lines, root, volcomp, written_by};

const FIXTURE: &str = "tests/data/sinumerik/bspline.mpf";

/// The basis function N(i, p) at `u` over `knots` (Cox–de Boor recursion;
/// the last knot belongs to the last non-empty span).
fn basis(i: usize, p: usize, u: f64, knots: &[f64]) -> f64 {
    if p == 0 {
        let last = *knots.last().unwrap();
        let inside = knots[i] <= u && u < knots[i + 1];
        let at_end = u == last && knots[i] < u && u <= knots[i + 1];
        return f64::from(inside || at_end);
    }
    let left = if knots[i + p] == knots[i] {
        0.0
    } else {
        (u - knots[i]) / (knots[i + p] - knots[i]) * basis(i, p - 1, u, knots)
    };
    let right = if knots[i + p + 1] == knots[i + 1] {
        0.0
    } else {
        (knots[i + p + 1] - u) / (knots[i + p + 1] - knots[i + 1]) * basis(i + 1, p - 1, u, knots)
    };
    left + right
}

/// The rational curve of `points` and `weights` (degree `p`) with the
/// parameters of docs/dialects.md: chord lengths, knots averaged.
struct Curve {
    points: Vec<[f64; 2]>,
    weights: Vec<f64>,
    p: usize,
    params: Vec<f64>,
    knots: Vec<f64>,
}

impl Curve {
    fn new(points: &[[f64; 2]], weights: &[f64], p: usize) -> Curve {
        let mut params = vec![0.0];
        for k in 1..points.len() {
            let d = (points[k][0] - points[k - 1][0]).hypot(points[k][1] - points[k - 1][1]);
            params.push(params[k - 1] + d);
        }
        let n = points.len() - 1;
        let mut knots = vec![0.0; p + 1];
        for j in 1..=n - p {
            knots.push(params[j..j + p].iter().sum::<f64>() / p as f64);
        }
        knots.extend(std::iter::repeat_n(params[n], p + 1));
        Curve {
            points: points.to_vec(),
            weights: weights.to_vec(),
            p,
            params,
            knots,
        }
    }

    fn at(&self, u: f64) -> [f64; 2] {
        let mut sum = [0.0; 3];
        for (i, (q, w)) in self.points.iter().zip(&self.weights).enumerate() {
            let b = basis(i, self.p, u, &self.knots) * w;
            sum[0] += b * q[0];
            sum[1] += b * q[1];
            sum[2] += b;
        }
        [sum[0] / sum[2], sum[1] / sum[2]]
    }
}

/// The rows of `line`, in order.
fn of_line(rows: &[(usize, [f64; 3])], line: usize) -> Vec<[f64; 2]> {
    rows.iter()
        .filter(|r| r.0 == line)
        .map(|r| [r.1[0], r.1[1]])
        .collect()
}

fn distance_to_segment(q: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (q[0] - a[0] - t * d[0]).hypot(q[1] - a[1] - t * d[1])
}

/// Every chord of block `k` (lines `first_line + k - 1`) is within 0.5 µm
/// (+ 1 µm for the six printed decimals) of the curve between the block's
/// parameters, sampled densely; each block ends at the curve's point at
/// its parameter.
fn assert_follows(rows: &[(usize, [f64; 3])], curve: &Curve, first_line: usize) {
    let mut from = curve.points[0];
    for k in 1..curve.points.len() {
        let chords = of_line(rows, first_line + k - 1);
        assert!(!chords.is_empty(), "block {k}");
        let end = curve.at(curve.params[k]);
        let last = chords.last().unwrap();
        assert!(
            (last[0] - end[0]).abs() < 1e-6 && (last[1] - end[1]).abs() < 1e-6,
            "block {k}: {last:?} vs {end:?}"
        );
        let mut poly = vec![from];
        poly.extend(&chords);
        let (u0, u1) = (curve.params[k - 1], curve.params[k]);
        for s in 0..=400 {
            let q = curve.at(u0 + (u1 - u0) * s as f64 / 400.0);
            let d = poly
                .windows(2)
                .map(|w| distance_to_segment(q, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(d <= 0.5e-3 + 1e-6, "block {k}, sample {s}: {d}");
        }
        from = *last;
    }
}

#[test]
fn bspline_sections_follow_the_rational_b_spline() {
    let rows = targets(&["check", FIXTURE, "--targets", "-"]);
    // SD=1: the polygon, one move per block (lines 8–10).
    for (line, want) in [(8, [10.0, 0.0]), (9, [10.0, 10.0]), (10, [0.0, 10.0])] {
        assert_eq!(of_line(&rows, line), vec![want], "line {line}");
    }
    // SD=2, weights 1, 1/√2, 1: every point on the circle of radius 10
    // about (20, 0); the first block ends at 45°.
    for line in [13, 14] {
        for p in of_line(&rows, line) {
            assert!(((p[0] - 20.0).hypot(p[1]) - 10.0).abs() < 1e-6, "{p:?}");
        }
    }
    let h = 50f64.sqrt();
    let end13 = *of_line(&rows, 13).last().unwrap();
    assert!((end13[0] - (20.0 + h)).abs() < 1e-6 && (end13[1] - h).abs() < 1e-6);
    let circle = Curve::new(
        &[[30.0, 0.0], [30.0, 10.0], [20.0, 10.0]],
        &[1.0, std::f64::consts::FRAC_1_SQRT_2, 1.0],
        2,
    );
    assert_follows(&rows, &circle, 13);
    // SD=3: the block ends a Python script of the same recursion printed
    // (chord parameters 0, 11.18034, 21.18034, 32.36068, 43.54102,
    // 53.54102; inner knots 21.573787, 32.36068).
    let points = [
        [40.0, 0.0],
        [45.0, 10.0],
        [55.0, 10.0],
        [60.0, 0.0],
        [65.0, -10.0],
        [75.0, -10.0],
    ];
    let written = [
        [48.452787, 8.507969],
        [55.033888, 7.457983],
        [59.258794, 1.482413],
        [64.697177, -6.452668],
        [75.0, -10.0],
    ];
    for (k, want) in written.iter().enumerate() {
        let got = *of_line(&rows, 17 + k).last().unwrap();
        assert!(
            (got[0] - want[0]).abs() < 2e-6 && (got[1] - want[1]).abs() < 2e-6,
            "{got:?} {want:?}"
        );
    }
    let cubic = Curve::new(&points, &[1.0; 6], 3);
    assert_follows(&rows, &cubic, 17);
    // The section ends at G1: the next block is a straight move.
    assert_eq!(of_line(&rows, 22), vec![[80.0, 0.0]]);

    // PW=3 on the third point pulls the curve towards it: its block ends
    // nearer (60, 0), at the rational curve's point.
    let dir = tempfile::tempdir().unwrap();
    let weighted = dir.path().join("weighted.mpf");
    let text = std::fs::read_to_string(root().join(FIXTURE)).unwrap();
    std::fs::write(&weighted, text.replace("X60 Y0\n", "X60 Y0 PW=3\n")).unwrap();
    let heavy = targets(&["check", weighted.to_str().unwrap(), "--targets", "-"]);
    let curve = Curve::new(&points, &[1.0, 1.0, 1.0, 3.0, 1.0, 1.0], 3);
    assert_follows(&heavy, &curve, 17);
    let near = |p: [f64; 2]| (p[0] - 60.0).hypot(p[1]);
    let (plain, pulled) = (
        *of_line(&rows, 19).last().unwrap(),
        *of_line(&heavy, 19).last().unwrap(),
    );
    assert!(near(pulled) < near(plain) - 0.5, "{plain:?} {pulled:?}");
    assert!((pulled[0] - 59.670291).abs() < 2e-6 && (pulled[1] - 0.659417).abs() < 2e-6);
}

/// Written flat: no spline words are left, each chord carries its source
/// line, the `M8` between the control points stays in its place, and the
/// flat program moves as the original.
#[test]
fn bspline_is_written_flat_and_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.mpf");
    let text = written_by(&["check", FIXTURE, "--flatten", "-o"], &flat);
    let body = program_lines(&text).collect::<Vec<_>>().join("\n");
    for word in ["BSPLINE", "SD=", "PW=", "PL="] {
        assert!(!body.contains(word), "{word}: {text}");
    }
    assert!(text.contains("G1 X10 Y0 ; volcomp: line 8\n"), "{text}");
    let m8 = text.lines().position(|l| l.contains("M8")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[m8].ends_with("; volcomp: line 18"), "{}", lines[m8]);
    assert!(lines[m8 - 1].ends_with("; volcomp: line 17"));
    let a = targets(&["check", FIXTURE, "--targets", "-"]);
    let b = targets(&["check", flat.to_str().unwrap(), "--targets", "-"]);
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        assert!(
            (0..3).all(|k| (p.1[k] - q.1[k]).abs() < 1e-9),
            "{p:?} {q:?}"
        );
    }
    // compensate writes it flat too, and the output reads back.
    let comp = dir.path().join("comp.mpf");
    let written = written_by(
        &["compensate", "machines/ref-trt.toml", FIXTURE, "-o"],
        &comp,
    );
    assert!(!written.contains("BSPLINE X") && written.contains("; volcomp: line 19"));
    assert_success(&volcomp().arg("check").arg(&comp).output().unwrap());
}

/// What a section cannot hold yet, and bad spline words: located errors.
#[test]
fn bspline_refusals_are_located() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "G1 X0 Y0 F100\nBSPLINE X10 Y5 PW=4\nX20 Y0\nM30\n",
            "PW=4",
            ":2:",
        ),
        (
            "G1 X0 Y0 F100\nBSPLINE SD=4 X10 Y5\nX20 Y0\nM30\n",
            "SD=4",
            ":2:",
        ),
        (
            "G1 X0 Y0 F100\nBSPLINE X10 Y5\nTRANS X5\nX20 Y0\nM30\n",
            "inside a BSPLINE section",
            ":3:1",
        ),
        (
            "G1 X0 Y0 F100\nBSPLINE X10 Y5 C30\nX20 Y0\nM30\n",
            "rotary axes in a BSPLINE block",
            ":2:",
        ),
        (
            "G1 X0 Y0 F100\nASPLINE X10 Y5\nX20 Y0\nM30\n",
            "`ASPLINE` is not read",
            ":2:1",
        ),
        (
            "G1 X0 Y0 F100\nCSPLINE X10 Y5\nX20 Y0\nM30\n",
            "`CSPLINE` is not read",
            ":2:1",
        ),
    ];
    for (k, (program, says, at)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{k}.mpf"));
        std::fs::write(&path, program).unwrap();
        let out = volcomp().arg("check").arg(&path).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "{program}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{program}: {err}");
        assert!(err.contains(&format!("bad{k}.mpf{at}")), "{program}: {err}");
    }
}
