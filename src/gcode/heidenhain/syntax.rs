//! The syntax of Heidenhain Klartext blocks, lossless and without meaning.
//!
//! A block is one logical block of the program: a line, plus the lines that
//! follow it while a line ends with `~` (TNC 640 user's manual, "Programming
//! fundamentals › NC blocks": long blocks continue on `~` lines). It starts
//! with its block number; `;` starts a comment that runs to the end of the
//! physical line (before a trailing `~`); a `*` after the number is a section
//! line. The rest is space-separated words: keywords (`L`, `CC`, `CYCL`,
//! `DEF`, `FMAX`, `RL`…) and addresses with a value (`X+12.5`, `IX-3`,
//! `X+Q1`, `DR+`, `M128`, `Q200=+2`). Q formulas (`Q1 = Q2 * SIN(Q3)`) and
//! the `FN` functions keep their right-hand side as text, parsed by
//! [`Formula::parse`].
//!
//! Invariant: no input makes anything here panic; every token knows its byte
//! range in the block's raw bytes.
use std::ops::Range;

/// A parameter kind: `Q` (global), `QL` (local to the program), `QR`
/// (remanent), `QS` (strings: not read).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamKind {
    /// `Q`.
    Q,
    /// `QL`.
    Ql,
    /// `QR`.
    Qr,
}

/// A parameter reference `Q12`, `QL3`, `QR100`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Param {
    /// Which table.
    pub kind: ParamKind,
    /// Its number.
    pub number: u32,
}

/// The value of an address as written: a number or a signed parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    /// A number (sign included).
    Number(f64),
    /// A parameter, negated when written `-Q1`.
    Param {
        /// The parameter.
        param: Param,
        /// Written with a minus sign.
        negate: bool,
    },
    /// Only a sign (`DR+`, `DR-`, `SEQ-`): +1 or −1.
    Sign(f64),
}

/// A token's address, upper case, held inline (no allocation per token):
/// at most [`Address::CAPACITY`] bytes are kept of a longer one.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
pub struct Address {
    bytes: [u8; Address::CAPACITY],
    len: u8,
}

impl Address {
    /// Bytes kept of an address.
    pub const CAPACITY: usize = 23;

    /// The address of `text` (ASCII letters and digits), upper-cased.
    pub fn new(text: &str) -> Address {
        let mut a = Address::default();
        for (k, b) in text.bytes().take(Address::CAPACITY).enumerate() {
            a.bytes[k] = b.to_ascii_uppercase();
            a.len = k as u8 + 1;
        }
        a
    }

    /// It as text (a one-letter address, most of a program's words,
    /// without a UTF-8 check).
    pub fn as_str(&self) -> &str {
        match self.bytes[..self.len as usize] {
            [b @ b'A'..=b'Z'] => crate::gcode::syntax::parser::LETTERS[(b - b'A') as usize],
            ref bytes => std::str::from_utf8(bytes).unwrap_or(""),
        }
    }

    /// Its bytes (upper-case ASCII).
    #[inline]
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..self.len as usize]
    }

    /// Whether it is `other` (the first byte compared before the rest).
    fn is(&self, other: &[u8]) -> bool {
        let n = self.len as usize;
        n == other.len() && (n == 0 || self.bytes[0] == other[0]) && self.bytes[..n] == *other
    }
}

impl std::ops::Deref for Address {
    type Target = str;
    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl std::fmt::Debug for Address {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.as_str().fmt(f)
    }
}

impl std::fmt::Display for Address {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl PartialEq<str> for Address {
    fn eq(&self, other: &str) -> bool {
        self.is(other.as_bytes())
    }
}

impl PartialEq<&str> for Address {
    fn eq(&self, other: &&str) -> bool {
        self.is(other.as_bytes())
    }
}

/// One space-separated token of a block.
#[derive(Clone, Debug, PartialEq)]
pub struct Token {
    /// Byte range inside the block's raw bytes.
    pub span: Range<usize>,
    /// Byte range inside [`KlBlock::code`].
    pub text: Range<usize>,
    /// The address: the leading letters, upper case (`X`, `IX`, `FMAX`,
    /// `Q200`'s `Q` …); empty for a token that starts with a digit or sign.
    pub address: Address,
    /// The value after the address, when it has one.
    pub value: Option<Value>,
    /// Byte range of the value inside the raw bytes (empty when none).
    pub value_span: Range<usize>,
    /// Digits after the decimal point of a number value.
    pub decimals: u8,
    /// The number value was written with an explicit sign (`X+5`).
    pub signed: bool,
}

impl Token {
    /// The value as a plain number (not a parameter).
    pub fn number(&self) -> Option<f64> {
        match self.value {
            Some(Value::Number(v)) | Some(Value::Sign(v)) => Some(v),
            _ => None,
        }
    }
}

/// One logical block, parsed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KlBlock {
    /// The block number and its byte range.
    pub number: Option<(u64, Range<usize>)>,
    /// A `*` section line.
    pub section: bool,
    /// Written with the block-skip `/` before its number (`/81 M30`:
    /// skipped when the control's block skip is on).
    pub deleted: bool,
    /// The code tokens, in order (comments and `~` excluded).
    pub tokens: Vec<Token>,
    /// Byte ranges of the comments (from `;` to the end of the physical line
    /// or the `~`).
    pub comments: Vec<Range<usize>>,
    /// The bytes of the code part after the block number (comments removed,
    /// physical lines joined by a space), for formulas and names.
    pub code: String,
    /// Where each byte of `code` is in `raw`.
    code_map: CodeMap,
}

