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
    #[error("{}", work_limit_message(*tolerance, *noise, *below_noise, *limit, *best))]
    WorkLimit {
        tolerance: f64,
        /// The table's noise, estimated from the data.
        noise: f64,
        /// The tolerance is below half of it (the short default limit).
        below_noise: bool,
        /// The limit, samples × control points summed over the fits.
        limit: u64,
        /// The least Emax and its control points, over the counts searched
        /// completely.
        best: Option<(f64, usize)>,
    },
}

fn work_limit_message(
    tolerance: f64,
    noise: f64,
    below_noise: bool,
    limit: u64,
    best: Option<(f64, usize)>,
) -> String {
    format!(
        "the tolerance {tolerance} was not met within the search's work limit ({limit:.1e} samples \
× control points of least-squares fits){}{}; raise the tolerance, fix --control-points with a \
cheaper --method (ukm, epm, lam), or use --select cv",
        match best {
            Some((emax, count)) => {
                format!(": the least Emax was {emax:.4} with {count} control points")
            }
            None => String::new(),
        },
        if below_noise {
            format!(
                " (the tolerance is below half the table's noise, {noise:.4} estimated from the \
data: only a curve through the noise would meet it)"
            )
        } else {
            String::new()
        }
    )
}
