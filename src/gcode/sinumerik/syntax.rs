//! SINUMERIK 840D sl syntax: one line → tokens → a [`Line`] of statements,
//! with byte ranges, no meaning (Siemens, SINUMERIK 840D sl Programming
//! Manual *Fundamentals*, "Structure and contents of an NC program": blocks,
//! block numbers, `;` comments, `/` skip, addresses with values and with
//! `=` expressions; *Job planning*, "Flexible NC programming": variables,
//! arithmetic, program flow).
//!
//! Decisions (the manuals leave the lexer open):
//! - upper and lower case are the same (everything outside strings and
//!   comments is compared upper-cased);
//! - a single address letter followed by a number is a word, so words need
//!   no spaces (`G0X10Y5`); a run of two or more letters is a name that
//!   takes the letters and digits after it (`CYCLE800`, `LABEL1`); a letter
//!   and digits followed by `=` are an extended address or an `R` parameter
//!   (`A3=`, `I1=`, `R12=`);
//! - numbers may start with the point (`.02`) or end with it (`5.`).
use std::ops::Range;

use crate::gcode::syntax::parser::LETTERS;

/// A token of a line.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    /// A number: value, decimals written, whether a point was written.
    Num(f64, u8, bool),
    /// A name or address, upper-cased (a single letter without allocating).
    Name(Name),
    /// A string literal (`"…"` or `'…'`), without its quotes.
    Str(String),
    /// An operator or punctuation: `= == <> < > <= >= + - * / ( ) [ ] , : <<`.
    Sym(&'static str),
}

/// A name as a token holds it.
pub(crate) type Name = std::borrow::Cow<'static, str>;

/// A token and its byte range in the line.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Token {
    pub tok: Tok,
    pub start: usize,
    pub end: usize,
}

/// Why a line cannot be read (the message, the byte range).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SyntaxError {
    pub message: String,
    pub start: usize,
    pub end: usize,
}

fn err<T>(message: impl Into<String>, start: usize, end: usize) -> Result<T, SyntaxError> {
    Err(SyntaxError {
        message: message.into(),
        start,
        end,
    })
}

