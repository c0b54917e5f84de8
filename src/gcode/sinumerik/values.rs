//! SINUMERIK variables and expression values: `R` parameters, `DEF`
//! variables (types, arrays, initialisers) and the arithmetic functions
//! (Siemens, *Job planning*, "Flexible NC programming": "Variables",
//! "Definition of user variables (DEF)", "Arithmetic functions").
//!
//! Decisions: angles of `SIN COS TAN ASIN ACOS ATAN2` are degrees (as the
//! manual writes them); `INT` variables round on assignment; `BOOL` is 0 or
//! 1; `TRUNC` cuts towards zero and `ROUND` rounds half away from zero;
//! `STRING`, `AXIS` and `FRAME` variables are declared but not read in
//! arithmetic (a located error when a value is needed); a system variable
//! (`$…`) has the value the run gives it ([`SystemValues`]: `--sysvar`, or
//! the execution state where the program itself sets it), else it cannot be
//! known offline and is a located error.
use std::collections::HashMap;

use super::syntax::{BinOp, Expr};

/// How many `R` parameters there are (R0 … R999, the 840D sl default).
pub(crate) const R_COUNT: usize = 1000;

/// The declared type of a variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum VarType {
    Int,
    Real,
    Bool,
    Char,
    /// STRING, AXIS, FRAME: declared, not read in arithmetic.
    Other,
}

impl VarType {
    pub fn from_name(name: &str) -> Option<VarType> {
        Some(match name {
            "INT" => VarType::Int,
            "REAL" => VarType::Real,
            "BOOL" => VarType::Bool,
            "CHAR" => VarType::Char,
            "STRING" | "AXIS" | "FRAME" => VarType::Other,
            _ => return None,
        })
    }

    /// The value stored for `v`.
    pub fn store(self, v: f64) -> f64 {
        match self {
            VarType::Int | VarType::Char => round_half_away(v),
            VarType::Bool => f64::from(v != 0.0),
            VarType::Real | VarType::Other => v,
        }
    }
}

/// One variable: its type, dimensions (empty: a scalar) and values.
#[derive(Clone, Debug)]
pub(crate) struct Variable {
    pub ty: VarType,
    pub dims: Vec<usize>,
    pub values: Vec<f64>,
}

impl Variable {
    pub fn new(ty: VarType, dims: Vec<usize>) -> Variable {
        let n = dims.iter().product::<usize>().max(1);
        Variable {
            ty,
            dims,
            values: vec![0.0; n],
        }
    }

    /// The flat index of `index` (row-major), `None` out of range.
    pub fn flat(&self, index: &[f64]) -> Option<usize> {
        if index.len() != self.dims.len() {
            return None;
        }
        let mut k = 0usize;
        for (i, d) in index.iter().zip(&self.dims) {
            let i = round_half_away(*i);
            if !(0.0..*d as f64).contains(&i) {
                return None;
            }
            k = k * d + i as usize;
        }
        Some(k)
    }
}

/// The variables a block can see: the `R` parameters and the variables of
/// the running program level.
#[derive(Clone, Debug)]
pub(crate) struct Scope {
    pub vars: HashMap<String, Variable>,
}

/// Why an expression cannot be evaluated (message, byte range when known).
#[derive(Clone, Debug)]
pub(crate) struct EvalError {
    pub message: String,
    pub at: Option<std::ops::Range<usize>>,
    /// A system variable without a value (given none, not in the state).
    pub unknown_system: bool,
}

fn fail<T>(message: impl Into<String>, at: Option<std::ops::Range<usize>>) -> Result<T, EvalError> {
    Err(EvalError {
        message: message.into(),
        at,
        unknown_system: false,
    })
}

pub(crate) fn round_half_away(v: f64) -> f64 {
    v.round()
}

/// The value of a system variable: given its upper-cased name and the byte
/// range of its text (name and indices) in the line, the value, or the
/// message saying why it has none.
pub(crate) type SystemValues<'a> = &'a dyn Fn(&str, std::ops::Range<usize>) -> Result<f64, String>;

