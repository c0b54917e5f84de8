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

/// Issue 23: LinuxCNC refuses a program that starts with a byte order mark
/// (rs274: "Bad character '\357' used"), and so does volcomp, at 1:1.
#[test]
fn a_byte_order_mark_is_refused_as_linuxcnc_refuses_it() {
    let e = parse_program("\u{feff}%\nG0 X1\n").unwrap_err();
    assert_eq!((e.line, e.column), (1, 1));
    assert!(e.to_string().contains("Bad character '\\357' used"), "{e}");
    // Elsewhere than at the start of the file it is an unexpected character.
    assert!(parse_program("%\nG0 X1\n\u{feff}G0 X2\n").is_err());
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
        prop::sample::select(vec!["", "", "", "/", " /", "%"]),
    )
        .prop_map(|(n, words, comment, tight, prefix)| {
            if prefix == "%" {
                return ("%".to_string(), Vec::new());
            }
            let mut text = prefix.to_string();
            let mut expect = Vec::new();
            if let Some(n) = n {
                text.push_str(&format!("N{n}"));
                expect.push(('N', n as f64));
            }
            for (w, letter, value) in words {
                if !text.trim_start().trim_start_matches('/').is_empty() && !tight {
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
    fn numbers_parse_exactly_like_str_parse(
        int in 0u64..100_000_000_000_000_000,
        dec in 0usize..25,
        neg in any::<bool>(),
    ) {
        let digits = int.to_string();
        let text = if dec == 0 {
            digits
        } else {
            let padded = format!("{:0>width$}", digits, width = dec + 1);
            let (a, b) = padded.split_at(padded.len() - dec);
            format!("{a}.{b}")
        };
        let text = if neg { format!("-{text}") } else { text };
        let b = &parse_program(&format!("X{text}")).unwrap()[0];
        prop_assert_eq!(b.words[0].value.to_bits(), text.parse::<f64>().unwrap().to_bits(), "{}", text);
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
        if ev.is_home() {
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
        if let Some(m) = ev.motion() {
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

mod rewriting {
    use volcomp::axes::Axes;
    use volcomp::gcode::{
        BlockReader, Feed, InterpretOptions, Interpreter, Motion, ReadOptions, RewriteOptions,
        Rewriter, Target, interpret_program,
    };

    /// Rewrite a program, asking `plan` for the targets of every motion block
    /// (`None` = same); returns the output.
    pub fn rewrite(
        bytes: &[u8],
        plan: impl Fn(usize, &Motion) -> Option<(Vec<Axes>, Axes)>,
    ) -> Vec<u8> {
        let options = InterpretOptions::default();
        let mut reader = BlockReader::new(bytes, ReadOptions::default());
        let mut interpreter = Interpreter::new(options);
        let mut rewriter = Rewriter::new(RewriteOptions::default(), options.initial_position);
        let mut out = Vec::new();
        while let Some(block) = reader.next_block() {
            let block = block.unwrap();
            let event = interpreter.interpret(block).unwrap();
            let planned = event.motion().and_then(|m| plan(block.line, m));
            let target = match &planned {
                None => Target::Same,
                Some((via, end)) if via.is_empty() => Target::Move(*end),
                Some((via, end)) => Target::Split { via, end: *end },
            };
            rewriter.emit(block, &event, target, &mut out).unwrap();
        }
        out
    }

    fn motions(bytes: &[u8]) -> Vec<(usize, Motion)> {
        interpret_program(bytes, InterpretOptions::default())
            .unwrap_or_else(|e| panic!("{e}\n{}", String::from_utf8_lossy(bytes)))
            .into_iter()
            .filter_map(|(b, e)| e.motion().copied().map(|m| (b.line, m)))
            .collect()
    }

    pub fn close(a: &Axes, b: &Axes, tol: f64) -> bool {
        a.to_array()
            .iter()
            .zip(b.to_array())
            .all(|(x, y)| (x - y).abs() <= tol)
    }

    fn offset(a: Axes, k: usize) -> Axes {
        let s = if k % 2 == 0 { 1.0 } else { -1.0 };
        Axes::xyzac(
            a.x + 0.0123 * s,
            a.y - 0.0071,
            a.z + 0.0049 * s,
            a.a + 0.0031,
            a.c - 0.0207 * s,
        )
    }

    fn stream(
        bytes: &[u8],
        plan: impl FnMut(
            &volcomp::gcode::Block,
            &volcomp::gcode::BlockEvent,
            &mut Vec<Axes>,
        ) -> Option<Axes>,
    ) -> (Vec<u8>, volcomp::gcode::RewriteStats) {
        let mut out = Vec::new();
        let program =
            volcomp::gcode::Program::from_text(std::str::from_utf8(bytes).expect("utf-8"), "p.nc");
        let stats = volcomp::gcode::rewrite_stream(
            program.run(InterpretOptions::default()),
            &mut out,
            RewriteOptions::default(),
            plan,
        )
        .unwrap();
        (out, stats)
    }

    #[test]
    fn rewrite_stream_matches_the_block_api_and_counts() {
        use volcomp::gcode::RewriteStats;
        let plan = |line: usize, m: &Motion| {
            (line % 3 == 0).then(|| (vec![m.start.lerp(&m.end, 0.5)], offset(m.end, line)))
        };
        for path in super::fixtures() {
            let bytes = std::fs::read(&path).unwrap();
            let (out, stats) = stream(&bytes, |block, event, via| {
                let (v, end) = plan(block.line, event.motion()?)?;
                via.extend(v);
                Some(end)
            });
            assert_eq!(out, rewrite(&bytes, plan), "{}", path.display());
            assert_eq!(stats.blocks, bytes.split_inclusive(|&b| b == b'\n').count());
        }
        let bytes = std::fs::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/blind/01-backlash/program.nc"
        ))
        .unwrap();
        let (_, stats) = stream(&bytes, |block, event, via| {
            let m = event.motion()?;
            (block.line == 10 || block.line == 20).then(|| {
                if block.line == 20 {
                    via.push(m.start.lerp(&m.end, 0.5));
                }
                Axes {
                    c: m.end.c + 0.01,
                    ..m.end
                }
            })
        });
        assert_eq!(
            stats,
            RewriteStats {
                blocks: 3318,
                motions: 3313,
                rewritten: 2,
                pieces: 1,
                flat: 0
            }
        );
    }

    #[test]
    fn unchanged_targets_give_the_same_bytes() {
        for path in super::fixtures() {
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(rewrite(&bytes, |_, _| None), bytes, "{}", path.display());
        }
    }

    #[test]
    fn changing_one_axis_changes_only_that_word() {
        let bytes = std::fs::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/blind/01-backlash/program.nc"
        ))
        .unwrap();
        let out = rewrite(&bytes, |line, m| {
            (line == 10).then(|| {
                (
                    vec![],
                    Axes {
                        c: m.end.c + 0.01234,
                        ..m.end
                    },
                )
            })
        });
        let (a, b) = (
            String::from_utf8(bytes).unwrap(),
            String::from_utf8(out).unwrap(),
        );
        let diff: Vec<_> = a.lines().zip(b.lines()).filter(|(x, y)| x != y).collect();
        assert_eq!(
            diff,
            vec![(
                "N80 X-23.1840 Y-35.8426 Z-33.3938 A51.9344 C22.0802",
                "N80 X-23.1840 Y-35.8426 Z-33.3938 A51.9344 C22.0925"
            )]
        );
        assert_eq!(a.len(), b.len());
    }

    #[test]
    fn moved_targets_are_reached_in_every_fixture() {
        for path in super::fixtures() {
            let bytes = std::fs::read(&path).unwrap();
            let before = motions(&bytes);
            let out = rewrite(&bytes, |line, m| Some((vec![], offset(m.end, line))));
            let after = motions(&out);
            assert_eq!(before.len(), after.len(), "{}", path.display());
            for ((line, m0), (_, m1)) in before.iter().zip(&after) {
                let want = offset(m0.end, *line);
                // 5-decimal inches or 4-decimal mm: half a unit of the last digit.
                assert!(
                    close(&m1.end, &want, 0.00013),
                    "{}:{line}: {:?} vs {want:?}",
                    path.display(),
                    m1.end
                );
                assert_eq!(
                    std::mem::discriminant(&m0.kind),
                    std::mem::discriminant(&m1.kind)
                );
            }
            // Lines that did not hold a move are untouched.
            let text_in = String::from_utf8_lossy(&bytes).to_string();
            let text_out = String::from_utf8_lossy(&out).to_string();
            let moving: std::collections::HashSet<usize> = before.iter().map(|(l, _)| *l).collect();
            for (i, (x, y)) in text_in.split('\n').zip(text_out.split('\n')).enumerate() {
                if !moving.contains(&(i + 1)) {
                    assert_eq!(x, y, "{}:{}", path.display(), i + 1);
                }
            }
        }
    }

    #[test]
    fn split_moves_reach_every_piece_and_keep_g93_time() {
        for path in super::fixtures() {
            let bytes = std::fs::read(&path).unwrap();
            let before = motions(&bytes);
            let plan = |line: usize, m: &Motion| {
                let via = vec![
                    offset(m.start.lerp(&m.end, 1.0 / 3.0), line),
                    offset(m.start.lerp(&m.end, 2.0 / 3.0), line + 1),
                ];
                Some((via, m.end))
            };
            let out = rewrite(&bytes, plan);
            let after = motions(&out);
            // Every move becomes three (the offsets make every piece non-empty).
            let mut k = 0;
            for (line, m0) in &before {
                let (via, end) = plan(*line, m0).unwrap();
                let mut expect = via.clone();
                expect.push(end);
                let mut time = 0.0;
                let mut n = 0;
                for want in expect {
                    let (_, got) = &after[k];
                    assert!(
                        close(&got.end, &want, 0.00013),
                        "{}:{line}: {:?} vs {want:?}",
                        path.display(),
                        got.end
                    );
                    time += got.duration_min;
                    k += 1;
                    n += 1;
                }
                if let Feed::InverseTime(f) = m0.feed {
                    assert_eq!(n, 3);
                    approx::assert_relative_eq!(time, 1.0 / f, max_relative = 1e-6);
                }
            }
            assert_eq!(k, after.len(), "{}", path.display());
        }
    }

    #[test]
    fn incremental_values_follow_the_emitted_program() {
        let text = "G21 G91 G94\nG1 X1. Y1. F100\nX1. Y1.\nX1.\n";
        let out = rewrite(text.as_bytes(), |line, m| {
            (line == 2).then(|| {
                (
                    vec![],
                    Axes {
                        x: m.end.x + 0.5,
                        ..m.end
                    },
                )
            })
        });
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "G21 G91 G94\nG1 X1.5000 Y1. F100\nX0.5000 Y1.\nX1.\n"
        );
    }

    #[test]
    fn inch_programs_are_written_back_in_inches() {
        let text = "G20 G90 G94\nG1 X1. Y2. F10\n";
        let out = rewrite(text.as_bytes(), |_, m| {
            Some((
                vec![],
                Axes {
                    x: m.end.x + 0.254,
                    z: m.end.z - 0.0254,
                    ..m.end
                },
            ))
        });
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "G20 G90 G94\nG1 X1.01000 Y2. Z-0.00100 F10\n"
        );
    }

    #[test]
    fn split_under_g93_rescales_f_and_keeps_the_words() {
        let text =
            "N5 G21 G90 G93 G1 X0 Y0 Z0 A0 C0 F60.\nN10 X30. C30. F2.5 (cut)\r\nN20 G94 G0 Z5\n";
        let out = rewrite(text.as_bytes(), |line, _| {
            (line == 2).then(|| {
                (
                    vec![
                        Axes::xyzac(10.0, 0.0, 0.0, 0.0, 10.0),
                        Axes::xyzac(20.0, 0.0, 0.0, 0.0, 20.0),
                    ],
                    Axes::xyzac(30.0, 0.0, 0.0, 0.0, 30.0),
                )
            })
        });
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "N5 G21 G90 G93 G1 X0 Y0 Z0 A0 C0 F60.\n\
             G1 X10.0000 C10.0000 F7.500000\r\n\
             G1 X20.0000 C20.0000 F7.500000\r\n\
             N10 X30. C30. F7.500000 (cut)\r\n\
             N20 G94 G0 Z5\n"
        );
    }

    #[test]
    fn a_straightened_arc_restores_the_arc_mode_of_the_next_block() {
        let text = "G21 G90 G94 G17\nG0 X10 Y0\nN30 G2 X0 Y10 I-10 J0 F100\nN40 X-10 Y0 I0 J-10\n";
        let out = rewrite(text.as_bytes(), |line, m| {
            (line == 3).then(|| (vec![Axes::xyzac(7.0711, 7.0711, 0.0, 0.0, 0.0)], m.end))
        });
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "G21 G90 G94 G17\nG0 X10 Y0\nG1 X7.0711 Y7.0711 F100\nN30 G1 X0 Y10 F100\nN40 G2 X-10 Y0 I0 J-10\n"
        );
    }
}

