//! Machining cycles of Klartext programs (dialects.md "Heidenhain TNC",
//! issue 35 item 4): their definitions (`CYCL DEF n` with its `Q`
//! parameters, the old numbered forms `CYCL DEF 1.0 … 1.5`), the point
//! patterns of `PATTERN DEF`, and each cycle expanded into the moves the
//! control makes, in program coordinates, as the TNC's cycle programming
//! manuals define them. A cycle this module does not expand is refused at
//! its call, naming it (251–257 and 263–267 also name the detail of
//! their motion the manual's text as read here does not give); cycles that
//! do not move pass through. Where `search` did not return the manual's
//! text of a cycle run (204, 206, 208, 209, 241, 262), the cycle's doc
//! comment says so and docs/dialects.md lists the readings volcomp made.
//!
//! Semantics (the manuals are the contract, cited per cycle): HEIDENHAIN
//! *TNC 640 User's Manual Cycle Programming* (NC software 34059x), chapter
//! "Fixed cycles: drilling" and "Fixed cycles: tapping"; *TNC 320 User's
//! Manual Cycle Programming* (340 55x-04), chapter 3 "Fixed Cycles:
//! Drilling" and 4 "Tapping"; *iTNC 530 User's Manual* (340
//! 422), "Cycles for drilling" (old cycle 1 PECKING), "PATTERN DEF" and
//! "Calling cycles with CYCL CALL POS". The Q parameters keep the manuals'
//! meaning: Q200 set-up clearance, Q201 depth (its sign the direction),
//! Q203 surface coordinate, Q204 2nd set-up clearance, Q206 plunging feed,
//! Q208 retraction feed, Q202 plunging depth, Q210/Q211 dwell at top /
//! depth, …
//!
//! Invariant: pure and total: a step list or an error message, never a
//! panic, never a non-finite step (the caller checks positions).
use std::sync::Arc;

use super::geometry::arc_chords;
use super::machine::CHORD_TOLERANCE_MM;
use super::syntax::{KlBlock, Value, parse_block, read_param};
use crate::gcode::motion::{Plane, from_plane, to_plane};

/// A defined machining cycle (`CYCL DEF n` with its Q parameters).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CycleDef {
    /// The cycle number (200, 203 …; 1 for the old PECKING).
    pub number: u32,
    /// The values of its definition: Q200 … for the 2xx cycles, the
    /// minor block number (1.1 → 1 …) for the old numbered cycles.
    pub q: Vec<(u32, f64)>,
    /// The line of its `CYCL DEF`.
    pub line: usize,
}

impl CycleDef {
    fn get(&self, n: u32) -> Option<f64> {
        self.q.iter().rev().find(|(k, _)| *k == n).map(|(_, v)| *v)
    }

    fn set(&mut self, n: u32, v: f64) {
        self.q.retain(|(k, _)| *k != n);
        self.q.push((n, v));
    }
}

/// One step of an expanded cycle, program coordinates (mm), feeds mm/min.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Step {
    /// At rapid traverse (FMAX).
    Rapid([f64; 3]),
    /// At this feed rate.
    Feed([f64; 3], f64),
    /// A dwell, seconds.
    Dwell(f64),
}

/// Where and how a cycle is called.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Call {
    /// The tool position at the call (program coordinates, mm).
    pub start: [f64; 3],
    /// The working plane (its normal is the tool axis).
    pub plane: Plane,
    /// An INCH program (lengths × 25.4, feeds × 2.54).
    pub inch: bool,
    /// The spindle speed of the last `TOOL CALL … S` (rpm), for tapping.
    pub spindle_rpm: Option<f64>,
    /// The radius of the tool in the spindle (with `DR`), when the tool
    /// table gives it, for the cycles that mill about a centre (208).
    pub tool_radius: Option<f64>,
    /// Added to the surface coordinate Q203 (the tool-axis coordinate of
    /// `CYCL CALL POS` and of a `PATTERN DEF` point, mm).
    pub surface_shift: f64,
}

/// Why a cycle is not expanded.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum CycleError {
    /// What the control refuses (a missing parameter, …), in its words.
    Refused(String),
    /// What volcomp does not expand yet (names the feature).
    Unread(String),
}

/// The cycles [`expand`] expands.
pub(crate) const EXPANDED: [u32; 14] = [
    1, 200, 201, 202, 203, 204, 205, 206, 207, 208, 209, 240, 241, 262,
];

/// Cycles that do not move the tool and do not change where later blocks
/// go: passed through, counted. 9 (dwell, the dwell counted at its
/// definition), 13 (spindle orientation), 32/332 (tolerance), 392
/// (trochoidal settings), 247 (datum setting: the preset number only).
pub(crate) fn passes_through(number: u32) -> bool {
    matches!(number, 9 | 13 | 32 | 332 | 392 | 247)
}

/// Cycles that change where later blocks go, effective at their
/// definition (TNC 640 "Coordinate transformation cycles"): refused there.
pub(crate) fn transforms(number: u32) -> Option<&'static str> {
    match number {
        8 => Some("CYCL DEF 8 MIRROR IMAGE"),
        10 => Some("CYCL DEF 10 ROTATION"),
        11 => Some("CYCL DEF 11 SCALING"),
        26 => Some("CYCL DEF 26 AXIS-SPECIFIC SCALING"),
        _ => None,
    }
}

/// The definition of `CYCL DEF n …` (a 2xx cycle with its Q words), or a
/// line of an old numbered cycle (`CYCL DEF 1.2 DEPTH -20`) merged into
/// `current`. `value` reads token `k`'s value (a number or a parameter's;
/// called for tokens with a value only).
pub(crate) fn define(
    block: &KlBlock,
    major: u32,
    minor: u32,
    line: usize,
    current: Option<&CycleDef>,
    value: &dyn Fn(usize) -> f64,
) -> Result<CycleDef, String> {
    if major < 100 && minor > 0 {
        let mut def = match current {
            Some(d) if d.number == major => d.clone(),
            _ if major == 1 => {
                return Err(format!(
                    "CYCL DEF {major}.{minor} without its CYCL DEF {major}.0 before it"
                ));
            }
            _ => CycleDef {
                number: major,
                q: Vec::new(),
                line,
            },
        };
        if major == 1 {
            // `CYCL DEF 1.1 SET UP -2`, `1.5 F80`: the block's last value.
            let k = (3..block.tokens.len())
                .rev()
                .find(|&k| block.tokens[k].value.is_some())
                .ok_or_else(|| format!("CYCL DEF {major}.{minor} without its value"))?;
            def.set(minor, value(k));
        }
        return Ok(def);
    }
    let mut q = Vec::new();
    for (k, t) in block.tokens.iter().enumerate().skip(3) {
        let Some(p) = read_param(&t.address) else {
            continue;
        };
        // `Q201= -48` (hyperMILL pads the value) is one token: the tokeniser's.
        if t.value.is_some() {
            q.push((p.number, value(k)));
        }
    }
    Ok(CycleDef {
        number: major,
        q,
        line,
    })
}

/// The steps of `def` called at `call`: the moves the control makes, from
/// the call position to the cycle's end.
pub(crate) fn expand(def: &CycleDef, call: &Call) -> Result<Vec<Step>, CycleError> {
    let mut x = Expander::new(def, call)?;
    match def.number {
        1 => x.pecking_old()?,
        200 => x.drilling()?,
        201 => x.reaming()?,
        202 => x.boring()?,
        203 => x.universal_drilling()?,
        204 => x.back_boring()?,
        205 => x.universal_pecking()?,
        206 => x.tapping()?,
        207 => x.rigid_tapping()?,
        208 => x.bore_milling()?,
        209 => x.tapping_chip_breaking()?,
        240 => x.centering()?,
        241 => x.single_lip_drilling()?,
        262 => x.thread_milling()?,
        n if not_expanded(n).is_some() => {
            return Err(CycleError::Unread(format!(
                "CYCL DEF {n} (defined on line {}) called here: {}",
                def.line,
                not_expanded(n).unwrap_or_default()
            )));
        }
        n => {
            return Err(CycleError::Unread(format!(
                "CYCL DEF {n} (defined on line {}) called here: volcomp expands cycles {}",
                def.line,
                EXPANDED.map(|n| n.to_string()).join(", ")
            )));
        }
    }
    if x.steps.len() > MAX_STEPS {
        return Err(CycleError::Refused(format!(
            "CYCL DEF {}: more than {MAX_STEPS} moves",
            def.number
        )));
    }
    Ok(x.steps)
}

