//! RS274NGC expressions as LinuxCNC reads them: the syntax tree (built by the
//! parser, unevaluated) and its evaluation against a parameter table.
//!
//! Grammar (after `[`; spaces are allowed between tokens, letters are
//! case-insensitive):
//!
//! ```text
//! expression = "[" value { binary_op value } "]"
//! value      = number | "[" … "]" | "#" parameter | ("+"|"-") value   (sign before a non-digit)
//!            | unary_fn "[" … "]" | "ATAN" "[" … "]" "/" "[" … "]" | "EXISTS" "[" "#<name>" "]"
//! parameter  = "<" name ">" | integer_value          (##1 and #[#2+1] are indirect)
//! ```
//!
//! Precedence, lowest first, every level left-associative (LinuxCNC's
//! `precedence()`): `AND OR XOR` < `EQ NE GT GE LT LE` < `+ -` < `* / MOD` <
//! `**`. Relational operators compare with LinuxCNC's `TOLERANCE_EQUAL` (1e-6);
//! trigonometry is in degrees; `ROUND` rounds half away from zero; `MOD` is
//! always non-negative for a positive divisor (LinuxCNC's `fmod` correction).
//!
//! Invariants: every node keeps its byte span in the line (errors point at the
//! sub-expression that failed); evaluation never yields NaN or infinity (an
//! error instead, as LinuxCNC's "Calculation resulted in 'not a number'").
use std::fmt;

/// LinuxCNC's `TOLERANCE_EQUAL`: two numbers closer than this are equal.
pub const TOLERANCE_EQUAL: f64 = 1e-6;

/// Unary functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnaryFn {
    Abs,
    Acos,
    Asin,
    Cos,
    Exp,
    Fix,
    Fup,
    Ln,
    Round,
    Sin,
    Sqrt,
    Tan,
}

impl UnaryFn {
    /// Its name as LinuxCNC spells it (upper case).
    pub fn name(self) -> &'static str {
        match self {
            UnaryFn::Abs => "ABS",
            UnaryFn::Acos => "ACOS",
            UnaryFn::Asin => "ASIN",
            UnaryFn::Cos => "COS",
            UnaryFn::Exp => "EXP",
            UnaryFn::Fix => "FIX",
            UnaryFn::Fup => "FUP",
            UnaryFn::Ln => "LN",
            UnaryFn::Round => "ROUND",
            UnaryFn::Sin => "SIN",
            UnaryFn::Sqrt => "SQRT",
            UnaryFn::Tan => "TAN",
        }
    }
}

/// Binary operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinaryOp {
    Power,
    Times,
    Divide,
    Modulo,
    Plus,
    Minus,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl BinaryOp {
    /// LinuxCNC's precedence (higher binds tighter).
    pub fn precedence(self) -> u8 {
        match self {
            BinaryOp::And | BinaryOp::Or | BinaryOp::Xor => 2,
            BinaryOp::Eq
            | BinaryOp::Ne
            | BinaryOp::Gt
            | BinaryOp::Ge
            | BinaryOp::Lt
            | BinaryOp::Le => 3,
            BinaryOp::Plus | BinaryOp::Minus => 4,
            BinaryOp::Times | BinaryOp::Divide | BinaryOp::Modulo => 5,
            BinaryOp::Power => 6,
        }
    }
}

/// A parameter reference: `#12`, `##1`, `#[#2+1]`, `#<name>`, `#<_global>`.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamRef {
    /// A numbered parameter; the number is itself a value (must round to an integer).
    Numbered(Box<Expr>),
    /// A named parameter: lower case, spaces removed (a leading `_` makes it global).
    Named(String),
}

/// An expression node with its byte span in the line.
#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub start: usize,
    pub end: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    Number(f64),
    Param(ParamRef),
    Negate(Box<Expr>),
    Unary(UnaryFn, Box<Expr>),
    /// `ATAN[y]/[x]`, degrees.
    Atan(Box<Expr>, Box<Expr>),
    /// `EXISTS[#<name>]`: 1 when the named parameter is defined.
    Exists(String),
    Binary(BinaryOp, Box<Expr>, Box<Expr>),
}

