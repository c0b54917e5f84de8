//! The catalogue of unmodelled effects (effects.md "The catalogue"): names,
//! parameters, the displacement `Δ(ctx)` each adds to the cut surface, and the
//! signature columns `n·∂Δ/∂θ` that the diagnosis fits.
//!
//! Invariants: every effect is linear in its parameters except `thermal_drift`,
//! which is linear in `dx, dy, dz` for a fixed `tau` (its last parameter);
//! displacements are µm in part coordinates; parameter order is the order of
//! [`EffectKind::parameters`].
use crate::axes::Axis;
use crate::kinematics::ParameterLayout;
use crate::toolpath::PointContext;
use crate::toolpath::context::{LOCATION_PARAMETERS, SQUARENESS_PARAMETERS};

/// The `rotary_location` parameters of each pair of rotary letters (the offsets
/// and tilts of kinematics.md, named by the machine's own axes).
const LOCATION_AB: [&str; 8] = ParameterLayout::new([Axis::A, Axis::B]).location_effect_names();
const LOCATION_BC: [&str; 8] = ParameterLayout::new([Axis::B, Axis::C]).location_effect_names();
use crate::vec3::{dot, scale};
use serde::{Deserialize, Serialize};

/// The effects of the catalogue.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// `thermal_drift`: a machine-frame drift `(dx, dy, dz)` µm approached as
    /// `1 − exp(−t/tau)`, `tau` in minutes.
    ThermalDrift,
    /// `backlash`: half of `(bx, by, bz)` µm, signed by each axis's last
    /// direction of travel (machine frame).
    Backlash,
    /// `servo_lag`: `k·v²·κ` along the path's principal normal, `k` in s².
    ServoLag,
    /// `tool_deflection`: `c` µm along the part normal's component across the
    /// tool axis.
    ToolDeflection,
    /// `tool_wear`: `w` µm per metre of cut, along the part normal.
    ToolWear,
    /// `radius_offset`: `r` µm along the part normal.
    RadiusOffset,
    /// `setup_error`: the part displaced by `(tx, ty, tz)` µm and turned by
    /// `(rx, ry, rz)` µrad (part coordinates).
    SetupError,
    /// `squareness`: the linear axes out of square, `s_xy, s_xz, s_yz` µrad.
    Squareness,
    /// `rotary_location`: offsets (µm) and tilts (µrad) of the rotary axes'
    /// lines (named by the machine's rotary letters).
    RotaryLocation,
}

/// Why an effect given as text (`backlash:bx=6,by=0,bz=3`) was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EffectError {
    /// The name is not in the catalogue.
    #[error("unknown effect `{name}` (valid effects: {valid})")]
    UnknownEffect {
        /// The name given.
        name: String,
        /// The catalogue's names, comma-separated.
        valid: String,
    },
    /// A parameter name is not one of the effect's.
    #[error("effect `{effect}` has no parameter `{parameter}` (valid parameters: {valid})")]
    UnknownParameter {
        /// The effect's name.
        effect: String,
        /// The parameter name given.
        parameter: String,
        /// The effect's parameter names, comma-separated.
        valid: String,
    },
    /// A parameter is not `name=value` with a finite number.
    #[error("effect `{effect}`: `{text}` is not `name=value` with a finite number")]
    BadValue {
        /// The effect's name.
        effect: String,
        /// The text given for the parameter.
        text: String,
    },
    /// A parameter is given twice.
    #[error("effect `{effect}`: parameter `{parameter}` is given twice")]
    Duplicate {
        /// The effect's name.
        effect: String,
        /// The repeated parameter.
        parameter: String,
    },
    /// `thermal_drift` whose `tau` is missing or not positive.
    #[error("effect `thermal_drift`: `tau` must be given and positive (minutes), found {tau}")]
    BadTau {
        /// The `tau` found (minutes).
        tau: f64,
    },
}