/// Where the bytes of [`KlBlock::code`] are in the block's raw bytes: one
/// piece a physical line (its code copied whole), each followed by the
/// joining space, which stands for the line's end.
#[derive(Clone, Debug, Default, PartialEq)]
struct CodeMap {
    pieces: Vec<Piece>,
}

/// One physical line's code in [`CodeMap`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct Piece {
    /// Where it starts in the code and in the raw bytes, and its length.
    code: usize,
    raw: usize,
    len: usize,
    /// The raw offset the space after it stands for.
    space: usize,
}

impl CodeMap {
    /// The raw offset of code byte `i` (`None` past the code's end).
    #[inline]
    fn get(&self, i: usize) -> Option<usize> {
        for p in &self.pieces {
            if i < p.code + p.len {
                return Some(p.raw + (i - p.code));
            }
            if i == p.code + p.len {
                return Some(p.space);
            }
        }
        None
    }

    /// The first `n` code bytes removed (the block number read on the
    /// gathered code).
    fn drain_front(&mut self, mut n: usize) {
        let mut code = 0;
        self.pieces.retain_mut(|p| {
            if n > p.len {
                n -= p.len + 1;
                return false;
            }
            p.raw += n;
            p.len -= n;
            n = 0;
            p.code = code;
            code += p.len + 1;
            true
        });
    }
}

impl KlBlock {
    /// The token at `i`'s address, upper case (`""` past the end).
    pub fn address(&self, i: usize) -> &str {
        self.tokens.get(i).map_or("", |t| t.address.as_str())
    }

    /// Whether the tokens start with these keywords (whole tokens, no value).
    pub fn starts_with(&self, keywords: &[&str]) -> bool {
        keywords.len() <= self.tokens.len()
            && keywords
                .iter()
                .zip(&self.tokens)
                .all(|(k, t)| t.value.is_none() && t.address == *k)
    }

    /// The first token with this address (after token `from`).
    pub fn find(&self, address: &str, from: usize) -> Option<&Token> {
        self.tokens.iter().skip(from).find(|t| t.address == address)
    }

    /// The parameter a Q formula block assigns (`Q1 = …`, `QL2=…`).
    pub fn assigned(&self) -> Option<Param> {
        let eq = memchr::memchr(b'=', self.code.as_bytes())?;
        read_param(self.code[..eq].trim())
    }
}

/// Parse one logical block's raw bytes (physical lines joined with their
/// line endings inside).
pub fn parse_block(raw: &[u8]) -> KlBlock {
    let mut out = KlBlock::default();
    parse_block_into(raw, &mut out);
    out
}

/// [`parse_block`] into `out`, reusing its buffers.
pub fn parse_block_into(raw: &[u8], out: &mut KlBlock) {
    out.number = None;
    out.section = false;
    out.deleted = false;
    out.tokens.clear();
    out.comments.clear();
    let mut code = std::mem::take(&mut out.code);
    let mut map = std::mem::take(&mut out.code_map);
    code.clear();
    map.pieces.clear();
    // The block number is read on the first physical line's code, before
    // the code is gathered (so the code starts after it); a first line with
    // no code (the number could come from the next line) is read on the
    // gathered code.
    let mut prefix_done = false;
    // Split physical lines; cut comments and trailing `~`.
    let mut line_start = 0;
    while line_start <= raw.len() {
        let line_end =
            memchr::memchr(b'\n', &raw[line_start..]).map_or(raw.len(), |k| line_start + k);
        let mut content_end = line_end;
        if content_end > line_start && raw[content_end - 1] == b'\r' {
            content_end -= 1;
        }
        // A trailing `~` (after spaces) continues the block.
        let mut trimmed = content_end;
        while trimmed > line_start && raw[trimmed - 1].is_ascii_whitespace() {
            trimmed -= 1;
        }
        if trimmed > line_start && raw[trimmed - 1] == b'~' {
            content_end = trimmed - 1;
        }
        // A leading `~` on a continuation line is the other convention.
        let mut from = line_start;
        while from < content_end && raw[from].is_ascii_whitespace() {
            from += 1;
        }
        if line_start > 0 && from < content_end && raw[from] == b'~' {
            from += 1;
        }
        // The code runs to a `;` outside quotes.
        let mut cut = content_end;
        let mut in_quote = false;
        // Most blocks have neither a quote nor a comment: no byte loop.
        let plain = memchr::memchr2(b'"', b';', &raw[from..content_end]).is_none();
        for (k, &b) in raw[from..if plain { from } else { content_end }]
            .iter()
            .enumerate()
        {
            if b == b'"' {
                in_quote = !in_quote;
            } else if b == b';' && !in_quote {
                cut = from + k;
                out.comments.push(cut..content_end);
                break;
            }
        }
        if line_start == 0 && from < cut {
            let rest = block_number(&raw[from..cut], from, out);
            from += rest;
            prefix_done = true;
        }
        let piece = &raw[from..cut];
        if piece.is_ascii() {
            code.push_str(std::str::from_utf8(piece).unwrap_or_default());
        } else {
            code.extend(
                piece
                    .iter()
                    .map(|&b| if b.is_ascii() { b as char } else { '?' }),
            );
        }
        map.pieces.push(Piece {
            code: code.len() - (cut - from),
            raw: from,
            len: cut - from,
            space: content_end.min(raw.len().saturating_sub(1)),
        });
        code.push(' ');
        line_start = line_end + 1;
    }
    if !prefix_done {
        let rest = block_number(code.as_bytes(), 0, out);
        if let Some((_, span)) = &mut out.number {
            let at = |i| map.get(i).unwrap_or(0);
            *span = at(span.start)..at(span.end - 1) + 1;
        }
        code.drain(..rest);
        map.drain_front(rest);
    }
    if code.trim_start().starts_with('*') {
        out.section = true;
    }
    if !out.section {
        tokenize(&code, &map, &mut out.tokens);
    }
    out.code = code;
    out.code_map = map;
}

