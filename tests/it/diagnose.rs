//! The sim-to-real gap engine: effect catalogue, simulate, noise floor and the
//! blind diagnosis on synthetic contexts (a saddle raster, diagnose::synthetic).
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::sync::OnceLock;
use std::time::Instant;
use volcomp::diagnose::synthetic::{SyntheticOptions, SyntheticPart, random_effect, saddle_raster};
use volcomp::diagnose::{
    DiagnoseOptions, DiagnoseReport, Effect, EffectError, EffectKind, SimulateOptions, diagnose,
    simulate,
};
use volcomp::toolpath::PointContext;

fn part() -> &'static SyntheticPart {
    static PART: OnceLock<SyntheticPart> = OnceLock::new();
    PART.get_or_init(|| saddle_raster(&SyntheticOptions::default()))
}

fn run(effects: &[Effect], noise_um: f64, seed: u64) -> DiagnoseReport {
    let p = part();
    let m = simulate(
        &p.contexts,
        &p.truth_um,
        effects,
        &SimulateOptions { noise_um, seed },
    )
    .unwrap();
    diagnose(&p.contexts, &m.deviations_um(), &DiagnoseOptions::default()).unwrap()
}

#[test]
fn effect_specs_parse_and_reject_with_the_valid_names() {
    let e = Effect::parse("backlash:bx=6,by=0,bz=3").unwrap();
    assert_eq!(e.kind, EffectKind::Backlash);
    assert_eq!(e.values, vec![6.0, 0.0, 3.0]);
    assert_eq!(Effect::parse(&e.to_spec()).unwrap(), e);
    let t = Effect::parse("thermal_drift:dz=5,tau=12").unwrap();
    assert_eq!(t.values, vec![0.0, 0.0, 5.0, 12.0]);
    let msg = Effect::parse("backlask:bx=1").unwrap_err().to_string();
    assert!(
        msg.contains("backlask")
            && msg.contains("thermal_drift")
            && msg.contains("rotary_location"),
        "{msg}"
    );
    let msg = Effect::parse("backlash:bq=1").unwrap_err().to_string();
    assert!(msg.contains("bq") && msg.contains("bx, by, bz"), "{msg}");
    assert!(matches!(
        Effect::parse("backlash:bx"),
        Err(EffectError::BadValue { .. })
    ));
    assert!(matches!(
        Effect::parse("backlash:bx=1,bx=2"),
        Err(EffectError::Duplicate { .. })
    ));
    assert!(matches!(
        Effect::parse("thermal_drift:dx=1"),
        Err(EffectError::BadTau { .. })
    ));
    assert!(matches!(
        Effect::parse("radius_offset:r=inf"),
        Err(EffectError::BadValue { .. })
    ));
    let r = Effect::parse("rotary_location:EY0A=3,EB0C=20").unwrap();
    assert_eq!(r.values[0], 3.0);
    assert_eq!(r.values[7], 20.0);
}

fn context() -> PointContext {
    part().contexts[57].clone()
}