/// Why an evaluation failed (LinuxCNC's message text).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EvalErrorKind {
    #[error("Attempt to divide by zero")]
    DivideByZero,
    #[error("Attempt to raise negative to non-integer power")]
    NegativePower,
    #[error("Argument to acos out of range")]
    AcosRange,
    #[error("Argument to asin out of range")]
    AsinRange,
    #[error("Zero or negative argument to ln")]
    LnDomain,
    #[error("Negative argument to sqrt")]
    SqrtDomain,
    #[error("Calculation resulted in 'not a number'")]
    NotANumber,
    #[error("Calculation resulted in 'infinity'")]
    Infinity,
    #[error("Non-integer value for integer")]
    NonInteger,
    #[error("Parameter number out of range")]
    ParameterOutOfRange,
    #[error("Named parameter #<{0}> not defined")]
    UndefinedNamed(String),
    #[error("Parameter number {0} is read-only")]
    ReadOnly(i64),
    #[error("Named parameter #<{0}> is read-only")]
    ReadOnlyNamed(String),
}

/// An evaluation error and the byte span of the sub-expression that failed.
#[derive(Clone, Debug, PartialEq)]
pub struct EvalError {
    pub kind: EvalErrorKind,
    pub start: usize,
    pub end: usize,
}

impl fmt::Display for EvalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.kind.fmt(f)
    }
}

/// What an expression reads: parameters.
pub trait ParamSource {
    /// Numbered parameter `n` (already checked to be an integer); `Err` when
    /// out of range or not readable now.
    fn numbered(&self, n: i64) -> Result<f64, EvalErrorKind>;
    /// Named parameter (lower case, no spaces); `None` when not defined.
    fn named(&self, name: &str) -> Option<f64>;
}

/// LinuxCNC's `read_integer_value` rule: a value within 1e-4 of an integer is
/// that integer (and `x.9999…` above it rounds up).
pub fn to_integer(v: f64) -> Option<i64> {
    if !v.is_finite() || v.abs() > 2e9 {
        return None;
    }
    let floor = v.floor();
    if v - floor > 0.9999 {
        Some(v.ceil() as i64)
    } else if v - floor > 0.0001 {
        None
    } else {
        Some(floor as i64)
    }
}

impl Expr {
    /// Evaluate against `params`.
    pub fn eval(&self, params: &dyn ParamSource) -> Result<f64, EvalError> {
        let err = |kind| EvalError {
            kind,
            start: self.start,
            end: self.end,
        };
        let v = match &self.kind {
            ExprKind::Number(v) => *v,
            ExprKind::Param(ParamRef::Numbered(index)) => {
                let n = index.eval(params)?;
                let n = to_integer(n).ok_or_else(|| err(EvalErrorKind::NonInteger))?;
                params.numbered(n).map_err(err)?
            }
            ExprKind::Param(ParamRef::Named(name)) => params
                .named(name)
                .ok_or_else(|| err(EvalErrorKind::UndefinedNamed(name.clone())))?,
            ExprKind::Negate(a) => -a.eval(params)?,
            ExprKind::Exists(name) => f64::from(params.named(name).is_some() as u8),
            ExprKind::Atan(y, x) => {
                let (y, x) = (y.eval(params)?, x.eval(params)?);
                y.atan2(x).to_degrees()
            }
            ExprKind::Unary(f, a) => {
                let x = a.eval(params)?;
                match f {
                    UnaryFn::Abs => x.abs(),
                    UnaryFn::Acos => {
                        if !(-1.0..=1.0).contains(&x) {
                            return Err(err(EvalErrorKind::AcosRange));
                        }
                        x.acos().to_degrees()
                    }
                    UnaryFn::Asin => {
                        if !(-1.0..=1.0).contains(&x) {
                            return Err(err(EvalErrorKind::AsinRange));
                        }
                        x.asin().to_degrees()
                    }
                    UnaryFn::Cos => x.to_radians().cos(),
                    UnaryFn::Exp => x.exp(),
                    UnaryFn::Fix => x.floor(),
                    UnaryFn::Fup => x.ceil(),
                    UnaryFn::Ln => {
                        if x <= 0.0 {
                            return Err(err(EvalErrorKind::LnDomain));
                        }
                        x.ln()
                    }
                    // LinuxCNC: (double)(int)(x ± 0.5), i.e. half away from zero.
                    UnaryFn::Round => (x + if x < 0.0 { -0.5 } else { 0.5 }).trunc(),
                    UnaryFn::Sin => x.to_radians().sin(),
                    UnaryFn::Sqrt => {
                        if x < 0.0 {
                            return Err(err(EvalErrorKind::SqrtDomain));
                        }
                        x.sqrt()
                    }
                    UnaryFn::Tan => x.to_radians().tan(),
                }
            }
            ExprKind::Binary(op, a, b) => {
                let (l, r) = (a.eval(params)?, b.eval(params)?);
                let truth = |c: bool| f64::from(c as u8);
                match op {
                    BinaryOp::Divide => {
                        if r == 0.0 {
                            return Err(err(EvalErrorKind::DivideByZero));
                        }
                        l / r
                    }
                    BinaryOp::Modulo => {
                        let m = l % r;
                        if m < 0.0 { m + r.abs() } else { m }
                    }
                    BinaryOp::Power => {
                        if l < 0.0 && r.floor() != r {
                            return Err(err(EvalErrorKind::NegativePower));
                        }
                        l.powf(r)
                    }
                    BinaryOp::Times => l * r,
                    BinaryOp::Plus => l + r,
                    BinaryOp::Minus => l - r,
                    BinaryOp::And => truth(l != 0.0 && r != 0.0),
                    BinaryOp::Or => truth(l != 0.0 || r != 0.0),
                    BinaryOp::Xor => truth((l != 0.0) != (r != 0.0)),
                    BinaryOp::Eq => truth((l - r).abs() < TOLERANCE_EQUAL),
                    BinaryOp::Ne => truth((l - r).abs() >= TOLERANCE_EQUAL),
                    BinaryOp::Le => truth((l - r).abs() < TOLERANCE_EQUAL || l <= r),
                    BinaryOp::Ge => truth((l - r).abs() < TOLERANCE_EQUAL || l >= r),
                    BinaryOp::Lt => truth(l < r),
                    BinaryOp::Gt => truth(l > r),
                }
            }
        };
        if v.is_nan() {
            Err(err(EvalErrorKind::NotANumber))
        } else if v.is_infinite() {
            Err(err(EvalErrorKind::Infinity))
        } else {
            Ok(v)
        }
    }
}

