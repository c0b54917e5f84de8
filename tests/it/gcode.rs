//! The G-code front end: parser round trip, interpreter snapshots, rewriter,
//! errors, and no panic on any input.
use std::path::Path;

use proptest::prelude::*;
use volcomp::gcode::{BlockReader, ReadOptions, parse_program, parse_program_bytes, print_program};

fn fixture_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/gcode"))
}

fn fixtures() -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(fixture_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "nc"))
        .collect();
    v.sort();
    v
}

#[test]
fn parse_then_print_is_identity_on_every_fixture() {
    let files = fixtures();
    assert!(files.len() >= 10, "fixtures missing: {files:?}");
    let mut blind = fixtures();
    blind.push(
        Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/blind/01-backlash/program.nc"
        ))
        .to_path_buf(),
    );
    for path in blind {
        let bytes = std::fs::read(&path).unwrap();
        let blocks = parse_program_bytes(&bytes, ReadOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(print_program(&blocks), bytes, "{}", path.display());
        // Spans are consistent with the file.
        for b in &blocks {
            let span = b.span();
            assert_eq!(&bytes[span.start as usize..span.end as usize], &b.raw[..]);
            for w in &b.words {
                assert!(w.start < w.end && w.end <= b.raw.len());
                assert!(b.raw[w.start].eq_ignore_ascii_case(&w.letter));
            }
        }
    }
}

#[test]
fn crlf_and_missing_final_newline_are_remembered() {
    let blocks = parse_program("G0 X1\r\nG1 X2\nG1 X3").unwrap();
    use volcomp::gcode::LineEnding::*;
    let endings: Vec<_> = blocks.iter().map(|b| b.ending).collect();
    assert_eq!(endings, vec![CrLf, Lf, None]);
    assert_eq!(blocks[2].line, 3);
    assert_eq!(blocks[1].offset, 7);
}

#[test]
fn exact_values_survive() {
    let b = &parse_program("G93 G1 X  16.339 F30070.6535 y 1 0.5\n").unwrap()[0];
    let v: Vec<f64> = b.words.iter().map(|w| w.value).collect();
    assert_eq!(v, vec![93.0, 1.0, 16.339, 30070.6535, 10.5]);
    assert_eq!(b.words[2].decimals, 3);
    assert_eq!(&b.raw[b.words[2].start..b.words[2].end], b"X  16.339");
}

/// One generated word: its text and the value it must parse to.
fn word_strategy() -> impl Strategy<Value = (String, char, f64)> {
    (
        prop::sample::select(vec![
            'G', 'M', 'X', 'Y', 'Z', 'A', 'C', 'F', 'S', 'T', 'H', 'I', 'J', 'K', 'R', 'P', 'Q',
            'E', 'B', 'U',
        ]),
        any::<bool>(),
        -99999i64..99999,
        0u32..6,
        0usize..3,
        prop::sample::select(vec!["", "+", "-"]),
    )
        .prop_map(|(letter, lower, int, decimals, spaces, sign)| {
            let mag = int.unsigned_abs();
            let digits = if decimals == 0 {
                format!("{mag}")
            } else {
                let s = format!("{:0width$}", mag, width = decimals as usize + 1);
                let (a, b) = s.split_at(s.len() - decimals as usize);
                format!("{a}.{b}")
            };
            let value: f64 = digits.parse::<f64>().unwrap() * if sign == "-" { -1.0 } else { 1.0 };
            // Spaces between the letter and the number and inside the number.
            let mut spaced = String::new();
            for (i, ch) in digits.chars().enumerate() {
                if i == 1 && spaces == 2 {
                    spaced.push(' ');
                }
                spaced.push(ch);
            }
            let pad = if spaces >= 1 { " " } else { "" };
            let l = if lower {
                letter.to_ascii_lowercase()
            } else {
                letter
            };
            (format!("{l}{pad}{sign}{spaced}"), letter, value)
        })
}