#[test]
fn displacements_follow_the_catalogue() {
    let ctx = context();
    let n = ctx.normal;
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let eff = |s: &str| Effect::parse(s).unwrap();
    approx::assert_abs_diff_eq!(
        eff("radius_offset:r=2.5").deviation_um(&ctx),
        2.5,
        epsilon = 1e-12
    );
    approx::assert_abs_diff_eq!(
        eff("tool_wear:w=4").deviation_um(&ctx),
        4.0 * ctx.cut_length_m,
        epsilon = 1e-12
    );
    let nu = dot(n, ctx.tool_axis);
    approx::assert_abs_diff_eq!(
        eff("tool_deflection:c=3").deviation_um(&ctx),
        3.0 * (1.0 - nu * nu),
        epsilon = 1e-12
    );
    let b = eff("backlash:bx=6,by=2,bz=4").displacement(&ctx);
    let expect = ctx.machine_to_part([ctx.sigma[0] * 3.0, ctx.sigma[1], ctx.sigma[2] * 2.0]);
    for k in 0..3 {
        approx::assert_abs_diff_eq!(b[k], expect[k], epsilon = 1e-12);
    }
    let t = eff("thermal_drift:dx=1,dy=2,dz=3,tau=2").displacement(&ctx);
    let f = 1.0 - (-ctx.time_min / 2.0).exp();
    let expect = ctx.machine_to_part([f, 2.0 * f, 3.0 * f]);
    for k in 0..3 {
        approx::assert_abs_diff_eq!(t[k], expect[k], epsilon = 1e-12);
    }
    let s = eff("servo_lag:k=0.002").displacement(&ctx);
    let mm = 0.002 * ctx.speed_mm_s.powi(2) * ctx.curvature_per_mm * 1000.0;
    let expect = ctx.machine_to_part(ctx.principal_normal.map(|v| v * mm));
    for k in 0..3 {
        approx::assert_abs_diff_eq!(s[k], expect[k], epsilon = 1e-12);
    }
    // setup_error: t + ω × p with ω in µrad and p in mm (× 1e-3 → µm).
    let p = ctx.point;
    let d = eff("setup_error:tx=1,ty=2,tz=3,rx=100,ry=-50,rz=20").displacement(&ctx);
    let w = [100.0, -50.0, 20.0];
    let wxp = [
        w[1] * p[2] - w[2] * p[1],
        w[2] * p[0] - w[0] * p[2],
        w[0] * p[1] - w[1] * p[0],
    ];
    let expect = [
        1.0 + wxp[0] * 1e-3,
        2.0 + wxp[1] * 1e-3,
        3.0 + wxp[2] * 1e-3,
    ];
    for k in 0..3 {
        approx::assert_abs_diff_eq!(d[k], expect[k], epsilon = 1e-12);
    }
    // squareness / rotary_location: the context Jacobians.
    let q = eff("squareness:s_xz=10").displacement(&ctx);
    for k in 0..3 {
        approx::assert_abs_diff_eq!(q[k], 10.0 * ctx.squareness_jacobian[1][k], epsilon = 1e-12);
    }
    let l = eff("rotary_location:EX0C=2,EA0C=30").displacement(&ctx);
    for k in 0..3 {
        let e = 2.0 * ctx.location_jacobian[4][k] + 30.0 * ctx.location_jacobian[6][k];
        approx::assert_abs_diff_eq!(l[k], e, epsilon = 1e-12);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Every effect is linear in its linear parameters (tau fixed): the
    /// deviation is the signature row dotted with the parameters.
    #[test]
    fn deviation_is_signature_times_parameters(kind in 0usize..9, point in 0usize..300, seed in 0u64..1000) {
        let kind = EffectKind::ALL[kind];
        let ctx = &part().contexts[point];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let effect = random_effect(kind, &part().contexts, (1.0, 5.0), &mut rng);
        let mut row = Vec::new();
        kind.signature(ctx, effect.tau(), &mut row);
        let lin: f64 = row.iter().zip(&effect.values).map(|(a, b)| a * b).sum();
        prop_assert!((lin - effect.deviation_um(ctx)).abs() < 1e-9);
    }
}

#[test]
fn simulate_moves_points_by_truth_effects_and_noise() {
    let p = part();
    let none = simulate(
        &p.contexts,
        &p.truth_um,
        &[],
        &SimulateOptions {
            noise_um: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    let bl = Effect::parse("backlash:bx=6,by=1,bz=3").unwrap();
    let with = simulate(
        &p.contexts,
        &p.truth_um,
        std::slice::from_ref(&bl),
        &SimulateOptions {
            noise_um: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    for (i, ctx) in p.contexts.iter().enumerate() {
        let e = p.truth_um[i];
        let ne: f64 = (0..3).map(|k| e[k] * ctx.normal[k]).sum();
        approx::assert_abs_diff_eq!(none.points[i].deviation_um(), ne, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(
            with.points[i].deviation_um() - none.points[i].deviation_um(),
            bl.deviation_um(ctx),
            epsilon = 1e-9
        );
        // The tangential part of e moves the point too (m = p + e/1000).
        for k in 0..3 {
            approx::assert_abs_diff_eq!(
                none.points[i].measured[k],
                ctx.point[k] + e[k] / 1000.0,
                epsilon = 1e-12
            );
        }
    }
    let noisy = |seed| {
        let options = SimulateOptions {
            noise_um: 0.3,
            seed,
        };
        simulate(&p.contexts, &p.truth_um, &[], &options).unwrap()
    };
    let (a, b, c) = (noisy(5), noisy(5), noisy(6));
    assert_eq!(a, b, "seeded");
    assert_ne!(a, c);
    let noise: Vec<f64> = a
        .deviations_um()
        .iter()
        .zip(none.deviations_um())
        .map(|(x, y)| x - y)
        .collect();
    let sd = (noise.iter().map(|v| v * v).sum::<f64>() / noise.len() as f64).sqrt();
    assert!((sd - 0.3).abs() < 0.05, "noise sd {sd}");
    assert!(
        simulate(
            &p.contexts,
            &p.truth_um[1..],
            &[],
            &SimulateOptions::default()
        )
        .is_err()
    );
    assert!(
        simulate(
            &p.contexts,
            &p.truth_um,
            &[],
            &SimulateOptions {
                noise_um: -1.0,
                seed: 1
            }
        )
        .is_err()
    );
}

#[test]
fn noise_floor_is_estimated_from_the_data() {
    // With and without large systematic effects, the estimate is the probe noise.
    for (effects, sigma) in [
        (vec![], 0.3),
        (vec![Effect::parse("backlash:bx=8,by=3,bz=5").unwrap()], 0.3),
        (
            vec![Effect::parse("thermal_drift:dx=5,dy=-3,dz=6,tau=2").unwrap()],
            0.5,
        ),
        (
            vec![Effect::parse("setup_error:tx=3,rx=80,ry=-60,rz=40").unwrap()],
            0.2,
        ),
    ] {
        let r = run(&effects, sigma, 11);
        let est = r.gap.noise_floor_um;
        assert!(
            (est / sigma - 1.0).abs() < 0.2,
            "estimated {est} for σ = {sigma} with {effects:?}"
        );
        assert_eq!(r.gap.noise_floor_source, "estimated");
    }
    // Given noise is used as is.
    let p = part();
    let m = simulate(&p.contexts, &p.truth_um, &[], &SimulateOptions::default()).unwrap();
    let opts = DiagnoseOptions {
        noise_um: Some(0.25),
        ..DiagnoseOptions::default()
    };
    let r = diagnose(&p.contexts, &m.deviations_um(), &opts).unwrap();
    assert_eq!(r.gap.noise_floor_um, 0.25);
    assert_eq!(r.gap.noise_floor_source, "given");
}

fn check_blind(kind: EffectKind, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed * 31 + kind as u64);
    let effect = random_effect(kind, &part().contexts, (2.0, 6.0), &mut rng);
    let r = run(std::slice::from_ref(&effect), 0.3, 100 + seed);
    assert_eq!(
        r.selected.first().map(String::as_str),
        Some(kind.name()),
        "{effect:?}: {:?}\n{:?}",
        r.selection_notes,
        r.effects
            .iter()
            .map(|e| (&e.name, e.heldout_rms_after_um))
            .collect::<Vec<_>>()
    );
    assert_eq!(r.effects[0].name, kind.name());
    let ratio = r.after.heldout_rms_um / r.gap.noise_floor_um;
    assert!(
        ratio < 1.5,
        "{effect:?}: held-out after {} vs floor {}",
        r.after.heldout_rms_um,
        r.gap.noise_floor_um
    );
    assert_eq!(r.effects.len(), EffectKind::ALL.len());
    assert!(r.effects[0].shrink_pct > 50.0);
}

#[test]
fn blind_single_effects_are_found() {
    for kind in EffectKind::ALL {
        for seed in 0..2 {
            check_blind(kind, seed);
        }
    }
}

#[test]
fn blind_no_effect_selects_nothing() {
    for seed in 0..3 {
        let r = run(&[], 0.3, 200 + seed);
        assert!(r.selected.is_empty(), "{:?}", r.selection_notes);
        assert!(r.summary[0].contains("no unmodelled effect"));
        assert_eq!(r.after.residual_rms_um, r.gap.residual_rms_um);
    }
}

#[test]
fn blind_two_effects_are_both_found() {
    let pairs = [
        (
            "backlash:bx=6,by=2,bz=4",
            "thermal_drift:dx=3,dy=-2,dz=-5,tau=2",
        ),
        ("servo_lag:k=0.002", "radius_offset:r=-3"),
        ("tool_deflection:c=4", "squareness:s_xy=60,s_xz=-40,s_yz=30"),
    ];
    for (a, b) in pairs {
        let effects = [Effect::parse(a).unwrap(), Effect::parse(b).unwrap()];
        let r = run(&effects, 0.3, 9);
        let mut got = r.selected.clone();
        got.sort();
        let mut want: Vec<String> = effects.iter().map(|e| e.kind.name().to_string()).collect();
        want.sort();
        assert_eq!(got, want, "{:?}", r.selection_notes);
        assert!(r.after.heldout_rms_um < 1.5 * r.gap.noise_floor_um);
    }
}

#[test]
fn report_has_the_contract_fields() {
    let r = run(&[Effect::parse("backlash:bx=6,by=0,bz=3").unwrap()], 0.3, 3);
    let json = serde_json::to_value(&r).unwrap();
    for key in [
        "points",
        "points_used",
        "gap",
        "localization",
        "effects",
        "selected",
        "after",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
    for key in [
        "measured_profile_um",
        "predicted_profile_um",
        "residual_rms_um",
        "noise_floor_um",
    ] {
        assert!(json["gap"][key].is_number(), "{key}");
    }
    for key in ["worst_points", "worst_blocks", "by_time", "by_region"] {
        assert!(json["localization"][key].is_array(), "{key}");
    }
    assert!(r.localization.worst_points.len() >= 10);
    let e = &json["effects"][0];
    for key in [
        "name",
        "params",
        "heldout_rms_before_um",
        "heldout_rms_after_um",
        "shrink_pct",
        "aliases",
    ] {
        assert!(e.get(key).is_some(), "{key}");
    }
    assert!(json["after"]["predicted_profile_um"].is_number());
    assert!(json["after"]["residual_rms_um"].is_number());
    // Parameters recovered to within a few standard errors / 10 %.
    let bl = &r.effects[0];
    assert_eq!(bl.name, "backlash");
    assert!((bl.params["bx"] - 6.0).abs() < 0.6, "{:?}", bl.params);
    assert!((bl.params["bz"] - 3.0).abs() < 0.6, "{:?}", bl.params);
    assert!(
        r.summary[0].contains("Backlash") && r.summary[0].contains("on X"),
        "{}",
        r.summary[0]
    );
    // worst points are ordered by |residual|.
    let res: std::collections::HashMap<_, _> = r
        .residuals
        .iter()
        .map(|p| (p.id.clone(), p.residual_um.abs()))
        .collect();
    let w = &r.localization.worst_points;
    assert!(w.windows(2).all(|p| res[&p[0]] >= res[&p[1]]));
    // The direction split shows the backlash: mean residual differs by σ_x.
    let dir = |s: &str| {
        r.localization
            .by_direction
            .iter()
            .find(|d| d.axis == "x" && d.sign == s)
            .unwrap()
            .mean_um
    };
    let effect = Effect::parse("backlash:bx=6,by=0,bz=3").unwrap();
    let expect = |sign: f64| {
        let v: Vec<f64> = part()
            .contexts
            .iter()
            .filter(|c| c.sigma[0] == sign)
            .map(|c| effect.deviation_um(c))
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (got, want) = (dir("+") - dir("-"), expect(1.0) - expect(-1.0));
    assert!((got - want).abs() < 0.3, "{got} vs {want}");
    let html = volcomp::diagnose::render_html(&r);
    assert!(
        html.starts_with("<!DOCTYPE html>") && html.contains("<svg") && html.contains("backlash")
    );
    assert!(!html.contains("NaN"));
}

#[test]
fn aliases_are_reported_for_indistinguishable_effects() {
    // On a part whose tool axis is fixed, tool_deflection is a function of the
    // normal only; a radius offset is a constant along n. Build contexts where
    // n·u is constant: then tool_deflection ≡ (1 − (n·u)²)·c is a constant too.
    let mut contexts = part().contexts.clone();
    for c in &mut contexts {
        c.tool_axis = c.normal;
        // tilt by a fixed angle around a perpendicular: n·u = cos 20°
        let n = c.normal;
        let t = if n[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let d: f64 = (0..3).map(|k| t[k] * n[k]).sum();
        let mut p = [t[0] - d * n[0], t[1] - d * n[1], t[2] - d * n[2]];
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        p = p.map(|v| v / l);
        let (s, co) = 20f64.to_radians().sin_cos();
        c.tool_axis = [0, 1, 2].map(|k| co * n[k] + s * p[k]);
    }
    let truth = part().truth_um.clone();
    let m = simulate(
        &contexts,
        &truth,
        &[Effect::parse("radius_offset:r=4").unwrap()],
        &SimulateOptions::default(),
    )
    .unwrap();
    let r = diagnose(&contexts, &m.deviations_um(), &DiagnoseOptions::default()).unwrap();
    let ro = r
        .effects
        .iter()
        .find(|e| e.name == "radius_offset")
        .unwrap();
    assert!(
        ro.aliases.contains(&"tool_deflection".to_string()),
        "{:?}",
        ro.aliases
    );
    assert!(
        r.summary.iter().any(|s| s.contains("cannot be told apart")),
        "{:?}",
        r.summary
    );
}

#[test]
fn bad_inputs_are_typed_errors() {
    let p = part();
    assert!(diagnose(&p.contexts, &[1.0], &DiagnoseOptions::default()).is_err());
    let mut m = vec![0.0; p.contexts.len()];
    m[3] = f64::NAN;
    let e = diagnose(&p.contexts, &m, &DiagnoseOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains(&p.contexts[3].id) && e.contains("finite"), "{e}");
    let opts = DiagnoseOptions {
        noise_um: Some(0.0),
        ..DiagnoseOptions::default()
    };
    assert!(diagnose(&p.contexts, &vec![0.0; p.contexts.len()], &opts).is_err());
    let mut uncut = p.contexts.clone();
    uncut.iter_mut().for_each(|c| c.cut = false);
    assert!(diagnose(&uncut, &vec![0.0; uncut.len()], &DiagnoseOptions::default()).is_err());
}

#[test]
fn uncut_points_are_left_out() {
    let p = part();
    let mut contexts = p.contexts.clone();
    contexts[0].cut = false;
    contexts[1].cut = false;
    let m = simulate(&contexts, &p.truth_um, &[], &SimulateOptions::default()).unwrap();
    let r = diagnose(&contexts, &m.deviations_um(), &DiagnoseOptions::default()).unwrap();
    assert_eq!(r.points, contexts.len());
    assert_eq!(r.points_used, contexts.len() - 2);
}

#[test]
fn diagnosis_of_372_points_takes_well_under_two_seconds() {
    let p = saddle_raster(&SyntheticOptions {
        rows: 16,
        plan_spacing_mm: 4.0,
        ..SyntheticOptions::default()
    });
    let n = p.contexts.len();
    assert!((360..=385).contains(&n), "{n} points");
    let m = simulate(
        &p.contexts,
        &p.truth_um,
        &[Effect::parse("backlash:bx=6").unwrap()],
        &SimulateOptions::default(),
    )
    .unwrap();
    let d = m.deviations_um();
    let start = Instant::now();
    let r = diagnose(&p.contexts, &d, &DiagnoseOptions::default()).unwrap();
    let secs = start.elapsed().as_secs_f64();
    assert_eq!(r.selected, vec!["backlash".to_string()]);
    assert!(secs < 2.0, "{secs} s for {n} points");
}

/// The blind cases of an independent implementation (tests/data/blind), with the
/// contexts our toolpath layer builds for them (tests/data/diagnose/*-contexts.json,
/// written by `volcomp diagnose … --dump-contexts` on ref-trt; regenerate them when
/// the toolpath or the SMEM fit changes).
struct BlindCase {
    name: &'static str,
    contexts: Vec<PointContext>,
    measured_um: Vec<f64>,
    expected_predicted_um: Vec<f64>,
    truth: Vec<Effect>,
}

fn blind_case(name: &'static str) -> BlindCase {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let contexts: Vec<PointContext> = serde_json::from_str(
        &std::fs::read_to_string(root.join(format!("diagnose/{name}-contexts.json"))).unwrap(),
    )
    .unwrap();
    let dir = root.join("blind").join(name);
    let m = volcomp::inspection::Measurement::read(&dir.join("measured.csv")).unwrap();
    let expected: std::collections::HashMap<String, f64> =
        std::fs::read_to_string(dir.join("expected_predicted.csv"))
            .unwrap()
            .lines()
            .skip(1)
            .filter_map(|l| l.split_once(','))
            .map(|(id, v)| (id.to_string(), v.parse().unwrap()))
            .collect();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let truth = truth["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            let kind = EffectKind::from_name(e["name"].as_str().unwrap()).unwrap();
            let pairs: Vec<(&str, f64)> = e["params"]
                .as_object()
                .unwrap()
                .iter()
                .map(|(k, v)| (k.as_str(), v.as_f64().unwrap()))
                .collect();
            Effect::from_pairs(kind, &pairs).unwrap()
        })
        .collect();
    assert_eq!(contexts.len(), m.points.len());
    for (c, p) in contexts.iter().zip(&m.points) {
        assert_eq!(c.id, p.plan.id);
    }
    BlindCase {
        name,
        expected_predicted_um: contexts.iter().map(|c| expected[&c.id]).collect(),
        measured_um: m.deviations_um(),
        contexts,
        truth,
    }
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = v.collect();
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
fn blind_cases_of_the_reference_implementation() {
    for name in ["01-backlash", "02-thermal_drift", "03-none"] {
        let case = blind_case(name);
        assert!(
            case.contexts.iter().all(|c| c.cut),
            "{name}: every plan point is cut"
        );
        // Our prediction (fitted tables) vs the reference's true-function prediction.
        let pred_diff = rms(case
            .contexts
            .iter()
            .zip(&case.expected_predicted_um)
            .map(|(c, e)| c.predicted_um - e));
        // Our effect formulas vs the reference's: measured − expected − Σ n·Δ is the noise.
        let leftover = rms((0..case.contexts.len()).map(|i| {
            let c = &case.contexts[i];
            case.measured_um[i]
                - case.expected_predicted_um[i]
                - case.truth.iter().map(|e| e.deviation_um(c)).sum::<f64>()
        }));
        println!(
            "{name}: prediction vs expected_predicted RMS {pred_diff:.3} µm; measured − expected − effects RMS {leftover:.3} µm (noise 0.3)"
        );
        assert!(pred_diff < 0.6, "{name}: {pred_diff}");
        assert!(
            leftover < 0.36,
            "{name}: effect formulas disagree with the reference ({leftover} µm)"
        );
        let r = diagnose(
            &case.contexts,
            &case.measured_um,
            &DiagnoseOptions::default(),
        )
        .unwrap();
        let want: Vec<String> = case
            .truth
            .iter()
            .map(|e| e.kind.name().to_string())
            .collect();
        assert_eq!(r.selected, want, "{}: {:?}", case.name, r.selection_notes);
        if !want.is_empty() {
            assert_eq!(r.effects[0].name, want[0]);
            assert!(r.effects[0].shrink_pct > 80.0);
        }
    }
}

/// The bundled saddle (samples/saddle.nc, samples/saddle-plan.csv) on ref-trt:
/// the contexts our toolpath layer builds and a noise-free simulate of them
/// (the machine's own volumetric error), fixtures in tests/data/diagnose.
fn saddle() -> &'static SyntheticPart {
    static PART: OnceLock<SyntheticPart> = OnceLock::new();
    PART.get_or_init(|| {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/diagnose");
        let json = std::fs::read_to_string(root.join("saddle-contexts.json")).unwrap();
        let truth = volcomp::inspection::Measurement::read(&root.join("saddle-truth.csv")).unwrap();
        volcomp::diagnose::synthetic::from_fixture(&json, &truth).unwrap()
    })
}

fn run_saddle(effects: &[Effect], seed: u64) -> DiagnoseReport {
    let p = saddle();
    let m = simulate(
        &p.contexts,
        &p.truth_um,
        effects,
        &SimulateOptions {
            noise_um: 0.3,
            seed,
        },
    )
    .unwrap();
    diagnose(&p.contexts, &m.deviations_um(), &DiagnoseOptions::default()).unwrap()
}

#[test]
fn saddle_blind_single_effects_none_and_pairs() {
    assert_eq!(saddle().contexts.len(), 372);
    for kind in EffectKind::ALL {
        for seed in 0..2 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed * 17 + kind as u64);
            let effect = random_effect(kind, &saddle().contexts, (2.0, 6.0), &mut rng);
            let r = run_saddle(std::slice::from_ref(&effect), 300 + seed);
            assert_eq!(
                r.selected.first().map(String::as_str),
                Some(kind.name()),
                "{effect:?}: {:?}",
                r.selection_notes
            );
            assert_eq!(r.effects[0].name, kind.name());
            // The model is right here: it is never blamed.
            assert!(!r.model_check.mismatch, "{effect:?}: {:?}", r.model_check);
            let ratio = r.after.heldout_rms_um / r.gap.noise_floor_um;
            // servo_lag: one plan point of the saddle has κ = 21.8 /mm (the next
            // largest 1.3 /mm); held out, it cannot be predicted from the others,
            // so the held-out RMS is dominated by it (docs/diagnose.md).
            if kind != EffectKind::ServoLag {
                assert!(
                    ratio < 1.5,
                    "{effect:?}: held-out after {} vs floor {}",
                    r.after.heldout_rms_um,
                    r.gap.noise_floor_um
                );
            } else {
                assert!(r.after.residual_rms_um < 1.5 * r.gap.noise_floor_um);
            }
        }
    }
    for seed in 0..2 {
        let r = run_saddle(&[], 400 + seed);
        assert!(r.selected.is_empty(), "{:?}", r.selection_notes);
        assert!(!r.model_check.mismatch, "{:?}", r.model_check);
    }
    for (a, b) in [
        (
            "backlash:bx=6,by=2,bz=4",
            "thermal_drift:dx=3,dy=-2,dz=-5,tau=2",
        ),
        (
            "backlash:bx=-4,by=3,bz=5",
            "setup_error:tx=2,ty=-3,tz=1,rx=60,ry=-40,rz=50",
        ),
        ("tool_wear:w=0.8", "backlash:bx=3,by=5,bz=2"),
    ] {
        let effects = [Effect::parse(a).unwrap(), Effect::parse(b).unwrap()];
        let r = run_saddle(&effects, 9);
        let mut got = r.selected.clone();
        got.sort();
        let mut want: Vec<String> = effects.iter().map(|e| e.kind.name().to_string()).collect();
        want.sort();
        assert_eq!(got, want, "{:?}", r.selection_notes);
    }
}

mod cli {
    use std::path::{Path, PathBuf};

    use crate::support::volcomp;

    fn data(p: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
    }

    /// ref-trt without its error tables (nominal, with its squareness and
    /// location values): no SMEM fit, so the end-to-end run stays fast.
    fn nominal_machine(dir: &Path) -> PathBuf {
        let text = std::fs::read_to_string(data("machines/ref-trt.toml")).unwrap();
        let mut out = String::new();
        let mut skip = false;
        for line in text.lines() {
            if line.starts_with('[') {
                skip = line.trim() == "[errors]";
            }
            if !skip {
                out.push_str(line);
                out.push('\n');
            }
        }
        let path = dir.join("ref-trt-nominal.toml");
        std::fs::write(&path, out).unwrap();
        path
    }

    /// Run `volcomp COMMAND FILES... ARGS...`.
    fn command(cmd: &str, files: &[&Path], args: &[&str]) -> std::process::Output {
        volcomp().arg(cmd).args(files).args(args).output().unwrap()
    }

    fn ok(out: &std::process::Output) -> String {
        crate::support::assert_success(out);
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    /// The diagnosis selection draws a bar (percentage and time left) only
    /// on a terminal (issue 37 item 4): with the bar's delay at 0 ms,
    /// `diagnose` piped writes no bar and no escape codes; the same run on
    /// a pseudo-terminal (`script`, when the system has it) draws the
    /// selection's bar.
    #[test]
    fn the_selection_shows_progress_only_on_a_terminal() {
        let dir = tempfile::tempdir().unwrap();
        let machine = nominal_machine(dir.path());
        let program = data("samples/saddle.nc");
        let plan = data("samples/saddle-plan.csv");
        let measured = dir.path().join("meas.csv");
        let args = [
            "--effect",
            "backlash:bx=15,by=12,bz=8",
            "--seed",
            "5",
            "-o",
            measured.to_str().unwrap(),
        ];
        ok(&command("simulate", &[&machine, &program, &plan], &args));
        let report = dir.path().join("diag.json");
        let out = volcomp()
            .env("VOLCOMP_PROGRESS_AFTER_MS", "0")
            .arg("diagnose")
            .args([&machine, &program, &measured])
            .arg("--report")
            .arg(&report)
            .output()
            .unwrap();
        ok(&out);
        for text in [&out.stdout, &out.stderr] {
            let text = String::from_utf8_lossy(text);
            assert!(!text.contains("% ["), "a bar when piped: {text}");
            assert!(!text.contains('\u{1b}'), "escape codes when piped: {text}");
        }
        if Path::new("/usr/bin/script").exists() {
            let command = format!(
                "{} diagnose {} {} {} --report {}",
                env!("CARGO_BIN_EXE_volcomp"),
                machine.display(),
                program.display(),
                measured.display(),
                report.display()
            );
            let tty = std::process::Command::new("/usr/bin/script")
                .env("VOLCOMP_PROGRESS_AFTER_MS", "0")
                .env("VOLCOMP_MODEL_CACHE", crate::support::model_cache())
                .args(["-qec", &command, "/dev/null"])
                .output()
                .unwrap();
            let shown = String::from_utf8_lossy(&tty.stdout);
            assert!(
                shown.contains("diagnosing (selection)") && shown.contains("% ["),
                "no selection bar on a terminal: {shown}"
            );
        }
    }

    /// A part cut on a machine whose tables are 1.5 × ref-trt's, diagnosed with
    /// ref-trt's model: the model is named, no effect is selected.
    #[test]
    fn a_machine_with_other_errors_is_diagnosed_as_a_model_mismatch() {
        let dir = tempfile::tempdir().unwrap();
        let tables = dir.path().join("ref-trt");
        std::fs::create_dir(&tables).unwrap();
        for axis in ["x", "y", "z", "a", "c"] {
            let text =
                std::fs::read_to_string(data(&format!("machines/ref-trt/{axis}.csv"))).unwrap();
            let scaled: Vec<String> = text
                .lines()
                .map(|line| {
                    let fields: Vec<&str> = line.split(',').collect();
                    if fields[0].parse::<f64>().is_err() {
                        return line.to_string();
                    }
                    std::iter::once(fields[0].to_string())
                        .chain(
                            fields[1..]
                                .iter()
                                .map(|v| format!("{:.4}", 1.5 * v.parse::<f64>().unwrap())),
                        )
                        .collect::<Vec<_>>()
                        .join(",")
                })
                .collect();
            std::fs::write(tables.join(format!("{axis}.csv")), scaled.join("\n") + "\n").unwrap();
        }
        let other = dir.path().join("other.toml");
        std::fs::copy(data("machines/ref-trt.toml"), &other).unwrap();
        let program = data("samples/saddle.nc");
        let plan = data("samples/saddle-plan.csv");
        let measured = dir.path().join("meas.csv");
        let args = ["--seed", "3", "-o", measured.to_str().unwrap()];
        ok(&command("simulate", &[&other, &program, &plan], &args));
        let report = dir.path().join("diag.json");
        let followup = dir.path().join("followup.nc");
        let stdout = ok(&command(
            "diagnose",
            &[&data("machines/ref-trt.toml"), &program, &measured],
            &[
                "--report",
                report.to_str().unwrap(),
                "--followup-program",
                followup.to_str().unwrap(),
            ],
        ));
        assert!(stdout.contains("selected: none"), "{stdout}");
        // Issue 26: a wrong model never ends in "no follow-up is needed".
        assert!(!stdout.contains("No follow-up is needed"), "{stdout}");
        // Issue 36: after the verdict a follow-up tells the model's factors
        // from the effect that explains most alone (re-probes in other poses:
        // a table error changes with the pose as the tables say).
        assert!(stdout.contains("To tell model factors from"), "{stdout}");
        assert!(followup.exists() && followup.with_extension("csv").exists());
        assert!(
            stdout.contains("The error model itself does not match this machine"),
            "{stdout}"
        );
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let design = &v["followup_design"];
        let expected = design["expected_separation_sigma"].as_f64().unwrap();
        println!(
            "follow-up after the verdict: {} vs {}: {expected:.1} σ expected",
            design["selected"], design["rivals"]
        );
        assert!(expected > 3.0, "{design}");
        let factors = v["model_check"]["factors"].as_object().unwrap();
        // Measured: X ×1.48, Y ×1.47, Z ×1.63, A ×1.14, C ×1.41 (truth 1.5).
        for axis in ["X", "Y", "Z", "C"] {
            let b = factors[axis].as_f64().unwrap();
            assert!((b - 0.5).abs() < 0.2, "{axis}: {b}");
        }
    }

    #[test]
    fn simulate_then_diagnose_end_to_end() {
        let dir = tempfile::tempdir().unwrap();
        let machine = nominal_machine(dir.path());
        let program = data("tests/data/blind/01-backlash/program.nc");
        let plan = data("tests/data/blind/01-backlash/plan.csv");
        let measured = dir.path().join("meas.csv");
        let effect = ["--effect", "backlash:bx=6,by=0,bz=3", "--seed", "4", "-o"];
        let mut args: Vec<&str> = effect.to_vec();
        args.push(measured.to_str().unwrap());
        let stdout = ok(&command("simulate", &[&machine, &program, &plan], &args));
        assert!(
            stdout.contains("372 points (372 cut") && stdout.contains("backlash"),
            "{stdout}"
        );
        let report = dir.path().join("diag.json");
        let html = dir.path().join("diag.html");
        let args = [
            "--report",
            report.to_str().unwrap(),
            "--html",
            html.to_str().unwrap(),
        ];
        let stdout = ok(&command(
            "diagnose",
            &[&machine, &program, &measured],
            &args,
        ));
        assert!(
            stdout.contains("selected: backlash") && stdout.contains("Backlash of about"),
            "{stdout}"
        );
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        assert_eq!(json["selected"][0], "backlash");
        assert_eq!(json["points_used"], 372);
        let bx = json["effects"][0]["params"]["bx"].as_f64().unwrap();
        assert!((bx - 6.0).abs() < 0.6, "bx = {bx}");
        let page = std::fs::read_to_string(&html).unwrap();
        assert!(page.contains("<svg") && page.contains("Residual"));
    }

    /// The follow-up loop through the command line: the design writes a
    /// probing program our reader accepts and its plan; the simulated
    /// follow-up, fitted with the measurement, keeps the right effect and
    /// reports the separation achieved.
    #[test]
    fn a_followup_is_designed_simulated_and_combined() {
        let dir = tempfile::tempdir().unwrap();
        let machine = nominal_machine(dir.path());
        let program = data("samples/saddle.nc");
        let plan = data("samples/saddle-plan.csv");
        let measured = dir.path().join("meas.csv");
        let followup = dir.path().join("followup.nc");
        let followup_plan = dir.path().join("followup.csv");
        let effect = "thermal_drift:dx=3,dy=-4,dz=5,tau=20";
        let sim = |plan: &Path, out: &Path, extra: &[&str]| {
            let mut args = vec![
                "--effect",
                effect,
                "--seed",
                "3",
                "-o",
                out.to_str().unwrap(),
            ];
            args.extend_from_slice(extra);
            ok(&command("simulate", &[&machine, &program, plan], &args))
        };
        sim(&plan, &measured, &[]);
        let report = dir.path().join("diag.json");
        let html = dir.path().join("diag.html");
        let stdout = ok(&command(
            "diagnose",
            &[&machine, &program, &measured],
            &[
                "--report",
                report.to_str().unwrap(),
                "--followup-program",
                followup.to_str().unwrap(),
                "--html",
                html.to_str().unwrap(),
            ],
        ));
        let page = std::fs::read_to_string(&html).unwrap();
        assert!(page.contains("Follow-up design") && page.contains("F12"));
        assert!(stdout.contains("selected: thermal_drift"), "{stdout}");
        assert!(stdout.contains("To tell thermal_drift from"), "{stdout}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let design = &json["followup_design"];
        assert_eq!(design["probes"].as_array().unwrap().len(), 12);
        assert!(
            design["expected_separation_sigma"].as_f64().unwrap() > 3.0,
            "{design}"
        );
        let rows = std::fs::read_to_string(&followup_plan).unwrap();
        assert!(rows.starts_with("id,x,y,z,i,j,k,a,c,t_min\n"), "{rows}");
        assert_eq!(rows.lines().count(), 13);
        let text = std::fs::read_to_string(&followup).unwrap();
        assert_eq!(text.matches("G38.2 ").count(), 12, "{text}");
        ok(&command("check", &[&followup], &[]));

        let measured2 = dir.path().join("meas2.csv");
        let stdout = sim(
            &plan,
            &measured2,
            &["--followup", followup_plan.to_str().unwrap()],
        );
        assert!(stdout.contains("simulated 12 follow-up probes"), "{stdout}");
        let report2 = dir.path().join("diag2.json");
        let stdout = ok(&command(
            "diagnose",
            &[&machine, &program, &measured],
            &[
                "--report",
                report2.to_str().unwrap(),
                "--followup",
                measured2.to_str().unwrap(),
            ],
        ));
        assert!(stdout.contains("selected: thermal_drift"), "{stdout}");
        assert!(stdout.contains("Follow-up (12 probes"), "{stdout}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report2).unwrap()).unwrap();
        for s in json["followup"]["separations"].as_array().unwrap() {
            let (achieved, expected) = (
                s["achieved_sigma"].as_f64().unwrap(),
                s["if_selected_sigma"].as_f64().unwrap(),
            );
            assert!(achieved > 3.0, "{s}");
            assert!((achieved - expected).abs() < 1.5 + 0.2 * expected, "{s}");
        }

        // A plan file as the program name, and a probe of a point the
        // measurement does not have, are refused; nothing is written.
        let out = command(
            "diagnose",
            &[&machine, &program, &measured],
            &[
                "--report",
                report.to_str().unwrap(),
                "--followup-program",
                followup_plan.to_str().unwrap(),
            ],
        );
        assert_eq!(out.status.code(), Some(2));
        let stranger = dir.path().join("stranger.csv");
        let mut lines: Vec<String> = std::fs::read_to_string(&measured2)
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        let mut fields: Vec<String> = lines[1].split(',').map(String::from).collect();
        // The plan point and the probed point moved together (a probe of
        // another point, not a reading far off its point).
        for k in [1, 10] {
            fields[k] = format!("{}", fields[k].parse::<f64>().unwrap() + 7.0);
        }
        lines[1] = fields.join(",");
        std::fs::write(&stranger, lines.join("\n") + "\n").unwrap();
        let report3 = dir.path().join("diag3.json");
        let out = command(
            "diagnose",
            &[&machine, &program, &measured],
            &[
                "--report",
                report3.to_str().unwrap(),
                "--followup",
                stranger.to_str().unwrap(),
            ],
        );
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("stranger.csv") && err.contains("probe F01"),
            "{err}"
        );
        assert!(!report3.exists());
    }

    #[test]
    fn bad_effects_are_usage_errors_and_bad_files_input_errors() {
        let dir = tempfile::tempdir().unwrap();
        let machine = nominal_machine(dir.path());
        let program = data("tests/data/blind/01-backlash/program.nc");
        let plan = data("tests/data/blind/01-backlash/plan.csv");
        let args = ["-o", "/dev/null", "--effect", "backlash:bq=1"];
        let out = command("simulate", &[&machine, &program, &plan], &args);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("bq") && err.contains("bx, by, bz"), "{err}");
        let missing = dir.path().join("missing.csv");
        let report = dir.path().join("r.json");
        let out = command(
            "diagnose",
            &[&machine, &program, &missing],
            &["--report", report.to_str().unwrap()],
        );
        assert_eq!(out.status.code(), Some(1));
        assert!(String::from_utf8_lossy(&out.stderr).contains("missing.csv"));
        assert!(!report.exists(), "nothing written on bad input");
    }

    /// Issue 36 "Show": a stale-table run and a clean run, each diagnosed
    /// with `--write-machine`. The part is cut on ref-trt (noise 0.3 µm, no
    /// effect); the clean run diagnoses it with ref-trt's own file, the stale
    /// run with a file whose Y table is stale (its values in reverse order
    /// of position). Neither gives advice within 2 σ of zero, and the
    /// written file changes nothing the advice does not name: the clean run
    /// names nothing, the stale one blames the model, so both files are
    /// their input with a comment block, and no table is copied.
    #[test]
    fn a_stale_table_run_and_a_clean_run_write_nothing_they_do_not_advise() {
        let dir = tempfile::tempdir().unwrap();
        let stale_dir = dir.path().join("stale");
        std::fs::create_dir_all(stale_dir.join("ref-trt")).unwrap();
        for axis in ["x", "y", "z", "a", "c"] {
            let text =
                std::fs::read_to_string(data(&format!("machines/ref-trt/{axis}.csv"))).unwrap();
            let out = if axis == "y" {
                let lines: Vec<&str> = text.lines().collect();
                let (header, rows) = lines.split_first().unwrap();
                let split = |l: &str| -> (String, String) {
                    let (position, values) = l.split_once(',').unwrap();
                    (position.to_string(), values.to_string())
                };
                let rows: Vec<(String, String)> = rows.iter().map(|l| split(l)).collect();
                let mut out = vec![header.to_string()];
                for (i, (position, _)) in rows.iter().enumerate() {
                    out.push(format!("{position},{}", rows[rows.len() - 1 - i].1));
                }
                out.join("\n") + "\n"
            } else {
                text
            };
            std::fs::write(stale_dir.join(format!("ref-trt/{axis}.csv")), out).unwrap();
        }
        let stale = stale_dir.join("ref-trt.toml");
        std::fs::copy(data("machines/ref-trt.toml"), &stale).unwrap();
        let right = data("machines/ref-trt.toml");
        let program = data("samples/saddle.nc");
        let plan = data("samples/saddle-plan.csv");
        let measured = dir.path().join("meas.csv");
        let args = ["--seed", "11", "-o", measured.to_str().unwrap()];
        ok(&command("simulate", &[&right, &program, &plan], &args));
        for (what, machine) in [("clean", &right), ("stale", &stale)] {
            let out_dir = dir.path().join(what);
            std::fs::create_dir_all(&out_dir).unwrap();
            let report = out_dir.join("diag.json");
            let written = out_dir.join("written.toml");
            let args = [
                "--report",
                report.to_str().unwrap(),
                "--write-machine",
                written.to_str().unwrap(),
            ];
            let stdout = ok(&command("diagnose", &[machine, &program, &measured], &args));
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
            // No advice within 2 σ of zero, whatever is selected.
            for (effect, list) in v["after"]["checks"].as_object().unwrap() {
                for c in list.as_array().unwrap() {
                    let (value, std) = (c["value"].as_f64().unwrap(), c["std"].as_f64().unwrap());
                    if c["name"] != "tau" && c["identifiable"] == true {
                        assert_eq!(
                            c["distinguishable"],
                            value.abs() >= 2.0 * std,
                            "{what} {effect} {c}"
                        );
                    }
                }
            }
            assert_eq!(
                v["model_check"]["mismatch"],
                what == "stale",
                "{what}: {stdout}"
            );
            if what == "clean" {
                assert_eq!(v["selected"], serde_json::json!([]), "{what}: {stdout}");
            }
            // Measured: the stale run names thermal_drift beside the verdict
            // (dx 14.2 ± 2.5, dz 14.9 ± 1.7 µm, z 147 against the model
            // factors' 72; against a Y table free in shape its z is -45):
            // a known limit (docs/diagnose.md). The file still changes
            // nothing: the model is blamed.
            assert!(stdout.contains("Nothing changed"), "{what}: {stdout}");
            // The written file is the input with a comment block on top:
            // the same keys and values, line for line.
            let settings = |text: &str| -> Vec<String> {
                text.lines()
                    .map(str::trim)
                    .filter(|l| !l.is_empty() && !l.starts_with('#'))
                    .map(String::from)
                    .collect()
            };
            let text = std::fs::read_to_string(&written).unwrap();
            let body = settings(&text);
            let input = settings(&std::fs::read_to_string(machine).unwrap());
            assert_eq!(body.len(), input.len(), "{what}:\n{text}");
            for (a, b) in body.iter().zip(&input) {
                // Table paths are re-pointed from the new folder; nothing else moves.
                if !a.contains(".csv") {
                    assert_eq!(a, b, "{what}");
                }
            }
            let copies = std::fs::read_dir(&out_dir)
                .unwrap()
                .filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .path()
                        .extension()
                        .is_some_and(|x| x == "csv")
                })
                .count();
            assert_eq!(copies, 0, "{what}: no table copied");
            println!(
                "{what}: selected {}, model verdict {}, written file unchanged below its comment",
                v["selected"], v["model_check"]["mismatch"]
            );
        }
    }

    /// The B/C day (issue 36 "Show"): on bc-trt (B and C on the table),
    /// head-table (B in the head, C under the part) and head-head (C and B in
    /// the head), rotary location, squareness and backlash are each simulated
    /// on the machine's bundled saddle and diagnosed: the effect is named,
    /// its parameters and the localisation speak B and C (bands of B and of
    /// C over their real span, no A bands), and the page plots B and C.
    #[test]
    fn the_b_c_day_localises_each_effect_on_the_machines_own_axes() {
        let dir = tempfile::tempdir().unwrap();
        let effects = [
            (
                "rotary_location",
                "rotary_location:EX0B=10,EZ0B=-8,EA0B=60,EX0C=6,EA0C=40",
            ),
            ("squareness", "squareness:s_xy=150,s_xz=-100,s_yz=80"),
            ("backlash", "backlash:bx=6,by=4,bz=5"),
        ];
        for machine in ["bc-trt", "head-table", "head-head"] {
            let toml = data(&format!("machines/{machine}.toml"));
            let program = data(&format!("samples/{machine}/saddle.nc"));
            let plan = data(&format!("samples/{machine}/saddle-plan.csv"));
            for (name, spec) in effects {
                let what = format!("{machine} {name}");
                let measured = dir.path().join(format!("{machine}-{name}.csv"));
                let args = [
                    "--effect",
                    spec,
                    "--seed",
                    "36",
                    "--noise-um",
                    "0.3",
                    "-o",
                    measured.to_str().unwrap(),
                ];
                ok(&command("simulate", &[&toml, &program, &plan], &args));
                let report = dir.path().join(format!("{machine}-{name}.json"));
                let html = dir.path().join(format!("{machine}-{name}.html"));
                let args = [
                    "--report",
                    report.to_str().unwrap(),
                    "--html",
                    html.to_str().unwrap(),
                ];
                let stdout = ok(&command("diagnose", &[&toml, &program, &measured], &args));
                let v: serde_json::Value =
                    serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
                assert_eq!(v["selected"][0], name, "{what}: {stdout}");
                assert_eq!(v["rotary_axes"], serde_json::json!(["B", "C"]), "{what}");
                let loc = &v["localization"];
                assert!(loc.get("by_a").is_none(), "{what}: {loc}");
                let mut spans = Vec::new();
                for axis in ["by_b", "by_c"] {
                    let bands = loc[axis].as_array().unwrap();
                    assert_eq!(bands.len(), 6, "{what} {axis}");
                    let lo = bands[0]["from_deg"].as_f64().unwrap();
                    let hi = bands[5]["to_deg"].as_f64().unwrap();
                    // The saddle turns B over ≥ 4° and C over ≥ 40°.
                    assert!(hi - lo > 4.0, "{what} {axis}: {lo}..{hi}");
                    let points: u64 = bands.iter().map(|b| b["points"].as_u64().unwrap()).sum();
                    assert_eq!(points, 372, "{what} {axis}");
                    spans.push(format!("{lo:.1}..{hi:.1}°"));
                }
                if name == "rotary_location" {
                    let params = v["after"]["params"]["rotary_location"].as_object().unwrap();
                    assert!(
                        params.keys().all(|k| k.ends_with('B') || k.ends_with('C')),
                        "{what}: {params:?}"
                    );
                }
                let page = std::fs::read_to_string(&html).unwrap();
                assert!(
                    page.contains("Residual vs B") && page.contains("Residual vs C"),
                    "{what}"
                );
                assert!(!page.contains("Residual vs A"), "{what}");
                println!(
                    "{what}: selected {} (z {:.0}), residual RMS {:.2} -> {:.2} µm, B {}, C {}",
                    v["selected"],
                    v["after"]["significance"][name]
                        .as_f64()
                        .unwrap_or(f64::NAN),
                    v["gap"]["residual_rms_um"].as_f64().unwrap_or(f64::NAN),
                    v["after"]["residual_rms_um"].as_f64().unwrap_or(f64::NAN),
                    spans[0],
                    spans[1]
                );
            }
        }
    }
}

/// A part measured on a machine whose errors are 1.5 × the modelled ones: no
/// catalogue effect is forced onto it; the model itself is named, with the
/// factor of each axis.
#[test]
fn a_machine_model_that_is_off_is_named_not_forced_onto_an_effect() {
    let p = saddle();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let noise = rand_distr::Normal::new(0.0, 0.3).unwrap();
    use rand_distr::Distribution;
    let measured: Vec<f64> = p
        .contexts
        .iter()
        .map(|c| 1.5 * c.predicted_um + noise.sample(&mut rng))
        .collect();
    let r = diagnose(&p.contexts, &measured, &DiagnoseOptions::default()).unwrap();
    assert!(
        r.model_check.mismatch && r.model_check.follows_model,
        "{:?}",
        r.model_check
    );
    assert!(r.selected.is_empty(), "{:?}", r.selection_notes);
    for (axis, b) in &r.model_check.factors {
        assert!((b - 0.5).abs() < 0.15, "{axis}: factor {b}");
    }
    assert!(
        r.summary[0].starts_with("The error model itself does not match this machine"),
        "{:?}",
        r.summary
    );
}

/// A gap that no catalogue effect and no axis factor explains (a pattern over
/// the part, 3 µm) is said to stay unexplained, naming the model, not forced.
#[test]
fn an_unexplained_gap_is_said_to_be_unexplained() {
    let p = saddle();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let noise = rand_distr::Normal::new(0.0, 0.3).unwrap();
    use rand_distr::Distribution;
    let measured: Vec<f64> = p
        .contexts
        .iter()
        .map(|c| {
            c.predicted_um
                + 3.0 * (c.point[0] / 6.0).sin() * (c.point[1] / 5.0).cos()
                + noise.sample(&mut rng)
        })
        .collect();
    let r = diagnose(&p.contexts, &measured, &DiagnoseOptions::default()).unwrap();
    assert!(
        r.model_check.unexplained && r.model_check.mismatch,
        "{:?}",
        r.model_check
    );
    assert!(
        r.summary.iter().any(|s| s.contains("stays unexplained")),
        "{:?}",
        r.summary
    );
}

/// A part tilted over a wide A range (the synthetic dome, A 15–85°) tells
/// rotary_location from setup_error, which alias on the saddle: each is
/// selected when injected, and setup_error no longer reproduces a
/// rotary_location (the 8 location parameters still span a setup error).
#[test]
fn a_wide_a_range_separates_rotary_location_from_setup_error() {
    let part = saddle_raster(&SyntheticOptions::dome());
    for (kind, seed) in [
        (EffectKind::RotaryLocation, 1u64),
        (EffectKind::RotaryLocation, 2),
        (EffectKind::SetupError, 3),
    ] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let effect = random_effect(kind, &part.contexts, (2.0, 6.0), &mut rng);
        let m = simulate(
            &part.contexts,
            &part.truth_um,
            &[effect],
            &SimulateOptions {
                noise_um: 0.3,
                seed,
            },
        )
        .unwrap();
        let r = diagnose(
            &part.contexts,
            &m.deviations_um(),
            &DiagnoseOptions::default(),
        )
        .unwrap();
        assert_eq!(
            r.selected.first().map(String::as_str),
            Some(kind.name()),
            "{:?}",
            r.selection_notes
        );
        let fit = r.effects.iter().find(|e| e.name == kind.name()).unwrap();
        if kind == EffectKind::RotaryLocation {
            assert!(
                !fit.aliases.iter().any(|a| a == "setup_error"),
                "{:?}",
                fit.aliases
            );
        }
    }
}

/// The follow-up on the saddle (contexts of the fixture, probes placed by the
/// toolpath layer on ref-trt): a rotary location error that the measurement
/// alone selects as its alias, a set-up error, is named right once the
/// designed probes are fitted with it; the achieved separation is the
/// expected one.
#[test]
fn a_followup_tells_rotary_location_from_setup_error() {
    use volcomp::diagnose::followup::{self, FollowupOptions, ProbeReading};
    use volcomp::diagnose::{diagnose_with_followup, simulate_followup};
    use volcomp::machine::{ErrorModel, Machine, ModelOptions};
    use volcomp::toolpath::{ProbeTool, probe_context};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("machines/ref-trt.toml")).unwrap();
    let model = ErrorModel::from_machine(&machine, &ModelOptions::default()).unwrap();
    let part = saddle();
    let contexts = &part.contexts;
    let end = volcomp::toolpath::last_time_min(contexts);
    let tool = ProbeTool {
        length_mm: machine.tool.length,
        radius_mm: 1.0,
    };
    let candidates = followup::candidates(contexts, |cut, rotary| {
        probe_context(&model, &tool, Some(&machine.limits), cut, rotary, end)
    })
    .unwrap();
    // The case of `cargo run --example followup` (rotary_location, seed 1).
    let mut rng = ChaCha8Rng::seed_from_u64(8001);
    let effect = random_effect(EffectKind::RotaryLocation, contexts, (2.0, 6.0), &mut rng);
    let noise = SimulateOptions {
        noise_um: 0.3,
        seed: 78,
    };
    let measured = simulate(
        contexts,
        &part.truth_um,
        std::slice::from_ref(&effect),
        &noise,
    )
    .unwrap()
    .deviations_um();
    let before = diagnose(contexts, &measured, &DiagnoseOptions::default()).unwrap();
    assert_eq!(
        before.selected,
        ["setup_error"],
        "{:?}",
        before.selection_notes
    );
    let design = followup::design(
        contexts,
        &measured,
        &before,
        &candidates,
        end,
        &FollowupOptions::default(),
    )
    .unwrap()
    .expect("an alias to separate");
    assert_eq!(design.rivals, ["rotary_location"]);
    assert_eq!(design.probes.len(), 12);
    let separation = &design.separations[0];
    // The measurement alone barely tells them apart (BIC chose the alias).
    assert!(separation.before_sigma < 5.0, "{separation:?}");
    assert!(separation.expected_sigma > 10.0, "{separation:?}");
    // Probed at other poses: the set-up error cancels there, the location
    // error does not.
    assert!(design.probes.iter().any(|p| p.pose != "cutting pose"));
    let probes: Vec<_> = design.probes.iter().map(|p| p.probe.clone()).collect();
    let truth: Vec<f64> = probes
        .iter()
        .map(|p| contexts[p.of].predicted_um - p.context.predicted_um)
        .collect();
    let values = simulate_followup(
        contexts,
        &probes,
        &truth,
        &[effect],
        &SimulateOptions {
            seed: 5001,
            ..noise
        },
    )
    .unwrap();
    let readings: Vec<ProbeReading> = probes
        .into_iter()
        .zip(values)
        .map(|(probe, reading_um)| ProbeReading { probe, reading_um })
        .collect();
    let after = diagnose_with_followup(contexts, &measured, &readings, &DiagnoseOptions::default())
        .unwrap();
    assert_eq!(
        after.selected,
        ["rotary_location"],
        "{:?}",
        after.selection_notes
    );
    let outcome = followup::outcome(contexts, &measured, &before, &readings).unwrap();
    let s = &outcome.separations[0];
    // The rival (rotary_location) is the truth: the selection fits worse.
    let achieved = -s.achieved_sigma.unwrap();
    assert!(
        (achieved - s.if_rival_sigma).abs() < 1.5 + 0.2 * s.if_rival_sigma,
        "{s:?}"
    );
    // Without noise, a set-up error reads nothing on the machine, and a
    // thermal drift reads its change since the cut.
    let zero = SimulateOptions {
        noise_um: 0.0,
        seed: 1,
    };
    let probes: Vec<_> = readings.iter().map(|r| r.probe.clone()).collect();
    let none = vec![0.0; probes.len()];
    let setup = Effect::parse("setup_error:tx=5,ty=-3,tz=2,rx=40,ry=-30,rz=20").unwrap();
    for v in simulate_followup(contexts, &probes, &none, &[setup], &zero).unwrap() {
        assert!(v.abs() < 1e-9, "{v}");
    }
    let drift = Effect::parse("thermal_drift:dz=5,tau=3").unwrap();
    let values = simulate_followup(
        contexts,
        &probes,
        &none,
        std::slice::from_ref(&drift),
        &zero,
    )
    .unwrap();
    for (p, v) in probes.iter().zip(values) {
        let expected = drift.deviation_um(&contexts[p.of]) - drift.deviation_um(&p.context);
        assert!((v - expected).abs() < 1e-12);
    }
}

/// Issue 26 (close the loop): `simulate` of a compensated (stamped) program
/// cuts what that program cuts — the compensated path through the machine —
/// so without noise it measures what `predict` headlines for it (0.23 µm on
/// the saddle, against 32.42 µm for the program as written), and `diagnose`
/// of that part compares it with the same prediction.
#[test]
fn simulate_of_a_compensated_program_cuts_the_compensated_part() {
    use crate::support::{assert_success, root, volcomp};
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name);
    let run = |args: &[&std::ffi::OsStr]| {
        let out = volcomp().args(args).current_dir(root()).output().unwrap();
        assert_success(&out);
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr)
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    let machine = os("machines/ref-trt.toml");
    let plan = os("samples/saddle-plan.csv");
    run(&[
        &os("compensate"),
        &machine,
        &os("samples/saddle.nc"),
        &os("-o"),
        d("comp.nc").as_os_str(),
    ]);
    let profile = |program: &std::ffi::OsStr, name: &str| {
        let text = run(&[
            &os("simulate"),
            &machine,
            program,
            &plan,
            &os("--noise-um"),
            &os("0"),
            &os("-o"),
            d(name).as_os_str(),
        ]);
        let at = text.find("measured profile ").expect("profile") + "measured profile ".len();
        text[at..]
            .split_whitespace()
            .next()
            .unwrap()
            .parse::<f64>()
            .unwrap()
    };
    let before = profile(&os("samples/saddle.nc"), "m1.csv");
    let after = profile(d("comp.nc").as_os_str(), "m2.csv");
    assert!((before - 32.42).abs() < 0.01, "{before}");
    assert!((after - 0.23).abs() < 0.01, "{after}");
    let predicted = run(&[
        &os("predict"),
        &machine,
        d("comp.nc").as_os_str(),
        &os("--plan"),
        &plan,
        &os("--report"),
        d("p.json").as_os_str(),
    ]);
    assert!(
        predicted.contains("the part will measure profile 0.23 µm"),
        "{predicted}"
    );
    // Diagnosing the compensated part against its own prediction: nothing left.
    let diagnosis = run(&[
        &os("diagnose"),
        &machine,
        d("comp.nc").as_os_str(),
        d("m2.csv").as_os_str(),
        &os("--noise-um"),
        &os("0.1"),
        &os("--report"),
        d("d.json").as_os_str(),
    ]);
    assert!(diagnosis.contains("selected: none"), "{diagnosis}");
}