/// The tokens of `raw` (up to its `;` comment) and the comment's range.
pub(crate) fn tokenize(
    raw: &[u8],
    tokens: &mut Vec<Token>,
) -> Result<Option<Range<usize>>, SyntaxError> {
    tokens.clear();
    let n = raw.len();
    let mut i = 0;
    while i < n {
        let c = raw[i];
        if c == b' ' || c == b'\t' || c == b'\r' || c == 0x0c {
            i += 1;
            continue;
        }
        if c == b';' {
            return Ok(Some(i..n));
        }
        let start = i;
        if c.is_ascii_alphabetic() || c == b'_' || c == b'$' {
            let mut j = i;
            while j < n && (raw[j].is_ascii_alphabetic() || raw[j] == b'_' || raw[j] == b'$') {
                j += 1;
            }
            let letters = j - i;
            if letters == 1 && c != b'_' && c != b'$' {
                // An address letter: `X10`, `G0`, or `A3=` / `R12=` (extended).
                let mut k = j;
                while k < n && raw[k].is_ascii_digit() {
                    k += 1;
                }
                let mut m = k;
                while m < n && raw[m] == b' ' {
                    m += 1;
                }
                let extended = k > j && m < n && raw[m] == b'=' && raw.get(m + 1) != Some(&b'=');
                let end = if extended { k } else { j };
                let upper = c.to_ascii_uppercase();
                let tok = if end == j {
                    Tok::Name(Name::Borrowed(LETTERS[(upper - b'A') as usize]))
                } else {
                    Tok::Name(Name::Owned(
                        (upper as char).to_string()
                            + std::str::from_utf8(&raw[j..end]).unwrap_or(""),
                    ))
                };
                tokens.push(Token { tok, start, end });
                i = end;
                continue;
            }
            while j < n && (raw[j].is_ascii_alphanumeric() || raw[j] == b'_' || raw[j] == b'$') {
                j += 1;
            }
            let name = String::from_utf8_lossy(&raw[i..j]).to_ascii_uppercase();
            tokens.push(Token {
                tok: Tok::Name(Name::Owned(name)),
                start,
                end: j,
            });
            i = j;
            continue;
        }
        if c.is_ascii_digit() || (c == b'.' && raw.get(i + 1).is_some_and(u8::is_ascii_digit)) {
            let Digits {
                end: j,
                point,
                decimals,
                ..
            } = scan_digits(raw, i);
            let decimals = u8::try_from(decimals).unwrap_or(u8::MAX);
            // Siemens' exponent `EX` (`1.5EX3`).
            if j + 2 < n + 1
                && raw.get(j).is_some_and(|b| b.eq_ignore_ascii_case(&b'E'))
                && raw
                    .get(j + 1)
                    .is_some_and(|b| b.eq_ignore_ascii_case(&b'X'))
            {
                let mut k = j + 2;
                if raw.get(k).is_some_and(|b| *b == b'-' || *b == b'+') {
                    k += 1;
                }
                let digits = k;
                while k < n && raw[k].is_ascii_digit() {
                    k += 1;
                }
                if k > digits {
                    let mantissa: f64 = parse_number(&raw[i..j]);
                    let exp: i32 = std::str::from_utf8(&raw[j + 2..k])
                        .ok()
                        .and_then(|s| s.parse().ok())
                        .unwrap_or(0);
                    let v = mantissa * 10f64.powi(exp);
                    if !v.is_finite() {
                        return err("number out of range", i, k);
                    }
                    tokens.push(Token {
                        tok: Tok::Num(v, decimals, point),
                        start,
                        end: k,
                    });
                    i = k;
                    continue;
                }
            }
            let v = parse_number(&raw[i..j]);
            if !v.is_finite() {
                return err("number out of range", i, j);
            }
            tokens.push(Token {
                tok: Tok::Num(v, decimals, point),
                start,
                end: j,
            });
            i = j;
            continue;
        }
        if c == b'"' || c == b'\'' {
            let Some(k) = raw[i + 1..].iter().position(|&b| b == c) else {
                return err("string not closed on this line", i, n);
            };
            tokens.push(Token {
                tok: Tok::Str(String::from_utf8_lossy(&raw[i + 1..i + 1 + k]).into_owned()),
                start,
                end: i + 2 + k,
            });
            i += k + 2;
            continue;
        }
        let two = raw.get(i..i + 2);
        let sym: Option<&'static str> = match two {
            Some(b"==") => Some("=="),
            Some(b"<>") => Some("<>"),
            Some(b"<=") => Some("<="),
            Some(b">=") => Some(">="),
            Some(b"<<") => Some("<<"),
            _ => None,
        };
        if let Some(s) = sym {
            tokens.push(Token {
                tok: Tok::Sym(s),
                start,
                end: i + 2,
            });
            i += 2;
            continue;
        }
        let one: &'static str = match c {
            b'=' => "=",
            b'<' => "<",
            b'>' => ">",
            b'+' => "+",
            b'-' => "-",
            b'*' => "*",
            b'/' => "/",
            b'(' => "(",
            b')' => ")",
            b'[' => "[",
            b']' => "]",
            b',' => ",",
            b':' => ":",
            b'%' => "%",
            _ => {
                return err(
                    format!(
                        "unexpected character `{}`",
                        String::from_utf8_lossy(&raw[i..(i + 1).min(n)])
                    ),
                    i,
                    i + 1,
                );
            }
        };
        tokens.push(Token {
            tok: Tok::Sym(one),
            start,
            end: i + 1,
        });
        i += 1;
    }
    Ok(None)
}