const MAX_STEPS: usize = 200_000;

/// Builds a cycle's steps along the tool axis.
struct Expander<'a> {
    def: &'a CycleDef,
    call: &'a Call,
    /// Index of the tool axis coordinate (0 X, 1 Y, 2 Z).
    axis: usize,
    /// The current position (program coordinates).
    at: [f64; 3],
    steps: Vec<Step>,
    scale: f64,
}

impl<'a> Expander<'a> {
    fn new(def: &'a CycleDef, call: &'a Call) -> Result<Self, CycleError> {
        let normal = from_plane(call.plane, [0.0, 0.0, 1.0]);
        let axis = normal.iter().position(|v| *v != 0.0).unwrap_or(2);
        Ok(Expander {
            def,
            call,
            axis,
            at: call.start,
            steps: Vec::new(),
            scale: if call.inch { 25.4 } else { 1.0 },
        })
    }

    /// A length parameter (mm), required.
    fn length(&self, n: u32, name: &str) -> Result<f64, CycleError> {
        Ok(self.required(n, name)? * self.scale)
    }

    fn required(&self, n: u32, name: &str) -> Result<f64, CycleError> {
        self.def.get(n).ok_or_else(|| {
            CycleError::Refused(format!(
                "CYCL DEF {} (line {}) without Q{n} ({name})",
                self.def.number, self.def.line
            ))
        })
    }

    fn optional(&self, n: u32) -> f64 {
        self.def.get(n).unwrap_or(0.0)
    }