/// Issue 26: a seeded subset of the robustness generator (the full table is
/// `cargo run --release --example robustness`): localised servo lag named,
/// a local decoy reported as an anomaly and not as an effect, clean runs
/// without anomaly, scaled and noisy tables named as the model, no
/// implausible parameter unflagged, aliases two-way.
#[test]
fn robustness_subset_meets_the_issue_targets() {
    use volcomp::diagnose::robustness::{CaseClass, RobustnessOptions, cases, part, score};
    let part = part();
    let duration = volcomp::toolpath::last_time_min(&part.contexts);
    let options = RobustnessOptions {
        seeds_per_effect: 0,
        noise_levels: &[0.6],
        servo_runs: 3,
        pair_runs: 0,
        wrong_model_runs: [1, 1, 1],
        none_runs: 1,
        decoy_runs: 2,
    };
    for c in cases(&part, &options) {
        let r = diagnose(&c.contexts, &c.measured_um, &DiagnoseOptions::default()).unwrap();
        let s = score(&c, &r, duration);
        let what = format!(
            "{:?} seed {}: {:?} {:?}",
            c.class, c.seed, r.selection_notes, r.summary
        );
        match c.class {
            CaseClass::LocalisedServoLag => assert!(s.all_found, "{what}"),
            CaseClass::Decoy => {
                assert!(s.anomaly, "{what}");
                assert!(!s.false_positive, "{what}");
                assert!(!r.model_check.mismatch, "{what}");
                assert!(
                    r.summary.iter().any(|l| l.contains("local anomaly")),
                    "{what}"
                );
            }
            CaseClass::Clean => assert!(!s.anomaly && !s.false_positive, "{what}"),
            CaseClass::ScaledTables => {
                assert!(s.model_named && s.all_found, "{what}");
                assert!(r.summary[0].contains("tables scaled or stale"), "{what}");
            }
            CaseClass::NoisyTables => assert!(s.model_named && !s.false_positive, "{what}"),
            // A stale table: the model is named and no effect beside it
            // (what a scale leaves of a table of another shape is not an
            // effect: docs/diagnose.md "Selection").
            CaseClass::StaleTable => {
                assert!(s.model_named && !s.false_positive, "{what}");
                assert!(
                    r.selection_notes
                        .iter()
                        .any(|n| n.contains("also free in shape") && n.contains("not named")),
                    "{what}"
                );
            }
            CaseClass::NoEffect => assert!(!s.false_positive && !r.model_check.mismatch, "{what}"),
            _ => {}
        }
        assert_eq!(s.unflagged, 0, "{what}");
        assert_eq!(s.alias_two_way, s.alias_relations, "{what}");
    }
}