mod errors {
    use volcomp::gcode::{InterpretOptions, interpret_program};

    const BAD: [(&str, &str); 12] = [
        ("unclosed comment", "G0 X0 Y0\nG1 X1 (no end F100\n"),
        ("word without number", "G0 X0\nG1 X Y2 F100\n"),
        ("parameter in an axis word", "G0 X0\nG1 X#100 F100\n"),
        ("expression in an axis word", "G0 X0\nG1 X[1+2] F100\n"),
        ("O-word subroutine", "%\nO100 sub\nG1 X1\nO100 endsub\n"),
        ("named O-word", "o<probe> call\n"),
        ("M98 call", "G0 X0\nN20 M98 P1000\n"),
        (
            "cutter compensation during a move",
            "G0 X0 Y0\nG41 D1 G1 X10 Y0 F300\n",
        ),
        ("unknown geometric G code", "G0 X0\nG33 X10 K1\n"),
        ("unexpected character", "G0 X0\nG1 X1 = 5\n"),
        ("axis words without motion mode", "G21 G90\nX10 Y10\n"),
        ("arc R too small", "G0 X0 Y0\nG2 X10 Y0 R2 F100\n"),
    ];

    fn render(text: &str, lenient: bool) -> String {
        let options = InterpretOptions {
            lenient,
            ..Default::default()
        };
        match interpret_program(text.as_bytes(), options) {
            Ok(events) => {
                let warnings: Vec<String> = events
                    .iter()
                    .flat_map(|(_, e)| e.warnings.iter().map(|w| w.to_string()))
                    .collect();
                format!("ok; warnings:\n{}", warnings.join("\n"))
            }
            Err(e) => e.with_path("bad.nc").to_string(),
        }
    }