impl EffectKind {
    /// Every effect of the catalogue, in catalogue order.
    pub const ALL: [EffectKind; 9] = [
        EffectKind::ThermalDrift,
        EffectKind::Backlash,
        EffectKind::ServoLag,
        EffectKind::ToolDeflection,
        EffectKind::ToolWear,
        EffectKind::RadiusOffset,
        EffectKind::SetupError,
        EffectKind::Squareness,
        EffectKind::RotaryLocation,
    ];

    /// The effect's name in the CLI, the reports and effects.md (`thermal_drift`).
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::ThermalDrift => "thermal_drift",
            EffectKind::Backlash => "backlash",
            EffectKind::ServoLag => "servo_lag",
            EffectKind::ToolDeflection => "tool_deflection",
            EffectKind::ToolWear => "tool_wear",
            EffectKind::RadiusOffset => "radius_offset",
            EffectKind::SetupError => "setup_error",
            EffectKind::Squareness => "squareness",
            EffectKind::RotaryLocation => "rotary_location",
        }
    }

    /// The effect named `name` (as [`EffectKind::name`] spells it), if any.
    pub fn from_name(name: &str) -> Option<EffectKind> {
        EffectKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// All parameter names on an A/C machine; for `thermal_drift` the nonlinear
    /// `tau` comes last.
    pub fn parameters(self) -> &'static [&'static str] {
        self.parameters_for([Axis::A, Axis::C])
    }

    /// All parameter names on a machine whose rotary letters are `rotary` (letter
    /// order): `rotary_location` names its own axes (`EX0B …` on a B/C machine).
    pub fn parameters_for(self, rotary: [Axis; 2]) -> &'static [&'static str] {
        match self {
            EffectKind::RotaryLocation => match rotary {
                [Axis::A, Axis::B] => &LOCATION_AB,
                [Axis::B, Axis::C] => &LOCATION_BC,
                _ => &LOCATION_PARAMETERS,
            },
            other => other.parameters_common(),
        }
    }

    fn parameters_common(self) -> &'static [&'static str] {
        match self {
            EffectKind::ThermalDrift => &["dx", "dy", "dz", "tau"],
            EffectKind::Backlash => &["bx", "by", "bz"],
            EffectKind::ServoLag => &["k"],
            EffectKind::ToolDeflection => &["c"],
            EffectKind::ToolWear => &["w"],
            EffectKind::RadiusOffset => &["r"],
            EffectKind::SetupError => &["tx", "ty", "tz", "rx", "ry", "rz"],
            EffectKind::Squareness => &SQUARENESS_PARAMETERS,
            EffectKind::RotaryLocation => &LOCATION_PARAMETERS,
        }
    }

    /// Units of each parameter (same order as [`EffectKind::parameters`]).
    pub fn units(self) -> &'static [&'static str] {
        match self {
            EffectKind::ThermalDrift => &["µm", "µm", "µm", "min"],
            EffectKind::Backlash => &["µm", "µm", "µm"],
            EffectKind::ServoLag => &["s²"],
            EffectKind::ToolDeflection => &["µm"],
            EffectKind::ToolWear => &["µm/m"],
            EffectKind::RadiusOffset => &["µm"],
            EffectKind::SetupError => &["µm", "µm", "µm", "µrad", "µrad", "µrad"],
            EffectKind::Squareness => &["µrad", "µrad", "µrad"],
            EffectKind::RotaryLocation => &["µm", "µm", "µrad", "µrad", "µm", "µm", "µrad", "µrad"],
        }
    }

    /// Number of parameters the effect is linear in (all but `tau`).
    pub fn linear_count(self) -> usize {
        match self {
            EffectKind::ThermalDrift => 3,
            k => k.parameters().len(),
        }
    }

    /// Does the effect have a nonlinear parameter (`tau`)?
    pub fn is_nonlinear(self) -> bool {
        self == EffectKind::ThermalDrift
    }

    /// Does the effect displace a probe on the machine as it displaced the tool?
    /// Thermal drift, backlash and the machine's geometry do (at the probe's
    /// time, approach and pose), and a set-up error moves the part for both;
    /// servo lag (no curvature at probing speed), tool deflection (no cutting
    /// force), wear and radius offset (a calibrated stylus) do not: they stay
    /// in the cut surface (docs/diagnose.md "Follow-up").
    pub fn acts_on_probe(self) -> bool {
        matches!(
            self,
            EffectKind::ThermalDrift
                | EffectKind::Backlash
                | EffectKind::SetupError
                | EffectKind::Squareness
                | EffectKind::RotaryLocation
        )
    }

    /// Displacement (µm, part coordinates) per unit of each linear parameter at
    /// `ctx`; `tau` (min) is used by `thermal_drift` only. Appends
    /// [`EffectKind::linear_count`] vectors to `out`.
    pub fn basis(self, ctx: &PointContext, tau: f64, out: &mut Vec<[f64; 3]>) {
        let unit = |k: usize| {
            let mut e = [0.0; 3];
            e[k] = 1.0;
            e
        };
        match self {
            EffectKind::ThermalDrift => {
                let f = 1.0 - (-ctx.time_min / tau).exp();
                for k in 0..3 {
                    out.push(scale(ctx.machine_to_part(unit(k)), f));
                }
            }
            EffectKind::Backlash => {
                for k in 0..3 {
                    out.push(scale(ctx.machine_to_part(unit(k)), ctx.sigma[k] / 2.0));
                }
            }
            EffectKind::ServoLag => {
                let mm = ctx.speed_mm_s * ctx.speed_mm_s * ctx.curvature_per_mm;
                out.push(scale(
                    ctx.machine_to_part(ctx.principal_normal),
                    mm * 1000.0,
                ));
            }
            EffectKind::ToolDeflection => {
                let (n, u) = (ctx.normal, ctx.tool_axis);
                let nu = dot(n, u);
                out.push([n[0] - nu * u[0], n[1] - nu * u[1], n[2] - nu * u[2]]);
            }
            EffectKind::ToolWear => out.push(scale(ctx.normal, ctx.cut_length_m)),
            EffectKind::RadiusOffset => out.push(ctx.normal),
            EffectKind::SetupError => {
                let p = ctx.point;
                for k in 0..3 {
                    out.push(unit(k));
                }
                // ω_k e_k × p, ω in µrad and p in mm: × 1e-3 to µm.
                out.push([0.0, -p[2] * 1e-3, p[1] * 1e-3]);
                out.push([p[2] * 1e-3, 0.0, -p[0] * 1e-3]);
                out.push([-p[1] * 1e-3, p[0] * 1e-3, 0.0]);
            }
            EffectKind::Squareness => out.extend_from_slice(&ctx.squareness_jacobian),
            EffectKind::RotaryLocation => out.extend_from_slice(&ctx.location_jacobian),
        }
    }

    /// Signature row at `ctx`: `n·∂Δ/∂θ_j` for the linear parameters (appended to `out`).
    pub fn signature(self, ctx: &PointContext, tau: f64, out: &mut Vec<f64>) {
        let mut basis = Vec::with_capacity(8);
        self.basis(ctx, tau, &mut basis);
        out.extend(basis.iter().map(|b| dot(ctx.normal, *b)));
    }
}