/// The block number at the start of `code` (a `/` block skip before it),
/// set on `out` with its span (offsets in `code` plus `at`); returns where
/// the rest of the code starts.
fn block_number(code: &[u8], at: usize, out: &mut KlBlock) -> usize {
    let mut k = 0;
    while k < code.len() && code[k] == b' ' {
        k += 1;
    }
    if k < code.len() && code[k] == b'/' {
        out.deleted = true;
        k += 1;
    }
    let digits_start = k;
    while k < code.len() && code[k].is_ascii_digit() {
        k += 1;
    }
    if k > digits_start && (k == code.len() || !code[k].is_ascii_alphabetic()) {
        if let Some(n) = digits_u64(&code[digits_start..k]) {
            out.number = Some((n, at + digits_start..at + k));
        }
        k
    } else {
        digits_start
    }
}

/// ASCII digits as a `u64`, `None` past its range (as `str::parse`, without
/// a UTF-8 check).
pub(crate) fn digits_u64(digits: &[u8]) -> Option<u64> {
    if digits.is_empty() {
        return None;
    }
    if digits.len() <= 19 {
        // At most 19 digits cannot overflow.
        let mut n = 0u64;
        for &d in digits {
            let d = d.wrapping_sub(b'0');
            if d > 9 {
                return None;
            }
            n = n * 10 + u64::from(d);
        }
        return Some(n);
    }
    digits.iter().try_fold(0u64, |n, &d| {
        n.checked_mul(10)?
            .checked_add(u64::from(d.checked_sub(b'0').filter(|d| *d < 10)?))
    })
}

/// Split `code` into tokens at spaces (quoted names stay whole).
fn tokenize(code: &str, map: &CodeMap, tokens: &mut Vec<Token>) {
    let bytes = code.as_bytes();
    let mut k = 0;
    while k < bytes.len() {
        while k < bytes.len() && bytes[k] == b' ' {
            k += 1;
        }
        if k >= bytes.len() {
            break;
        }
        let start = k;
        if let Some((t, end)) = signed_number_word(bytes, start, map) {
            tokens.push(t);
            k = end;
            continue;
        }
        if let Some((t, end)) = keyword(bytes, start, map) {
            tokens.push(t);
            k = end;
            continue;
        }
        let mut in_quote = false;
        while k < bytes.len() && (in_quote || bytes[k] != b' ') {
            if bytes[k] == b'"' {
                in_quote = !in_quote;
            }
            k += 1;
        }
        // `Q201= -48` (hyperMILL pads a cycle parameter's value): the
        // parameter and the number after the spaces are one word.
        if bytes[k - 1] == b'=' && k - start > 1 && read_param(&code[start..k - 1]).is_some() {
            let mut j = k;
            while j < bytes.len() && bytes[j] == b' ' {
                j += 1;
            }
            if j > k && j < bytes.len() && matches!(bytes[j], b'+' | b'-' | b'.' | b'0'..=b'9') {
                k = j;
                while k < bytes.len() && bytes[k] != b' ' {
                    k += 1;
                }
            }
        }
        // `DR+F2777`, `DR+FQ1`: a direction sign with the feed written on
        // (hyperMILL writes it so): two words, `DR+` and `F…`.
        let w = &bytes[start..k];
        let split = (w.len() > 4
            && w[..2].eq_ignore_ascii_case(b"DR")
            && matches!(w[2], b'+' | b'-')
            && w[3].eq_ignore_ascii_case(&b'F'))
        .then_some(start + 3);
        for (a, b) in split.map_or([(start, k), (k, k)], |m| [(start, m), (m, k)]) {
            if a < b {
                let mut t = token(&code[a..b], map, a);
                t.text = a..b;
                tokens.push(t);
            }
        }
    }
}