    #[test]
    fn bad_input_is_located_with_a_caret_and_a_hint() {
        let mut all = String::new();
        for (name, text) in BAD {
            let msg = render(text, false);
            assert!(msg.contains("--> bad.nc:"), "{name}: {msg}");
            assert!(msg.contains('^') && msg.contains("hint:"), "{name}: {msg}");
            all.push_str(&format!("=== {name}\n{msg}\n\n"));
        }
        insta::assert_snapshot!(all);
    }

    #[test]
    fn lenient_passes_bad_input_through_with_warnings() {
        let mut all = String::new();
        for (name, text) in BAD {
            let msg = render(text, true);
            assert!(msg.starts_with("ok"), "{name}: {msg}");
            assert!(msg.contains("--lenient"), "{name}: {msg}");
            all.push_str(&format!("=== {name}\n{msg}\n\n"));
        }
        insta::assert_snapshot!(all);
    }

    #[test]
    fn column_points_at_the_spot() {
        let e = interpret_program(b"G0 X0\nN7 G1 Y 2 X#3\n", Default::default()).unwrap_err();
        assert_eq!((e.line, e.column), (2, 12));
    }
}

mod robustness {
    use proptest::prelude::*;
    use volcomp::axes::Axes;
    use volcomp::gcode::{
        BlockReader, InterpretOptions, Interpreter, ReadOptions, RewriteOptions, Rewriter, Target,
    };