    /// A feed parameter (mm/min; FMAX written as a word is not a number).
    fn feed(&self, n: u32, name: &str) -> Result<f64, CycleError> {
        let f = self.required(n, name)? * if self.call.inch { 2.54 } else { 1.0 };
        if f <= 0.0 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF {}: Q{n} ({name}) must be a positive feed rate",
                self.def.number
            )));
        }
        Ok(f)
    }

    /// The retraction feed Q208: 0 or absent → `fallback` (the manuals:
    /// "If you enter Q208 = 0, the tool retracts at the feed rate Q206").
    fn retraction(&self, fallback: f64) -> f64 {
        let f = self.optional(208) * if self.call.inch { 2.54 } else { 1.0 };
        if f > 0.0 { f } else { fallback }
    }

    /// The deepened starting point Q379 (below the surface, mm; at most
    /// the depth; 0 when absent).
    fn deepened_start(&self, g: &Geometry) -> f64 {
        (self.optional(379).abs() * self.scale).min(g.depth)
    }

    /// FMAX to the set-up clearance; with a deepened starting point, at
    /// Q253 on to the set-up clearance above it (cycles 205 and 241).
    fn approach_deepened(&mut self, g: &Geometry, deepened: f64) -> Result<(), CycleError> {
        self.rapid_to(g.above(g.clearance));
        if deepened > 0.0 {
            let pre = self.feed(253, "feed rate for pre-positioning")?;
            self.feed_to(g.below(deepened - g.clearance), pre);
        }
        Ok(())
    }

    /// The tool-axis geometry of a 2xx cycle: the surface, the direction of
    /// depth (the sign of Q201) and the depth (positive, mm).
    fn geometry(&self) -> Result<Geometry, CycleError> {
        let depth = self.length(201, "depth")?;
        let surface = self.length(203, "surface coordinate")? + self.call.surface_shift;
        Ok(Geometry {
            surface,
            dir: if depth < 0.0 { -1.0 } else { 1.0 },
            depth: depth.abs(),
            clearance: self.length(200, "set-up clearance")?.abs(),
            second: self.optional(204).abs() * self.scale,
        })
    }

    /// The point at tool-axis coordinate `v` over the call position.
    fn point(&self, v: f64) -> [f64; 3] {
        let mut p = self.at;
        p[self.axis] = v;
        p
    }

    fn rapid_to(&mut self, v: f64) {
        let p = self.point(v);
        self.push(Step::Rapid(p));
    }

    fn feed_to(&mut self, v: f64, f: f64) {
        let p = self.point(v);
        self.push(Step::Feed(p, f));
    }

    fn push(&mut self, s: Step) {
        if let Step::Rapid(p) | Step::Feed(p, _) = s {
            self.at = p;
        }
        if self.steps.len() <= MAX_STEPS {
            self.steps.push(s);
        }
    }

    fn dwell(&mut self, seconds: f64) {
        if seconds > 0.0 {
            self.push(Step::Dwell(seconds));
        }
    }

    /// The end of most 2xx cycles: to the set-up clearance (at `feed`, or
    /// FMAX), then at FMAX to the 2nd set-up clearance when it is higher.
    fn leave(&mut self, g: &Geometry, feed: Option<f64>) {
        match feed {
            Some(f) => self.feed_to(g.above(g.clearance), f),
            None => self.rapid_to(g.above(g.clearance)),
        }
        if g.second > g.clearance {
            self.rapid_to(g.above(g.second));
        }
    }

    /// Cycle 200 DRILLING (TNC 640 Cycle Programming, "DRILLING (Cycle
    /// 200)"; TNC 320 340 55x-04, 3.3): FMAX to the set-up
    /// clearance; pecks of Q202 at Q206, after each FMAX back to the set-up
    /// clearance, dwell Q210, FMAX to the set-up clearance above the depth
    /// reached; at the depth dwell Q211; FMAX to the set-up clearance, then
    /// to the 2nd set-up clearance. DEPTH = 0: the cycle is not run.
    fn drilling(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        let peck = self.length(202, "plunging depth")?.abs();
        if g.depth == 0.0 {
            return Ok(());
        }
        self.rapid_to(g.above(g.clearance));
        let step = if peck <= 0.0 { g.depth } else { peck };
        let mut reached = 0.0f64;
        loop {
            reached = (reached + step).min(g.depth);
            self.feed_to(g.below(reached), feed);
            if reached >= g.depth - 1e-12 || self.steps.len() > MAX_STEPS {
                break;
            }
            self.rapid_to(g.above(g.clearance));
            self.dwell(self.optional(210));
            self.rapid_to(g.below(reached - g.clearance));
        }
        self.dwell(self.optional(211));
        self.leave(&g, None);
        Ok(())
    }

    /// Cycle 201 REAMING (TNC 640, "REAMING (Cycle 201)"; TNC 320 3.4):
    /// FMAX to the set-up clearance, Q206 to the depth, dwell Q211,
    /// back to the set-up clearance at Q208 (0: at Q206), FMAX to the 2nd
    /// set-up clearance.
    fn reaming(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        if g.depth == 0.0 {
            return Ok(());
        }
        self.rapid_to(g.above(g.clearance));
        self.feed_to(g.below(g.depth), feed);
        self.dwell(self.optional(211));
        let back = self.retraction(feed);
        self.leave(&g, Some(back));
        Ok(())
    }

    /// Cycle 202 BORING (TNC 640, "BORING (Cycle 202)"; TNC 320 3.5):
    /// FMAX to the set-up clearance, Q206 to the depth, dwell Q211,
    /// the spindle oriented to Q336, the tool disengaged 0.2 mm in the
    /// direction Q214 (1 −, 2 − minor, 3 +, 4 + minor axis of the working
    /// plane; 0 none), back at Q208 (0: at Q206) to the set-up clearance,
    /// FMAX to the 2nd set-up clearance, and back to the hole's centre.
    fn boring(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        if g.depth == 0.0 {
            return Ok(());
        }
        let [du, dv] = self.disengaging(0.2 * self.scale)?;
        self.rapid_to(g.above(g.clearance));
        self.feed_to(g.below(g.depth), feed);
        self.dwell(self.optional(211));
        let centre = self.at;
        if du != 0.0 || dv != 0.0 {
            let d = from_plane(self.call.plane, [du, dv, 0.0]);
            let p = [centre[0] + d[0], centre[1] + d[1], centre[2] + d[2]];
            self.push(Step::Rapid(p));
        }
        let back = self.retraction(feed);
        self.leave(&g, Some(back));
        if du != 0.0 || dv != 0.0 {
            let mut p = centre;
            p[self.axis] = self.at[self.axis];
            self.push(Step::Rapid(p));
        }
        Ok(())
    }

    /// The displacement (u, v) of `distance` (mm, already scaled) in the
    /// disengaging direction Q214 (cycles 202 and 204): 1 −, 2 − minor,
    /// 3 +, 4 + minor axis of the working plane, 0 none.
    fn disengaging(&self, distance: f64) -> Result<[f64; 2], CycleError> {
        let direction = self.optional(214);
        let d = distance;
        let v = match direction as i64 {
            _ if direction.fract() != 0.0 => None,
            0 => Some([0.0, 0.0]),
            1 => Some([-d, 0.0]),
            2 => Some([0.0, -d]),
            3 => Some([d, 0.0]),
            4 => Some([0.0, d]),
            _ => None,
        };
        v.ok_or_else(|| {
            CycleError::Refused(format!(
                "CYCL DEF {}: Q214 (disengaging direction) must be 0 to 4, not {direction}",
                self.def.number
            ))
        })
    }

    /// Cycle 204 BACK BORING (TNC 640 Cycle Programming, "BACK BORING
    /// (Cycle 204)"; its parameters as the TNC 426 User's Manual, 8.2, gives
    /// them: Q249 depth of counterbore, from the underside of the workpiece,
    /// positive in the positive spindle axis direction; Q250 material
    /// thickness; Q251 off-centre distance of the boring bar; Q252 tool
    /// edge height, from the underside of the bar (the tool's length
    /// reference) to the cutting tooth; Q253 pre-positioning feed; Q254
    /// counterboring feed; Q255 dwell at the top of the counterbore; Q214
    /// "the direction in which the TNC displaces the tool by the
    /// off-center distance (after spindle orientation)": 1 −, 2 − minor,
    /// 3 +, 4 + minor axis): FMAX to the set-up clearance over the centre;
    /// the spindle oriented (Q336: no axis moves) and the tool displaced
    /// by Q251 in the direction Q214; at Q253 down through the hole until
    /// the tooth is the set-up clearance below the underside; back over
    /// the centre; at Q254 up until the tooth is at the counterbore depth
    /// Q249 above the underside; dwell Q255; back down to the tooth's
    /// set-up clearance below the underside; displaced again; FMAX to the
    /// set-up clearance and the 2nd; back over the centre.
    ///
    /// The cycle run's text was not returned by `search` here: its order
    /// of steps is as recalled from the TNC 640 manual, and the feeds of
    /// the in-plane moves and of the way back down (Q253), and the final
    /// return to the centre (as cycle 202), are volcomp's readings
    /// (docs/dialects.md). The workpiece is taken with its surface Q203
    /// on the positive side of the tool axis (the cycle has no Q201 to
    /// give the direction); Q249 < 0 is refused.
    fn back_boring(&mut self) -> Result<(), CycleError> {
        let surface = self.length(203, "surface coordinate")? + self.call.surface_shift;
        let clearance = self.length(200, "set-up clearance")?.abs();
        let second = self.optional(204).abs() * self.scale;
        let depth = self.length(249, "depth of counterbore")?;
        let thickness = self.length(250, "material thickness")?.abs();
        let off = self.length(251, "off-centre distance")?.abs();
        let edge = self.length(252, "tool edge height")?.abs();
        let pre = self.feed(253, "feed rate for pre-positioning")?;
        let bore = self.feed(254, "feed rate for counterboring")?;
        if depth < 0.0 {
            return Err(CycleError::Unread(format!(
                "CYCL DEF 204 (line {}) with a negative depth of counterbore Q249 (towards the negative spindle axis)",
                self.def.line
            )));
        }
        if depth == 0.0 {
            return Ok(());
        }
        let [du, dv] = self.disengaging(off)?;
        let g = Geometry {
            surface,
            dir: -1.0,
            depth: thickness,
            clearance,
            second,
        };
        self.rapid_to(g.above(g.clearance));
        let centre = self.at;
        let d = from_plane(self.call.plane, [du, dv, 0.0]);
        let aside = |p: [f64; 3]| [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
        self.push(Step::Rapid(aside(centre)));
        // The tip: the tooth is `edge` above it.
        let low = g.below(thickness + clearance + edge);
        self.feed_to(low, pre);
        let mut under = centre;
        under[self.axis] = low;
        self.push(Step::Feed(under, pre));
        self.feed_to(g.below(thickness - depth + edge), bore);
        self.dwell(self.optional(255));
        self.feed_to(low, pre);
        self.push(Step::Rapid(aside(self.at)));
        self.leave(&g, None);
        let mut back = centre;
        back[self.axis] = self.at[self.axis];
        self.push(Step::Rapid(back));
        Ok(())
    }

    /// Cycle 203 UNIVERSAL DRILLING (TNC 640, "UNIVERSAL DRILLING (Cycle
    /// 203)"; TNC 320 3.6): FMAX to the set-up clearance; plunges
    /// of Q202 at Q206, each Q212 shorter but not under Q205; after a
    /// plunge either a chip break (back by Q256, at most Q213 times in a
    /// row) or back at Q208 to the set-up clearance, dwell Q210, FMAX to
    /// the set-up clearance above the depth reached; at the depth dwell
    /// Q211, back at Q208 to the set-up clearance, FMAX to the 2nd.
    fn universal_drilling(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        let first = self.length(202, "plunging depth")?.abs();
        if g.depth == 0.0 {
            return Ok(());
        }
        let decrement = self.optional(212).abs() * self.scale;
        let minimum = self.optional(205).abs() * self.scale;
        let breaks = self.optional(213).max(0.0).round() as u64;
        let retract = self.optional(256).abs() * self.scale;
        let back = self.retraction(feed);
        self.rapid_to(g.above(g.clearance));
        let mut step = if first <= 0.0 { g.depth } else { first };
        let (mut reached, mut broken) = (0.0f64, 0u64);
        loop {
            reached = (reached + step).min(g.depth);
            self.feed_to(g.below(reached), feed);
            if reached >= g.depth - 1e-12 || self.steps.len() > MAX_STEPS {
                break;
            }
            if broken < breaks {
                broken += 1;
                self.rapid_to(g.below(reached - retract));
            } else {
                broken = 0;
                self.feed_to(g.above(g.clearance), back);
                self.dwell(self.optional(210));
                self.rapid_to(g.below(reached - g.clearance));
            }
            step = shorter(step, decrement, minimum);
        }
        self.dwell(self.optional(211));
        self.leave(&g, Some(back));
        Ok(())
    }

    /// Cycle 205 UNIVERSAL PECKING (TNC 640, "UNIVERSAL PECKING (Cycle
    /// 205)"; TNC 320 3.8): FMAX to the set-up clearance (with a
    /// deepened starting point Q379, at Q253 to the set-up clearance above
    /// it); plunges of Q202 at Q206, each Q212 shorter but not under Q205,
    /// chip breaks of Q256 after every Q257 of infeed; after each plunge
    /// back at Q208 to the set-up clearance and FMAX to the advanced stop
    /// distance above the depth reached (Q258 for the first, Q259 for the
    /// last, changing at the same rate between); at the depth dwell Q211,
    /// back at Q208, FMAX to the 2nd set-up clearance. Q395 = 1 (depth to
    /// the full diameter) needs the tool's point angle: not read.
    fn universal_pecking(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        let first = self.length(202, "plunging depth")?.abs();
        if self.optional(395) != 0.0 {
            return Err(CycleError::Unread(
                "CYCL DEF 205 with Q395 = 1 (depth to the full tool diameter)".into(),
            ));
        }
        if g.depth == 0.0 {
            return Ok(());
        }
        let decrement = self.optional(212).abs() * self.scale;
        let minimum = self.optional(205).abs() * self.scale;
        let upper = self.optional(258).abs() * self.scale;
        let lower = self.def.get(259).map_or(upper, |v| v.abs() * self.scale);
        let chip = self.optional(257).abs() * self.scale;
        let retract = self.optional(256).abs() * self.scale;
        let deepened = self.deepened_start(&g);
        let back = self.retraction(feed);
        // The plunges (their depths), to know the last one's stop distance.
        let mut plunges = Vec::new();
        let mut step = if first <= 0.0 { g.depth } else { first };
        let mut reached = deepened;
        while reached < g.depth - 1e-12 && plunges.len() <= MAX_STEPS {
            reached = (reached + step).min(g.depth);
            plunges.push(reached);
            step = shorter(step, decrement, minimum);
        }
        self.approach_deepened(&g, deepened)?;
        let mut from = deepened;
        let n = plunges.len();
        for (k, &to) in plunges.iter().enumerate() {
            if k > 0 {
                // Back out for chip removal, then FMAX to the advanced stop distance.
                self.feed_to(g.above(g.clearance), back);
                let t = if n > 2 {
                    (k - 1) as f64 / (n - 2) as f64
                } else {
                    0.0
                };
                let stop = upper + (lower - upper) * t;
                self.rapid_to(g.below(from - stop));
            }
            if chip > 0.0 {
                let mut d = from + chip;
                while d < to - 1e-12 && self.steps.len() <= MAX_STEPS {
                    self.feed_to(g.below(d), feed);
                    self.rapid_to(g.below(d - retract));
                    d += chip;
                }
            }
            self.feed_to(g.below(to), feed);
            from = to;
        }
        self.dwell(self.optional(211));
        self.leave(&g, Some(back));
        Ok(())
    }

    /// Cycle 207 RIGID TAPPING (TNC 640 Cycle Programming, "RIGID TAPPING
    /// (Cycle 207)"; TNC 320 4.3): FMAX to the set-up clearance,
    /// to the depth in one move at the feed the spindle speed and the
    /// pitch Q239 give (F = S · pitch), the spindle reversed, back to the
    /// set-up clearance at the same feed, FMAX to the 2nd set-up
    /// clearance.
    fn rigid_tapping(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let pitch = self.length(239, "pitch")?.abs();
        let Some(rpm) = self.call.spindle_rpm.filter(|s| *s > 0.0) else {
            return Err(CycleError::Refused(
                "CYCL DEF 207 needs the spindle speed (TOOL CALL … S)".into(),
            ));
        };
        if g.depth == 0.0 {
            return Ok(());
        }
        let feed = rpm * pitch;
        if feed <= 0.0 {
            return Err(CycleError::Refused(
                "CYCL DEF 207: the pitch Q239 must not be 0".into(),
            ));
        }
        self.rapid_to(g.above(g.clearance));
        self.feed_to(g.below(g.depth), feed);
        self.leave(&g, Some(feed));
        Ok(())
    }

    /// Cycle 240 CENTERING (TNC 640, "CENTERING (Cycle 240)"; TNC 320
    /// 3.9) with Q343 = 0 (to the depth Q201): FMAX to the set-up
    /// clearance, Q206 to the depth, dwell Q211, FMAX to the set-up
    /// clearance and the 2nd. Q343 = 1 (to a diameter) needs the tool's
    /// point angle: not read.
    fn centering(&mut self) -> Result<(), CycleError> {
        if self.optional(343) != 0.0 {
            return Err(CycleError::Unread(
                "CYCL DEF 240 with Q343 = 1 (centering to a diameter)".into(),
            ));
        }
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        if g.depth == 0.0 {
            return Ok(());
        }
        self.rapid_to(g.above(g.clearance));
        self.feed_to(g.below(g.depth), feed);
        self.dwell(self.optional(211));
        self.leave(&g, None);
        Ok(())
    }

    /// The tapping feed: the spindle speed of the `TOOL CALL` times the
    /// pitch Q239 (mm/min), for the rigid tapping cycles.
    fn tapping_feed(&self) -> Result<f64, CycleError> {
        let pitch = self.length(239, "pitch")?.abs();
        let Some(rpm) = self.call.spindle_rpm.filter(|s| *s > 0.0) else {
            return Err(CycleError::Refused(format!(
                "CYCL DEF {} needs the spindle speed (TOOL CALL … S)",
                self.def.number
            )));
        };
        let feed = rpm * pitch;
        if feed <= 0.0 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF {}: the pitch Q239 must not be 0",
                self.def.number
            )));
        }
        Ok(feed)
    }

    /// Cycle 206 TAPPING with a floating tap holder (TNC 640 Cycle
    /// Programming, "TAPPING with a floating tap holder (Cycle 206)"):
    /// FMAX to the set-up clearance, to the depth in one move at Q206, the
    /// spindle reversed after the dwell Q211, back to the set-up clearance
    /// at Q206, FMAX to the 2nd set-up clearance. (The manual's text of
    /// this cycle was not found by `search` here: this is volcomp's
    /// reading of the cycle run, see docs/dialects.md.)
    fn tapping(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        if g.depth == 0.0 {
            return Ok(());
        }
        self.rapid_to(g.above(g.clearance));
        self.feed_to(g.below(g.depth), feed);
        self.dwell(self.optional(211));
        self.leave(&g, Some(feed));
        Ok(())
    }

    /// Cycle 209 TAPPING WITH CHIP BREAKING (TNC 640 Cycle Programming,
    /// "TAPPING WITH CHIP BREAKING (Cycle 209)"; TNC 320 340 55x-03, 8.2,
    /// whose parameter page was read: Q257 "depth at which the TNC carries
    /// out chip breaking"): FMAX to the set-up clearance; infeeds of Q257
    /// at F = S · pitch; after each, the spindle reversed and the tool
    /// retracted by Q256 × the pitch (Q256 = 0: to the set-up clearance)
    /// at Q403 × that feed, then on to the next infeed; at the depth back
    /// to the set-up clearance at Q403 × the feed, FMAX to the 2nd set-up
    /// clearance. Q336 (the spindle angle) does not move an axis. The
    /// text of Q256 (a multiple of the pitch) and of the retraction feed
    /// was not found by `search` here: volcomp's reading.
    fn tapping_chip_breaking(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.tapping_feed()?;
        if g.depth == 0.0 {
            return Ok(());
        }
        let pitch = self.length(239, "pitch")?.abs();
        let infeed = self.optional(257).abs() * self.scale;
        let retract = self.optional(256).abs() * pitch;
        let factor = self.def.get(403).filter(|f| *f > 0.0).unwrap_or(1.0);
        let out = feed * factor;
        self.rapid_to(g.above(g.clearance));
        let step = if infeed <= 0.0 { g.depth } else { infeed };
        let mut reached = 0.0f64;
        loop {
            reached = (reached + step).min(g.depth);
            self.feed_to(g.below(reached), feed);
            if reached >= g.depth - 1e-12 || self.steps.len() > MAX_STEPS {
                break;
            }
            if retract > 0.0 {
                self.feed_to(g.below(reached - retract), out);
            } else {
                self.feed_to(g.above(g.clearance), out);
            }
        }
        self.leave(&g, Some(out));
        Ok(())
    }

    /// Cycle 241 SINGLE-LIP DEEP-HOLE DRILLING (TNC 640 Cycle
    /// Programming, "SINGLE-LIP DEEP-HOLE DRILLING (Cycle 241)"): FMAX to
    /// the set-up clearance; with a deepened starting point Q379, at the
    /// pre-positioning feed Q253 to the set-up clearance above it; at Q206
    /// to the depth; dwell Q211; back at Q208 (0: Q206) to the set-up
    /// clearance, FMAX to the 2nd set-up clearance. The spindle speeds and
    /// directions (Q426–Q428) and the coolant M functions (Q429, Q430) do
    /// not move an axis. A dwell depth Q435 and the pecking of the newer
    /// cycle (Q202 shorter than the depth) are refused: their motion was
    /// not read. The manual's text of this cycle was not found by `search`
    /// here: volcomp's reading of its cycle run (docs/dialects.md).
    fn single_lip_drilling(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        if self.optional(435) != 0.0 {
            return Err(CycleError::Unread(format!(
                "CYCL DEF 241 (line {}) with a dwell depth Q435 (where the tool dwells on the way)",
                self.def.line
            )));
        }
        let peck = self.optional(202).abs() * self.scale;
        if peck > 0.0 && peck < g.depth {
            return Err(CycleError::Unread(format!(
                "CYCL DEF 241 (line {}) with a plunging depth Q202 shorter than the depth (pecking)",
                self.def.line
            )));
        }
        if g.depth == 0.0 {
            return Ok(());
        }
        let deepened = self.deepened_start(&g);
        let back = self.retraction(feed);
        self.approach_deepened(&g, deepened)?;
        self.feed_to(g.below(g.depth), feed);
        self.dwell(self.optional(211));
        self.leave(&g, Some(back));
        Ok(())
    }

    /// Cycle 208 BORE MILLING (TNC 640 Cycle Programming, "BORE MILLING
    /// (Cycle 208)"): FMAX to the set-up clearance over the centre; to
    /// the bore circumference on a rounded arc; a helix at Q206 down to
    /// the depth, Q334 per turn, on the circle of radius Q335/2 − the tool
    /// radius (the tool table's R + DR); at the depth one more full circle;
    /// back to the centre; FMAX to the set-up clearance and the 2nd. A
    /// nominal diameter equal to the tool's: straight down at Q206, no
    /// helix. Q351 +1 (or 0, or absent) climb milling, counter-clockwise
    /// (DR+) about the tool axis with M3; −1 up-cut, clockwise. Q342 (the
    /// roughing diameter) only lifts the control's check of the ratio of
    /// the nominal to the tool diameter: it does not move the tool.
    ///
    /// The manual's text of this cycle was not found by `search` here, so
    /// these readings are volcomp's, listed in docs/dialects.md: the
    /// rounded approach arc is a semicircle from the centre, tangent to the
    /// helix at its start on the working plane's first axis (+u), at Q206
    /// at the set-up clearance (in the air); the helix starts at the set-up
    /// clearance; the way back to the centre is a straight line at Q206.
    fn bore_milling(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let feed = self.feed(206, "feed rate for plunging")?;
        let per_turn = self.length(334, "plunging depth per helix")?.abs();
        let diameter = self.length(335, "nominal diameter")?.abs();
        let Some(tool) = self.call.tool_radius else {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 208 (line {}) needs the tool radius: the tool in the spindle is not in the tool table (a tool called by name needs `name` in the machine file's [[tools]])",
                self.def.line
            )));
        };
        let r = diameter / 2.0 - tool;
        if r < -1e-9 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 208: the nominal diameter Q335 ({diameter} mm) is smaller than the tool's ({} mm)",
                2.0 * tool
            )));
        }
        if g.depth == 0.0 {
            return Ok(());
        }
        let ccw = self.optional(351) >= 0.0;
        self.rapid_to(g.above(g.clearance));
        let centre = self.at;
        if r <= 1e-9 {
            self.feed_to(g.below(g.depth), feed);
            self.leave(&g, None);
            return Ok(());
        }
        if per_turn <= 0.0 {
            return Err(CycleError::Refused(
                "CYCL DEF 208: the plunging depth per helix Q334 must be greater than 0".into(),
            ));
        }
        let c = to_plane(self.call.plane, centre);
        let w_top = c[2];
        let w_bottom = to_plane(self.call.plane, self.point(g.below(g.depth)))[2];
        // The approach: a semicircle of diameter r from the centre to (u + r, v).
        let half = [c[0] + r / 2.0, c[1]];
        let first = [c[0] + r, c[1], w_top];
        self.arc_in_plane(half, [c[0], c[1], w_top], first, !ccw, 0, feed);
        // The helix: (travel / Q334) turns from the set-up clearance.
        let turns = (w_top - w_bottom).abs() / per_turn;
        if turns > MAX_STEPS as f64 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 208: more than {MAX_STEPS} helix turns"
            )));
        }
        let end = self.helix([c[0], c[1]], first, w_bottom, turns, ccw, feed);
        // One more full circle at the depth, then back to the centre.
        self.arc_in_plane([c[0], c[1]], end, end, !ccw, 0, feed);
        let bottom_centre = from_plane(self.call.plane, [c[0], c[1], w_bottom]);
        self.push(Step::Feed(bottom_centre, feed));
        self.leave(&g, None);
        Ok(())
    }

    /// Cycle 262 THREAD MILLING (TNC 640 Cycle Programming, "THREAD
    /// MILLING (Cycle 262)" and "Fundamentals of thread milling"; the
    /// parameters as the TNC 426/430 User's Manual, 8.3, pp. 247/251, gives them: Q335
    /// nominal diameter, Q239 pitch, its sign the hand (+ right, − left),
    /// Q201 thread depth, Q355 threads per step (0: one 360° helix to the
    /// depth, 1: one continuous helix over the thread's length, > 1: several
    /// helices with approach and departure, offset by Q355 × the pitch),
    /// Q253 pre-positioning feed, Q351 +1 climb / −1 up-cut with M3, Q207
    /// milling feed): FMAX to the set-up clearance over the centre; at Q253
    /// to the starting plane, then the compensating move in the tool axis
    /// that makes the helical approach arrive at it; the approach, the
    /// helix on the circle of radius Q335/2 − the tool radius (tool table
    /// R + DR), the departure to the centre; FMAX to the set-up clearance
    /// and the 2nd. The working direction is the fundamentals' table:
    /// right-hand and climb, or left-hand and up-cut, out of the hole
    /// (Z+ for a hole in −Z); the other two into it. Climb (Q351 = +1, 0
    /// or absent, as 208) is counter-clockwise about the tool axis.
    ///
    /// The cycle run's own text and the fundamentals' table were not
    /// returned by `search` here (the order of the run above and the table
    /// are as recalled from the TNC 640 manual), so these details are
    /// volcomp's readings (docs/dialects.md): the starting
    /// plane is the depth when working out of the hole, the surface (Q355
    /// = 1) or one pitch above the depth (Q355 = 0) when working into it;
    /// with Q355 = k > 1 each helix is one turn, the helices one k × pitch
    /// apart from the depth upwards (taken from the top down when working
    /// into the hole), as many as cover the depth; the approach is a
    /// semicircle of diameter (helix radius) from the centre to the helix
    /// start on the working plane's first axis (+u), tangent to the helix
    /// and rising at its lead (a quarter pitch), the departure the same
    /// from the helix end back to the centre; approach, helix and
    /// departure at Q207 scaled to the tool centre (Q207 × helix radius /
    /// thread radius: the fundamentals say the feed refers to the cutting
    /// edge); the moves between helices at Q253.
    fn thread_milling(&mut self) -> Result<(), CycleError> {
        let g = self.geometry()?;
        let diameter = self.length(335, "nominal diameter")?.abs();
        let pitch = self.length(239, "thread pitch")?;
        let pre = self.feed(253, "feed rate for pre-positioning")?;
        let milling = self.feed(207, "feed rate for milling")?;
        let per_step = self.optional(355);
        let line = self.def.line;
        if per_step < 0.0 || per_step.fract() != 0.0 || per_step > 1e6 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 262 (line {line}): Q355 (threads per step) must be a whole number from 0, not {per_step}"
            )));
        }
        if pitch == 0.0 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 262 (line {line}): the thread pitch Q239 must not be 0"
            )));
        }
        let Some(tool) = self.call.tool_radius else {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 262 (line {line}) needs the tool radius: the tool in the spindle is not in the tool table (a tool called by name needs `name` in the machine file's [[tools]])"
            )));
        };
        let r = diameter / 2.0 - tool;
        if r <= 1e-9 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 262 (line {line}): the tool ({} mm) is not smaller than the nominal diameter Q335 ({diameter} mm)",
                2.0 * tool
            )));
        }
        if g.depth == 0.0 {
            return Ok(());
        }
        let ccw = self.optional(351) >= 0.0;
        let lead = pitch.abs();
        // Out of the hole (towards the surface) or into it.
        let out = (pitch > 0.0) == ccw;
        // Each helix as (start, end) depths below the surface.
        let mut helices: Vec<(f64, f64)> = Vec::new();
        match per_step as u64 {
            1 => helices.push((g.depth, 0.0)),
            0 => helices.push((g.depth, g.depth - lead)),
            k => {
                let offset = k as f64 * lead;
                let n = (g.depth / offset - 1e-9).ceil().max(1.0);
                if n > MAX_STEPS as f64 {
                    return Err(CycleError::Refused(format!(
                        "CYCL DEF 262: more than {MAX_STEPS} helices"
                    )));
                }
                for j in 0..n as u64 {
                    let b = g.depth - j as f64 * offset;
                    helices.push((b, b - lead));
                }
            }
        }
        if !out {
            helices.reverse();
            for h in &mut helices {
                *h = (h.1, h.0);
            }
        }
        let turns = helices
            .iter()
            .map(|(a, b)| (a - b).abs() / lead)
            .sum::<f64>();
        if turns > MAX_STEPS as f64 {
            return Err(CycleError::Refused(format!(
                "CYCL DEF 262: more than {MAX_STEPS} helix turns"
            )));
        }
        let feed = milling * r / (diameter / 2.0);
        self.rapid_to(g.above(g.clearance));
        let centre = self.at;
        let plane = self.call.plane;
        let axis = self.axis;
        let w_at = |b: f64| {
            let mut p = centre;
            p[axis] = g.below(b);
            to_plane(plane, p)[2]
        };
        let c = to_plane(plane, centre);
        // The approach and the departure each travel a quarter pitch (the
        // helix's lead over a semicircle of half its radius).
        let quarter = lead / 4.0;
        for (from, to) in helices {
            if self.steps.len() > MAX_STEPS {
                break;
            }
            let down = if to > from { 1.0 } else { -1.0 };
            self.feed_to(g.below(from), pre);
            self.feed_to(g.below(from - down * quarter), pre);
            let start = [c[0], c[1], w_at(from - down * quarter)];
            let first = [c[0] + r, c[1], w_at(from)];
            self.arc_in_plane([c[0] + r / 2.0, c[1]], start, first, !ccw, 0, feed);
            let end = self.helix(
                [c[0], c[1]],
                first,
                w_at(to),
                (to - from).abs() / lead,
                ccw,
                feed,
            );
            let half = [(c[0] + end[0]) / 2.0, (c[1] + end[1]) / 2.0];
            let back = [c[0], c[1], w_at(to + down * quarter)];
            self.arc_in_plane(half, end, back, !ccw, 0, feed);
        }
        self.leave(&g, None);
        Ok(())
    }

    /// A helix about `centre` (u, v) from `from` (u, v, w; on the circle)
    /// through `turns` turns (counter-clockwise when `ccw`) to the tool-axis
    /// coordinate `w_end`, turn by turn (each turn's chords within the
    /// tolerance); returns its end (u, v, w).
    fn helix(
        &mut self,
        centre: [f64; 2],
        from: [f64; 3],
        w_end: f64,
        turns: f64,
        ccw: bool,
        feed: f64,
    ) -> [f64; 3] {
        let rate = if turns > 0.0 {
            (w_end - from[2]) / turns
        } else {
            0.0
        };
        let whole = (turns + 1e-9).floor();
        let mut at = from;
        for k in 1..=whole as u64 {
            if self.steps.len() > MAX_STEPS {
                return at;
            }
            let to = [from[0], from[1], from[2] + rate * k as f64];
            self.arc_in_plane(centre, at, to, !ccw, 0, feed);
            at = to;
        }
        let rest = turns - whole;
        if rest <= 1e-9 {
            return at;
        }
        let sense = if ccw { 1.0 } else { -1.0 };
        let a0 = (from[1] - centre[1]).atan2(from[0] - centre[0]);
        let r = (from[0] - centre[0]).hypot(from[1] - centre[1]);
        let a = a0 + sense * rest * std::f64::consts::TAU;
        let to = [centre[0] + r * a.cos(), centre[1] + r * a.sin(), w_end];
        self.arc_in_plane(centre, at, to, !ccw, 0, feed);
        to
    }

    /// An arc (or helix) in the working plane about `centre` (u, v) from
    /// `from` to `to` (u, v, w), `turns` extra full turns, as chords within
    /// the Klartext reader's chord tolerance (`geometry::arc_chords`).
    fn arc_in_plane(
        &mut self,
        centre: [f64; 2],
        from: [f64; 3],
        to: [f64; 3],
        clockwise: bool,
        turns: u32,
        feed: f64,
    ) {
        let plane = self.call.plane;
        for q in arc_chords(centre, from, to, clockwise, turns, CHORD_TOLERANCE_MM) {
            if self.steps.len() > MAX_STEPS {
                break;
            }
            self.push(Step::Feed(from_plane(plane, q), feed));
        }
    }

    /// The old cycle 1 PECKING (`CYCL DEF 1.0 PECKING`, `1.1 SET UP`, `1.2
    /// DEPTH`, `1.3 PECKG`, `1.4 DWELL`, `1.5 F`; iTNC 530 User's Manual,
    /// "PECKING (Cycle 1)"; TNC 426 User's Manual 8.2): from the call
    /// position (the set-up clearance above the surface) at F to the first
    /// pecking depth; FMAX back to the start and again to the depth reached
    /// less the advanced stop distance t (0.6 mm up to a 30 mm hole, else
    /// depth / 50, at most 7 mm); again at F; at the hole's depth dwell,
    /// FMAX back to the start. Depths count from the start, signed as the
    /// DEPTH.
    fn pecking_old(&mut self) -> Result<(), CycleError> {
        let get = |k: u32, name: &str| {
            self.def.get(k).ok_or_else(|| {
                CycleError::Refused(format!(
                    "CYCL DEF 1 (line {}) without 1.{k} {name}",
                    self.def.line
                ))
            })
        };
        let setup = get(1, "SET UP")?.abs() * self.scale;
        let depth = get(2, "DEPTH")? * self.scale;
        let peck = get(3, "PECKG")?.abs() * self.scale;
        let dwell = get(4, "DWELL")?.max(0.0);
        let feed = get(5, "F")? * if self.call.inch { 2.54 } else { 1.0 };
        if feed <= 0.0 {
            return Err(CycleError::Refused(
                "CYCL DEF 1.5: the feed rate must be positive".into(),
            ));
        }
        if depth == 0.0 {
            return Ok(());
        }
        let dir = depth.signum();
        let start = self.at[self.axis];
        let total = setup + depth.abs();
        let stop = if depth.abs() <= 30.0 {
            0.6
        } else {
            (depth.abs() / 50.0).min(7.0)
        };
        let step = if peck <= 0.0 { total } else { peck };
        let mut reached = 0.0f64;
        loop {
            reached = (reached + step).min(total);
            self.feed_to(start + dir * reached, feed);
            if reached >= total - 1e-12 || self.steps.len() > MAX_STEPS {
                break;
            }
            self.rapid_to(start);
            self.rapid_to(start + dir * (reached - stop).max(0.0));
        }
        self.dwell(dwell);
        self.rapid_to(start);
        Ok(())
    }
}