// ---------------------------------------------------------------------------
// Parsing.

/// Why an expression could not be read (LinuxCNC's wording where it has one).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SyntaxErrorKind {
    #[error("Unclosed expression")]
    Unclosed,
    #[error("Unknown operation")]
    UnknownOperation,
    #[error("Unknown word where unary operation could be")]
    UnknownFunction,
    #[error("Left bracket missing after unary operation name")]
    BracketAfterFunction,
    #[error("Slash missing after first ATAN argument")]
    AtanSlash,
    #[error("Left bracket missing after slash with ATAN")]
    AtanBracket,
    #[error("No characters found in reading real value")]
    NoValue,
    #[error("Bad number format")]
    BadNumber,
    #[error("Named parameter not terminated")]
    NameNotTerminated,
    #[error("Expected #<name> in EXISTS")]
    ExistsArgument,
    /// volcomp's limit (LinuxCNC's 255-character lines hold about 120
    /// levels and answer "Command too long" beyond).
    #[error(
        "expression nested more than {MAX_NESTING} levels deep (brackets, functions, # references, signs)"
    )]
    TooDeep,
    /// volcomp's limit on one expression's size.
    #[error("expression of more than {MAX_TERMS} terms and operations")]
    TooLarge,
}

/// Deepest nesting of one value: `[`, a function, a `#` reference, a sign.
pub const MAX_NESTING: usize = 256;

/// Most terms and operations in one value (a line of LinuxCNC holds at most
/// about 128): bounds the depth of its tree, so that evaluating and dropping
/// it never exhausts the stack.
pub const MAX_TERMS: usize = 4096;

/// What parsing one value has used of [`MAX_NESTING`] and [`MAX_TERMS`].
#[derive(Default)]
struct Budget {
    depth: usize,
    terms: usize,
}

impl Budget {
    fn term(&mut self, at: usize) -> Result<(), SyntaxError> {
        self.terms += 1;
        if self.terms > MAX_TERMS {
            return Err(SyntaxError {
                kind: SyntaxErrorKind::TooLarge,
                at,
            });
        }
        Ok(())
    }
}

/// A syntax error at byte `at` of the line.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntaxError {
    pub kind: SyntaxErrorKind,
    pub at: usize,
}