/// Issue 36: a tie at the headline is decided by the likelihood on all
/// points, less the points of a local anomaly. Robustness decoy seed 90001 (a
/// thermal drift beside a 4 µm bump): held out thermal_drift and setup_error
/// tie; on all points setup_error's six parameters took part of the bump and
/// were named first. The drift is named, setup_error stays its alias, and
/// the bump is reported.
#[test]
fn a_bump_does_not_decide_a_tie_at_the_headline() {
    use volcomp::diagnose::robustness::{CaseClass, RobustnessOptions, cases, part};
    let part = part();
    let options = RobustnessOptions {
        decoy_runs: 2,
        ..RobustnessOptions::none()
    };
    let c = cases(&part, &options)
        .into_iter()
        .find(|c| c.class == CaseClass::Decoy && c.seed == 90_001)
        .unwrap();
    assert_eq!(c.injected, vec![EffectKind::ThermalDrift]);
    let r = diagnose(&c.contexts, &c.measured_um, &DiagnoseOptions::default()).unwrap();
    let what = format!("{:?} {:?}", r.selection_notes, r.summary);
    assert_eq!(r.selected, vec!["thermal_drift".to_string()], "{what}");
    let drift = r
        .effects
        .iter()
        .find(|e| e.name == "thermal_drift")
        .unwrap();
    assert!(drift.aliases.iter().any(|a| a == "setup_error"), "{what}");
    assert!(!r.local_anomalies.is_empty(), "{what}");
}