/// Why a machining cycle volcomp knows of is not expanded: the detail of
/// its motion the manual's text (as read here) does not give exactly.
fn not_expanded(number: u32) -> Option<&'static str> {
    Some(match number {
        251 | 252 | 253 | 254 | 256 | 257 => {
            "the pocket, slot and stud cycles (251-257) are not expanded: the manual's cycle run (TNC 640 34059x-01, 5.6, read for 256) gives the order of the passes, not the path: how many stepovers of at most Q370 x the tool radius and where each lies (TNC 620 340 56x-02, 5.6: \"the TNC always calculates a constant stepover\"), the helical or reciprocating plunge of Q366 (its angle is the TNC tool table's ANGLE column, which volcomp's tool table does not have), and the finishing passes (Q338 infeed, Q385 feed) and their approach"
        }
        263 | 264 | 265 | 267 => {
            "thread milling with countersinking or drilling (263 thread milling/countersinking, 264 thread drilling/milling, 265 helical thread drilling/milling, 267 outside thread milling) is not expanded: the manual's text as read here gives their parameters (Q356 countersinking or hole depth, Q357 clearance to the side, Q358/Q359 countersinking at the front, Q360 before or after the thread, Q202/Q257/Q256 drilling, Q376 the outside start angle) but not the path of the countersinking, drilling and outside approach moves; cycle 262 is expanded"
        }
        _ => return None,
    })
}