/// An address word of a plain line (see [`plain_words`]): its letter
/// (upper case), value (sign included), decimals written, whether a point
/// was written, and its byte range (letter to last digit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PlainWord {
    pub letter: u8,
    pub value: f64,
    pub decimals: u8,
    pub point: bool,
    pub start: usize,
    pub end: usize,
}

/// The letters a plain line is made of: the block number, G codes, axes,
/// centres and the feed (the words of almost every line a CAM system
/// writes).
const PLAIN_LETTERS: &[u8] = b"NGXYZABCUVWIJKF";

/// The words of a *plain* line: nothing but address words of
/// [`PLAIN_LETTERS`], each written `LETTER[+|-]number` without spaces
/// inside (`N10 G1 Y.5 F800`, `G0X10`), before an optional `;`
/// comment (whose range is returned). `None` for any other line: the
/// tokeniser and the statement layer read it. A plain line's tokens would
/// be, word by word, the name, the sign and the number this gives, so
/// reading it here (without tokens) hands on the same words.
pub(crate) fn plain_words(raw: &[u8], words: &mut Vec<PlainWord>) -> Option<Option<Range<usize>>> {
    words.clear();
    let n = raw.len();
    let mut i = 0;
    let mut comment = None;
    while i < n {
        let c = raw[i];
        if c == b' ' || c == b'\t' || c == b'\r' || c == 0x0c {
            i += 1;
            continue;
        }
        if c == b';' {
            comment = Some(i..n);
            break;
        }
        let letter = c.to_ascii_uppercase();
        if !PLAIN_LETTERS.contains(&letter) {
            return None;
        }
        let start = i;
        i += 1;
        let negative = match raw.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        // `digits [. digits]` scanned and converted in one pass.
        let digits = i;
        let Digits {
            end,
            point,
            decimals,
            mantissa,
            ndigits,
        } = scan_digits(raw, i);
        i = end;
        // A number has a digit (what follows it is read as the next word:
        // a name, an exponent `EX`, `=` or `[` are not plain).
        if ndigits == 0 {
            return None;
        }
        let v = if decimals == 0 && ndigits <= 15 {
            // A whole number (`N10`, `G1`, `F800`): exact, no division by 1.
            mantissa as f64
        } else {
            match crate::gcode::syntax::parser::exact_from_parts(mantissa, ndigits, decimals) {
                Some(v) => v,
                None => parse_number(&raw[digits..i]),
            }
        };
        if !v.is_finite() {
            return None;
        }
        words.push(PlainWord {
            letter,
            value: if negative { -v } else { v },
            decimals: u8::try_from(decimals).unwrap_or(u8::MAX),
            point,
            start,
            end: i,
        });
    }
    Some(comment)
}

/// The digits of a number: `digits [. digits]` (either part may be empty).
struct Digits {
    /// Where the digits end.
    end: usize,
    /// A point was written.
    point: bool,
    /// The decimals written.
    decimals: usize,
    /// The digits as one integer (wrapping past 19 digits: used only up to
    /// 15, see `exact_from_parts`).
    mantissa: u64,
    /// How many digits, both parts.
    ndigits: usize,
}

/// The digits of a number from `i`, scanned and converted in one pass (a
/// caller that needs only the end pays nothing more once inlined).
#[inline]
fn scan_digits(raw: &[u8], i: usize) -> Digits {
    let rest = raw.get(i..).unwrap_or_default();
    let mut mantissa = 0u64;
    // Each digit: its value below 10 (no separate test, count or bounds
    // check beyond the slice's own).
    let digits = |mut k: usize, mantissa: &mut u64| {
        while let Some(&c) = rest.get(k) {
            let d = c.wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            *mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(d));
            k += 1;
        }
        k
    };
    let whole = digits(0, &mut mantissa);
    let (point, end) = if rest.get(whole) == Some(&b'.') {
        (true, digits(whole + 1, &mut mantissa))
    } else {
        (false, whole)
    };
    let decimals = if point { end - whole - 1 } else { 0 };
    Digits {
        end: i + end,
        point,
        decimals,
        mantissa,
        ndigits: whole + decimals,
    }
}

