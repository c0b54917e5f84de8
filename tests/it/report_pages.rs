//! The rendered outputs (HTML pages and SVG figures) locked down: each page is
//! snapshot as its visible text, line by line, with every inline figure
//! replaced by a line that counts its elements and digests its drawing
//! (numbers rounded to 0.1 first, so that the digest follows what is drawn).
//! A change to a page's text or to any figure shows up here.
use crate::support::{assert_success, root, volcomp};
use std::collections::BTreeMap;
use std::path::Path;

/// Run volcomp with `args` in the project root; it must succeed.
fn run(args: &[&str]) {
    let out = volcomp().args(args).current_dir(root()).output().unwrap();
    assert_success(&out);
}

/// `text` with every number rounded to one decimal.
fn rounded_numbers(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let starts_number = chars[i].is_ascii_digit()
            || (chars[i] == '-' && chars.get(i + 1).is_some_and(|c| c.is_ascii_digit()));
        if !starts_number {
            out.push(chars[i]);
            i += 1;
            continue;
        }
        let start = i;
        i += 1;
        while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
            i += 1;
        }
        let token: String = chars[start..i].iter().collect();
        match token.parse::<f64>() {
            Ok(v) => {
                let r = format!("{v:.1}");
                out.push_str(if r == "-0.0" { "0.0" } else { &r });
            }
            Err(_) => out.push_str(&token),
        }
    }
    out
}

/// 64-bit FNV-1a of `text`.
fn digest(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// One line for a figure: its elements by name and the digest of its drawing.
fn figure_line(svg: &str) -> String {
    let mut elements: BTreeMap<String, usize> = BTreeMap::new();
    for piece in svg.split('<').skip(1) {
        let name: String = piece
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric())
            .collect();
        if !name.is_empty() {
            *elements.entry(name).or_default() += 1;
        }
    }
    let counts: Vec<String> = elements.iter().map(|(k, n)| format!("{k} {n}")).collect();
    format!(
        "[figure: {}; digest {:016x}]",
        counts.join(", "),
        digest(&rounded_numbers(svg))
    )
}

/// The visible text of `page`, a line per text run, its figures as
/// [`figure_line`]s and its style sheet left out.
fn skeleton(page: &str) -> String {
    let mut lines = Vec::new();
    let mut rest = page;
    while !rest.is_empty() {
        let (before, figure, after) = match rest.find("<svg") {
            Some(start) => {
                let end = rest[start..]
                    .find("</svg>")
                    .map_or(rest.len(), |e| start + e + "</svg>".len());
                (&rest[..start], Some(&rest[start..end]), &rest[end..])
            }
            None => (rest, None, ""),
        };
        text_lines(before, &mut lines);
        if let Some(svg) = figure {
            lines.push(figure_line(svg));
        }
        rest = after;
    }
    lines.join("\n")
}

/// The text runs of `html` (tags and the style sheet removed), appended to `out`.
fn text_lines(html: &str, out: &mut Vec<String>) {
    let mut html = html.to_string();
    while let Some(start) = html.find("<style") {
        let end = html[start..]
            .find("</style>")
            .map_or(html.len(), |e| start + e + "</style>".len());
        html.replace_range(start..end, "");
    }
    let mut text = String::new();
    let mut in_tag = false;
    for c in html.chars() {
        match c {
            '<' => {
                in_tag = true;
                text.push('\n');
            }
            '>' if in_tag => in_tag = false,
            c if !in_tag => text.push(c),
            _ => {}
        }
    }
    out.extend(
        text.lines()
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .map(str::to_string),
    );
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The HTML page of `volcomp ARGS --report R --html H` (a whole page, no NaN).
fn page_of(args: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (report, html) = (dir.path().join("r.json"), dir.path().join("r.html"));
    let mut args = args.to_vec();
    args.extend(["--report", report.to_str().unwrap()]);
    args.extend(["--html", html.to_str().unwrap()]);
    run(&args);
    let page = read(&html);
    assert!(page.starts_with("<!DOCTYPE html>") && !page.contains("NaN"));
    page
}

#[test]
fn the_predict_page_of_the_saddle() {
    let page = page_of(&[
        "predict",
        "machines/ref-trt.toml",
        "samples/saddle.nc",
        "--plan",
        "samples/saddle-plan.csv",
    ]);
    insta::assert_snapshot!(skeleton(&page));
}

#[test]
fn the_diagnose_page_of_a_blind_example() {
    let case = "tests/data/blind/01-backlash";
    let page = page_of(&[
        "diagnose",
        "machines/ref-trt.toml",
        &format!("{case}/program.nc"),
        &format!("{case}/measured.csv"),
        "--plan-frame",
        "part",
    ]);
    assert!(page.contains("Backlash of about"), "{page}");
    insta::assert_snapshot!(skeleton(&page));
}

#[test]
fn the_figures_of_fit_and_map() {
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    run(&[
        "fit",
        "machines/ref-trt.toml",
        "--plot",
        plots.to_str().unwrap(),
    ]);
    let map = dir.path().join("map.svg");
    run(&[
        "map",
        "machines/ref-trt.toml",
        "--out",
        map.to_str().unwrap(),
    ]);
    let mut figures: Vec<String> = Vec::new();
    let mut names: Vec<_> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    for name in ["EXX.svg", "EAC.svg"] {
        assert!(names.iter().any(|n| n == name), "{names:?}");
        figures.push(format!("{name}\n{}", skeleton(&read(&plots.join(name)))));
    }
    figures.push(format!("map.svg\n{}", skeleton(&read(&map))));
    insta::assert_snapshot!(format!(
        "fit --plot wrote {} figures: {}\n\n{}",
        names.len(),
        names.join(" "),
        figures.join("\n\n")
    ));
}

#[test]
fn the_skeleton_rounds_and_digests_figures() {
    assert_eq!(
        rounded_numbers("x=\"12.345\" y=-0.04 z7"),
        "x=\"12.3\" y=0.0 z7.0"
    );
    let a = skeleton("<p>a</p><svg><line x1=\"1.00\"/></svg><p>b</p>");
    let b = skeleton("<p>a</p><svg><line x1=\"1.01\"/></svg><p>b</p>");
    let c = skeleton("<p>a</p><svg><line x1=\"1.50\"/></svg><p>b</p>");
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert!(a.starts_with("a\n[figure: line 1, svg 1; digest "), "{a}");
    assert!(a.ends_with("]\nb"), "{a}");
}