/// The next plunge: `step` less `decrement`, not under `minimum` (nor 0).
fn shorter(step: f64, decrement: f64, minimum: f64) -> f64 {
    if decrement <= 0.0 {
        return step;
    }
    let floor = if minimum > 0.0 {
        minimum.min(step)
    } else {
        step.min(1e-3)
    };
    (step - decrement).max(floor)
}

/// The tool-axis geometry of a 2xx cycle.
struct Geometry {
    surface: f64,
    /// −1 when the depth goes to −axis (Q201 negative).
    dir: f64,
    depth: f64,
    clearance: f64,
    second: f64,
}

impl Geometry {
    /// The coordinate `h` above the surface (away from the workpiece).
    fn above(&self, h: f64) -> f64 {
        self.surface - self.dir * h
    }

    /// The coordinate `d` below the surface (into the workpiece).
    fn below(&self, d: f64) -> f64 {
        self.surface + self.dir * d
    }
}

/// The points of a `PATTERN DEF` (in-plane coordinates u v of the working
/// plane, and the surface shift in the tool axis), in machining order.
#[derive(Clone, Debug, PartialEq, Default)]
pub(crate) struct Pattern {
    /// (u, v, surface shift) of each point, mm.
    pub points: Vec<[f64; 3]>,
    /// The line of its `PATTERN DEF`.
    pub line: usize,
}