/// The digits of a number (ASCII, `.` allowed at either end).
#[inline]
fn parse_number(digits: &[u8]) -> f64 {
    if let Some(v) = crate::gcode::syntax::parser::exact_decimal(digits) {
        return v;
    }
    let text = std::str::from_utf8(digits).unwrap_or("");
    let text = text.strip_suffix('.').unwrap_or(text);
    if text.is_empty() {
        return 0.0;
    }
    text.parse::<f64>().unwrap_or(f64::NAN)
}

/// A binary operator of the NC language (*Job planning*, "Arithmetic
/// operations", "Comparison and logic operations").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    IntDiv,
    Mod,
    Eq,
    Ne,
    Lt,
    Gt,
    Le,
    Ge,
    And,
    Or,
    Xor,
    Concat,
}

/// An expression, with the byte range it came from.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Expr {
    /// A number.
    Num(f64),
    /// A string (messages only).
    Str(String),
    /// `R12`, `R[expr]`.
    R(Box<Expr>),
    /// A user variable (`NAME`, `NAME[i, j]`), upper-cased.
    Var(String, Vec<Expr>, Range<usize>),
    /// A system variable (`$P_…`, `$AA_…`), upper-cased, with its indices.
    System(String, Range<usize>),
    /// `-x`, `NOT x`.
    Neg(Box<Expr>),
    /// `NOT x`.
    Not(Box<Expr>),
    /// `a op b`.
    Bin(BinOp, Box<Expr>, Box<Expr>),
    /// A function call `NAME(args)`.
    Call(String, Vec<Expr>, Range<usize>),
}

