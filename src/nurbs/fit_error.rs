//! Why a fit failed: the error type shared by the adaptive loop (`smem`) and
//! the knot search strategies (`exhaustive`, `genetic`, `optimise`), in its own
//! file so that neither imports the other for it.

/// Why fitting a curve to an error table failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// The positions and values have different lengths.
    #[error("{positions} positions but {values} values")]
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of values.
        values: usize,
    },
    /// Fewer samples than a curve of this degree needs.
    #[error("{samples} samples cannot be fitted with degree {degree} (at least {need} needed)")]
    TooFewSamples {
        /// Number of samples given.
        samples: usize,
        /// Degree of the curve.
        degree: usize,
        /// Least number of samples for that degree.
        need: usize,
    },
    /// A position or value is NaN or infinite.
    #[error("sample {index}: {what} is not a finite number")]
    NotFinite {
        /// Index of the sample (0-based).
        index: usize,
        /// Which number: "position" or "value".
        what: &'static str,
    },
    /// Positions are not strictly increasing.
    #[error("sample {index}: position {position} does not increase")]
    NotIncreasing {
        /// Index of the sample (0-based).
        index: usize,
        /// Its position, not greater than the one before.
        position: f64,
    },
    /// The fit options are invalid (the message says which).
    #[error("invalid fit options: {0}")]
    Options(String),
    /// The exhaustive knot search would try more knot sets than its limit allows.
    #[error(
        "the exhaustive search over C({candidates}, {choose}) = {count} knot sets exceeds the limit {limit}"
    )]
    TooManyCombinations {
        /// Number of candidate knot positions.
        candidates: usize,
        /// Number of interior knots chosen from them.
        choose: usize,
        /// Number of knot sets, C(candidates, choose).
        count: u64,
        /// The limit on that number.
        limit: u64,
    },
    /// No candidate knot vector gave a usable curve (spans without data, or a curve whose position x(u) folds back).
    #[error(
        "no feasible fit: every candidate knot vector left spans without data or made x(u) fold back"
    )]
    NoFeasibleFit,
    /// The tolerance was not met within the search's work limit.
    #[error("{}", work_limit_message(*tolerance, *noise, *below_noise, *limit, *best))]
    WorkLimit {
        /// The tolerance asked for, table units (µm or µrad).
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