/// `PATTERN DEF` with its `POS`, `ROW`, `PAT`, `FRAME`, `CIRC` and
/// `PITCHCIRC` entries (TNC 640 Cycle Programming, "Pattern definition
/// PATTERN DEF"; iTNC 530 User's Manual 340 422, 11.3): each entry's
/// points in order. Coordinates are absolute in the working plane (`IX`,
/// `IY` incremental from the previous point); `Z` is the surface
/// coordinate, added to the cycle's Q203. A `PAT`/`FRAME` is machined row
/// by row from its first point; `ROTX`/`ROTY` (sheared rows) are not read.
pub(crate) fn pattern(
    block: &KlBlock,
    line: usize,
    plane: Plane,
    inch: bool,
    value: &dyn Fn(&Value) -> f64,
) -> Result<Arc<Pattern>, CycleError> {
    let scale = if inch { 25.4 } else { 1.0 };
    let code = block.code.as_str();
    let mut points: Vec<[f64; 3]> = Vec::new();
    let mut rest = code;
    let upper = code.to_ascii_uppercase();
    let mut offset = 0;
    // Skip `PATTERN DEF`.
    if let Some(k) = upper.find("DEF") {
        offset = k + 3;
        rest = &code[offset..];
    }
    while let Some(open) = rest.find('(') {
        let name = rest[..open].trim().to_ascii_uppercase();
        let Some(close) = rest[open..].find(')') else {
            return Err(CycleError::Refused(
                "PATTERN DEF: an entry without its closing `)`".into(),
            ));
        };
        let inner = &rest[open + 1..open + close];
        let words = parse_block(inner.as_bytes());
        let kind: String = name
            .chars()
            .take_while(|c| c.is_ascii_alphabetic())
            .collect();
        let get = |a: &str| -> Option<f64> {
            words
                .tokens
                .iter()
                .find(|t| t.address == a)
                .and_then(|t| t.value.as_ref())
                .map(value)
        };
        let need = |a: &str| {
            get(a).ok_or_else(|| CycleError::Refused(format!("PATTERN DEF {name}: no {a}")))
        };
        let last = points.last().copied().unwrap_or([0.0; 3]);
        let coordinate = |letter: &str, slot: usize| -> Option<f64> {
            // The in-plane slot of X/Y/Z: a word for the tool axis is the surface.
            match get(letter) {
                Some(v) => Some(v * scale),
                None => get(&format!("I{letter}")).map(|v| last[slot] + v * scale),
            }
        };
        // X Y Z → the plane's (u, v, w).
        let mut uvw = [None; 3];
        for (k, letter) in ["X", "Y", "Z"].iter().enumerate() {
            let mut e = [0.0; 3];
            e[k] = 1.0;
            let q = to_plane(plane, e);
            let slot = q.iter().position(|v| *v == 1.0).unwrap_or(2);
            uvw[slot] = coordinate(letter, slot);
        }
        let (u0, v0) = match (uvw[0], uvw[1]) {
            (Some(u), Some(v)) => (u, v),
            _ => {
                return Err(CycleError::Refused(format!(
                    "PATTERN DEF {name}: both working-plane coordinates are needed"
                )));
            }
        };
        let w = uvw[2].unwrap_or(0.0);
        let count = |a: &str| -> Result<usize, CycleError> {
            let n = need(a)?;
            if n < 1.0 || n.fract() != 0.0 || n > 100_000.0 {
                return Err(CycleError::Refused(format!(
                    "PATTERN DEF {name}: {a} must be a whole number from 1"
                )));
            }
            Ok(n as usize)
        };
        let turn = |du: f64, dv: f64, deg: f64| {
            let (s, c) = deg.to_radians().sin_cos();
            [u0 + du * c - dv * s, v0 + du * s + dv * c, w]
        };
        match kind.as_str() {
            "POS" => points.push([u0, v0, w]),
            "ROW" => {
                let d = need("D")? * scale;
                let n = count("NUM")?;
                let rot = get("ROT").unwrap_or(0.0);
                for k in 0..n {
                    points.push(turn(k as f64 * d, 0.0, rot));
                }
            }
            "PAT" | "FRAME" => {
                if get("ROTX").unwrap_or(0.0) != 0.0 || get("ROTY").unwrap_or(0.0) != 0.0 {
                    return Err(CycleError::Unread(format!(
                        "PATTERN DEF {name} with ROTX/ROTY (sheared rows)"
                    )));
                }
                let (dx, dy) = (need("DX")? * scale, need("DY")? * scale);
                let (nx, ny) = (count("NUMX")?, count("NUMY")?);
                let rot = get("ROT").unwrap_or(0.0);
                for j in 0..ny {
                    for i in 0..nx {
                        let border = i == 0 || j == 0 || i + 1 == nx || j + 1 == ny;
                        if kind == "PAT" || border {
                            points.push(turn(i as f64 * dx, j as f64 * dy, rot));
                        }
                    }
                }
            }
            "CIRC" | "PITCHCIRC" => {
                let r = need("D")? * scale / 2.0;
                let n = count("NUM")?;
                let start = get("START").unwrap_or(0.0);
                let step = if kind == "CIRC" {
                    360.0 / n as f64
                } else {
                    need("STEP")?
                };
                for k in 0..n {
                    let (s, c) = (start + k as f64 * step).to_radians().sin_cos();
                    points.push([u0 + r * c, v0 + r * s, w]);
                }
            }
            _ => {
                return Err(CycleError::Unread(format!("PATTERN DEF entry {name}")));
            }
        }
        if points.len() > MAX_STEPS {
            return Err(CycleError::Refused(format!(
                "PATTERN DEF: more than {MAX_STEPS} points"
            )));
        }
        offset += open + close + 1;
        rest = &code[offset..];
    }
    if points.is_empty() {
        return Err(CycleError::Refused(
            "PATTERN DEF without an entry (POS, ROW, PAT, FRAME, CIRC, PITCHCIRC)".into(),
        ));
    }
    Ok(Arc::new(Pattern { points, line }))
}