/// One token: the leading letters are its address, the rest its value.
fn token(text: &str, map: &CodeMap, at: usize) -> Token {
    let raw_start = map.get(at).unwrap_or(0);
    let raw_end = map
        .get(at + text.len().saturating_sub(1))
        .map_or(raw_start, |e| e + 1);
    let bytes = text.as_bytes();
    let mut k = 0;
    while k < bytes.len() && bytes[k].is_ascii_alphabetic() {
        k += 1;
    }
    // `P1X+0` (a point of `PLANE POINTS`): the address is `P1X`.
    if k == 1
        && bytes[0].eq_ignore_ascii_case(&b'P')
        && bytes.len() > 2
        && matches!(bytes[1], b'1'..=b'3')
        && matches!(bytes[2].to_ascii_uppercase(), b'X' | b'Y' | b'Z')
    {
        k = 3;
    }
    // `FQ2`, `FQL3` (an address whose value is a parameter, written
    // without a sign): the address is `F`, the value `Q2`.
    let letters = &text[..k];
    if bytes.get(k).is_some_and(u8::is_ascii_digit) {
        let upper = letters.to_ascii_uppercase();
        for q in ["QL", "QR", "Q"] {
            if upper.len() > q.len() && upper.ends_with(q) {
                k -= q.len();
                break;
            }
        }
    }
    // `Q200=+2` (a cycle parameter): the address is `Q200`.
    if let Some(eq) = memchr::memchr(b'=', bytes)
        && eq > k
        && read_param(&text[..eq]).is_some()
    {
        k = eq;
    }
    let address = Address::new(&text[..k]);
    let mut v = &text[k..];
    let mut v_at = at + k;
    if let Some(s) = v.strip_prefix('=') {
        // After spaces (`Q201= -48`: one word, see `tokenize`).
        let value = s.trim_start_matches(' ');
        v_at += 1 + s.len() - value.len();
        v = value;
    }
    let value_span = if v.is_empty() {
        raw_end..raw_end
    } else {
        map.get(v_at).unwrap_or(raw_end)..raw_end
    };
    let (value, decimals, signed) = read_value(v);
    Token {
        span: raw_start..raw_end,
        text: 0..0,
        address,
        value,
        value_span,
        decimals,
        signed,
    }
}

/// The most common token, a letter and a signed number (`X+12.5`,
/// `C-3`) up to a space or the code's end, read in one pass from
/// `code[start..]`: what [`tokenize`] and [`token`]'s general path give it
/// (a one-letter address, the number as [`read_value`] converts it), and
/// where it ends; `None` for any other token.
#[inline]
fn signed_number_word(code: &[u8], start: usize, map: &CodeMap) -> Option<(Token, usize)> {
    let (&[letter, sign], body) = code.get(start..)?.split_first_chunk::<2>()?;
    if !letter.is_ascii_alphabetic() || !(sign == b'+' || sign == b'-') {
        return None;
    }
    let mut mantissa: u64 = 0;
    let mut ndigits = 0usize;
    let mut point: Option<usize> = None;
    let mut len = 0;
    for &b in body {
        if b.is_ascii_digit() {
            mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(b - b'0'));
            ndigits += 1;
        } else if b == b'.' && point.is_none() {
            point = Some(len);
        } else if b == b' ' {
            break;
        } else {
            return None;
        }
        len += 1;
    }
    let decimals = point.map_or(0, |p| len - p - 1);
    let x = crate::gcode::syntax::parser::exact_from_parts(mantissa, ndigits, decimals)?;
    let end = start + 2 + len;
    let raw_start = map.get(start).unwrap_or(0);
    let raw_end = map.get(end - 1).map_or(raw_start, |e| e + 1);
    let mut address = Address::default();
    address.bytes[0] = letter.to_ascii_uppercase();
    address.len = 1;
    Some((
        Token {
            value_span: map.get(start + 1).unwrap_or(raw_end)..raw_end,
            span: raw_start..raw_end,
            text: start..end,
            address,
            value: Some(Value::Number(if sign == b'-' { -x } else { x })),
            decimals: decimals.min(255) as u8,
            signed: true,
        },
        end,
    ))
}

/// A token of letters only (`L`, `FMAX`, `CYCL`) up to a space or the
/// code's end, read in one pass: what [`tokenize`] and [`token`] give it
/// (its address, no value), and where it ends; `None` for any other token.
#[inline]
fn keyword(code: &[u8], start: usize, map: &CodeMap) -> Option<(Token, usize)> {
    let len = code[start..]
        .iter()
        .position(|&b| !b.is_ascii_alphabetic())
        .unwrap_or(code.len() - start);
    let end = start + len;
    if len == 0 || code.get(end).is_some_and(|&b| b != b' ') {
        return None;
    }
    let raw_start = map.get(start).unwrap_or(0);
    let raw_end = map.get(end - 1).map_or(raw_start, |e| e + 1);
    let mut address = Address::default();
    for (k, b) in code[start..end].iter().take(Address::CAPACITY).enumerate() {
        address.bytes[k] = b.to_ascii_uppercase();
        address.len = k as u8 + 1;
    }
    Some((
        Token {
            span: raw_start..raw_end,
            text: start..end,
            address,
            value: None,
            value_span: raw_end..raw_end,
            decimals: 0,
            signed: false,
        },
        end,
    ))
}