fn skip_space(line: &[u8], mut p: usize) -> usize {
    while p < line.len() && matches!(line[p], b' ' | b'\t' | b'\r') {
        p += 1;
    }
    p
}

/// Case-insensitive match of `word` at `p`, spaces allowed between its letters
/// (LinuxCNC removes every space before reading). Returns the end.
fn keyword_at(line: &[u8], p: usize, word: &str) -> Option<usize> {
    let mut q = p;
    for (i, c) in word.bytes().enumerate() {
        if i > 0 {
            q = skip_space(line, q);
        }
        if q < line.len() && line[q].eq_ignore_ascii_case(&c) {
            q += 1;
        } else {
            return None;
        }
    }
    Some(q)
}

/// The unary function names, longest first where one is a prefix of another.
const FUNCTIONS: [(&str, UnaryFn); 12] = [
    ("ABS", UnaryFn::Abs),
    ("ACOS", UnaryFn::Acos),
    ("ASIN", UnaryFn::Asin),
    ("COS", UnaryFn::Cos),
    ("EXP", UnaryFn::Exp),
    ("FIX", UnaryFn::Fix),
    ("FUP", UnaryFn::Fup),
    ("LN", UnaryFn::Ln),
    ("ROUND", UnaryFn::Round),
    ("SIN", UnaryFn::Sin),
    ("SQRT", UnaryFn::Sqrt),
    ("TAN", UnaryFn::Tan),
];

/// Whether a value that is not a plain number starts at `p` (after spaces):
/// `[`, `#`, a sign before one of those or a letter, or a function name.
pub fn starts_computed_value(line: &[u8], p: usize) -> bool {
    let p = skip_space(line, p);
    match line.get(p) {
        Some(b'[' | b'#') => true,
        Some(b'+' | b'-') => {
            let q = skip_space(line, p + 1);
            matches!(line.get(q), Some(c) if *c == b'[' || *c == b'#' || c.is_ascii_alphabetic())
        }
        Some(c) if c.is_ascii_alphabetic() => function_at(line, p).is_some(),
        _ => false,
    }
}

/// A function name at `p` followed by `[` (after spaces): (function or ATAN/EXISTS, end of name).
fn function_at(line: &[u8], p: usize) -> Option<(FunctionName, usize)> {
    let followed = |end: usize| matches!(line.get(skip_space(line, end)), Some(b'['));
    for (name, f) in [
        ("ATAN", FunctionName::Atan),
        ("EXISTS", FunctionName::Exists),
    ] {
        if let Some(end) = keyword_at(line, p, name).filter(|&e| followed(e)) {
            return Some((f, end));
        }
    }
    for (name, f) in FUNCTIONS {
        if let Some(end) = keyword_at(line, p, name).filter(|&e| followed(e)) {
            return Some((FunctionName::Unary(f), end));
        }
    }
    None
}

#[derive(Clone, Copy)]
enum FunctionName {
    Unary(UnaryFn),
    Atan,
    Exists,
}

/// A plain number at `p`: `[+-] digits [. digits]` (spaces allowed inside,
/// LinuxCNC drops them). Returns value and end.
fn number_at(line: &[u8], p: usize) -> Result<(f64, usize), SyntaxError> {
    let mut q = skip_space(line, p);
    let mut text = String::new();
    if q < line.len() && (line[q] == b'+' || line[q] == b'-') {
        text.push(line[q] as char);
        q += 1;
    }
    let mut end = q;
    let mut digits = 0;
    loop {
        q = skip_space(line, q);
        match line.get(q) {
            Some(c) if c.is_ascii_digit() || *c == b'.' => {
                text.push(*c as char);
                digits += c.is_ascii_digit() as usize;
                q += 1;
                end = q;
            }
            _ => break,
        }
    }
    if digits == 0 {
        return Err(SyntaxError {
            kind: if end > p {
                SyntaxErrorKind::BadNumber
            } else {
                SyntaxErrorKind::NoValue
            },
            at: skip_space(line, p),
        });
    }
    let text = text.replace("-.", "-0.").replace("+.", "+0.");
    let text = if text.starts_with('.') {
        format!("0{text}")
    } else {
        text
    };
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok((v, end)),
        _ => Err(SyntaxError {
            kind: SyntaxErrorKind::BadNumber,
            at: skip_space(line, p),
        }),
    }
}

