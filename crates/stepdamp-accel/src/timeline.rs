//! The move of `M973` and `M974` as `calibration.cpp` plans it (`v6.3.1`, lines 871–1209):
//! a list of constant-acceleration segments along the move's direction, and the planned
//! annotation times. Speeds in motor rev/s, distances in motor revolutions, times in s from
//! the start of the first settle block.

use crate::capture::{
    CaptureError, Gcode, MARKER_ACCEL_REV_S2, MARKER_SPEED_REV_S, PlannedTimes, RAMP_ACCEL_REV_S2, SETTLE_PEAK_MM_S,
    SETTLE_S,
};

/// One constant-acceleration piece.
#[derive(Debug, Clone, Copy)]
struct Segment {
    t0: f64,
    dur: f64,
    v0: f64,
    v1: f64,
    d0: f64,
}

/// The planned move.
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    segments: Vec<Segment>,
    /// The times the firmware annotates.
    pub times: PlannedTimes,
}

/// Builds the segments one block at a time.
struct Builder {
    segments: Vec<Segment>,
    t: f64,
    d: f64,
    mm_per_rev: f64,
}

impl Builder {
    fn ramp(&mut self, v0: f64, v1: f64, dur: f64) {
        if dur > 0.0 {
            self.segments.push(Segment { t0: self.t, dur, v0, v1, d0: self.d });
            self.t += dur;
            self.d += 0.5 * (v0 + v1) * dur;
        }
    }

    /// `plan_no_movement_block`: 0 → 0.1 mm/s → 0 over 0.2 s (calibration.cpp:871–902).
    fn settle(&mut self) {
        let peak = SETTLE_PEAK_MM_S / self.mm_per_rev;
        self.ramp(0.0, peak, SETTLE_S / 2.0);
        self.ramp(peak, 0.0, SETTLE_S / 2.0);
    }

    /// `plan_accel_block` (calibration.cpp:935–983): nothing when the speeds are equal.
    fn accel(&mut self, v0: f64, v1: f64, accel: f64) {
        self.ramp(v0, v1, (v1 - v0).abs() / accel);
    }

    /// The end both G-codes share: ramp down from `v`, settle, marker, settle; returns the
    /// time the second marker begins (`end_marker`).
    fn stop_from(&mut self, v: f64) -> f64 {
        self.accel(v, 0.0, RAMP_ACCEL_REV_S2);
        self.settle();
        let end_marker = self.t;
        self.marker();
        self.settle();
        end_marker
    }

    /// `plan_marker_move` (calibration.cpp:1036–1048): out and back at ±2 rev/s.
    fn marker(&mut self) {
        let (v, a) = (MARKER_SPEED_REV_S, MARKER_ACCEL_REV_S2);
        self.accel(0.0, v, a);
        self.accel(v, 0.0, a);
        self.accel(0.0, -v, a);
        self.accel(-v, 0.0, a);
    }
}

/// The plan of `g`; `mm_per_rev` converts the settle blocks' millimetres.
pub(crate) fn plan(g: &Gcode, mm_per_rev: f64) -> Result<Plan, CaptureError> {
    let mut b = Builder { segments: Vec::new(), t: 0.0, d: 0.0, mm_per_rev };
    let times = match *g {
        Gcode::ParamSweep { speed, revs, .. } => {
            let bad = !(speed.is_finite() && speed > 0.0 && revs.is_finite());
            if bad {
                return Err(param(
                    "M973 F/R",
                    format!("F{speed} R{revs}"),
                    "F > 0 (the firmware refuses F ≤ 0), finite R",
                ));
            }
            param_sweep(&mut b, speed, revs.abs())
        }
        Gcode::SpeedSweep { start_speed: a, end_speed: v, revs, .. } => {
            let finite = a.is_finite() && v.is_finite() && revs.is_finite();
            if !finite || a < 0.0 || v < 0.0 || revs == 0.0 || (a == 0.0 && v == 0.0) {
                return Err(param("M974 A/B/R", format!("A{a} B{v} R{revs}"), "A, B ≥ 0, not both 0, R ≠ 0"));
            }
            if a == v {
                return Err(param(
                    "M974 A/B",
                    format!("A{a} B{v}"),
                    "A = B: the firmware asserts A ≠ B (plan_accel_over_dist_block, calibration.cpp:989)",
                ));
            }
            speed_sweep(&mut b, a, v, revs.abs() / 2.0)
        }
    };
    Ok(Plan { segments: b.segments, times })
}

fn param(what: &'static str, value: String, allowed: &str) -> CaptureError {
    CaptureError::Parameter { what, value, allowed: allowed.into() }
}

/// `capture_param_sweep_samples` (calibration.cpp:1107–1160).
fn param_sweep(b: &mut Builder, v: f64, revs: f64) -> PlannedTimes {
    b.settle();
    let start_marker = b.t;
    b.marker();
    b.accel(0.0, v, RAMP_ACCEL_REV_S2);
    let constant_start = b.t;
    let dur = (revs + 2.0 * SETTLE_S * v) / v;
    b.ramp(v, v, dur);
    let constant_end = b.t;
    let end_marker = b.stop_from(v);
    PlannedTimes {
        start_marker,
        end_marker,
        signal_start: constant_start + SETTLE_S,
        signal_end: constant_end - SETTLE_S,
    }
}

/// `capture_speed_sweep_samples` (calibration.cpp:1162–1209); `half` = `|R|/2`.
fn speed_sweep(b: &mut Builder, a: f64, v: f64, half: f64) -> PlannedTimes {
    b.settle();
    let start_marker = b.t;
    b.marker();
    b.settle();
    b.accel(0.0, a, RAMP_ACCEL_REV_S2);
    let signal_start = b.t;
    // plan_accel_over_dist_block: uniform acceleration over `half`, for 2·half/(a+v) s.
    let dur = 2.0 * half / (a + v);
    b.ramp(a, v, dur);
    b.ramp(v, a, dur);
    let signal_end = b.t;
    let end_marker = b.stop_from(a);
    PlannedTimes { start_marker, end_marker, signal_start, signal_end }
}

impl Plan {
    /// A cursor for times that mostly increase (each sample after the last).
    pub(crate) fn cursor(&self) -> Cursor<'_> {
        Cursor { plan: self, i: 0 }
    }
}

/// Evaluates a plan at times, remembering the last segment.
pub(crate) struct Cursor<'a> {
    plan: &'a Plan,
    i: usize,
}

impl Cursor<'_> {
    /// `(distance, speed, acceleration)` at `t`: at rest before the plan and after it.
    pub(crate) fn at(&mut self, t: f64) -> (f64, f64, f64) {
        let s = &self.plan.segments;
        let Some(last) = s.last() else { return (0.0, 0.0, 0.0) };
        if t <= s[0].t0 {
            return (0.0, 0.0, 0.0);
        }
        if t >= last.t0 + last.dur {
            return (last.d0 + 0.5 * (last.v0 + last.v1) * last.dur, 0.0, 0.0);
        }
        if s[self.i].t0 > t {
            self.i = 0;
        }
        while self.i + 1 < s.len() && s[self.i + 1].t0 <= t {
            self.i += 1;
        }
        let g = s[self.i];
        let tau = t - g.t0;
        let acc = (g.v1 - g.v0) / g.dur;
        (g.d0 + g.v0 * tau + 0.5 * acc * tau * tau, g.v0 + acc * tau, acc)
    }
}