/// A value as written: `+12.5`, `-3`, `7`, `+Q1`, `-QL3`, `+`, `-`.
fn read_value(v: &str) -> (Option<Value>, u8, bool) {
    if v.is_empty() {
        return (None, 0, false);
    }
    let (negate, body, signed) = match v.as_bytes()[0] {
        b'+' => (false, &v[1..], true),
        b'-' => (true, &v[1..], true),
        _ => (false, v, false),
    };
    if body.is_empty() {
        return if signed {
            (Some(Value::Sign(if negate { -1.0 } else { 1.0 })), 0, true)
        } else {
            (None, 0, false)
        };
    }
    if let Some(param) = read_param(body) {
        return (Some(Value::Param { param, negate }), 0, signed);
    }
    if let Some(x) = crate::gcode::syntax::parser::exact_decimal(body.as_bytes()) {
        let decimals = memchr::memchr(b'.', body.as_bytes())
            .map_or(0, |p| (body.len() - p - 1).min(255) as u8);
        return (
            Some(Value::Number(if negate { -x } else { x })),
            decimals,
            signed,
        );
    }
    if body
        .bytes()
        .all(|b| b.is_ascii_digit() || b == b'.' || b == b',')
        && body.bytes().any(|b| b.is_ascii_digit())
    {
        let body = body.replace(',', ".");
        if let Ok(x) = body.parse::<f64>()
            && x.is_finite()
        {
            let decimals = body
                .find('.')
                .map_or(0, |p| (body.len() - p - 1).min(255) as u8);
            return (
                Some(Value::Number(if negate { -x } else { x })),
                decimals,
                signed,
            );
        }
    }
    (None, 0, signed)
}

/// `Q12`, `QL3`, `QR100` (upper or lower case).
pub fn read_param(text: &str) -> Option<Param> {
    // Only `Q…` is a parameter: anything else is refused before upper-casing.
    if !text.starts_with(['Q', 'q']) {
        return None;
    }
    let upper = text.to_ascii_uppercase();
    let (kind, digits) = if let Some(d) = upper.strip_prefix("QL") {
        (ParamKind::Ql, d)
    } else if let Some(d) = upper.strip_prefix("QR") {
        (ParamKind::Qr, d)
    } else if let Some(d) = upper.strip_prefix('Q') {
        (ParamKind::Q, d)
    } else {
        return None;
    };
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) || digits.len() > 6 {
        return None;
    }
    Some(Param {
        kind,
        number: digits.parse().ok()?,
    })
}

/// A Q formula or an `FN` right-hand side, parsed.
#[derive(Clone, Debug, PartialEq)]
pub enum Formula {
    /// A number.
    Number(f64),
    /// A parameter.
    Param(Param),
    /// `-x`.
    Neg(Box<Formula>),
    /// A binary operation.
    Binary(BinaryOp, Box<Formula>, Box<Formula>),
    /// A function of one argument.
    Function(Function, Box<Formula>),
}

/// Binary operators of Q formulas and `FN` functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinaryOp {
    /// `+`.
    Add,
    /// `-`.
    Sub,
    /// `*`.
    Mul,
    /// `/` or `DIV`.
    Div,
    /// `^`.
    Pow,
    /// `LEN` (FN 8: √(a² + b²)).
    Len,
    /// `ANG` (FN 13: the angle of the vector (a, b), degrees).
    Ang,
}

/// Functions of Q formulas (TNC 640 user's manual, "Q parameters ›
/// Formulas": SIN COS TAN ASIN ACOS ATAN SQ SQRT LN LOG ABS INT NEG FRAC
/// SGN EXP; angles in degrees).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    /// Sine of degrees.
    Sin,
    /// Cosine of degrees.
    Cos,
    /// Tangent of degrees.
    Tan,
    /// Arc sine, degrees.
    Asin,
    /// Arc cosine, degrees.
    Acos,
    /// Arc tangent, degrees.
    Atan,
    /// Square.
    Sq,
    /// Square root.
    Sqrt,
    /// Natural logarithm.
    Ln,
    /// Decimal logarithm.
    Log,
    /// e^x.
    Exp,
    /// Absolute value.
    Abs,
    /// Integer part (towards zero).
    Int,
    /// Negation.
    Neg,
    /// Fractional part.
    Frac,
    /// Sign (−1, 0, 1).
    Sgn,
}