/// An effect with parameter values (in the order of [`EffectKind::parameters`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Effect {
    /// Which effect.
    pub kind: EffectKind,
    /// Its parameter values (units as in [`EffectKind`]; `tau` last for `thermal_drift`).
    pub values: Vec<f64>,
}

impl Effect {
    /// An effect with every parameter 0 (and `tau` = 1 min for `thermal_drift`).
    pub fn zero(kind: EffectKind) -> Effect {
        let mut values = vec![0.0; kind.parameters().len()];
        if kind.is_nonlinear() {
            values[3] = 1.0;
        }
        Effect { kind, values }
    }

    /// Build from named values; unnamed parameters are 0 (`tau` must be given).
    pub fn from_pairs(kind: EffectKind, pairs: &[(&str, f64)]) -> Result<Effect, EffectError> {
        Effect::from_pairs_for(kind, pairs, [Axis::A, Axis::C])
    }

    /// [`Effect::from_pairs`] with the parameter names of a machine whose rotary
    /// letters are `rotary`.
    pub fn from_pairs_for(
        kind: EffectKind,
        pairs: &[(&str, f64)],
        rotary: [Axis; 2],
    ) -> Result<Effect, EffectError> {
        let names = kind.parameters_for(rotary);
        let mut values = vec![0.0; names.len()];
        let mut given = vec![false; values.len()];
        for (name, value) in pairs {
            let Some(i) = names.iter().position(|p| p == name) else {
                return Err(EffectError::UnknownParameter {
                    effect: kind.name().into(),
                    parameter: name.to_string(),
                    valid: names.join(", "),
                });
            };
            if given[i] {
                return Err(EffectError::Duplicate {
                    effect: kind.name().into(),
                    parameter: name.to_string(),
                });
            }
            if !value.is_finite() {
                return Err(EffectError::BadValue {
                    effect: kind.name().into(),
                    text: format!("{name}={value}"),
                });
            }
            given[i] = true;
            values[i] = *value;
        }
        if kind.is_nonlinear() && values[3] <= 0.0 {
            return Err(EffectError::BadTau { tau: values[3] });
        }
        Ok(Effect { kind, values })
    }