/// Read a real value (LinuxCNC's `read_real_value`) starting at `p`.
pub fn parse_value(line: &[u8], p: usize) -> Result<Expr, SyntaxError> {
    parse_value_in(line, p, &mut Budget::default())
}

fn parse_value_in(line: &[u8], p: usize, budget: &mut Budget) -> Result<Expr, SyntaxError> {
    let p = skip_space(line, p);
    if budget.depth >= MAX_NESTING {
        return Err(SyntaxError {
            kind: SyntaxErrorKind::TooDeep,
            at: p,
        });
    }
    budget.term(p)?;
    budget.depth += 1;
    let value = parse_value_at(line, p, budget);
    budget.depth -= 1;
    value
}

fn parse_value_at(line: &[u8], p: usize, budget: &mut Budget) -> Result<Expr, SyntaxError> {
    let Some(&c) = line.get(p) else {
        return Err(SyntaxError {
            kind: SyntaxErrorKind::NoValue,
            at: p,
        });
    };
    match c {
        b'[' => parse_bracketed(line, p, budget),
        b'#' => {
            let (r, end) = parse_param_ref_in(line, p, budget)?;
            Ok(Expr {
                kind: ExprKind::Param(r),
                start: p,
                end,
            })
        }
        b'+' | b'-' => {
            let q = skip_space(line, p + 1);
            let next = line.get(q).copied().unwrap_or(0);
            if next != 0 && !next.is_ascii_digit() && next != b'.' {
                let inner = parse_value_in(line, q, budget)?;
                let end = inner.end;
                if c == b'+' {
                    Ok(Expr { start: p, ..inner })
                } else {
                    Ok(Expr {
                        kind: ExprKind::Negate(Box::new(inner)),
                        start: p,
                        end,
                    })
                }
            } else {
                let (v, end) = number_at(line, p)?;
                Ok(Expr {
                    kind: ExprKind::Number(v),
                    start: p,
                    end,
                })
            }
        }
        c if c.is_ascii_alphabetic() => {
            let Some((f, name_end)) = function_at(line, p) else {
                let kind = if FUNCTIONS
                    .iter()
                    .map(|(n, _)| *n)
                    .chain(["ATAN", "EXISTS"])
                    .any(|n| keyword_at(line, p, n).is_some())
                {
                    SyntaxErrorKind::BracketAfterFunction
                } else {
                    SyntaxErrorKind::UnknownFunction
                };
                return Err(SyntaxError { kind, at: p });
            };
            let open = skip_space(line, name_end);
            match f {
                FunctionName::Unary(f) => {
                    let arg = parse_bracketed(line, open, budget)?;
                    let end = arg.end;
                    Ok(Expr {
                        kind: ExprKind::Unary(f, Box::new(arg)),
                        start: p,
                        end,
                    })
                }
                FunctionName::Atan => {
                    let y = parse_bracketed(line, open, budget)?;
                    let slash = skip_space(line, y.end);
                    if line.get(slash) != Some(&b'/') {
                        return Err(SyntaxError {
                            kind: SyntaxErrorKind::AtanSlash,
                            at: slash,
                        });
                    }
                    let open2 = skip_space(line, slash + 1);
                    if line.get(open2) != Some(&b'[') {
                        return Err(SyntaxError {
                            kind: SyntaxErrorKind::AtanBracket,
                            at: open2,
                        });
                    }
                    let x = parse_bracketed(line, open2, budget)?;
                    let end = x.end;
                    Ok(Expr {
                        kind: ExprKind::Atan(Box::new(y), Box::new(x)),
                        start: p,
                        end,
                    })
                }
                FunctionName::Exists => {
                    // EXISTS[#<name>]
                    let hash = skip_space(line, open + 1);
                    let bad = SyntaxError {
                        kind: SyntaxErrorKind::ExistsArgument,
                        at: hash,
                    };
                    if line.get(hash) != Some(&b'#') {
                        return Err(bad);
                    }
                    let lt = skip_space(line, hash + 1);
                    if line.get(lt) != Some(&b'<') {
                        return Err(bad);
                    }
                    let (name, after) = parse_name(line, lt)?;
                    let close = skip_space(line, after);
                    if line.get(close) != Some(&b']') {
                        return Err(SyntaxError {
                            kind: SyntaxErrorKind::Unclosed,
                            at: close,
                        });
                    }
                    Ok(Expr {
                        kind: ExprKind::Exists(name),
                        start: p,
                        end: close + 1,
                    })
                }
            }
        }
        _ => {
            let (v, end) = number_at(line, p)?;
            Ok(Expr {
                kind: ExprKind::Number(v),
                start: p,
                end,
            })
        }
    }
}

