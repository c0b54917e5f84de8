//! Why a fit failed: the error type shared by the adaptive loop (`smem`) and
//! the knot search strategies (`exhaustive`, `genetic`, `optimise`), in its own
//! file so that neither imports the other for it.

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("{positions} positions but {values} values")]
    LengthMismatch { positions: usize, values: usize },
    #[error("{samples} samples cannot be fitted with degree {degree} (at least {need} needed)")]
    TooFewSamples {
        samples: usize,
        degree: usize,
        need: usize,
    },
    #[error("sample {index}: {what} is not a finite number")]
    NotFinite { index: usize, what: &'static str },
    #[error("sample {index}: position {position} does not increase")]
    NotIncreasing { index: usize, position: f64 },
    #[error("invalid fit options: {0}")]
    Options(String),
    #[error(
        "the exhaustive search over C({candidates}, {choose}) = {count} knot sets exceeds the limit {limit}"
    )]
    TooManyCombinations {
        candidates: usize,
        choose: usize,
        count: u64,
        limit: u64,
    },
    #[error(
        "no feasible fit: every candidate knot vector left spans without data or made x(u) fold back"
    )]
    NoFeasibleFit,
}