/// Issue 26: a rotation about the axis of a surface of revolution (the
/// synthetic dome, about Z) cannot be seen: a set-up error's `rz` is reported
/// as not identifiable, with its unit and ±, and left out of the advice.
#[test]
fn a_rotation_about_the_axis_of_a_surface_of_revolution_is_not_identifiable() {
    let part = saddle_raster(&SyntheticOptions::dome());
    let effect = Effect::parse("setup_error:tx=4,ty=-3,tz=2,rx=60,ry=-40,rz=500").unwrap();
    let m = simulate(
        &part.contexts,
        &part.truth_um,
        &[effect],
        &SimulateOptions {
            noise_um: 0.3,
            seed: 4,
        },
    )
    .unwrap();
    let r = diagnose(
        &part.contexts,
        &m.deviations_um(),
        &DiagnoseOptions::default(),
    )
    .unwrap();
    assert_eq!(r.selected, ["setup_error"], "{:?}", r.selection_notes);
    let checks = &r.after.checks["setup_error"];
    let rz = checks.iter().find(|c| c.name == "rz").unwrap();
    assert!(!rz.identifiable, "{rz:?}");
    assert_eq!(rz.unit, "µrad");
    let tx = checks.iter().find(|c| c.name == "tx").unwrap();
    assert!(tx.identifiable && tx.plausible && tx.std > 0.0, "{tx:?}");
    assert_eq!(tx.unit, "µm");
    let advice = r
        .summary
        .iter()
        .find(|s| s.starts_with("Workpiece set-up error"))
        .unwrap();
    assert!(
        advice.contains("n/a") && advice.contains("left out of this advice"),
        "{advice}"
    );
}

