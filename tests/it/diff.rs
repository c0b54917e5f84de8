//! `diff`: a program against itself, and the saddle against its compensation.
use crate::compensate::{compensate_text, read};
use crate::predict::rounded;
use crate::support::{assert_success, root, volcomp};
use volcomp::diff::{DiffOptions, diff_programs};
use volcomp::gcode::Frame;

fn diff(a: &str, b: &str) -> volcomp::diff::DiffReport {
    diff_programs(
        volcomp::gcode::Program::from_text(a, "a.nc"),
        volcomp::gcode::Program::from_text(b, "b.nc"),
        &DiffOptions::default(),
    )
    .expect("diffs")
}

#[test]
fn a_program_against_itself_has_no_change() {
    for path in [
        "samples/saddle.nc",
        "samples/saddle-tcp.nc",
        "tests/data/compensate/linuxcnc-demo.ngc",
    ] {
        let text = read(path);
        let r = diff(&text, &text);
        assert!(r.is_identical(), "{path}");
        assert_eq!(r.unchanged, text.lines().count());
        assert_eq!(r.max_xyz_change_um, 0.0);
        assert!(r.largest.is_empty());
    }
}

#[test]
fn saddle_against_its_compensation_snapshot() {
    let original = read("samples/saddle.nc");
    let (compensated, report) = compensate_text(&original, Frame::Joint);
    let r = diff(&original, &compensated);
    assert_eq!(r.added, report.blocks_added);
    assert_eq!(r.removed, 0);
    assert_eq!(r.changed, report.blocks_changed);
    approx::assert_relative_eq!(
        r.max_xyz_change_um,
        report.max_correction_um,
        max_relative = 1e-2
    );
    insta::assert_json_snapshot!("saddle_diff", rounded(serde_json::to_value(&r).unwrap()));
}

#[test]
fn split_pieces_are_added_blocks() {
    let original = read("tests/data/compensate/linuxcnc-demo.ngc");
    let (compensated, report) = compensate_text(&original, Frame::Joint);
    let r = diff(&original, &compensated);
    assert_eq!(r.added, report.blocks_added);
    assert_eq!(r.removed, 0);
    assert_eq!(r.paired, original.lines().count());
}

#[test]
fn cli_prints_a_table_and_writes_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let b = dir.path().join("b.nc");
    // Move the X word of the first cutting block (N70, roughing) by 2.8 µm.
    let original = read("samples/saddle.nc");
    let line = original.lines().find(|l| l.starts_with("N70 X")).unwrap();
    let x_word = line.split_whitespace().nth(1).unwrap();
    let x: f64 = x_word[1..].parse().unwrap();
    let moved = line.replacen(x_word, &format!("X{:.4}", x + 0.0028), 1);
    std::fs::write(&b, original.replacen(line, &moved, 1)).unwrap();
    let json = dir.path().join("d.json");
    let out = volcomp()
        .args(["diff", "samples/saddle.nc"])
        .arg(&b)
        .arg("--report")
        .arg(&json)
        .current_dir(root())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("1 changed"), "{stdout}");
    assert!(stdout.contains("axis"), "{stdout}");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(report["changed"], 1);
    assert!((report["max_xyz_change_um"].as_f64().unwrap() - 2.8).abs() < 1e-6);
}

#[test]
fn cli_locates_an_unparsable_program() {
    let dir = tempfile::tempdir().unwrap();
    let b = dir.path().join("bad.nc");
    std::fs::write(&b, "G21\nG1 X1 F100\nG1 X(2\n").unwrap();
    let out = volcomp()
        .args(["diff", "samples/saddle.nc"])
        .arg(&b)
        .current_dir(root())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("bad.nc:3:"), "{stderr}");
}

/// The provenance stamp of a compensated program is shown, not counted as
/// added blocks.
#[test]
fn the_stamp_of_a_compensated_program_is_not_an_added_block() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.nc");
    let run = volcomp()
        .args([
            "compensate",
            "machines/ref-trt.toml",
            "samples/saddle.nc",
            "-o",
        ])
        .arg(&out)
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&run);
    assert!(
        std::fs::read_to_string(&out)
            .unwrap()
            .contains("(volcomp-stamp ")
    );
    let diff = volcomp()
        .args(["diff", "samples/saddle.nc"])
        .arg(&out)
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&diff);
    let stdout = String::from_utf8_lossy(&diff.stdout);
    assert!(stdout.contains("compensated by volcomp"), "{stdout}");
    assert!(stdout.contains(", 0 added, 0 removed"), "{stdout}");
}