    /// Bytes that look like G-code often enough to reach the interpreter.
    fn gcode_ish() -> impl Strategy<Value = Vec<u8>> {
        prop::collection::vec(
            prop_oneof![
                4 => prop::sample::select(b"GMXYZACFIJKRPNO0123456789.-+ \n\r();/%#[]gxyzTRAOI".to_vec()),
                1 => any::<u8>(),
            ],
            0..300,
        )
    }

    fn run(bytes: &[u8], lenient: bool, moves: &[(f64, f64)]) -> Vec<u8> {
        let options = InterpretOptions {
            lenient,
            ..Default::default()
        };
        let mut reader = BlockReader::new(bytes, ReadOptions { lenient });
        let mut interpreter = Interpreter::new(options);
        let mut rewriter = Rewriter::new(RewriteOptions::default(), options.initial_position);
        let mut out = Vec::new();
        let mut k = 0;
        while let Some(block) = reader.next_block() {
            let Ok(block) = block else { continue };
            let Ok(event) = interpreter.interpret(block) else {
                continue;
            };
            let via;
            let target = match (event.motion(), moves.get(k)) {
                (Some(m), Some(&(dx, dc))) => {
                    k += 1;
                    let end = Axes {
                        x: m.end.x + dx,
                        c: m.end.c + dc,
                        ..m.end
                    };
                    if k % 2 == 0 {
                        via = [m.start.lerp(&end, 0.5), m.start.lerp(&end, 0.5), end];
                        Target::Split { via: &via, end }
                    } else {
                        Target::Move(end)
                    }
                }
                _ => Target::Same,
            };
            let _ = rewriter.emit(block, &event, target, &mut out);
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn no_panic_on_any_bytes(
            bytes in prop_oneof![gcode_ish(), prop::collection::vec(any::<u8>(), 0..300)],
            lenient in any::<bool>(),
            moves in prop::collection::vec((-1e3f64..1e3, -1e4f64..1e4), 0..4),
        ) {
            run(&bytes, lenient, &moves);
            // With every target unchanged, a lenient run reproduces the input.
            if lenient {
                prop_assert_eq!(run(&bytes, true, &[]), bytes);
            }
        }
    }
}

mod check_command {