/// `<name>` at `p` (which holds `<`): the normalised name and the end.
pub fn parse_name(line: &[u8], p: usize) -> Result<(String, usize), SyntaxError> {
    let mut name = String::new();
    let mut q = p + 1;
    while q < line.len() {
        let c = line[q];
        if c == b'>' {
            return Ok((name, q + 1));
        }
        if !matches!(c, b' ' | b'\t' | b'\r') {
            name.push(c.to_ascii_lowercase() as char);
        }
        q += 1;
    }
    Err(SyntaxError {
        kind: SyntaxErrorKind::NameNotTerminated,
        at: p,
    })
}

/// `#…` at `p` (which holds `#`): the reference and its end.
pub fn parse_param_ref(line: &[u8], p: usize) -> Result<(ParamRef, usize), SyntaxError> {
    parse_param_ref_in(line, p, &mut Budget::default())
}

fn parse_param_ref_in(
    line: &[u8],
    p: usize,
    budget: &mut Budget,
) -> Result<(ParamRef, usize), SyntaxError> {
    let q = skip_space(line, p + 1);
    if line.get(q) == Some(&b'<') {
        let (name, end) = parse_name(line, q)?;
        return Ok((ParamRef::Named(name), end));
    }
    let index = parse_value_in(line, q, budget)?;
    let end = index.end;
    Ok((ParamRef::Numbered(Box::new(index)), end))
}

/// `[ … ]` at `p` (which holds `[`).
fn parse_bracketed(line: &[u8], p: usize, budget: &mut Budget) -> Result<Expr, SyntaxError> {
    if line.get(p) != Some(&b'[') {
        return Err(SyntaxError {
            kind: SyntaxErrorKind::BracketAfterFunction,
            at: p,
        });
    }
    // Operands and operators, reduced by precedence (left-associative).
    let mut values: Vec<Expr> = vec![parse_value_in(line, p + 1, budget)?];
    let mut ops: Vec<BinaryOp> = Vec::new();
    let mut q = values[0].end;
    loop {
        q = skip_space(line, q);
        let Some(&c) = line.get(q) else {
            return Err(SyntaxError {
                kind: SyntaxErrorKind::Unclosed,
                at: p,
            });
        };
        if c == b']' {
            while let Some(op) = ops.pop() {
                reduce(&mut values, op);
            }
            let mut e = values.pop().expect("one value left");
            // The brackets belong to the expression's span.
            e.start = p;
            e.end = q + 1;
            return Ok(e);
        }
        let (op, after) = operator_at(line, q)?;
        while ops
            .last()
            .is_some_and(|top| top.precedence() >= op.precedence())
        {
            let top = ops.pop().expect("checked");
            reduce(&mut values, top);
        }
        budget.term(q)?;
        ops.push(op);
        let v = parse_value_in(line, after, budget)?;
        q = v.end;
        values.push(v);
    }
}

fn reduce(values: &mut Vec<Expr>, op: BinaryOp) {
    let b = values.pop().expect("two operands");
    let a = values.pop().expect("two operands");
    let (start, end) = (a.start, b.end);
    values.push(Expr {
        kind: ExprKind::Binary(op, Box::new(a), Box::new(b)),
        start,
        end,
    });
}