fn line_strategy() -> impl Strategy<Value = (String, Vec<(char, f64)>)> {
    (
        prop::option::of(1u32..99999),
        prop::collection::vec(word_strategy(), 0..7),
        prop::option::of(prop::sample::select(vec![
            "(cut)",
            "( é ü )",
            "; tail",
            "(a);b",
        ])),
        any::<bool>(),
    )
        .prop_map(|(n, words, comment, tight)| {
            let mut text = String::new();
            let mut expect = Vec::new();
            if let Some(n) = n {
                text.push_str(&format!("N{n}"));
                expect.push(('N', n as f64));
            }
            for (w, letter, value) in words {
                if !text.is_empty() && !tight {
                    text.push(' ');
                }
                text.push_str(&w);
                expect.push((letter, value));
            }
            if let Some(c) = comment {
                text.push_str(c);
            }
            (text, expect)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn generated_programs_round_trip(
        lines in prop::collection::vec((line_strategy(), any::<bool>()), 0..30),
        final_newline in any::<bool>(),
    ) {
        let mut text = String::new();
        let mut expect = Vec::new();
        let n = lines.len();
        for (i, ((line, words), crlf)) in lines.into_iter().enumerate() {
            text.push_str(&line);
            if i + 1 < n || final_newline {
                text.push_str(if crlf { "\r\n" } else { "\n" });
            }
            expect.push(words);
        }
        let blocks = parse_program(&text).unwrap();
        prop_assert_eq!(print_program(&blocks), text.as_bytes().to_vec());
        prop_assert_eq!(blocks.len(), text.split_inclusive('\n').count());
        for (b, e) in blocks.iter().zip(&expect) {
            let got: Vec<(char, f64)> = b.words.iter().map(|w| (w.letter as char, w.value)).collect();
            prop_assert_eq!(&got, e);
        }
    }

    #[test]
    fn reader_never_panics_on_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400), lenient in any::<bool>()) {
        let mut reader = BlockReader::new(&bytes[..], ReadOptions { lenient });
        let mut out = Vec::new();
        while let Some(block) = reader.next_block() {
            match block {
                Ok(b) => { b.write_raw(&mut out).unwrap(); }
                Err(e) => { let _ = e.to_string(); }
            }
        }
        if lenient {
            prop_assert_eq!(out, bytes);
        }
    }
}

/// Round for snapshots (6 decimals, no negative zero).
fn r6(v: f64) -> String {
    let s = format!("{:.6}", v);
    let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    if s == "-0" { "0".into() } else { s }
}

fn axes6(a: &volcomp::axes::Axes) -> String {
    format!(
        "[{}, {}, {}, {}, {}]",
        r6(a.x),
        r6(a.y),
        r6(a.z),
        r6(a.a),
        r6(a.c)
    )
}

/// One line per motion block and per notable event.
fn render_events(bytes: &[u8], options: volcomp::gcode::InterpretOptions) -> String {
    use volcomp::gcode::{MotionKind, interpret_program};
    let events = match interpret_program(bytes, options) {
        Ok(e) => e,
        Err(e) => return format!("ERROR {e}"),
    };
    let mut out = String::new();
    for (_, ev) in &events {
        let mut notes = Vec::new();
        if let Some(f) = ev.frame_switch {
            notes.push(format!("frame->{f:?}"));
        }
        if ev.home {
            notes.push("home".into());
        }
        if ev.program_end {
            notes.push("end".into());
        }
        if ev.skipped {
            notes.push("skipped".into());
        }
        for w in &ev.warnings {
            notes.push(format!("warn: {w}"));
        }
        if let Some(m) = &ev.motion {
            let kind = match m.kind {
                MotionKind::Rapid => "G0".to_string(),
                MotionKind::Linear => "G1".to_string(),
                MotionKind::Arc {
                    clockwise,
                    centre,
                    plane,
                    turns,
                } => format!(
                    "{} {:?} c=[{}, {}, {}]{}",
                    if clockwise { "G2" } else { "G3" },
                    plane,
                    r6(centre[0]),
                    r6(centre[1]),
                    r6(centre[2]),
                    if turns > 0 {
                        format!(" +{turns}turns")
                    } else {
                        String::new()
                    }
                ),
            };
            let feed = match m.feed {
                volcomp::gcode::Feed::Rapid => "rapid".to_string(),
                volcomp::gcode::Feed::PerMinute(f) => format!("F{}mm/min", r6(f)),
                volcomp::gcode::Feed::InverseTime(f) => format!("F{}/min(G93)", r6(f)),
            };
            out.push_str(&format!(
                "L{} {} {:?}{} end={} {} dur={} t={}",
                ev.line,
                kind,
                m.frame,
                if m.machine_coordinates { " G53" } else { "" },
                axes6(&m.end),
                feed,
                r6(m.duration_min),
                r6(ev.time_min)
            ));
        } else if notes.is_empty() {
            continue;
        } else {
            out.push_str(&format!("L{}", ev.line));
        }
        for n in notes {
            out.push_str(&format!(" | {n}"));
        }
        out.push('\n');
    }
    out
}

#[test]
fn interpreted_targets_of_every_fixture() {
    insta::glob!("../data/gcode", "*.nc", |path| {
        let bytes = std::fs::read(path).unwrap();
        insta::assert_snapshot!(render_events(&bytes, Default::default()));
    });
}
