//! The line parser: bytes of one line → [`Block`] words, keywords and comments
//! (grammar/gcode.ebnf is the exact grammar).
//!
//! Works on `&[u8]` so that any byte sequence is safe (non-UTF-8 bytes are
//! allowed inside comments and are an error elsewhere). nom combinators read the
//! trivia (white space, comments, keywords); numbers are scanned by hand because
//! spaces may appear inside them (`X 1 0.5` is `X10.5`, as in LinuxCNC) and
//! because they are the hot path: a number with at most 15 significant digits is
//! converted as `mantissa / 10^decimals` (one correctly rounded division of two
//! exact doubles, hence bit-identical to `str::parse::<f64>`), anything longer
//! goes through `str::parse::<f64>` on the digits with the spaces removed.
use nom::IResult;
use nom::bytes::complete::{tag, tag_no_case, take_till, take_while};
use nom::combinator::recognize;
use nom::sequence::tuple;

use super::block::{
    AssignTarget, Assignment, Block, Keyword, KeywordWord, OKeyword, OLabel, OWord, Word,
};
use super::expression::{
    ParamRef, SyntaxError, parse_name, parse_param_ref, parse_value, starts_computed_value,
};
use crate::gcode::error::{ErrorKind, GcodeError};

fn is_space(b: u8) -> bool {
    b == b' ' || b == b'\t' || b == b'\r'
}

fn ws(i: &[u8]) -> IResult<&[u8], &[u8]> {
    take_while(is_space)(i)
}

fn paren_comment(i: &[u8]) -> IResult<&[u8], &[u8]> {
    recognize(tuple((tag("("), take_till(|b| b == b')'), tag(")"))))(i)
}

fn keyword(i: &[u8]) -> IResult<&[u8], Keyword> {
    if let Ok((rest, _)) = tag_no_case::<_, _, nom::error::Error<&[u8]>>("TRAFOOF")(i) {
        return Ok((rest, Keyword::TraFoof));
    }
    let (rest, _) = tag_no_case("TRAORI")(i)?;
    Ok((rest, Keyword::TraOri))
}