/// A cursor over a line's tokens.
pub(crate) struct Cursor<'a> {
    pub tokens: &'a [Token],
    pub pos: usize,
    pub line_len: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(tokens: &'a [Token], line_len: usize) -> Self {
        Cursor {
            tokens,
            pos: 0,
            line_len,
        }
    }

    pub fn peek(&self) -> Option<&'a Token> {
        self.tokens.get(self.pos)
    }

    pub fn peek_at(&self, k: usize) -> Option<&'a Token> {
        self.tokens.get(self.pos + k)
    }

    pub fn next(&mut self) -> Option<&'a Token> {
        let t = self.tokens.get(self.pos);
        if t.is_some() {
            self.pos += 1;
        }
        t
    }

    /// The next token when it is a name: the name and its byte span
    /// (consumed either way, as [`Cursor::next`]).
    pub fn next_name(&mut self) -> Option<(&'a str, usize, usize)> {
        match self.next() {
            Some(Token {
                tok: Tok::Name(name),
                start,
                end,
            }) => Some((&name[..], *start, *end)),
            _ => None,
        }
    }

    /// The byte offset of the next token (the line's end at the end).
    pub fn here(&self) -> usize {
        self.peek().map_or(self.line_len, |t| t.start)
    }

    /// Whether the next token is the symbol `s` (not consumed).
    pub fn at_sym(&self, s: &str) -> bool {
        matches!(self.peek(), Some(Token { tok: Tok::Sym(x), .. }) if *x == s)
    }

    /// Whether the next token is the symbol `s`; consumed if so.
    pub fn eat_sym(&mut self, s: &str) -> bool {
        if self.at_sym(s) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    /// Whether the next token is the name `s`; consumed if so.
    pub fn eat_name(&mut self, s: &str) -> bool {
        if matches!(self.peek(), Some(Token { tok: Tok::Name(x), .. }) if x == s) {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    pub fn expect_sym(&mut self, s: &str) -> Result<(), SyntaxError> {
        if self.eat_sym(s) {
            Ok(())
        } else {
            let at = self.here();
            err(format!("`{s}` expected"), at, at + 1)
        }
    }

    /// The byte offset just after the last consumed token.
    pub fn last_end(&self) -> usize {
        self.pos
            .checked_sub(1)
            .and_then(|k| self.tokens.get(k))
            .map_or(0, |t| t.end)
    }

    /// An expression (precedence climbing: OR < XOR < AND < comparison <
    /// `<<` < + - < * / DIV MOD < unary).
    pub fn expr(&mut self) -> Result<Expr, SyntaxError> {
        self.binary(0)
    }

    fn binary(&mut self, min: u8) -> Result<Expr, SyntaxError> {
        let mut left = self.unary()?;
        while let Some((op, prec)) = self.peek().and_then(|t| binop(&t.tok)) {
            if prec < min {
                break;
            }
            self.pos += 1;
            let right = self.binary(prec + 1)?;
            left = Expr::Bin(op, Box::new(left), Box::new(right));
        }
        Ok(left)
    }

    fn unary(&mut self) -> Result<Expr, SyntaxError> {
        if self.eat_sym("-") {
            return Ok(Expr::Neg(Box::new(self.unary()?)));
        }
        if self.eat_sym("+") {
            return self.unary();
        }
        if self.eat_name("NOT") {
            return Ok(Expr::Not(Box::new(self.unary()?)));
        }
        self.primary()
    }

    fn primary(&mut self) -> Result<Expr, SyntaxError> {
        let at = self.here();
        let Some(t) = self.next() else {
            return err("an expression is missing", at, at + 1);
        };
        match &t.tok {
            Tok::Num(v, ..) => Ok(Expr::Num(*v)),
            Tok::Str(s) => Ok(Expr::Str(s.clone())),
            Tok::Sym("(") => {
                let e = self.expr()?;
                self.expect_sym(")")?;
                Ok(e)
            }
            Tok::Name(name) => {
                let name = name.clone().into_owned();
                if name == "TRUE" {
                    return Ok(Expr::Num(1.0));
                }
                if name == "FALSE" {
                    return Ok(Expr::Num(0.0));
                }
                if let Some(rest) = name.strip_prefix('R')
                    && !rest.is_empty()
                    && rest.bytes().all(|b| b.is_ascii_digit())
                {
                    let n: f64 = rest.parse().unwrap_or(f64::NAN);
                    return Ok(Expr::R(Box::new(Expr::Num(n))));
                }
                if name == "R" {
                    // `R12` arrives as `R` and a number; `R[expr]`.
                    if let Some(Token {
                        tok: Tok::Num(v, ..),
                        start,
                        ..
                    }) = self.peek()
                        && *start == t.end
                    {
                        let v = *v;
                        self.pos += 1;
                        return Ok(Expr::R(Box::new(Expr::Num(v))));
                    }
                    if self.eat_sym("[") {
                        let e = self.expr()?;
                        self.expect_sym("]")?;
                        return Ok(Expr::R(Box::new(e)));
                    }
                }
                if name.starts_with('$') {
                    let mut end = t.end;
                    if self.eat_sym("[") {
                        let mut depth = 1;
                        while let Some(u) = self.next() {
                            end = u.end;
                            match u.tok {
                                Tok::Sym("[") => depth += 1,
                                Tok::Sym("]") => {
                                    depth -= 1;
                                    if depth == 0 {
                                        break;
                                    }
                                }
                                _ => {}
                            }
                        }
                    }
                    return Ok(Expr::System(name, t.start..end));
                }
                if self.eat_sym("(") {
                    let mut args = Vec::new();
                    if !self.eat_sym(")") {
                        loop {
                            args.push(self.expr()?);
                            if self.eat_sym(")") {
                                break;
                            }
                            self.expect_sym(",")?;
                        }
                    }
                    return Ok(Expr::Call(name, args, t.start..self.last_end()));
                }
                let mut index = Vec::new();
                if self.eat_sym("[") {
                    loop {
                        index.push(self.expr()?);
                        if self.eat_sym("]") {
                            break;
                        }
                        self.expect_sym(",")?;
                    }
                }
                Ok(Expr::Var(name, index, t.start..self.last_end()))
            }
            _ => err("an expression is expected here", t.start, t.end),
        }
    }
}

fn binop(t: &Tok) -> Option<(BinOp, u8)> {
    Some(match t {
        Tok::Name(n) => match n.as_ref() {
            "OR" => (BinOp::Or, 1),
            "XOR" => (BinOp::Xor, 2),
            "AND" => (BinOp::And, 3),
            "DIV" => (BinOp::IntDiv, 7),
            "MOD" => (BinOp::Mod, 7),
            _ => return None,
        },
        Tok::Sym(s) => match *s {
            "==" => (BinOp::Eq, 4),
            "<>" => (BinOp::Ne, 4),
            "<" => (BinOp::Lt, 4),
            ">" => (BinOp::Gt, 4),
            "<=" => (BinOp::Le, 4),
            ">=" => (BinOp::Ge, 4),
            "<<" => (BinOp::Concat, 5),
            "+" => (BinOp::Add, 6),
            "-" => (BinOp::Sub, 6),
            "*" => (BinOp::Mul, 7),
            "/" => (BinOp::Div, 7),
            _ => return None,
        },
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(line: &str) -> Vec<Tok> {
        let mut t = Vec::new();
        tokenize(line.as_bytes(), &mut t).unwrap();
        t.into_iter().map(|t| t.tok).collect()
    }

    #[test]
    fn words_need_no_spaces_and_names_keep_their_digits() {
        assert_eq!(
            names("g0x10Y.5"),
            vec![
                Tok::Name("G".into()),
                Tok::Num(0.0, 0, false),
                Tok::Name("X".into()),
                Tok::Num(10.0, 0, false),
                Tok::Name("Y".into()),
                Tok::Num(0.5, 1, true),
            ]
        );
        assert_eq!(names("CYCLE800()")[0], Tok::Name("CYCLE800".into()));
        assert_eq!(names("A3=1")[0], Tok::Name("A3".into()));
        assert_eq!(names("R12 = 1")[0], Tok::Name("R12".into()));
        let mut t = Vec::new();
        assert_eq!(tokenize(b"G1 ; x", &mut t).unwrap(), Some(3..6));
    }

    /// A plain line's words are its tokens' address, sign and number; any
    /// other line is left to the tokeniser.
    #[test]
    fn plain_lines_give_their_tokens_words() {
        let plain = |line: &str| {
            let mut w = Vec::new();
            plain_words(line.as_bytes(), &mut w).map(|c| (w, c))
        };
        let (words, comment) = plain("n10 G1X-5.2 Y.5 F800. ; c").unwrap();
        assert_eq!(comment, Some(22..25));
        let got: Vec<_> = words
            .iter()
            .map(|w| (w.letter, w.value, w.decimals, w.point, w.start, w.end))
            .collect();
        assert_eq!(
            got,
            vec![
                (b'N', 10.0, 0, false, 0, 3),
                (b'G', 1.0, 0, false, 4, 6),
                (b'X', -5.2, 1, true, 6, 11),
                (b'Y', 0.5, 1, true, 12, 15),
                (b'F', 800.0, 0, true, 16, 21),
            ]
        );
        // Each word as the tokeniser sees it: name, sign, number.
        let mut t = Vec::new();
        tokenize(b"X-5.2", &mut t).unwrap();
        assert_eq!(t[2].tok, Tok::Num(5.2, 1, true));
        for other in [
            "X=1",
            "A3=1",
            "X 5",
            "X- 5",
            "X1.5EX3",
            "R1=2",
            "M30",
            "G1 X",
            "CYCLE800()",
            "X.",
            "/N10 X1",
            "LABEL: X1",
            "X1 Y\"a\"",
        ] {
            assert!(plain(other).is_none(), "{other}");
        }
    }
}