/// Cases of the independent generator (tests/data/oracle-cases, issue 36),
/// scored as their README says: servo lag strong at few points is found
/// (it was not: held-out RMS averaged its evidence away), the wrong model is
/// named beside the thermal drift (it was not: rotary_location alone), the
/// pair both named, the no-effect case quiet; the bowl's rotation about its
/// axis fixed at 0, and the held-out ties of s19 and s35 named by the
/// likelihood on all points with the other explanation as an alias.
#[test]
fn oracle_cases_are_diagnosed_as_their_readme_says() {
    use volcomp::diagnose::oracle::{OracleGroup, OracleMachine, diagnose_case, read_index, score};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("tests/data/oracle-cases");
    let cases = read_index(&dir).unwrap();
    assert_eq!(cases.len(), 6);
    let right = OracleMachine::load(&root.join("machines/ref-trt.toml")).unwrap();
    let wrong = OracleMachine::load(&dir.join("machines/x1.4.toml")).unwrap();
    for case in &cases {
        let machine = if case.group == OracleGroup::WrongModel {
            &wrong
        } else {
            &right
        };
        let report = diagnose_case(machine, &dir, case).unwrap();
        let s = score(case, &report);
        assert!(
            s.pass,
            "{}: said {}; {:?}",
            case.name, s.said, report.selection_notes
        );
        // On the bowl (a surface of revolution) the rotation about its axis
        // is not seen: fixed at 0, not fitted to rounding (issue 36).
        assert!(
            report.selection_notes[0].starts_with("fixed at 0")
                && report.selection_notes[0].contains("rz of setup_error"),
            "{}: {:?}",
            case.name,
            report.selection_notes
        );
        if case.name.starts_with("s19") || case.name.starts_with("s35") {
            // A tie on held-out points, named by the likelihood on all
            // points, the other explanation kept as its alias.
            assert!(
                report
                    .selection_notes
                    .iter()
                    .any(|n| n.contains("cannot be told apart on held-out points")
                        && n.contains("named first")),
                "{}: {:?}",
                case.name,
                report.selection_notes
            );
            assert!(
                !report
                    .effects
                    .iter()
                    .find(|e| e.name == report.selected[0])
                    .unwrap()
                    .aliases
                    .is_empty()
            );
        }
        if case.group == OracleGroup::WrongModel {
            // The verdict is said first, beside the effect.
            assert!(
                report.summary[0].contains("may not match")
                    && report.summary[0].contains("thermal_drift"),
                "{:?}",
                report.summary
            );
        }
    }
}