const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The one-letter addresses as text (a token or an address of a dialect
/// front without allocating or checking UTF-8).
pub(crate) const LETTERS: [&str; 26] = [
    "A", "B", "C", "D", "E", "F", "G", "H", "I", "J", "K", "L", "M", "N", "O", "P", "Q", "R", "S",
    "T", "U", "V", "W", "X", "Y", "Z",
];

/// `digits [. digits]` (no sign, no spaces) converted as the hot path of
/// [`scan_number`] converts it: `mantissa / 10^decimals` when both are exact
/// doubles (bit-identical to `str::parse::<f64>`); `None` for any other
/// text, which the caller parses the slow way. Shared by the SINUMERIK and
/// Heidenhain tokenisers.
pub(crate) fn exact_decimal(text: &[u8]) -> Option<f64> {
    let mut mantissa: u64 = 0;
    let mut ndigits = 0usize;
    let mut decimals = 0usize;
    let mut point = false;
    for &b in text {
        if b.is_ascii_digit() {
            mantissa = mantissa.wrapping_mul(10).wrapping_add((b - b'0') as u64);
            ndigits += 1;
            if point {
                decimals += 1;
            }
        } else if b == b'.' && !point {
            point = true;
        } else {
            return None;
        }
    }
    exact_from_parts(mantissa, ndigits, decimals)
}

/// [`exact_decimal`] of a number already scanned: its digits as one
/// (wrapping) `mantissa`, how many there are and how many follow the point.
#[inline]
pub(crate) fn exact_from_parts(mantissa: u64, ndigits: usize, decimals: usize) -> Option<f64> {
    (ndigits > 0 && ndigits <= 19 && mantissa < (1u64 << 53) && decimals < POW10.len())
        .then(|| mantissa as f64 / POW10[decimals])
}

/// A scanned number: value, decimals, point, and the end of its last digit or point.
struct Number {
    value: f64,
    decimals: u8,
    point: bool,
    end: usize,
}

enum NumberError {
    Missing,
    Malformed(usize),
    OutOfRange,
}

/// Scan `[sign] digits [. digits]` with spaces allowed anywhere, from `p`.
fn scan_number(line: &[u8], mut p: usize) -> Result<Number, NumberError> {
    let len = line.len();
    while p < len && is_space(line[p]) {
        p += 1;
    }
    let mut negative = false;
    if p < len && (line[p] == b'+' || line[p] == b'-') {
        negative = line[p] == b'-';
        p += 1;
    }
    let digits_from = p;
    let mut mantissa: u64 = 0;
    let mut ndigits = 0usize;
    let mut decimals = 0usize;
    let mut point = false;
    let mut end = p;
    loop {
        // A run of digits (the hot loop), then a point, a space or the end.
        let run_start = p;
        while p < len && line[p].is_ascii_digit() {
            // 19 digits always fit in a u64; with more the (wrapped) mantissa
            // is not used: longer numbers take the slow path.
            mantissa = mantissa
                .wrapping_mul(10)
                .wrapping_add((line[p] - b'0') as u64);
            ndigits += 1;
            p += 1;
        }
        if p > run_start {
            end = p;
            if point {
                decimals += p - run_start;
            }
        }
        if p >= len {
            break;
        }
        let b = line[p];
        if b == b'.' {
            if point {
                return Err(NumberError::Malformed(p));
            }
            point = true;
            end = p + 1;
        } else if !is_space(b) {
            break;
        }
        p += 1;
    }
    let exact = ndigits <= 19;
    if ndigits == 0 {
        return Err(if point {
            NumberError::Malformed(end.saturating_sub(1))
        } else {
            NumberError::Missing
        });
    }
    let value = if exact && mantissa < (1u64 << 53) && decimals < POW10.len() {
        mantissa as f64 / POW10[decimals]
    } else {
        let text: String = line[digits_from..end]
            .iter()
            .filter(|b| !is_space(**b))
            .map(|&b| b as char)
            .collect();
        let text = if text.starts_with('.') {
            format!("0{text}")
        } else {
            text
        };
        text.parse::<f64>()
            .map_err(|_| NumberError::Malformed(digits_from))?
    };
    if !value.is_finite() {
        return Err(NumberError::OutOfRange);
    }
    Ok(Number {
        value: if negative { -value } else { value },
        decimals: decimals.min(u8::MAX as usize) as u8,
        point,
        end,
    })
}

/// Parse `block.raw` into `block`'s words, keywords, assignments, O-word and
/// comments (they must be empty). On error the block is left partly filled;
/// the caller decides.
pub fn parse_line(block: &mut Block) -> Result<(), GcodeError> {
    let Block {
        raw,
        line: line_no,
        offset,
        words,
        keywords,
        comments,
        percent,
        deleted,
        assignments,
        o_word,
        exprs,
        ..
    } = block;
    let line: &[u8] = raw;
    let line_no = *line_no;
    let len = line.len();
    let err = |kind: ErrorKind, start: usize, end: usize| -> GcodeError {
        GcodeError::at(kind, line_no, line, start, end)
    };
    let syntax = |e: SyntaxError| -> GcodeError {
        GcodeError::at(ErrorKind::Syntax(e.kind), line_no, line, e.at, e.at + 1)
    };
    let pos_of = |rest: &[u8]| len - rest.len();
    // A carriage return with more of the line after it: classic Mac (CR-only)
    // line ends, which LinuxCNC would read as one long block. Refused rather
    // than run the whole program as one line.
    if let Some(k) = line
        .windows(2)
        .position(|w| w[0] == b'\r' && !matches!(w[1], b'\r' | b' ' | b'\t'))
    {
        return Err(err(ErrorKind::BareCarriageReturn, k, k + 1));
    }

    // A UTF-8 byte order mark at the start of the file: LinuxCNC refuses it
    // ("Bad character '\357' used").
    if *offset == 0 && line.starts_with(b"\xEF\xBB\xBF") {
        return Err(err(ErrorKind::ByteOrderMark, 0, 3));
    }
    let mut pos = ws(line).map(|(r, _)| pos_of(r)).unwrap_or(0);
    if pos < len && line[pos] == b'%' {
        *percent = true;
        return Ok(());
    }
    if pos < len && line[pos] == b'/' {
        *deleted = true;
        pos += 1;
    }
    loop {
        while pos < len && is_space(line[pos]) {
            pos += 1;
        }
        if pos >= len {
            break;
        }
        let c = line[pos];
        if o_word.is_some() && c != b'(' && c != b';' {
            return Err(err(ErrorKind::UnexpectedAfterOWord, pos, pos + 1));
        }
        match c {
            b'(' => match paren_comment(&line[pos..]) {
                Ok((rest, _)) => {
                    let end = pos_of(rest);
                    comments.push(pos..end);
                    pos = end;
                }
                Err(_) => return Err(err(ErrorKind::UnclosedComment, pos, pos + 1)),
            },
            b';' => {
                comments.push(pos..len);
                break;
            }
            b'#' => {
                // A parameter assignment: #n=value, #<name>=value.
                let (target, after) = parse_param_ref(line, pos).map_err(syntax)?;
                let eq = skip_space(line, after);
                if line.get(eq) != Some(&b'=') {
                    return Err(err(ErrorKind::MissingEquals, pos, after.max(pos + 1)));
                }
                let value = parse_value(line, eq + 1).map_err(syntax)?;
                let end = value.end;
                let target = match target {
                    ParamRef::Named(name) => AssignTarget::Named(name),
                    ParamRef::Numbered(index) => {
                        exprs.push(*index);
                        AssignTarget::Numbered(exprs.len() as u32 - 1)
                    }
                };
                exprs.push(value);
                assignments.push(Assignment {
                    target,
                    value: exprs.len() as u32 - 1,
                    start: pos,
                    end,
                });
                pos = end;
            }
            // `@` and `^`: LinuxCNC's polar radius and angle words.
            _ if c.is_ascii_alphabetic() || c == b'@' || c == b'^' => {
                let letter = c.to_ascii_uppercase();
                if letter == b'O' && words.is_empty() && assignments.is_empty() {
                    if let Some(o) =
                        parse_o_word(line, pos, exprs, comments).map_err(|e| match e {
                            OError::Syntax(e) => syntax(e),
                            OError::Kind(kind, at) => err(kind, at, at + 1),
                        })?
                    {
                        pos = o.end_of_args;
                        *o_word = Some(o.word);
                        continue;
                    }
                }
                if pos + 1 < len && line[pos + 1].is_ascii_alphabetic() {
                    if let Ok((rest, kw)) = keyword(&line[pos..]) {
                        let end = pos_of(rest);
                        if rest.first().is_none_or(|b| !b.is_ascii_alphanumeric()) {
                            keywords.push(KeywordWord {
                                keyword: kw,
                                start: pos,
                                end,
                            });
                            pos = end;
                            continue;
                        }
                    }
                    if !starts_computed_value(line, pos + 1) {
                        return Err(err(ErrorKind::MissingNumber(letter as char), pos, pos + 1));
                    }
                }
                if starts_computed_value(line, pos + 1) {
                    let value = parse_value(line, pos + 1).map_err(syntax)?;
                    let end = value.end;
                    exprs.push(value);
                    words.push(Word {
                        letter,
                        value: 0.0,
                        start: pos,
                        end,
                        decimals: 0,
                        point: false,
                        expr: Some(exprs.len() as u32 - 1),
                    });
                    pos = end;
                    continue;
                }
                let number = match scan_number(line, pos + 1) {
                    Ok(n) => n,
                    Err(NumberError::Missing) => {
                        return Err(err(ErrorKind::MissingNumber(letter as char), pos, pos + 1));
                    }
                    Err(NumberError::Malformed(at)) => {
                        return Err(err(ErrorKind::MalformedNumber(letter as char), at, at + 1));
                    }
                    Err(NumberError::OutOfRange) => {
                        return Err(err(
                            ErrorKind::NumberOutOfRange(letter as char),
                            pos,
                            pos + 1,
                        ));
                    }
                };
                words.push(Word {
                    letter,
                    value: number.value,
                    start: pos,
                    end: number.end,
                    decimals: number.decimals,
                    point: number.point,
                    expr: None,
                });
                pos = number.end;
            }
            _ => {
                // Show the whole (possibly multi-byte) character.
                let end = (pos + 1..=len)
                    .find(|&e| std::str::from_utf8(&line[pos..e]).is_ok())
                    .filter(|&e| e - pos <= 4)
                    .unwrap_or(pos + 1);
                // Control characters and bytes that are not UTF-8 by value.
                let shown = match std::str::from_utf8(&line[pos..end]) {
                    Ok(s) if !s.chars().any(char::is_control) => s.to_string(),
                    Ok(s) => s.chars().map(|c| format!("U+{:04X}", c as u32)).collect(),
                    Err(_) => format!("byte 0x{:02x}", line[pos]),
                };
                return Err(err(ErrorKind::UnexpectedCharacter(shown), pos, end));
            }
        }
    }
    Ok(())
}

fn skip_space(line: &[u8], mut p: usize) -> usize {
    while p < line.len() && is_space(line[p]) {
        p += 1;
    }
    p
}

struct ParsedOWord {
    word: OWord,
    end_of_args: usize,
}

enum OError {
    Syntax(SyntaxError),
    Kind(ErrorKind, usize),
}

/// An O-word control line starting at `pos` (which holds `O`): `None` when the
/// O word is a plain program number (`O1234`, no keyword follows).
fn parse_o_word(
    line: &[u8],
    pos: usize,
    exprs: &mut Vec<crate::gcode::syntax::expression::Expr>,
    comments: &mut Vec<std::ops::Range<usize>>,
) -> Result<Option<ParsedOWord>, OError> {
    let q = skip_space(line, pos + 1);
    let (label, after_label) = if line.get(q) == Some(&b'<') {
        let (name, end) = parse_name(line, q).map_err(OError::Syntax)?;
        (OLabel::Name(name), end)
    } else {
        if !starts_computed_value(line, q) && !line.get(q).is_some_and(|c| c.is_ascii_digit()) {
            return Ok(None);
        }
        let value = parse_value(line, q).map_err(OError::Syntax)?;
        let end = value.end;
        exprs.push(value);
        (OLabel::Number(exprs.len() as u32 - 1), end)
    };
    let k = skip_space(line, after_label);
    // LinuxCNC reads a line with its spaces removed and takes the first
    // keyword the text starts with (`o1 end if` is `o1 endif`).
    let matched = OKeyword::ALL.iter().find_map(|(name, keyword)| {
        let mut p = k;
        for c in name.bytes() {
            p = skip_space(line, p);
            if !line.get(p).is_some_and(|b| b.eq_ignore_ascii_case(&c)) {
                return None;
            }
            p += 1;
        }
        Some((*keyword, p))
    });
    let Some((keyword, word_end)) = matched else {
        let alphabetic = line.get(k).is_some_and(|b| b.is_ascii_alphabetic());
        if matches!(label, OLabel::Name(_)) || alphabetic {
            // `O<name>` must be followed by a keyword; `O100 foo` is not a word.
            return Err(OError::Kind(ErrorKind::UnknownOWordKeyword, k));
        }
        // A program number such as `O1234` (followed by words or nothing).
        exprs.pop();
        return Ok(None);
    };
    let mut args = Vec::new();
    let mut p = word_end;
    let takes = match keyword {
        OKeyword::Call => usize::MAX,
        OKeyword::While | OKeyword::If | OKeyword::ElseIf | OKeyword::Repeat => 1,
        OKeyword::Return | OKeyword::EndSub => 1,
        _ => 0,
    };
    let required = matches!(
        keyword,
        OKeyword::While | OKeyword::If | OKeyword::ElseIf | OKeyword::Repeat
    );
    loop {
        p = skip_space(line, p);
        match line.get(p) {
            Some(b'[') if args.len() < takes => {
                let e = parse_value(line, p).map_err(OError::Syntax)?;
                p = e.end;
                exprs.push(e);
                args.push(exprs.len() as u32 - 1);
            }
            // Comments between call arguments.
            Some(b'(') if keyword == OKeyword::Call => {
                match line[p..].iter().position(|&b| b == b')') {
                    Some(i) => {
                        comments.push(p..p + i + 1);
                        p += i + 1
                    }
                    None => return Err(OError::Kind(ErrorKind::UnclosedComment, p)),
                }
            }
            _ => break,
        }
    }
    if required && args.is_empty() {
        return Err(OError::Kind(
            ErrorKind::BracketAfterOKeyword(keyword.name()),
            p,
        ));
    }
    let end_of_args = p;
    Ok(Some(ParsedOWord {
        word: OWord {
            label,
            keyword,
            args,
            start: pos,
            end: word_end,
        },
        end_of_args,
    }))
}

/// Parse one line of text (no line ending) into a fresh block; line number 1.
pub fn parse_block(text: &str) -> Result<Block, GcodeError> {
    let mut block = Block::default();
    block.reset(1, 0);
    block.raw.extend_from_slice(text.as_bytes());
    block.ending = super::block::LineEnding::None;
    parse_line(&mut block)?;
    Ok(block)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(text: &str) -> Vec<(char, f64, u8)> {
        parse_block(text)
            .unwrap()
            .words
            .iter()
            .map(|w| (w.letter as char, w.value, w.decimals))
            .collect()
    }

    #[test]
    fn exact_decimal_is_str_parse_or_none() {
        for text in [
            "0",
            "12.",
            ".5",
            "30070.6535",
            "9007199254740991",
            "0.1",
            "123.4567890123",
        ] {
            let v = super::exact_decimal(text.as_bytes());
            let t = text.strip_suffix('.').unwrap_or(text);
            assert_eq!(v, Some(t.parse::<f64>().unwrap()), "{text}");
        }
        // Longer mantissas, signs, commas, exponents, two points: the slow path.
        for text in [
            "",
            ".",
            "9007199254740993",
            "-1",
            "1,5",
            "1e3",
            "1.2.3",
            "12345678901234567890",
        ] {
            assert_eq!(super::exact_decimal(text.as_bytes()), None, "{text}");
        }
    }

    #[test]
    fn numbers_in_every_spelling() {
        assert_eq!(
            words("x.5 X5. X+1 x-0.5 F30070.6535"),
            vec![
                ('X', 0.5, 1),
                ('X', 5.0, 0),
                ('X', 1.0, 0),
                ('X', -0.5, 1),
                ('F', 30070.6535, 4)
            ]
        );
        assert_eq!(
            words("X  16.339 F 159"),
            vec![('X', 16.339, 3), ('F', 159.0, 0)]
        );
        assert_eq!(words("X 1 0.5"), vec![('X', 10.5, 1)]);
        assert_eq!(words("g43.4H1"), vec![('G', 43.4, 1), ('H', 1.0, 0)]);
    }

    #[test]
    fn fast_path_matches_str_parse() {
        for text in [
            "0.1",
            "123456789.012345",
            "30070.6535",
            "1.000000000000000000001",
        ] {
            let b = parse_block(&format!("X{text}")).unwrap();
            assert_eq!(b.words[0].value, text.parse::<f64>().unwrap(), "{text}");
        }
    }

    #[test]
    fn keywords_comments_and_errors() {
        let b = parse_block("N5 TRAORI (tcp on) ; rest").unwrap();
        assert_eq!(b.keywords[0].keyword, Keyword::TraOri);
        assert_eq!(b.comments.len(), 2);
        assert!(matches!(
            parse_block("G1 (open").unwrap_err().kind,
            ErrorKind::UnclosedComment
        ));
        assert!(matches!(
            parse_block("G1 X Y1").unwrap_err().kind,
            ErrorKind::MissingNumber('X')
        ));
        let b = parse_block("O100 sub").unwrap();
        assert_eq!(b.o_word.as_ref().unwrap().keyword, OKeyword::Sub);
        let b = parse_block("o<Drill Hole> call [1] (depth) [#2*2] ; go").unwrap();
        let o = b.o_word.as_ref().unwrap();
        assert_eq!(o.label, OLabel::Name("drillhole".into()));
        assert_eq!(
            (o.keyword, o.args.len(), b.comments.len()),
            (OKeyword::Call, 2, 2)
        );
        assert!(matches!(
            parse_block("O100 while").unwrap_err().kind,
            ErrorKind::BracketAfterOKeyword("while")
        ));
        assert!(matches!(
            parse_block("O100 endif G1").unwrap_err().kind,
            ErrorKind::UnexpectedAfterOWord
        ));
        // LinuxCNC reads the line without its spaces.
        let b = parse_block("o1 end if").unwrap();
        assert_eq!(b.o_word.as_ref().unwrap().keyword, OKeyword::EndIf);
        let b = parse_block("O2 E L S E I F [1]").unwrap();
        assert_eq!(b.o_word.as_ref().unwrap().keyword, OKeyword::ElseIf);
        let b = parse_block("G1 X#1 Y[#<r> * 2] #3 = sin[30] #<_g>=-#1").unwrap();
        assert_eq!(b.words[1].expr, Some(0));
        assert_eq!(b.assignments.len(), 2);
        assert!(b.uses_language());
        assert!(matches!(
            parse_block("#1 5").unwrap_err().kind,
            ErrorKind::MissingEquals
        ));
    }
}