fn operator_at(line: &[u8], q: usize) -> Result<(BinaryOp, usize), SyntaxError> {
    let c = line[q];
    let simple = match c {
        b'+' => Some(BinaryOp::Plus),
        b'-' => Some(BinaryOp::Minus),
        b'/' => Some(BinaryOp::Divide),
        b'*' => {
            let r = skip_space(line, q + 1);
            if line.get(r) == Some(&b'*') {
                return Ok((BinaryOp::Power, r + 1));
            }
            Some(BinaryOp::Times)
        }
        _ => None,
    };
    if let Some(op) = simple {
        return Ok((op, q + 1));
    }
    const NAMED: [(&str, BinaryOp); 10] = [
        ("AND", BinaryOp::And),
        ("MOD", BinaryOp::Modulo),
        ("OR", BinaryOp::Or),
        ("XOR", BinaryOp::Xor),
        ("EQ", BinaryOp::Eq),
        ("NE", BinaryOp::Ne),
        ("GE", BinaryOp::Ge),
        ("GT", BinaryOp::Gt),
        ("LE", BinaryOp::Le),
        ("LT", BinaryOp::Lt),
    ];
    for (name, op) in NAMED {
        if let Some(end) = keyword_at(line, q, name) {
            return Ok((op, end));
        }
    }
    Err(SyntaxError {
        kind: SyntaxErrorKind::UnknownOperation,
        at: q,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    struct Table(HashMap<i64, f64>, HashMap<String, f64>);
    impl ParamSource for Table {
        fn numbered(&self, n: i64) -> Result<f64, EvalErrorKind> {
            if (1..5602).contains(&n) {
                Ok(*self.0.get(&n).unwrap_or(&0.0))
            } else {
                Err(EvalErrorKind::ParameterOutOfRange)
            }
        }
        fn named(&self, name: &str) -> Option<f64> {
            self.1.get(name).copied()
        }
    }

    fn eval(text: &str) -> Result<f64, EvalErrorKind> {
        let mut t = Table(HashMap::new(), HashMap::new());
        t.0.insert(1, 3.0);
        t.0.insert(2, 1.0);
        t.0.insert(3, 7.5);
        t.1.insert("r".into(), 2.0);
        let e = parse_value(text.as_bytes(), 0).map_err(|e| panic!("{text}: {e:?}"))?;
        e.eval(&t).map_err(|e| e.kind)
    }

    #[test]
    fn precedence_and_associativity() {
        assert_eq!(eval("[1 + 2 * 3]"), Ok(7.0));
        assert_eq!(eval("[2 ** 3 ** 2]"), Ok(64.0)); // left-associative, as LinuxCNC
        assert_eq!(eval("[10 - 4 - 3]"), Ok(3.0));
        assert_eq!(eval("[1 + 1 EQ 2 AND 3 GT 2]"), Ok(1.0));
        assert_eq!(eval("[-7 MOD 3]"), Ok(2.0));
        assert_eq!(eval("[2*[1+2]]"), Ok(6.0));
    }

    #[test]
    fn parameters_and_functions() {
        assert_eq!(eval("#1"), Ok(3.0));
        assert_eq!(eval("##2"), Ok(3.0)); // #[#2] = #1
        assert_eq!(eval("#[#2 + 2]"), Ok(7.5));
        assert_eq!(eval("#<R>"), Ok(2.0));
        assert_eq!(eval("-#<r>"), Ok(-2.0));
        assert_eq!(eval("sin[30]").map(|v| (v * 1e12).round()), Ok(0.5e12));
        assert_eq!(eval("ATAN[1]/[1]"), Ok(45.0));
        assert_eq!(eval("round[-2.5]"), Ok(-3.0));
        assert_eq!(eval("fix[-2.5]"), Ok(-3.0));
        assert_eq!(eval("fup[2.1]"), Ok(3.0));
        assert_eq!(eval("EXISTS[#<r>]"), Ok(1.0));
        assert_eq!(eval("EXISTS[#<nope>]"), Ok(0.0));
        assert_eq!(eval("[1 / 0]"), Err(EvalErrorKind::DivideByZero));
        assert_eq!(eval("sqrt[-1]"), Err(EvalErrorKind::SqrtDomain));
        assert_eq!(
            eval("#<nope>"),
            Err(EvalErrorKind::UndefinedNamed("nope".into()))
        );
        assert_eq!(eval("#[1.5]"), Err(EvalErrorKind::NonInteger));
        assert_eq!(eval("[1.0000001 EQ 1]"), Ok(1.0));
    }

    #[test]
    fn syntax_errors_are_located() {
        let e = parse_value(b"[1 + 2", 0).unwrap_err();
        assert_eq!(e.kind, SyntaxErrorKind::Unclosed);
        let e = parse_value(b"[1 ? 2]", 0).unwrap_err();
        assert_eq!((e.kind, e.at), (SyntaxErrorKind::UnknownOperation, 3));
        let e = parse_value(b"foo[1]", 0).unwrap_err();
        assert_eq!(e.kind, SyntaxErrorKind::UnknownFunction);
    }
}