impl Function {
    fn from_name(name: &str) -> Option<Function> {
        Some(match name {
            "SIN" => Function::Sin,
            "COS" => Function::Cos,
            "TAN" => Function::Tan,
            "ASIN" => Function::Asin,
            "ACOS" => Function::Acos,
            "ATAN" => Function::Atan,
            "SQ" => Function::Sq,
            "SQRT" => Function::Sqrt,
            "LN" => Function::Ln,
            "LOG" => Function::Log,
            "EXP" => Function::Exp,
            "ABS" => Function::Abs,
            "INT" => Function::Int,
            "NEG" => Function::Neg,
            "FRAC" => Function::Frac,
            "SGN" => Function::Sgn,
            _ => return None,
        })
    }
}

/// Why a formula cannot be read or computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FormulaError {
    /// Not a formula (what was found, at which byte of the text).
    #[error("cannot read the formula: {0}")]
    Syntax(String, usize),
    /// A division by zero.
    #[error("division by zero")]
    DivisionByZero,
    /// A function's argument outside its domain (the function).
    #[error("{0} of an argument outside its domain")]
    Domain(&'static str),
}

struct FormulaParser<'a> {
    text: &'a [u8],
    at: usize,
}

impl Formula {
    /// Parse `text` (the whole of it) as a formula.
    pub fn parse(text: &str) -> Result<Formula, FormulaError> {
        let mut p = FormulaParser {
            text: text.as_bytes(),
            at: 0,
        };
        let f = p.sum()?;
        p.skip_spaces();
        if p.at < p.text.len() {
            return Err(p.error());
        }
        Ok(f)
    }

    /// Compute it, reading parameters through `get`.
    pub fn eval(&self, get: &dyn Fn(Param) -> f64) -> Result<f64, FormulaError> {
        let v = match self {
            Formula::Number(x) => *x,
            Formula::Param(p) => get(*p),
            Formula::Neg(a) => -a.eval(get)?,
            Formula::Binary(op, a, b) => {
                let (a, b) = (a.eval(get)?, b.eval(get)?);
                match op {
                    BinaryOp::Add => a + b,
                    BinaryOp::Sub => a - b,
                    BinaryOp::Mul => a * b,
                    BinaryOp::Div => {
                        if b == 0.0 {
                            return Err(FormulaError::DivisionByZero);
                        }
                        a / b
                    }
                    BinaryOp::Pow => a.powf(b),
                    BinaryOp::Len => a.hypot(b),
                    BinaryOp::Ang => b.atan2(a).to_degrees(),
                }
            }
            Formula::Function(f, a) => {
                let x = a.eval(get)?;
                let domain = |ok: bool, name| {
                    if ok {
                        Ok(())
                    } else {
                        Err(FormulaError::Domain(name))
                    }
                };
                match f {
                    Function::Sin => x.to_radians().sin(),
                    Function::Cos => x.to_radians().cos(),
                    Function::Tan => x.to_radians().tan(),
                    Function::Asin => {
                        domain((-1.0..=1.0).contains(&x), "ASIN")?;
                        x.asin().to_degrees()
                    }
                    Function::Acos => {
                        domain((-1.0..=1.0).contains(&x), "ACOS")?;
                        x.acos().to_degrees()
                    }
                    Function::Atan => x.atan().to_degrees(),
                    Function::Sq => x * x,
                    Function::Sqrt => {
                        domain(x >= 0.0, "SQRT")?;
                        x.sqrt()
                    }
                    Function::Ln => {
                        domain(x > 0.0, "LN")?;
                        x.ln()
                    }
                    Function::Log => {
                        domain(x > 0.0, "LOG")?;
                        x.log10()
                    }
                    Function::Exp => x.exp(),
                    Function::Abs => x.abs(),
                    Function::Int => x.trunc(),
                    Function::Neg => -x,
                    Function::Frac => x.fract(),
                    Function::Sgn => {
                        if x > 0.0 {
                            1.0
                        } else if x < 0.0 {
                            -1.0
                        } else {
                            0.0
                        }
                    }
                }
            }
        };
        if v.is_finite() {
            Ok(v)
        } else {
            Err(FormulaError::Domain("the result"))
        }
    }
}