/// The oracle's pair p4 (rotary location + thermal drift on the dome), which
/// the measurement alone does not name: its report's follow-up, read on the
/// true machine with the case's own effects (`simulate --followup`) and
/// diagnosed with the measurement (`--followup`), names both without a model
/// verdict and recovers their values (tests/data/oracle-followup/README.md).
#[test]
fn an_oracle_pair_the_measurement_cannot_name_is_named_after_its_followup() {
    use crate::support::{assert_success, root, volcomp};
    use volcomp::diagnose::oracle::truth_effects;
    let data = root().join("tests/data/oracle-followup");
    let case = data.join("p4-rotary_location+thermal_drift");
    let truth = truth_effects(&case).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let at = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (machine, program, measured) = (
        root().join("machines/ref-trt.toml"),
        data.join("parts/dome.nc"),
        case.join("measured.csv"),
    );
    let run = |command: &str, extra: Vec<String>| {
        let out = volcomp()
            .arg(command)
            .args([&machine, &program, &measured])
            .args(extra)
            .current_dir(root())
            .output()
            .unwrap();
        assert_success(&out);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(at(name)).unwrap()).unwrap()
    };
    run(
        "diagnose",
        vec![
            "--report".into(),
            at("before.json"),
            "--followup-program".into(),
            at("followup.nc"),
        ],
    );
    let before = read("before.json");
    assert!(
        !before["followup_design"].is_null(),
        "{}",
        before["summary"]
    );
    let mut simulate = vec![
        "--followup".into(),
        at("followup.csv"),
        "-o".into(),
        at("readings.csv"),
    ];
    for e in &truth {
        simulate.extend(["--effect".into(), e.to_spec()]);
    }
    simulate.extend(["--noise-um", "0.3", "--seed", "1"].map(String::from));
    let stdout = run("simulate", simulate);
    assert!(stdout.contains("simulated 12 follow-up probes"), "{stdout}");
    run(
        "diagnose",
        vec![
            "--report".into(),
            at("after.json"),
            "--followup".into(),
            at("readings.csv"),
        ],
    );
    let after = read("after.json");
    let mut selected: Vec<&str> = after["selected"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    selected.sort_unstable();
    assert_eq!(
        selected,
        ["rotary_location", "thermal_drift"],
        "before: {} {}; after: {}",
        before["selected"],
        before["model_check"]["mismatch"],
        after["summary"]
    );
    assert_eq!(
        after["model_check"]["mismatch"], false,
        "{}",
        after["summary"]
    );
    // Every fitted parameter within 3 σ of the injected value (τ within
    // 10 %): the values, not only the names.
    for e in &truth {
        let name = e.kind.name();
        for check in after["after"]["checks"][name].as_array().unwrap() {
            let p = check["name"].as_str().unwrap();
            if p == "tau" {
                continue; // profiled, no σ: checked below
            }
            let j = e.kind.parameters().iter().position(|q| *q == p).unwrap();
            let (value, std) = (
                check["value"].as_f64().unwrap(),
                check["std"].as_f64().unwrap(),
            );
            assert!(
                (value - e.values[j]).abs() <= 3.0 * std + 0.05,
                "{name}.{p}: {value} ± {std}, injected {}",
                e.values[j]
            );
        }
        if e.kind == EffectKind::ThermalDrift {
            let tau = after["after"]["params"][name]["tau"].as_f64().unwrap();
            assert!((tau - e.tau()).abs() < 0.1 * e.tau(), "tau {tau}");
        }
    }
}