    #[test]
    fn check_summarises_a_program() {
        let path = super::fixture_dir().join("tcp_linuxcnc_demo.nc");
        let out = crate::support::volcomp()
            .arg("check")
            .arg(&path)
            .output()
            .unwrap();
        crate::support::assert_success(&out);
        let text = String::from_utf8(out.stdout).unwrap();
        assert!(text.contains("motion blocks: 6 (G0 2, G1 4"), "{text}");
        assert!(text.contains("2 switches, 4 part-frame"), "{text}");
        assert!(text.contains("G93 inverse-time moves: 4"), "{text}");
    }

    #[test]
    fn check_fails_with_a_located_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.nc");
        std::fs::write(&path, "G0 X0\nG1 X1 Y#<nope> F100\nM2\n").unwrap();
        let out = crate::support::volcomp()
            .arg("check")
            .arg(&path)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(
            err.contains("bad.nc:2:8") && err.contains("^") && err.contains("--lenient"),
            "{err}"
        );
        let out = crate::support::volcomp()
            .args(["check", "--lenient"])
            .arg(&path)
            .output()
            .unwrap();
        assert!(out.status.success());
    }
}

mod rewrite_property {
    use proptest::prelude::*;
    use volcomp::axes::Axes;
    use volcomp::gcode::{InterpretOptions, interpret_program};

    const FRAGMENTS: [&str; 40] = [
        "G0",
        "G1",
        "G1",
        "G2",
        "G3",
        "G91",
        "G90",
        "G20",
        "G21",
        "G93",
        "G94",
        "G17",
        "G18",
        "G19",
        "G90.1",
        "G91.1",
        "M428",
        "M429",
        "G43.4 H1",
        "G49",
        "TRAORI",
        "TRAFOOF",
        "G53",
        "X1.5",
        "Y-2",
        "Z.5",
        "A10",
        "C400",
        "x 3 .25",
        "I1",
        "J-1",
        "K2",
        "R5",
        "R-5",
        "F100",
        "F2.5",
        "N10",
        "(c)",
        "; c",
        "G91 G28 Z0",
    ];