impl FormulaParser<'_> {
    fn skip_spaces(&mut self) {
        while self.at < self.text.len() && self.text[self.at] == b' ' {
            self.at += 1;
        }
    }

    fn error(&self) -> FormulaError {
        let rest = String::from_utf8_lossy(&self.text[self.at.min(self.text.len())..]);
        let found = if rest.trim().is_empty() {
            "the end of the formula".to_string()
        } else {
            format!("`{}`", rest.trim())
        };
        FormulaError::Syntax(format!("unexpected {found}"), self.at)
    }

    /// An upper-case word at the cursor (letters only), without taking it.
    fn peek_word(&self) -> String {
        let mut k = self.at;
        while k < self.text.len() && self.text[k].is_ascii_alphabetic() {
            k += 1;
        }
        String::from_utf8_lossy(&self.text[self.at..k]).to_ascii_uppercase()
    }

    fn sum(&mut self) -> Result<Formula, FormulaError> {
        let mut left = self.product()?;
        loop {
            self.skip_spaces();
            let op = match self.text.get(self.at) {
                Some(b'+') => BinaryOp::Add,
                Some(b'-') => BinaryOp::Sub,
                _ => return Ok(left),
            };
            self.at += 1;
            let right = self.product()?;
            left = Formula::Binary(op, Box::new(left), Box::new(right));
        }
    }

    fn product(&mut self) -> Result<Formula, FormulaError> {
        let mut left = self.power()?;
        loop {
            self.skip_spaces();
            let op = match self.text.get(self.at) {
                Some(b'*') => {
                    self.at += 1;
                    BinaryOp::Mul
                }
                Some(b'/') => {
                    self.at += 1;
                    BinaryOp::Div
                }
                _ => {
                    let word = self.peek_word();
                    let op = match word.as_str() {
                        "DIV" => BinaryOp::Div,
                        "LEN" => BinaryOp::Len,
                        "ANG" => BinaryOp::Ang,
                        _ => return Ok(left),
                    };
                    self.at += word.len();
                    op
                }
            };
            let right = self.power()?;
            left = Formula::Binary(op, Box::new(left), Box::new(right));
        }
    }

    fn power(&mut self) -> Result<Formula, FormulaError> {
        let base = self.unary()?;
        self.skip_spaces();
        if self.text.get(self.at) == Some(&b'^') {
            self.at += 1;
            let exponent = self.power()?;
            return Ok(Formula::Binary(
                BinaryOp::Pow,
                Box::new(base),
                Box::new(exponent),
            ));
        }
        Ok(base)
    }

    fn unary(&mut self) -> Result<Formula, FormulaError> {
        self.skip_spaces();
        match self.text.get(self.at) {
            Some(b'+') => {
                self.at += 1;
                self.unary()
            }
            Some(b'-') => {
                self.at += 1;
                Ok(Formula::Neg(Box::new(self.unary()?)))
            }
            Some(b'(') => {
                self.at += 1;
                let f = self.sum()?;
                self.skip_spaces();
                if self.text.get(self.at) != Some(&b')') {
                    return Err(self.error());
                }
                self.at += 1;
                Ok(f)
            }
            Some(b) if b.is_ascii_digit() || *b == b'.' => {
                let start = self.at;
                while self.at < self.text.len()
                    && (self.text[self.at].is_ascii_digit() || self.text[self.at] == b'.')
                {
                    self.at += 1;
                }
                let s = String::from_utf8_lossy(&self.text[start..self.at]);
                s.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .map(Formula::Number)
                    .ok_or_else(|| {
                        self.at = start;
                        self.error()
                    })
            }
            Some(b) if b.is_ascii_alphabetic() => {
                let word = self.peek_word();
                if word == "PI" {
                    self.at += 2;
                    return Ok(Formula::Number(std::f64::consts::PI));
                }
                if let Some(f) = Function::from_name(&word) {
                    self.at += word.len();
                    let arg = self.unary()?;
                    return Ok(Formula::Function(f, Box::new(arg)));
                }
                // A parameter: letters Q/QL/QR then digits.
                let start = self.at;
                let mut k = self.at;
                while k < self.text.len() && self.text[k].is_ascii_alphanumeric() {
                    k += 1;
                }
                let text = String::from_utf8_lossy(&self.text[start..k]);
                match read_param(&text) {
                    Some(p) => {
                        self.at = k;
                        Ok(Formula::Param(p))
                    }
                    None => Err(self.error()),
                }
            }
            _ => Err(self.error()),
        }
    }
}

#[cfg(test)]
mod tests {
    /// Block numbers are read as `str::parse` reads them.
    #[test]
    fn digits_are_read_as_str_parse_reads_them() {
        for d in [
            "",
            "0",
            "0012",
            "18446744073709551615",
            "18446744073709551616",
        ] {
            assert_eq!(
                super::digits_u64(d.as_bytes()),
                d.parse::<u64>().ok(),
                "{d}"
            );
        }
    }

    use super::*;

    /// `Q201= -48` (hyperMILL pads a cycle parameter's value): one token,
    /// the parameter with its value, spanning the number; a Q formula's
    /// `Q1 = Q2` and a `=` before a word are left as they were.
    #[test]
    fn padded_parameter_value_is_one_token() {
        let b = parse_block(b"7 CYCL DEF 209 X~\n Q200=  3 ;A~\n Q201= -48 ;B~\n Q239=+2");
        let q: Vec<(String, Option<f64>)> = b.tokens[3..]
            .iter()
            .filter(|t| t.address.starts_with('Q'))
            .map(|t| (t.address.to_string(), t.number()))
            .collect();
        assert_eq!(
            q,
            vec![
                ("Q200".into(), Some(3.0)),
                ("Q201".into(), Some(-48.0)),
                ("Q239".into(), Some(2.0))
            ]
        );
        let raw = b"7 CYCL DEF 209 X~\n Q200=  3 ;A~\n Q201= -48 ;B~\n Q239=+2";
        let t = b.tokens.iter().find(|t| t.address == "Q201").unwrap();
        assert_eq!(&raw[t.value_span.clone()], b"-48");
        assert_eq!(b.tokens.len(), 7);
        let f = parse_block(b"8 Q1 = Q2 + 3");
        assert_eq!(f.tokens.len(), 5);
        let f = parse_block(b"8 Q1= SIN(30)");
        assert_eq!(f.tokens.len(), 2);
    }