/// Evaluate `e` with the `R` parameters `r`, the variables `scope` and the
/// system variables `system`.
pub(crate) fn eval(
    e: &Expr,
    r: &[f64],
    scope: &Scope,
    system: SystemValues,
) -> Result<f64, EvalError> {
    let v = match e {
        Expr::Num(v) => *v,
        Expr::Str(_) => return fail("a string where a number is needed", None),
        Expr::R(i) => {
            let n = eval(i, r, scope, system)?;
            let k = round_half_away(n);
            if !(0.0..R_COUNT as f64).contains(&k) {
                return fail(format!("R{n} does not exist (R0 … R{})", R_COUNT - 1), None);
            }
            r[k as usize]
        }
        Expr::Var(name, index, at) => {
            let Some(var) = scope.vars.get(name) else {
                return fail(
                    format!(
                        "`{name}` is not defined (DEF it, or it is an address this statement does not take)"
                    ),
                    Some(at.clone()),
                );
            };
            if var.ty == VarType::Other {
                return fail(
                    format!("`{name}` is not a number (STRING, AXIS or FRAME)"),
                    Some(at.clone()),
                );
            }
            let mut idx = Vec::with_capacity(index.len());
            for i in index {
                idx.push(eval(i, r, scope, system)?);
            }
            match var.flat(&idx) {
                Some(k) => var.values[k],
                None => {
                    return fail(
                        format!("index of `{name}` out of its dimensions {:?}", var.dims),
                        Some(at.clone()),
                    );
                }
            }
        }
        Expr::System(name, at) => system(name, at.clone()).map_err(|message| EvalError {
            message,
            at: Some(at.clone()),
            unknown_system: true,
        })?,
        Expr::Neg(a) => -eval(a, r, scope, system)?,
        Expr::Not(a) => f64::from(eval(a, r, scope, system)? == 0.0),
        Expr::Bin(op, a, b) => {
            let (x, y) = (eval(a, r, scope, system)?, eval(b, r, scope, system)?);
            match op {
                BinOp::Add => x + y,
                BinOp::Sub => x - y,
                BinOp::Mul => x * y,
                BinOp::Div => {
                    if y == 0.0 {
                        return fail("division by zero", None);
                    }
                    x / y
                }
                BinOp::IntDiv => {
                    if y == 0.0 {
                        return fail("division by zero", None);
                    }
                    (x / y).trunc()
                }
                BinOp::Mod => {
                    if y == 0.0 {
                        return fail("MOD by zero", None);
                    }
                    x % y
                }
                BinOp::Eq => f64::from(x == y),
                BinOp::Ne => f64::from(x != y),
                BinOp::Lt => f64::from(x < y),
                BinOp::Gt => f64::from(x > y),
                BinOp::Le => f64::from(x <= y),
                BinOp::Ge => f64::from(x >= y),
                BinOp::And => f64::from(x != 0.0 && y != 0.0),
                BinOp::Or => f64::from(x != 0.0 || y != 0.0),
                BinOp::Xor => f64::from((x != 0.0) != (y != 0.0)),
                BinOp::Concat => return fail("`<<` joins strings (messages only)", None),
            }
        }
        Expr::Call(name, args, at) => {
            let mut v = Vec::with_capacity(args.len());
            for a in args {
                v.push(eval(a, r, scope, system)?);
            }
            function(name, &v).map_err(|m| EvalError {
                message: m,
                at: Some(at.clone()),
                unknown_system: false,
            })?
        }
    };
    if !v.is_finite() {
        return fail("the value is not finite", None);
    }
    Ok(v)
}

/// The arithmetic functions (*Job planning*, "Arithmetic functions").
fn function(name: &str, a: &[f64]) -> Result<f64, String> {
    let want = |n: usize| {
        if a.len() == n {
            Ok(())
        } else {
            Err(format!("{name} takes {n} argument(s), {} given", a.len()))
        }
    };
    let deg = |v: f64| v.to_radians();
    Ok(match name {
        "SIN" => {
            want(1)?;
            deg(a[0]).sin()
        }
        "COS" => {
            want(1)?;
            deg(a[0]).cos()
        }
        "TAN" => {
            want(1)?;
            deg(a[0]).tan()
        }
        "ASIN" | "ACOS" => {
            want(1)?;
            if !(-1.0..=1.0).contains(&a[0]) {
                return Err(format!("{name}({}) is outside [-1, 1]", a[0]));
            }
            if name == "ASIN" {
                a[0].asin().to_degrees()
            } else {
                a[0].acos().to_degrees()
            }
        }
        "ATAN2" => {
            want(2)?;
            a[0].atan2(a[1]).to_degrees()
        }
        "SQRT" => {
            want(1)?;
            if a[0] < 0.0 {
                return Err(format!("SQRT of a negative number ({})", a[0]));
            }
            a[0].sqrt()
        }
        "POT" => {
            want(1)?;
            a[0] * a[0]
        }
        "ABS" => {
            want(1)?;
            a[0].abs()
        }
        "TRUNC" => {
            want(1)?;
            a[0].trunc()
        }
        "ROUND" => {
            want(1)?;
            round_half_away(a[0])
        }
        "ROUNDUP" => {
            want(1)?;
            if a[0] >= 0.0 {
                a[0].ceil()
            } else {
                a[0].floor()
            }
        }
        "EXP" => {
            want(1)?;
            a[0].exp()
        }
        "LN" => {
            want(1)?;
            if a[0] <= 0.0 {
                return Err(format!("LN of a number ≤ 0 ({})", a[0]));
            }
            a[0].ln()
        }
        "MOD" => {
            want(2)?;
            if a[1] == 0.0 {
                return Err("MOD by zero".into());
            }
            a[0] % a[1]
        }
        "MINVAL" => {
            want(2)?;
            a[0].min(a[1])
        }
        "MAXVAL" => {
            want(2)?;
            a[0].max(a[1])
        }
        "BOUND" => {
            want(3)?;
            a[2].clamp(a[0].min(a[1]), a[0].max(a[1]))
        }
        _ => return Err(format!("`{name}` is not a function volcomp knows")),
    })
}