/// The surface, the 2nd set-up clearance height of a 2xx cycle called at
/// `call`, and the direction away from the workpiece (+1 when the depth
/// Q201 is negative); `None` for a cycle without Q203 (the old cycles).
pub(crate) fn levels(def: &CycleDef, call: &Call) -> Option<(f64, f64, f64)> {
    let scale = if call.inch { 25.4 } else { 1.0 };
    let surface = def.get(203)? * scale + call.surface_shift;
    let up = if def.get(201).unwrap_or(-1.0) < 0.0 {
        1.0
    } else {
        -1.0
    };
    let second = surface + up * def.get(204).unwrap_or(0.0).abs() * scale;
    Some((surface, second, up))
}

/// The clearance height of `CYCL CALL PAT` for `def`: the greater of the
/// tool-axis coordinate at the call and the 2nd set-up clearance Q204
/// above the surface (TNC 640 Cycle Programming, "Calling cycles with
/// PATTERN DEF": "The control uses either the spindle axis coordinate
/// during cycle call or the value from cycle parameter Q204 as the
/// clearance height, whichever is greater"), "greater" away from the
/// workpiece. `None` for a cycle without Q203 (the old cycles).
pub(crate) fn clearance_height(def: &CycleDef, call: &Call, current: f64) -> Option<f64> {
    let (_, second, up) = levels(def, call)?;
    Some(if (current - second) * up >= 0.0 {
        current
    } else {
        second
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn def(number: u32, q: &[(u32, f64)]) -> CycleDef {
        CycleDef {
            number,
            q: q.to_vec(),
            line: 1,
        }
    }

    fn call() -> Call {
        Call {
            start: [10.0, 20.0, 50.0],
            plane: Plane::XY,
            inch: false,
            spindle_rpm: Some(500.0),
            tool_radius: Some(4.0),
            surface_shift: 0.0,
        }
    }

    fn z_path(steps: &[Step]) -> Vec<(char, f64)> {
        steps
            .iter()
            .filter_map(|s| match s {
                Step::Rapid(p) => Some(('r', (p[2] * 1e9).round() / 1e9)),
                Step::Feed(p, _) => Some(('f', (p[2] * 1e9).round() / 1e9)),
                Step::Dwell(_) => None,
            })
            .collect()
    }

    #[test]
    fn universal_drilling_breaks_chips_then_retracts() {
        // Depth 10 in plunges of 4, 3, 3 (decrement 1, minimum 3), one chip
        // break of 0.5 before each full retraction.
        let d = def(
            203,
            &[
                (200, 2.0),
                (201, -10.0),
                (206, 150.0),
                (202, 4.0),
                (203, 0.0),
                (204, 50.0),
                (212, 1.0),
                (213, 1.0),
                (205, 3.0),
                (208, 500.0),
                (256, 0.5),
            ],
        );
        let z = z_path(&expand(&d, &call()).unwrap());
        assert_eq!(
            z,
            vec![
                ('r', 2.0),
                ('f', -4.0),
                ('r', -3.5),
                ('f', -7.0),
                ('f', 2.0),
                ('r', -5.0),
                ('f', -10.0),
                ('f', 2.0),
                ('r', 50.0),
            ]
        );
    }

    #[test]
    fn universal_pecking_stops_short_by_the_advanced_distances() {
        let d = def(
            205,
            &[
                (200, 2.0),
                (201, -9.0),
                (206, 150.0),
                (202, 3.0),
                (203, 0.0),
                (204, 20.0),
                (258, 1.0),
                (259, 0.5),
            ],
        );
        let z = z_path(&expand(&d, &call()).unwrap());
        assert_eq!(
            z,
            vec![
                ('r', 2.0),
                ('f', -3.0),
                ('f', 2.0),
                ('r', -2.0),
                ('f', -6.0),
                ('f', 2.0),
                ('r', -5.5),
                ('f', -9.0),
                ('f', 2.0),
                ('r', 20.0),
            ]
        );
    }

    #[test]
    fn old_pecking_returns_to_the_start() {
        let mut d = def(1, &[]);
        for (k, v) in [(1, -2.0), (2, -8.0), (3, -5.0), (4, 0.0), (5, 80.0)] {
            d.set(k, v);
        }
        let mut c = call();
        c.start[2] = 2.0;
        let z = z_path(&expand(&d, &c).unwrap());
        assert_eq!(
            z,
            vec![
                ('f', -3.0),
                ('r', 2.0),
                ('r', -2.4),
                ('f', -8.0),
                ('r', 2.0)
            ]
        );
    }

    #[test]
    fn patterns_list_their_points() {
        let b = parse_block(
            b"PATTERN DEF ~\n ROW1 ( X+0 Y+0 D+10 NUM3 ROT+90 Z+1 ) ~\n CIRC1 ( X+0 Y+0 D+20 START+0 NUM4 Z+0 )",
        );
        let p = pattern(&b, 1, Plane::XY, false, &|v| match v {
            Value::Number(x) | Value::Sign(x) => *x,
            Value::Param { .. } => 0.0,
        })
        .unwrap();
        let want = [
            [0.0, 0.0, 1.0],
            [0.0, 10.0, 1.0],
            [0.0, 20.0, 1.0],
            [10.0, 0.0, 0.0],
            [0.0, 10.0, 0.0],
            [-10.0, 0.0, 0.0],
            [0.0, -10.0, 0.0],
        ];
        assert_eq!(p.points.len(), want.len());
        for (a, b) in p.points.iter().zip(want) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn values_after_spaces_are_read() {
        let b = parse_block(
            b"CYCL DEF 209 TAPPING W/ CHIP BRKG~\n Q200=  3 ;A~\n Q201= -48 ;B~\n Q239=+2",
        );
        let d = define(&b, 209, 0, 1, None, &|k| match &b.tokens[k].value {
            Some(Value::Number(x)) => *x,
            _ => f64::NAN,
        })
        .unwrap();
        assert_eq!(d.q, vec![(200, 3.0), (201, -48.0), (239, 2.0)]);
    }

    #[test]
    fn thread_milling_works_out_of_the_hole_for_right_climb_and_left_up_cut() {
        // The fundamentals' table: the first two moves after FMAX to Z+2
        // (Q253 to the starting plane, the quarter-pitch compensation).
        for (pitch, climb, want) in [
            (2.0, 1.0, [-8.0, -8.5]),
            (-2.0, -1.0, [-8.0, -8.5]),
            (2.0, -1.0, [0.0, 0.5]),
            (-2.0, 1.0, [0.0, 0.5]),
        ] {
            let d = def(
                262,
                &[
                    (335, 24.0),
                    (239, pitch),
                    (201, -8.0),
                    (355, 1.0),
                    (253, 500.0),
                    (351, climb),
                    (200, 2.0),
                    (203, 0.0),
                    (204, 50.0),
                    (207, 300.0),
                ],
            );
            let z = z_path(&expand(&d, &call()).unwrap());
            assert_eq!(z[..3], [('r', 2.0), ('f', want[0]), ('f', want[1])]);
        }
    }

    #[test]
    fn unexpanded_cycles_are_named() {
        let e = expand(&def(263, &[]), &call()).unwrap_err();
        assert!(matches!(e, CycleError::Unread(m) if m.contains("CYCL DEF 263")));
    }
}
