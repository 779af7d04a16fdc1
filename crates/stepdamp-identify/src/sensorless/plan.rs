//! The sensorless plan: which open-loop runs to record, and why (docs/sensorless.md).
//!
//! # The rules
//!
//! 1. **Quasi-static speeds.** The open-loop rotor is a mass on the magnetic spring
//!    `Km·I_hold` (N·m per electrical radian), resonant at `ω_n = √(Km·I_hold·Nr/J)`;
//!    harmonic `k` excites it at `k·Nr·ω`. Below resonance the load angle follows the
//!    detent almost statically (`δ ≈ τ_detent/(Km·I_hold)`), so the fit hardly depends on
//!    `J`, which the base profile may only guess. The fast run puts the highest order at
//!    [`SensorlessPlanOptions::resonance_fraction`] of `ω_n` computed with the base's `J`
//!    (the truth may be 3× larger, `ω_n` then 1.7× lower: the default keeps it below
//!    resonance even then); the slow run is half as fast.
//! 2. **Two speeds** separate `D` from `Fs`; **both directions** separate `Fs·sgn ω` from a
//!    constant torque.
//! 3. **Standstill first**: [`SensorlessPlanOptions::standstill_s`] holding `I_hold` at rest
//!    trims `R` (the flux integral's largest error source at low speed,
//!    [`super::flux`]), then a ramp at constant acceleration
//!    ([`SensorlessPlanOptions::ramp_s`]).
//! 4. **A turn pair** (when [`SensorlessPlanOptions::turn_speed_factor`] is not 0): both
//!    directions at that multiple of `ω_n` (electrical), where the rotor cannot follow the
//!    order-4 torques, so the estimated angle's order-4 error is the flux's own turn
//!    `Im[(X₅ − X₃)·e^{j4θe}]`: it splits the third from the fifth ([`super::turn`]). The
//!    torque fit leaves these runs out; their ramp is twice [`SensorlessPlanOptions::ramp_s`].
//! 5. **Duration**: [`SensorlessPlanOptions::electrical_periods`] electrical periods of
//!    steady running, at least [`SensorlessPlanOptions::min_steady_s`].

use crate::plan::{PlanError, PlannedRun, RunDrive};
use std::f64::consts::TAU;
use stepdamp_profile::Profile;

/// Options of the sensorless plan.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SensorlessPlanOptions {
    /// Harmonic orders to identify (the highest sets the speeds).
    pub orders: Vec<u16>,
    /// Highest harmonic's excitation at the fast speed as a fraction of the base's `ω_n`.
    pub resonance_fraction: f64,
    /// Electrical periods of steady running per run.
    pub electrical_periods: f64,
    /// Shortest steady part of a run, s.
    pub min_steady_s: f64,
    /// Standstill at `I_hold` before each run (trims `R`), s.
    pub standstill_s: f64,
    /// Ramp from rest to the speed, s.
    pub ramp_s: f64,
    /// Electrical speed of the turn runs as a multiple of the base's `ω_n` (0: no turn runs;
    /// otherwise at least [`super::turn::TURN_MIN_SPEED`]).
    pub turn_speed_factor: f64,
}

impl Default for SensorlessPlanOptions {
    fn default() -> Self {
        SensorlessPlanOptions {
            orders: crate::fit::DEFAULT_ORDERS.to_vec(),
            resonance_fraction: 0.35,
            electrical_periods: 40.0,
            min_steady_s: 1.0,
            standstill_s: 0.2,
            ramp_s: 0.2,
            turn_speed_factor: 2.0,
        }
    }
}

/// The sensorless plan. `Display` is what `stepdamp identify plan --sensorless` prints;
/// [`SensorlessPlan::to_csv`] its `--format csv`; `Serialize` its `--format json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SensorlessPlan {
    /// The base profile's name.
    pub motor: String,
    /// The open-loop natural frequency from the base profile, rad/s.
    pub natural_rad_s: f64,
    /// The runs (`dwell_s` is the standstill).
    pub runs: Vec<PlannedRun>,
    /// The options.
    pub options: SensorlessPlanOptions,
}

impl SensorlessPlan {
    /// Total logging time, s.
    pub fn total_s(&self) -> f64 {
        self.runs.iter().map(|r| r.duration_s).sum()
    }

    /// One row per run ([`crate::plan::runs_csv`]): at rest holding `I_hold` at the
    /// commanded angle for `standstill_s`, a constant-acceleration ramp to `speed_rad_s`
    /// over `ramp_s`, then that speed to `duration_s`; the log covers it all from `t = 0`.
    pub fn to_csv(&self) -> Result<String, csv::Error> {
        crate::plan::runs_csv(&self.runs)
    }
}

impl std::fmt::Display for SensorlessPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "sensorless identification plan for {}: open loop at the holding current, detent compensation off, no encoder",
            self.motor
        )?;
        writeln!(
            f,
            "open-loop natural frequency from the base profile: {:.1} Hz (J from the base: a guess is enough)",
            self.natural_rad_s / TAU
        )?;
        crate::plan::write_runs(f, &self.runs)?;
        writeln!(
            f,
            "one current: the flux circle's radius gives the phase gain and the sum of the third and fifth flux harmonics; a second current would show the same sum, not its split (docs/sensorless.md#the-flux-shape-without-a-sensor)"
        )?;
        if self.options.turn_speed_factor > 0.0 {
            writeln!(
                f,
                "the turn runs split that sum: far above the resonance the angle's order-4 error is the flux's X5 − X3 (docs/sensorless.md#the-split-from-a-fast-run)"
            )?;
        }
        write!(
            f,
            "total {:.1} s of logging; record t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v, v_b_v every control period from t = 0 (v: the mean winding voltage actually applied over the period)",
            self.total_s()
        )
    }
}