/// The oracle's truth read back (`truth.json`) and computed by volcomp's
/// catalogue reproduces the independent generator's measurement to about the
/// noise, and the ideal observer (docs/diagnose.md, seventh pass) finds its
/// pair (backlash + thermal drift on the bowl) separable.
#[test]
fn an_oracle_pair_read_from_its_truth_is_separable_on_its_part() {
    use volcomp::diagnose::EffectKind;
    use volcomp::diagnose::ideal_observer::separation;
    use volcomp::diagnose::oracle::{OracleMachine, read_index, truth_effects, truth_residual_rms};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("tests/data/oracle-cases");
    let case = read_index(&dir)
        .unwrap()
        .into_iter()
        .find(|c| c.name.starts_with("p1"))
        .unwrap();
    let truth = truth_effects(&dir.join(&case.name)).unwrap();
    assert_eq!(
        truth.iter().map(|e| e.kind).collect::<Vec<_>>(),
        [EffectKind::Backlash, EffectKind::ThermalDrift]
    );
    assert_eq!(truth[0].values, [13.54, 5.27, 4.37]);
    assert_eq!(truth[1].tau(), 3.4);
    let machine = OracleMachine::load(&root.join("machines/ref-trt.toml")).unwrap();
    let (contexts, measured) = machine.case_inputs(&dir, &case).unwrap();
    let rms = truth_residual_rms(&contexts, &measured, &truth);
    // Noise 0.3 µm; what is left beyond it is the two generators' and the
    // table fit's differences (0.39 µm measured).
    assert!((0.25..0.45).contains(&rms), "{rms}");
    let s = separation(&contexts, &truth, case.noise_um, &Default::default()).unwrap();
    assert!(s.separable() && s.margin > 100.0, "{s}");
}

/// A value within 2 σ of zero is not advice (issue 36): it is reported as
/// not distinguishable from zero and left out of the effect's advice.
#[test]
fn values_within_two_sigma_of_zero_are_not_advice() {
    use volcomp::diagnose::oracle::{OracleMachine, diagnose_case, read_index};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("tests/data/oracle-cases");
    let cases = read_index(&dir).unwrap();
    let right = OracleMachine::load(&root.join("machines/ref-trt.toml")).unwrap();
    let case = cases.iter().find(|c| c.name.starts_with("p1")).unwrap();
    let report = diagnose_case(&right, &dir, case).unwrap();
    let mut near_zero = 0;
    for (effect, list) in &report.after.checks {
        for c in list.iter().filter(|c| c.name != "tau") {
            let within = c.value.abs() < 2.0 * c.std;
            assert_eq!(c.distinguishable, !within, "{effect} {c:?}");
            if within && c.identifiable {
                near_zero += 1;
                assert!(
                    report
                        .summary
                        .iter()
                        .any(|s| s.contains("Not distinguishable from zero")
                            && s.contains(&c.display())),
                    "{c:?} {:?}",
                    report.summary
                );
            }
        }
    }
    println!("{near_zero} identifiable values within 2 σ of zero");
}

/// Issue 36, sixth pass: the follow-up the report designs, simulated with the
/// case's own truth, separates an alias pair of the robustness generator.
/// Seed 70003 (setup_error + squareness, noise 0.3 µm, a model that is not
/// the machine's): the measurement alone selects rotary_location and names
/// setup_error + squareness as the rival it cannot tell from it; with the 12
/// probes the design takes against that rival set (a whole hypothesis), both
/// injected effects are selected, without a model verdict, and the achieved
/// separation is the expected one.
#[test]
fn the_followup_separates_an_alias_pair_of_the_robustness_generator() {
    use volcomp::diagnose::robustness::{
        CaseClass, FollowupRunOptions, RobustnessOptions, cases, followup_run, part,
    };
    let part = part();
    let duration = volcomp::toolpath::last_time_min(&part.contexts);
    let options = RobustnessOptions {
        pair_runs: 4,
        ..RobustnessOptions::none()
    };
    let c = cases(&part, &options)
        .into_iter()
        .find(|c| c.class == CaseClass::Pair && c.seed == 70_003)
        .unwrap();
    assert_eq!(
        c.injected,
        vec![EffectKind::SetupError, EffectKind::Squareness]
    );
    let run = followup_run(&c, &FollowupRunOptions::default(), duration).unwrap();
    let what = format!(
        "before {:?} {:?}; after {:?} {:?}",
        run.before.selected,
        run.before.selection_notes,
        run.after.selected,
        run.after.selection_notes
    );
    // The alias: one effect explains the measurement as well as the pair.
    assert_eq!(run.before.selected, ["rotary_location"], "{what}");
    assert!(!run.before_score.all_found, "{what}");
    let design = run.design.as_ref().expect("a rival to separate");
    assert_eq!(design.probes.len(), 12);
    assert!(
        design
            .rivals
            .iter()
            .any(|r| r == "setup_error + squareness"),
        "{:?}",
        design.rivals
    );
    // After the follow-up: both selected, no model verdict.
    assert!(run.after_score.all_found, "{what}");
    assert!(!run.after.model_check.mismatch, "{what}");
    let outcome = run.outcome.as_ref().unwrap();
    let truth = outcome
        .separations
        .iter()
        .find(|s| s.rival == "setup_error + squareness")
        .unwrap();
    assert!(truth.before_sigma < 10.0, "{truth:?}");
    assert!(truth.if_rival_sigma > 25.0, "{truth:?}");
    // Achieved: positive when the selection before fits better; here the
    // truth does, by about what was expected.
    let achieved = -truth.achieved_sigma.unwrap();
    assert!(
        (achieved - truth.if_rival_sigma).abs() <= 1.5 + 0.2 * truth.if_rival_sigma,
        "{truth:?}"
    );
}

/// The generator's follow-up probe in the cutting pose with the cutting
/// tool's radius (3 mm) is the cut itself: the same tool axis, joints and
/// chain Jacobians (`synthetic::probe_context` follows `saddle_raster`'s
/// first-order A/C chain); at another C the rotary location's Jacobian
/// changes and the model's part of the reading stays zero.
#[test]
fn the_synthetic_probe_in_the_cutting_pose_is_the_cut() {
    use volcomp::diagnose::synthetic::probe_context;
    for cut in part().contexts.iter().step_by(37) {
        let pose = [cut.joints.a, cut.joints.c];
        let probe = probe_context(cut, pose, 99.0, 3.0);
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
        assert!(close(&probe.tool_axis, &cut.tool_axis), "{}", cut.id);
        assert!(
            close(&probe.joints.to_array(), &cut.joints.to_array()),
            "{}",
            cut.id
        );
        for (p, c) in probe
            .location_jacobian
            .iter()
            .chain(&probe.squareness_jacobian)
            .zip(cut.location_jacobian.iter().chain(&cut.squareness_jacobian))
        {
            assert!(close(p, c), "{}: {p:?} {c:?}", cut.id);
        }
        let turned = probe_context(cut, [pose[0], pose[1] + 90.0], 99.0, 3.0);
        let change: f64 = turned
            .location_jacobian
            .iter()
            .zip(&cut.location_jacobian)
            .map(|(p, c)| (0..3).map(|k| (p[k] - c[k]).abs()).sum::<f64>())
            .sum();
        assert!(change > 1e-3, "{}", cut.id);
        assert_eq!(turned.predicted_um, cut.predicted_um);
        assert_eq!(turned.time_min, 99.0);
    }
}