/// Issue 23: `diff` paired a split arc with its FIRST straight piece and
/// reported a 58 mm change where the correction is µm. A split block is paired
/// with the piece that ends where it ends (arcs as lines), and the report
/// says how many pieces it became; an arc of more pieces than the alignment
/// window (1,024) is followed along its path.
#[test]
fn a_split_arc_pairs_with_its_last_piece() {
    // A half circle of radius 40 and a full circle of radius 60 (about 2,400
    // chords at the default tolerance).
    let original = "G21 G90 G17 G94 F500\nG0 X-50 Y0 Z10 A0 C0\nG1 X-40 Y0 Z0\nG2 X40 Y0 I40 J0\nG1 X60\nG3 X60 Y0 I-60 J0\nG1 X70\nM2\n";
    let (compensated, report) = compensate_text(original, Frame::Joint);
    assert_eq!(report.blocks_split, 2, "{report:?}");
    let r = diff(original, &compensated);
    assert_eq!(r.removed, 0);
    assert_eq!(r.added, report.blocks_added);
    assert_eq!(r.paired, original.lines().count());
    assert_eq!(r.split_blocks, 2);
    assert_eq!(r.split_pieces, report.blocks_added + 2);
    assert_eq!((r.splits[0].line_a, r.splits[1].line_a), (4, 6));
    assert!(r.splits[1].pieces > 1024, "{:?}", r.splits);
    // Every change is a correction (µm), none a pairing with the wrong piece.
    assert!(r.max_xyz_change_um < 10.0, "{}", r.max_xyz_change_um);
    approx::assert_relative_eq!(
        r.max_xyz_change_um,
        report.max_correction_um,
        max_relative = 1e-2
    );
    let split = r.largest.iter().find(|c| c.line_a == 4).expect("listed");
    assert_eq!(split.pieces, r.splits[0].pieces);
    // The command's summary says it too.
    let dir = tempfile::tempdir().expect("temp dir");
    let (a, b) = (dir.path().join("a.nc"), dir.path().join("b.nc"));
    std::fs::write(&a, original).expect("written");
    std::fs::write(&b, &compensated).expect("written");
    let out = volcomp()
        .arg("diff")
        .arg(&a)
        .arg(&b)
        .output()
        .expect("runs");
    assert_success(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains(&format!(
            "2 blocks of A became {} blocks of B",
            r.split_pieces
        )) && text.contains("(split into"),
        "{text}"
    );
}

/// The straight pieces of a spline written flat are short: the last few all
/// end within `--match-tol` of the curve's end. The block pairs with the one
/// that ends closest to its end (the last), not the first within reach.
#[test]
fn a_flat_spline_pairs_with_its_last_piece() {
    let original = "G21 G17 G90 G94 F600\nG0 X10 Y10 Z0 A0 C0\nG5 I5 J0 P-5 Q0 X30 Y20\nG5 P-5 Q0 X50 Y10\nG5.1 I5 J5 X60 Y10\nG1 X10 Y10\nM2\n";
    let (compensated, report) = compensate_text(original, Frame::Joint);
    let r = diff(original, &compensated);
    assert_eq!(r.removed, 0);
    let lines: Vec<usize> = r.splits.iter().map(|s| s.line_a).collect();
    assert_eq!(lines[..3], [3, 4, 5], "{:?}", r.splits);
    assert!(
        r.max_xyz_change_um <= report.max_correction_um + 0.1,
        "{r:?}"
    );
    // The paired piece is the curve's last: it ends where the curve ends.
    for (s, end) in r
        .splits
        .iter()
        .zip([[30.0, 20.0], [50.0, 10.0], [60.0, 10.0]])
    {
        let last = compensated.lines().nth(s.last_line_b - 1).unwrap();
        let word = |letter: char| -> f64 {
            last.split_whitespace()
                .find_map(|w| w.strip_prefix(letter))
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN)
        };
        let d = (word('X') - end[0]).hypot(word('Y') - end[1]);
        assert!(d < 0.005, "line {} → {last}", s.line_a);
    }
}

/// Curves smaller than `--match-tol` (LinuxCNC's `systems.ngc` writes letters
/// of G5.1 curves a tenth of a millimetre high): every piece of several
/// curves ends within the tolerance of each curve's end. The comment the
/// writer puts before a block it writes flat says which block the pieces
/// stand for; the curve pairs with its own last piece. Canned cycles too.
#[test]
fn blocks_written_flat_pair_by_the_writers_comment() {
    let mut original = String::from("G21 G17 G90 G94 F600\nG0 X10 Y10 Z5 A0 C0\nG1 Z0\n");
    for k in 0..20 {
        let x = 10.0 + 0.01 * k as f64;
        original.push_str(&format!("G5.1 I0.002 J0.004 X{:.3} Y10.01\n", x + 0.005));
        original.push_str(&format!("G5.1 I0.002 J-0.004 X{:.3} Y10\n", x + 0.01));
    }
    original.push_str("G0 Z5\nM3 S1000\nG91 G82 X1 R-4 Z-2 P0.5 L3\nG90 G80\nM2\n");
    let (compensated, report) = compensate_text(&original, Frame::Joint);
    let r = diff(&original, &compensated);
    assert_eq!(r.removed, 0, "{r:?}");
    assert_eq!(r.paired, original.lines().count());
    // 40 curves and one cycle, each paired with its last piece.
    assert_eq!(r.split_blocks, 41, "{:?}", r.splits);
    assert!(
        r.max_xyz_change_um <= report.max_correction_um + 0.1,
        "{} vs {}",
        r.max_xyz_change_um,
        report.max_correction_um
    );
}