    /// Parse `name` or `name:k=v,k=v` (effects.md), e.g. `backlash:bx=6,by=0,bz=3`,
    /// with an A/C machine's names.
    pub fn parse(spec: &str) -> Result<Effect, EffectError> {
        Effect::parse_for(spec, [Axis::A, Axis::C])
    }

    /// [`Effect::parse`] with the names of a machine whose rotary letters are
    /// `rotary` (`rotary_location:EX0B=3` on a B/C machine).
    pub fn parse_for(spec: &str, rotary: [Axis; 2]) -> Result<Effect, EffectError> {
        let (name, rest) = match spec.split_once(':') {
            Some((n, r)) => (n.trim(), r.trim()),
            None => (spec.trim(), ""),
        };
        let kind = EffectKind::from_name(name).ok_or_else(|| EffectError::UnknownEffect {
            name: name.to_string(),
            valid: EffectKind::ALL.map(EffectKind::name).join(", "),
        })?;
        let mut pairs = Vec::new();
        for item in rest.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let bad = || EffectError::BadValue {
                effect: name.to_string(),
                text: item.to_string(),
            };
            let (k, v) = item.split_once('=').ok_or_else(bad)?;
            let v: f64 = v.trim().parse().map_err(|_| bad())?;
            pairs.push((k.trim(), v));
        }
        Effect::from_pairs_for(kind, &pairs, rotary)
    }

    /// `tau` of `thermal_drift` (unused otherwise).
    pub fn tau(&self) -> f64 {
        if self.kind.is_nonlinear() {
            self.values[3]
        } else {
            1.0
        }
    }

    /// Displacement Δ (µm, part coordinates) at `ctx`.
    pub fn displacement(&self, ctx: &PointContext) -> [f64; 3] {
        let mut basis = Vec::with_capacity(8);
        self.kind.basis(ctx, self.tau(), &mut basis);
        let mut d = [0.0; 3];
        for (b, v) in basis.iter().zip(&self.values) {
            for k in 0..3 {
                d[k] += b[k] * v;
            }
        }
        d
    }

    /// Change of the measured deviation, `n·Δ` (µm).
    pub fn deviation_um(&self, ctx: &PointContext) -> f64 {
        dot(ctx.normal, self.displacement(ctx))
    }

    /// `name:k=v,...` (the CLI form, A/C names; parses back to the same effect).
    pub fn to_spec(&self) -> String {
        self.to_spec_for([Axis::A, Axis::C])
    }

    /// [`Effect::to_spec`] with the names of a machine whose rotary letters are
    /// `rotary`.
    pub fn to_spec_for(&self, rotary: [Axis; 2]) -> String {
        let pairs: Vec<String> = self
            .kind
            .parameters_for(rotary)
            .iter()
            .zip(&self.values)
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        format!("{}:{}", self.kind.name(), pairs.join(","))
    }
}