    /// The one-pass readers of signed numbers and keywords give each token
    /// what the general token reader gives it (spans, value, decimals), on
    /// one-line and continued blocks, with comments, lower case, long
    /// addresses and numbers the exact path does not convert.
    #[test]
    fn one_pass_tokens_are_the_general_ones() {
        for raw in [
            &b"3 L X+50.0000 Y-0.0500 Z+.5 A+5. C-280 R0 FMAX"[..],
            b"12 l x+12.5 IY-3 Z+Q1 R0 F800 M3 ; rapid",
            b"4 L X+1.2.3 Y+ Z- A+12345678901234567890 B+9007199254740993 C+1,5",
            b"5 CYCL DEF 200 ~\r\n  Q200=+2 ;A~\r\n  Q201= -20 ;B\r\n",
            b"6 ABCDEFGHIJKLMNOPQRSTUVWXYZABC X+1 DR+F2777 P1X+0",
            b"  7 L  X+1   Y-2 ",
            b"8\n L X+3 ~\n Y+4",
            b"\n9 L X+1 Y+2",
        ] {
            let b = parse_block(raw);
            assert!(!b.tokens.is_empty());
            for t in &b.tokens {
                let mut general = token(&b.code[t.text.clone()], &b.code_map, t.text.start);
                general.text = t.text.clone();
                assert_eq!(&general, t, "{}", String::from_utf8_lossy(raw));
            }
        }
    }

    #[test]
    fn linear_block_tokens() {
        let b = parse_block(b"12 L X+12.5 IY-3 Z+Q1 R0 FMAX M3 ; rapid");
        assert_eq!(b.number.as_ref().map(|n| n.0), Some(12));
        assert_eq!(b.address(0), "L");
        assert_eq!(b.tokens[1].address, "X");
        assert_eq!(b.tokens[1].number(), Some(12.5));
        assert_eq!(b.tokens[1].decimals, 1);
        assert!(b.tokens[1].signed);
        assert_eq!(b.tokens[2].address, "IY");
        assert_eq!(b.tokens[2].number(), Some(-3.0));
        assert_eq!(
            b.tokens[3].value,
            Some(Value::Param {
                param: Param {
                    kind: ParamKind::Q,
                    number: 1
                },
                negate: false
            })
        );
        assert_eq!(b.tokens[4].address, "R");
        assert_eq!(b.tokens[5].address, "FMAX");
        assert_eq!(b.comments.len(), 1);
        let raw = b"12 L X+12.5 IY-3 Z+Q1 R0 FMAX M3 ; rapid";
        assert_eq!(&raw[b.tokens[1].span.clone()], b"X+12.5");
        assert_eq!(&raw[b.tokens[1].value_span.clone()], b"+12.5");
    }

    #[test]
    fn continuation_and_cycle_parameters() {
        let raw =
            b"7 CYCL DEF 200 DRILLING ~\r\n  Q200=+2 ;SET-UP CLEARANCE ~\r\n  Q201=-20 ;DEPTH";
        let b = parse_block(raw);
        assert!(b.starts_with(&["CYCL", "DEF"]));
        let q = b.find("Q200", 0).unwrap();
        assert_eq!(q.number(), Some(2.0));
        assert_eq!(&raw[q.span.clone()], b"Q200=+2");
        assert_eq!(b.comments.len(), 2);
    }

    #[test]
    fn formulas() {
        let f = Formula::parse("+Q1 + +3 * SIN(30) - SQ 2").unwrap();
        let v = f.eval(&|_| 2.0).unwrap();
        assert!((v - (2.0 + 1.5 - 4.0)).abs() < 1e-12);
        let f = Formula::parse("+3 LEN +4").unwrap();
        assert_eq!(f.eval(&|_| 0.0).unwrap(), 5.0);
        let f = Formula::parse("+10 DIV +Q2").unwrap();
        assert_eq!(f.eval(&|_| 0.0), Err(FormulaError::DivisionByZero));
        assert!(Formula::parse("3 +").is_err());
        assert!(Formula::parse("SQRT Q").is_err());
    }

    #[test]
    fn section_and_names() {
        let b = parse_block(b"3 * - ROUGHING");
        assert!(b.section);
        let b = parse_block(b"4 TOOL CALL \"MILL D10\" Z S5000");
        assert_eq!(b.tokens[2].address, "");
        assert_eq!(b.tokens[3].address, "Z");
    }

    #[test]
    fn arbitrary_bytes_do_not_panic() {
        for raw in [
            &b""[..],
            b"~",
            b"\n~\n",
            b"99999999999999999999999 L",
            b"1 L X+",
            b"1 L X+.",
            b"\xff\xfe ;\"",
            b"1 Q1 = (",
        ] {
            let b = parse_block(raw);
            let _ = Formula::parse(&b.code);
        }
    }
}