/// The open-loop natural frequency `ω_n = √(Km·I_hold·Nr/J)` of a profile, electrical rad/s.
pub fn natural_rad_s(base: &Profile) -> f64 {
    let m = &base.motor;
    (m.km_nm_per_a * base.drive.holding_current_a * f64::from(m.pole_pairs) / m.inertia_kg_m2).sqrt()
}

/// Makes the sensorless plan for a base profile.
pub fn plan(base: &Profile, o: &SensorlessPlanOptions) -> Result<SensorlessPlan, PlanError> {
    let bad = |m: String| Err(PlanError::Options(m));
    if !(o.resonance_fraction.is_finite() && o.resonance_fraction > 0.0 && o.resonance_fraction < 1.0) {
        return bad(format!("resonance fraction {}: must be in (0, 1)", o.resonance_fraction));
    }
    if !(o.electrical_periods.is_finite() && (2.0..=1e5).contains(&o.electrical_periods)) {
        return bad(format!("{} electrical periods per run: must be in 2..=100000", o.electrical_periods));
    }
    for (what, v, min) in
        [("minimum steady time", o.min_steady_s, 0.0), ("standstill", o.standstill_s, 0.02), ("ramp", o.ramp_s, 0.0)]
    {
        if !(v.is_finite() && (min..=60.0).contains(&v)) {
            return bad(format!("{what} {v} s: must be in {min}..=60 s"));
        }
    }
    let f = o.turn_speed_factor;
    if !(f == 0.0 || (super::turn::TURN_MIN_SPEED..=5.0).contains(&f)) {
        return bad(format!("turn speed factor {f}: must be 0 or in {}..=5", super::turn::TURN_MIN_SPEED));
    }
    let Some(&kmax) = o.orders.iter().max() else { return bad("no harmonic orders".into()) };
    let nr = f64::from(base.motor.pole_pairs);
    let wn = natural_rad_s(base);
    let w_hi = o.resonance_fraction * wn / (f64::from(kmax) * nr);
    let w_lo = 0.5 * w_hi;
    let steady = |w: f64| (o.electrical_periods * TAU / (nr * w)).max(o.min_steady_s);
    let mut runs = Vec::new();
    for (w, why) in [
        (w_lo, "slow: half the fast speed, so D separates from Fs"),
        (w_hi, "fast: the highest order well below the resonance, so the load angle follows the detent"),
    ] {
        for (dir, sign) in [("fwd", 1.0), ("rev", -1.0)] {
            let st = steady(w);
            let k_hz = f64::from(kmax) * nr * w / TAU;
            runs.push(PlannedRun {
                name: format!("sensorless-{}-{dir}-{w:.3}rad_s", runs.len() + 1),
                drive: RunDrive::OpenLoop { holding_current_a: base.drive.holding_current_a },
                speed_rad_s: sign * w,
                dwell_s: o.standstill_s,
                ramp_s: o.ramp_s,
                duration_s: o.standstill_s + o.ramp_s + st,
                reason: format!(
                    "{why}; harmonic {kmax} at {k_hz:.1} Hz = {:.2} × the natural frequency; {} ({:.0} electrical periods in {st:.2} s steady; standstill trims R)",
                    k_hz * TAU / wn,
                    if sign > 0.0 { "forward" } else { "reverse: separates Fs·sgn(ω) from a constant torque" },
                    st * nr * w / TAU
                ),
            });
        }
    }
    if f > 0.0 {
        let w = f * wn / nr;
        for (dir, sign) in [("fwd", 1.0), ("rev", -1.0)] {
            let (ramp, st) = (2.0 * o.ramp_s, steady(w));
            runs.push(PlannedRun {
                name: format!("sensorless-{}-{dir}-{w:.3}rad_s", runs.len() + 1),
                drive: RunDrive::OpenLoop { holding_current_a: base.drive.holding_current_a },
                speed_rad_s: sign * w,
                dwell_s: o.standstill_s,
                ramp_s: ramp,
                duration_s: o.standstill_s + ramp + st,
                reason: format!(
                    "turn: harmonic 4 at {:.1} × the natural frequency, too fast for the rotor to follow, so the angle's order-4 error is the flux's X5 − X3 (splits the third from the fifth; left out of the torque fit); {}",
                    4.0 * f,
                    if sign > 0.0 { "forward" } else { "reverse" }
                ),
            });
        }
    }
    if !runs.iter().all(|r| r.speed_rad_s.is_finite() && r.duration_s.is_finite()) {
        return bad(format!("{}: the profile gives no finite natural frequency (ω_n = {wn} rad/s)", base.name));
    }
    Ok(SensorlessPlan { motor: base.name.clone(), natural_rad_s: wn, runs, options: o.clone() })
}