    fn program() -> impl Strategy<Value = String> {
        prop::collection::vec(
            (
                prop::collection::vec(prop::sample::select(FRAGMENTS.to_vec()), 0..5),
                any::<bool>(),
            ),
            1..25,
        )
        .prop_map(|lines| {
            let mut text = String::from("G21 G90 G94 G17 G0 X0 Y0 Z0 A0 C0\n");
            for (words, crlf) in lines {
                // A ';' comment must come last on its line.
                let (mut body, tail): (Vec<&str>, Vec<&str>) =
                    words.into_iter().partition(|w| !w.starts_with(';'));
                body.extend(tail.into_iter().take(1));
                text.push_str(&body.join(" "));
                text.push_str(if crlf { "\r\n" } else { "\n" });
            }
            text
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Moved and split targets of any valid program are reached when the
        /// output is read back, block by block.
        #[test]
        fn rewritten_programs_reach_the_requested_targets(
            text in program(),
            seed in 0u64..1000,
            split in any::<bool>(),
        ) {
            let bytes = text.as_bytes();
            let Ok(before) = interpret_program(bytes, InterpretOptions::default()) else {
                return Ok(());
            };
            let delta = |line: usize, k: usize| {
                let s = ((seed as usize + line * 7 + k * 3) % 11) as f64 - 5.0;
                (0.0137 * s, -0.0071 * s, 0.0043 * s, 0.011 * s, -0.023 * s)
            };
            let shift = |a: Axes, line: usize, k: usize| {
                let d = delta(line, k);
                Axes::xyzac(a.x + d.0, a.y + d.1, a.z + d.2, a.a + d.3, a.c + d.4)
            };
            let plan = |line: usize, m: &volcomp::gcode::Motion| {
                let end = shift(m.end, line, 0);
                let via = if split && line % 2 == 0 {
                    vec![shift(m.start.lerp(&m.end, 0.5), line, 1)]
                } else {
                    vec![]
                };
                Some((via, end))
            };
            let out = super::rewriting::rewrite(bytes, plan);
            let after = interpret_program(&out, InterpretOptions::default())
                .map_err(|e| TestCaseError::fail(format!("{e}\n--- in:\n{text}\n--- out:\n{}", String::from_utf8_lossy(&out))))?;
            // (target, is an intermediate piece: dropped when it has zero length)
            let mut want = Vec::new();
            for (b, e) in &before {
                if let Some(m) = e.motion() {
                    let (via, end) = plan(b.line, m).unwrap();
                    want.extend(via.into_iter().map(|v| (v, true)));
                    want.push((end, false));
                }
            }
            let got: Vec<Axes> = after.iter().filter_map(|(_, e)| e.motion().copied().map(|m| m.end)).collect();
            let mut k = 0;
            for (w, piece) in &want {
                if k < got.len() && super::rewriting::close(&got[k], w, 1.3e-4) {
                    k += 1;
                } else {
                    prop_assert!(*piece, "target {:?} not reached (got {:?})\n--- in:\n{}\n--- out:\n{}", w, got.get(k), text, String::from_utf8_lossy(&out));
                }
            }
            prop_assert_eq!(k, got.len(), "extra moves\n--- in:\n{}\n--- out:\n{}", text, String::from_utf8_lossy(&out));
        }
    }
}

mod interpreting {
    use volcomp::gcode::{
        Feed, Frame, InterpretOptions, MotionKind, WarningKind, interpret_program,
    };

    fn motions(text: &str, options: InterpretOptions) -> Vec<volcomp::gcode::BlockEvent> {
        interpret_program(text.as_bytes(), options)
            .unwrap()
            .into_iter()
            .map(|(_, e)| e)
            .collect()
    }

    #[test]
    fn an_axis_the_machine_lacks_is_a_bad_character() {
        use volcomp::axes::{Axis, AxisSet};
        // Without a machine, rs274's X Y Z A B C: B is an axis, U is not.
        let ev = motions("G0 X0 B5\nG1 X1 B6 F100\n", Default::default());
        assert_eq!(ev[1].motion().copied().unwrap().end.b, 6.0);
        let err = interpret_program("G0 X0 U1\n".as_bytes(), Default::default()).unwrap_err();
        assert_eq!(err.line, 1);
        assert_eq!(err.column, 7);
        assert!(err.to_string().contains("Bad character 'u' used"), "{err}");
        // An A/C machine: B is a located error, and under --lenient a reported
        // warning, the word ignored.
        let ac = InterpretOptions {
            axes: AxisSet::of(&[Axis::X, Axis::Y, Axis::Z, Axis::A, Axis::C]),
            ..Default::default()
        };
        let err = interpret_program("G0 X0\nG1 X1 B6 F100\n".as_bytes(), ac).unwrap_err();
        assert_eq!((err.line, err.column), (2, 7));
        assert!(
            err.to_string().contains("no B axis (its axes: XYZAC)"),
            "{err}"
        );
        let lenient = InterpretOptions {
            lenient: true,
            ..ac
        };
        let ev = motions("G0 X0\nG1 X1 B6 F100\n", lenient);
        assert_eq!(ev[1].motion().copied().unwrap().end.b, 0.0);
        assert!(matches!(
            &ev[1].warnings[0].kind,
            WarningKind::Lenient(volcomp::gcode::ErrorKind::AxisNotOnMachine { letter: 'B', .. })
        ));
    }

    #[test]
    fn initial_frame_g53_and_rapid_rate() {
        let options = InterpretOptions {
            initial_frame: Frame::Part,
            rapid_mm_per_min: 5000.0,
            ..Default::default()
        };
        let ev = motions("G0 X10\nG53 G0 Z-100\nG91 G0 Z100\n", options);
        let m0 = ev[0].motion().copied().unwrap();
        assert_eq!(m0.frame, Frame::Part);
        let m1 = ev[1].motion().copied().unwrap();
        assert!(m1.machine_coordinates);
        assert_eq!(m1.end.z, -100.0);
        approx::assert_relative_eq!(m1.duration_min, (100.0f64.powi(2) * 1.0).sqrt() / 5000.0);
        let m2 = ev[2].motion().copied().unwrap();
        assert!(!m2.machine_coordinates);
        assert_eq!(m2.end.z, 0.0);
        assert_eq!(m2.feed, Feed::Rapid);
        // LinuxCNC refuses G53 under G91, and with other motions than G0/G1.
        for bad in [
            "G91 G53 G0 Z-100\n",
            "G91\nG53 G1 Z1 F100\n",
            "G53 G2 X1 R1 F100\n",
        ] {
            assert!(interpret_program(bad.as_bytes(), options).is_err(), "{bad}");
        }
    }

    #[test]
    fn time_starts_at_the_first_target_and_rotary_moves_use_degrees() {
        let ev = motions("G0 X100\nG1 C90 F45\nG93 G1 A10 F4\n", Default::default());
        assert_eq!(ev[0].time_min, 0.0);
        approx::assert_relative_eq!(ev[1].motion().copied().unwrap().duration_min, 2.0);
        approx::assert_relative_eq!(ev[2].motion().copied().unwrap().duration_min, 0.25);
        approx::assert_relative_eq!(ev[2].time_min, 2.25);
    }

    #[test]
    fn r_arcs_in_inches_pick_the_right_centre() {
        let ev = motions(
            "G20 G17 G0 X1 Y0\nG3 X0 Y1 R1 F10\nG3 X1 Y0 R-1\n",
            Default::default(),
        );
        let MotionKind::Arc { centre, .. } = ev[1].motion().copied().unwrap().kind else {
            panic!()
        };
        approx::assert_abs_diff_eq!(centre[0], 0.0, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(centre[1], 0.0, epsilon = 1e-9);
        let m = ev[2].motion().copied().unwrap();
        approx::assert_relative_eq!(
            m.xyz_length(),
            1.5 * std::f64::consts::PI * 25.4,
            max_relative = 1e-9
        );
    }
}

/// `Word::code10` as it was written with `f64::round` (its rounding is now
/// done without the library call): the reference it must equal.
fn code10_with_round(value: f64) -> Option<i32> {
    let t = value * 10.0;
    let r = t.round();
    ((t - r).abs() < 1e-6 && r.abs() < 1e9).then_some(r as i32)
}

fn code_word(value: f64) -> volcomp::gcode::Word {
    volcomp::gcode::Word {
        letter: b'G',
        value,
        start: 0,
        end: 0,
        decimals: 0,
        point: false,
        expr: None,
    }
}

#[test]
fn code10_rounds_halves_away_from_zero_as_round_does() {
    let specials = [
        0.0,
        -0.0,
        0.05,
        -0.05,
        0.15,
        0.25,
        -0.25,
        1.0,
        43.4,
        -43.4,
        1.25,
        64.05,
        99_999_999.95,
        -99_999_999.95,
        1e8,
        1e9,
        4_503_599_627_370_495.5,
        f64::MAX,
        f64::MIN_POSITIVE,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for v in specials {
        assert_eq!(code_word(v).code10(), code10_with_round(v), "{v}");
        // Just beside every special value too (one unit in the last place).
        for w in [
            f64::from_bits(v.to_bits().wrapping_add(1)),
            f64::from_bits(v.to_bits().wrapping_sub(1)),
        ] {
            assert_eq!(code_word(w).code10(), code10_with_round(w), "{w}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2048))]

    #[test]
    fn code10_equals_the_rounded_code(
        tenths in -2_000_000_000i64..2_000_000_000,
        offset in prop_oneof![Just(0.0), Just(0.05), Just(-0.05), -0.1f64..0.1],
        any_value in any::<f64>(),
    ) {
        let v = tenths as f64 / 10.0 + offset;
        prop_assert_eq!(code_word(v).code10(), code10_with_round(v));
        prop_assert_eq!(code_word(any_value).code10(), code10_with_round(any_value));
    }
}
