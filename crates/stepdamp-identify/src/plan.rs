//! The experiment plan: which servo-mode runs to record for identification, and why.
//! Running them on the simulator is [`crate::simulate`] (feature `simulate`).
//!
//! # The rules (measured on the simulator, 50 random motors; see the tests)
//!
//! 1. **Servo stiffness.** The detent has negative stiffness up to
//!    `S = Σ_k k·Nr·A_k` (N·m/rad) at some angles. A position loop softer than that lets the
//!    rotor snap from detent well to detent well (stick–slip, speed swinging from 0 to 3×
//!    the command), and the identification then rests on a violent `J·dω/dt`. The plan sets
//!    the position-loop bandwidth so that its stiffness `J·ω_b²` is at least
//!    [`PlanOptions::stiffness_margin`]` × S` (2 by default), and at least
//!    [`PlanOptions::min_servo_bandwidth_hz`]. `A_k` comes from the base profile; when it
//!    has no detent, typical values are assumed (docs/identification.md): `A_4` 5 %, `A_2` 2.5 %,
//!    `A_1` 1.5 % of the holding torque `√2·Km·I_hold`. The velocity filter is put at the
//!    loop bandwidth: a higher corner passes more encoder-quantisation noise into the
//!    torque, a lower one costs phase margin.
//! 2. **Slowest speed.** An encoder servo at speed `ω` sees a new count every
//!    `2π/(cpr·ω)` s. If that is longer than the loop's time constant `1/ω_b`, the loop
//!    reacts to every count: quantisation jitter stops and restarts the rotor inside a
//!    count, static friction takes over, and `Fs` comes out 10–40 % low (measured). The fit
//!    leaves such runs out (docs/identification.md#what-the-fit-needs-and-what-it-does-when-it-does-not-get-it),
//!    so the slow run's count rate is [`SLOW_COUNT_RATE_MARGIN`] times `ω_b` (in rad/s):
//!    `ω_lo = SLOW_COUNT_RATE_MARGIN·ω_b·2π/cpr`.
//! 3. **Second speed.** `ω_hi` at a count rate of [`FAST_COUNT_RATE_PER_BANDWIDTH`]` × ω_b`
//!    (1.6 `ω_lo`, above the fit's [`SPEED_RATIO`](crate::fit::SPEED_RATIO)) separates `D` from `Fs` (with one speed
//!    they are confounded). It keeps the highest harmonic `k_max·Nr·ω_hi` within the loop's
//!    bandwidth for `k_max = 4`, 4000 counts and `Nr = 50` (0.63 `f_b`); what the loop does
//!    not follow is measured through `J·dω/dt`.
//! 4. **Both directions** at each speed: separates `Fs·sgn(ω)` from a constant torque (a
//!    load or a current offset) and averages direction-dependent effects.
//! 5. **Duration**: [`PlanOptions::electrical_periods`] electrical periods (40 by default)
//!    of steady running at the run's speed, at least [`PlanOptions::min_steady_s`], after a
//!    50 ms standstill and a 0.1 s ramp. The fit averages whole periods; more periods
//!    shrink the noise as `1/√periods`.
//! 6. **A back-EMF run** ([`back_emf_run`]): one fast servo run whose logged voltages give
//!    the flux linkage's odd harmonics and the phases' imbalance ([`crate::emf`]), the
//!    ripple that grows with the current, which the slow runs at `i_d = 0` cannot see.

use std::f64::consts::TAU;
use std::path::PathBuf;
use stepdamp_profile::{DetentTerm, Profile};

/// Options of the plan and of its simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanOptions {
    /// Harmonic orders to be identified (the highest one is checked against the loop).
    pub orders: Vec<u16>,
    /// Servo stiffness over the detent's largest negative stiffness (≥ 1).
    pub stiffness_margin: f64,
    /// Lowest position-loop bandwidth in Hz.
    pub min_servo_bandwidth_hz: f64,
    /// Electrical periods of steady running per run.
    pub electrical_periods: f64,
    /// Shortest steady part of a run, s.
    pub min_steady_s: f64,
    /// Current-sensor noise of the simulation, standard deviation in A.
    pub current_noise_a: f64,
    /// Base seed of the simulation's noise (each run gets its own, derived from it).
    pub seed: u64,
}

impl Default for PlanOptions {
    fn default() -> Self {
        PlanOptions {
            orders: crate::fit::DEFAULT_ORDERS.to_vec(),
            stiffness_margin: 2.0,
            min_servo_bandwidth_hz: 60.0,
            electrical_periods: 40.0,
            min_steady_s: 2.0,
            current_noise_a: 0.01,
            seed: 1,
        }
    }
}

/// How the drive runs a planned run: what it needs besides the speed profile.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "mode", rename_all = "kebab-case")]
pub enum RunDrive {
    /// Servo on the encoder angle (the patent's identification runs), detent compensation off.
    Servo {
        /// Position-loop bandwidth, Hz.
        servo_bandwidth_hz: f64,
        /// Velocity-estimate filter, Hz.
        velocity_filter_hz: f64,
        /// d-axis current held, A (0: the patent's `i_d = 0`).
        d_current_a: f64,
    },
    /// Open loop: the current vector of magnitude `holding_current_a` (peak, A) at the
    /// commanded angle, compensation off.
    OpenLoop {
        /// Current-vector magnitude (each phase's peak), A.
        holding_current_a: f64,
    },
}

impl RunDrive {
    /// Its name in the CSV's `mode` column and the JSON: `servo` or `open-loop`.
    pub fn mode(&self) -> &'static str {
        match self {
            RunDrive::Servo { .. } => "servo",
            RunDrive::OpenLoop { .. } => "open-loop",
        }
    }
}

/// One run to record.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PlannedRun {
    /// File stem of its log, e.g. `run-1-fwd-1.017rad_s`.
    pub name: String,
    /// How the drive runs it.
    pub drive: RunDrive,
    /// Commanded speed in rad/s (sign = direction).
    pub speed_rad_s: f64,
    /// Standstill before the ramp, s.
    pub dwell_s: f64,
    /// Ramp from rest, s.
    pub ramp_s: f64,
    /// Total duration, s.
    pub duration_s: f64,
    /// Why this run.
    pub reason: String,
}

/// The plan. Its `Display` is what `stepdamp identify plan` prints (settings, runs with
/// their reasons, notes, total logging time); `Serialize` is its `--format json`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Plan {
    /// The base profile with the servo settings of the plan (what the drive must run).
    pub profile: Profile,
    /// Position-loop bandwidth in Hz.
    pub servo_bandwidth_hz: f64,
    /// Velocity filter corner in Hz.
    pub velocity_filter_hz: f64,
    /// The detent stiffness bound `S = Σ k·Nr·A_k` used, N·m/rad.
    pub detent_stiffness_nm_per_rad: f64,
    /// Whether `S` came from the profile (else assumed typical values).
    pub detent_from_profile: bool,
    /// Why these servo settings.
    pub servo_reason: String,
    /// The runs.
    pub runs: Vec<PlannedRun>,
    /// Cautions (e.g. a harmonic beyond the loop's bandwidth).
    pub notes: Vec<String>,
}

impl Plan {
    /// Total simulated time, s.
    pub fn total_s(&self) -> f64 {
        self.runs.iter().map(|r| r.duration_s).sum()
    }
}

impl std::fmt::Display for Plan {
    /// The plan as text: settings, runs with their reasons, notes, then the total logging
    /// time ([`Plan::total_s`]) and the signals to record.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "identification plan for {}: servo mode, detent compensation off, {} encoder counts/rev",
            self.profile.name, self.profile.encoder.counts_per_rev
        )?;
        writeln!(
            f,
            "servo: position-loop bandwidth {:.1} Hz, velocity filter {:.1} Hz",
            self.servo_bandwidth_hz, self.velocity_filter_hz
        )?;
        writeln!(f, "  why: {}", self.servo_reason)?;
        write_runs(f, &self.runs)?;
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        write!(
            f,
            "total {:.1} s of logging; record t_s, theta_fb_rad, i_q_a (or i_a_a, i_b_a) every control period, and i_a_a, i_b_a, v_a_v, v_b_v in the back-EMF run (v: the mean winding voltage actually applied over the period)",
            self.total_s()
        )
    }
}

/// The columns of [`runs_csv`]: the run, how the drive runs it, its speed profile, then the
/// drive's settings (empty where they do not apply: `holding_current_a` is open loop's,
/// the other three the servo's).
pub const RUNS_CSV_HEADER: &str = "run,mode,speed_rad_s,duration_s,standstill_s,ramp_s,holding_current_a,d_current_a,servo_bandwidth_hz,velocity_filter_hz";

/// The plan's runs as the text of `identify plan` prints them, each with its reason (both
/// routes' plans).
pub(crate) fn write_runs(f: &mut std::fmt::Formatter<'_>, runs: &[PlannedRun]) -> std::fmt::Result {
    writeln!(f, "runs:")?;
    for r in runs {
        writeln!(
            f,
            "  {:<28} {:+8.4} rad/s  {:6.2} s (standstill {:.2} s, ramp {:.2} s)",
            r.name, r.speed_rad_s, r.duration_s, r.dwell_s, r.ramp_s
        )?;
        writeln!(f, "      why: {}", r.reason)?;
    }
    Ok(())
}

/// One CSV row per run under [`RUNS_CSV_HEADER`] (`identify plan --format csv`), so a
/// script or another drive can perform exactly the plan without reading its text: a run
/// starts at rest holding the current for `standstill_s`, ramps at constant acceleration to
/// `speed_rad_s` over `ramp_s`, and holds it until `duration_s`, in the `mode` and with the
/// settings of its row; its log covers it all from `t = 0`.
pub fn runs_csv(runs: &[PlannedRun]) -> Result<String, csv::Error> {
    #[derive(serde::Serialize)]
    struct Row<'a> {
        run: &'a str,
        mode: &'a str,
        speed_rad_s: f64,
        duration_s: f64,
        standstill_s: f64,
        ramp_s: f64,
        holding_current_a: Option<f64>,
        d_current_a: Option<f64>,
        servo_bandwidth_hz: Option<f64>,
        velocity_filter_hz: Option<f64>,
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in runs {
        let (hold, servo) = match r.drive {
            RunDrive::OpenLoop { holding_current_a } => (Some(holding_current_a), None),
            RunDrive::Servo { servo_bandwidth_hz, velocity_filter_hz, d_current_a } => {
                (None, Some((d_current_a, servo_bandwidth_hz, velocity_filter_hz)))
            }
        };
        let row = Row {
            run: &r.name,
            mode: r.drive.mode(),
            speed_rad_s: r.speed_rad_s,
            duration_s: r.duration_s,
            standstill_s: r.dwell_s,
            ramp_s: r.ramp_s,
            holding_current_a: hold,
            d_current_a: servo.map(|s| s.0),
            servo_bandwidth_hz: servo.map(|s| s.1),
            velocity_filter_hz: servo.map(|s| s.2),
        };
        w.serialize(row)?;
    }
    let bytes = w.into_inner().map_err(|e| csv::Error::from(e.into_error()))?;
    String::from_utf8(bytes).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e).into())
}

/// Why the plan could not be made or run.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// Bad options.
    #[error("{0}")]
    Options(String),
    /// The simulator refused the set-up.
    /// (Not a `source`: the message already carries it, and a chain would print it twice.)
    #[cfg(feature = "simulate")]
    #[error("simulator: {0}")]
    Sim(stepdamp_sim::SimError),
    /// A file could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

#[cfg(feature = "simulate")]
impl From<stepdamp_sim::SimError> for PlanError {
    fn from(e: stepdamp_sim::SimError) -> Self {
        PlanError::Sim(e)
    }
}

/// Typical detent when the profile has none (docs/identification.md): `A_4` 5 %, `A_2` 2.5 %,
/// `A_1` 1.5 % of the two-phase holding torque `√2·Km·I_hold`.
pub fn assumed_detent(p: &Profile) -> Vec<DetentTerm> {
    let hold = std::f64::consts::SQRT_2 * p.motor.km_nm_per_a * p.drive.holding_current_a;
    [(4, 0.05), (2, 0.025), (1, 0.015)]
        .iter()
        .map(|&(order, f)| DetentTerm { order, amplitude_nm: f * hold, phase_rad: 0.0 })
        .collect()
}

/// Makes the plan for a base profile.
pub fn plan(base: &Profile, o: &PlanOptions) -> Result<Plan, PlanError> {
    let kmax = check_options(o)?;
    let servo = Servo::for_profile(base, o);
    let (nr, j, fb) = (f64::from(base.motor.pole_pairs), base.motor.inertia_kg_m2, servo.fb);
    let mut notes = Vec::new();
    if fb > base.drive.current_loop_bandwidth_hz / 5.0 {
        notes.push(format!(
            "the servo bandwidth {fb:.0} Hz is more than a fifth of the current loop's {:.0} Hz: the loop may ring; a stiffer load coupling or a smaller stiffness margin helps",
            base.drive.current_loop_bandwidth_hz
        ));
    }
    let speeds = Speeds::for_servo(servo.wb, f64::from(base.encoder.counts_per_rev), kmax, nr);
    if speeds.f_k(speeds.w_hi) > fb {
        notes.push(format!(
            "harmonic {kmax} runs at {:.0} Hz at the fast speed, above the servo bandwidth {fb:.0} Hz: the loop does not follow it and the fit relies on J·dω/dt (J = {j:.3e} kg·m² must be right); a finer encoder allows slower runs",
            speeds.f_k(speeds.w_hi)
        ));
    }
    let mut runs = planned_runs(&speeds, fb, o);
    let emf = back_emf_run(base, fb, runs.len() + 1);
    // The run must be recognised as one by its mean electrical frequency over the whole log.
    let moving_s = emf.duration_s - emf.dwell_s - 0.5 * emf.ramp_s;
    let f_mean = nr * emf.speed_rad_s.abs() * moving_s / (TAU * emf.duration_s);
    if f_mean >= crate::emf::EMF_MIN_ELECTRICAL_HZ {
        runs.push(emf);
    } else {
        notes.push(format!(
            "no back-EMF run: the fastest this drive allows (PWM {:.0} Hz, bus {:.0} V) is {:.0} Hz electrical, under the {} Hz the back-EMF fit needs; the flux section (the ripple that grows with the current) must come from elsewhere",
            base.drive.pwm_hz,
            base.drive.bus_voltage_v,
            f_mean,
            crate::emf::EMF_MIN_ELECTRICAL_HZ
        ));
    }
    let profile = base
        .edited(&base.name, |p| {
            p.servo.bandwidth_hz = fb;
            p.servo.velocity_filter_hz = fb;
        })
        .map_err(|e| PlanError::Options(format!("the planned servo settings: {e}")))?;
    Ok(Plan {
        profile,
        servo_bandwidth_hz: fb,
        velocity_filter_hz: fb,
        detent_stiffness_nm_per_rad: servo.s,
        detent_from_profile: servo.from_profile,
        servo_reason: servo.reason,
        runs,
        notes,
    })
}

/// Checks the options' ranges; returns the highest order.
fn check_options(o: &PlanOptions) -> Result<u16, PlanError> {
    let bad = |m: String| Err(PlanError::Options(m));
    if !(o.stiffness_margin.is_finite() && o.stiffness_margin >= 1.0) {
        return bad(format!("stiffness margin {}: must be ≥ 1", o.stiffness_margin));
    }
    if !(o.min_servo_bandwidth_hz.is_finite() && o.min_servo_bandwidth_hz > 0.0) {
        return bad(format!("minimum servo bandwidth {} Hz: must be > 0", o.min_servo_bandwidth_hz));
    }
    if !(o.electrical_periods.is_finite() && (2.0..=1e5).contains(&o.electrical_periods)) {
        return bad(format!("{} electrical periods per run: must be in 2..=100000", o.electrical_periods));
    }
    if !(o.min_steady_s.is_finite() && o.min_steady_s >= 0.0) {
        return bad(format!("minimum steady time {} s: must be ≥ 0", o.min_steady_s));
    }
    if !(o.current_noise_a.is_finite() && o.current_noise_a >= 0.0) {
        return bad(format!("current noise {} A: must be ≥ 0", o.current_noise_a));
    }
    match o.orders.iter().max() {
        Some(&kmax) => Ok(kmax),
        None => bad("no harmonic orders".into()),
    }
}

/// The servo settings of the plan (rule 1 of the module documentation).
struct Servo {
    /// The detent stiffness bound `S = Σ k·Nr·A_k`, N·m/rad.
    s: f64,
    /// Whether `S` came from the profile's detent (else [`assumed_detent`]).
    from_profile: bool,
    /// Position-loop bandwidth, rad/s.
    wb: f64,
    /// The same in Hz (and the velocity filter's corner).
    fb: f64,
    /// Why these settings.
    reason: String,
}

impl Servo {
    /// The bandwidth whose stiffness `J·ω_b²` is the margin times `S`, at least the
    /// options' lowest bandwidth.
    fn for_profile(base: &Profile, o: &PlanOptions) -> Self {
        let nr = f64::from(base.motor.pole_pairs);
        let j = base.motor.inertia_kg_m2;
        let from_profile = !base.motor.detent.is_empty();
        let detent = if from_profile { base.motor.detent.clone() } else { assumed_detent(base) };
        let s: f64 = detent.iter().map(|h| f64::from(h.order) * nr * h.amplitude_nm).sum();
        let wb_stiff = (o.stiffness_margin * s / j).sqrt();
        let wb = wb_stiff.max(TAU * o.min_servo_bandwidth_hz);
        let fb = wb / TAU;
        let reason = format!(
            "stiffness J·ω_b² = {:.2} N·m/rad ≥ {:.1} × the detent's largest negative stiffness Σk·Nr·A_k = {:.2} N·m/rad ({}), so the rotor cannot snap between detent wells; velocity filter at the bandwidth (less encoder noise in the torque than a higher corner, more phase margin than a lower one)",
            j * wb * wb,
            (j * wb * wb / s.max(f64::MIN_POSITIVE)).min(1e6),
            s,
            if from_profile { "detent of the profile" } else { "no detent in the profile: typical values assumed" },
        );
        Servo { s, from_profile, wb, fb, reason }
    }
}

/// The slow run's encoder count rate over the servo bandwidth in rad/s (rule 2 of the module
/// documentation): the plan's margin over the fit's count-rate rule (docs/identification.md#what-the-fit-needs-and-what-it-does-when-it-does-not-get-it,
/// [`crate::conditions::slow_levels_to_leave_out`]: a slow level whose friction is over 4 %
/// short of the fast level's while the drive reacts to each count is left out). A drive
/// tuned to the plan's `ω_b` by another rule may react faster than the plan's: on the
/// independent generator (`tests/independent/servo_real.rs`: stiffness `3·J·ω_b²`, speed
/// filter at `5·f_b`), 16 motors of `tests/real_independent.rs` with the preset's `J`, the
/// slow runs were left out on all 16 at a count rate of 1.0× `ω_b` (friction 8 % or more
/// short), on 15 at 1.1× and 6 at 1.15× (both speeds scaled), on 2 at 1.2×, on none at 1.25×
/// (`J` fitted on all, worst 0.82 of the tolerance): the first factor tried that keeps them.
pub const SLOW_COUNT_RATE_MARGIN: f64 = 1.25;

/// The fast run's encoder count rate over the servo bandwidth in rad/s (rule 3 of the module
/// documentation): order 4 at 0.63 `f_b` (4000 counts, `Nr` 50), under the fit's warning at
/// 0.8 `f_b`. It does not grow with [`SLOW_COUNT_RATE_MARGIN`]: scaled ×1.25 too, it put order
/// 4 past the real loop of the 10 random motors of `src/tests.rs` with `J` ×2.5–3 the base's;
/// their fast runs' friction (fitted with the base's `J`) came out 3–69 % high, and the
/// count-rate rule left their slow runs out.
pub const FAST_COUNT_RATE_PER_BANDWIDTH: f64 = 2.0;

/// The two speeds of the plan (rules 2 and 3 of the module documentation).
struct Speeds {
    /// Slow speed: a count rate [`SLOW_COUNT_RATE_MARGIN`] times the loop bandwidth, rad/s.
    w_lo: f64,
    /// Fast speed: a count rate [`FAST_COUNT_RATE_PER_BANDWIDTH`] times the loop bandwidth, rad/s.
    w_hi: f64,
    /// Encoder counts per revolution.
    cpr: f64,
    /// Highest harmonic order.
    kmax: u16,
    /// Rotor pole pairs.
    nr: f64,
}

impl Speeds {
    fn for_servo(wb: f64, cpr: f64, kmax: u16, nr: f64) -> Self {
        let count_rate_to_speed = wb * TAU / cpr;
        Speeds {
            w_lo: SLOW_COUNT_RATE_MARGIN * count_rate_to_speed,
            w_hi: FAST_COUNT_RATE_PER_BANDWIDTH * count_rate_to_speed,
            cpr,
            kmax,
            nr,
        }
    }

    /// Frequency of the highest harmonic at speed `w` rad/s, Hz.
    fn f_k(&self, w: f64) -> f64 {
        f64::from(self.kmax) * self.nr * w / TAU
    }
}

/// The four runs (rules 4 and 5 of the module documentation): slow then fast, each forward
/// then reverse, with their reasons; `fb` is the servo bandwidth, Hz.
fn planned_runs(sp: &Speeds, fb: f64, o: &PlanOptions) -> Vec<PlannedRun> {
    let (kmax, nr) = (sp.kmax, sp.nr);
    let dwell = 0.05;
    let ramp = 0.1;
    let steady = |w: f64| (o.electrical_periods * TAU / (nr * w)).max(o.min_steady_s);
    let mut runs = Vec::new();
    let mut i = 0;
    for (w, why) in [
        (
            sp.w_lo,
            format!(
                "slow: the encoder counts {:.0} times/s = {SLOW_COUNT_RATE_MARGIN} × the servo bandwidth in rad/s, so quantisation jitter cannot stall the rotor within a count; harmonic {kmax} at {:.1} Hz ({:.2} × bandwidth)",
                sp.cpr * sp.w_lo / TAU,
                sp.f_k(sp.w_lo),
                sp.f_k(sp.w_lo) / fb
            ),
        ),
        (
            sp.w_hi,
            format!(
                "fast: {:.2} × the slow speed, so D separates from Fs; harmonic {kmax} at {:.1} Hz ({:.2} × bandwidth)",
                sp.w_hi / sp.w_lo,
                sp.f_k(sp.w_hi),
                sp.f_k(sp.w_hi) / fb
            ),
        ),
    ] {
        for (dir, sign) in [("fwd", 1.0), ("rev", -1.0)] {
            i += 1;
            let st = steady(w);
            runs.push(PlannedRun {
                name: format!("run-{i}-{dir}-{w:.3}rad_s"),
                // The plan's profile sets the velocity filter at the bandwidth (`plan`).
                drive: RunDrive::Servo { servo_bandwidth_hz: fb, velocity_filter_hz: fb, d_current_a: 0.0 },
                speed_rad_s: sign * w,
                dwell_s: dwell,
                ramp_s: ramp,
                duration_s: dwell + ramp + 0.05 + st,
                reason: format!(
                    "{why}; {} ({:.0} electrical periods in {st:.2} s steady)",
                    if sign > 0.0 {
                        "forward"
                    } else {
                        "reverse: with the forward run separates Fs·sgn(ω) from a constant torque"
                    },
                    st * nr * w / TAU
                ),
            });
        }
    }
    runs
}

/// The highest flux harmonic of the back-EMF run ([`crate::emf::DEFAULT_FLUX_ORDERS`]) stays
/// below the PWM frequency over this: 16 control periods per period of that harmonic.
pub const EMF_PERIODS_PER_HARMONIC: f64 = 16.0;

/// The back-EMF run's back-EMF stays below this fraction of the bus voltage (room for the
/// current loop).
pub const EMF_BUS_FRACTION: f64 = 0.3;

/// Steady time of the back-EMF run, s (≈ 175 electrical periods for `patent-motor`).
pub const EMF_STEADY_S: f64 = 1.0;

/// The back-EMF run (rule 6 of the module documentation), numbered `index`: forward at the
/// speed where the highest fitted flux harmonic has [`EMF_PERIODS_PER_HARMONIC`] control
/// periods, or where the back-EMF reaches [`EMF_BUS_FRACTION`] of the bus, whichever is
/// slower; a 0.2 s ramp and [`EMF_STEADY_S`] steady.
pub fn back_emf_run(base: &Profile, fb: f64, index: usize) -> PlannedRun {
    let nr = f64::from(base.motor.pole_pairs);
    let nmax = f64::from(*crate::emf::DEFAULT_FLUX_ORDERS.iter().max().unwrap_or(&7));
    let w_pwm = TAU * base.drive.pwm_hz / (EMF_PERIODS_PER_HARMONIC * nmax * nr);
    let w_bus = EMF_BUS_FRACTION * base.drive.bus_voltage_v / base.motor.km_nm_per_a;
    let w = (w_pwm.min(w_bus) * 1e3).floor() / 1e3;
    let (dwell, ramp) = (0.05, 0.2);
    let f_e = nr * w / TAU;
    PlannedRun {
        name: format!("run-{index}-emf-{w:.3}rad_s"),
        drive: RunDrive::Servo { servo_bandwidth_hz: fb, velocity_filter_hz: fb, d_current_a: 0.0 },
        speed_rad_s: w,
        dwell_s: dwell,
        ramp_s: ramp,
        // 0.05 s beyond the steady part, as the other runs have.
        duration_s: dwell + ramp + 0.05 + EMF_STEADY_S,
        reason: format!(
            "back-EMF: log the phase currents and the applied voltages (i_a_a, i_b_a, v_a_v, v_b_v); their back-EMF gives the flux linkage's 3rd and 5th harmonics and the phases' imbalance, the ripple that grows with the current, which the slow runs at i_d = 0 cannot see; {f_e:.0} Hz electrical, harmonic {nmax} at {:.0} Hz = PWM/{:.0}, back-EMF {:.1} V = {:.0} % of the bus ({:.0} electrical periods in {EMF_STEADY_S} s steady)",
            nmax * f_e,
            base.drive.pwm_hz / (nmax * f_e),
            base.motor.km_nm_per_a * w,
            100.0 * base.motor.km_nm_per_a * w / base.drive.bus_voltage_v,
            f_e * EMF_STEADY_S
        ),
    }
}

#[cfg(feature = "simulate")]
pub use crate::simulate::{PlanRun, run_plan, run_seed, simulate_plan, simulate_run, write_rows_atomic};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patent_motor_plan_runs_both_directions_at_two_speeds_with_reasons() {
        let p = Profile::preset("patent-motor").unwrap();
        let plan = plan(&p, &PlanOptions::default()).unwrap();
        assert_eq!(plan.runs.len(), 5);
        let speeds: Vec<f64> = plan.runs.iter().map(|r| r.speed_rad_s).collect();
        // The back-EMF run last: 7th flux harmonic at PWM/16 = 1250 Hz, so 178.5 Hz
        // electrical → 22.439 rad/s mechanical (Nr 50); back-EMF 6.7 V, under 30 % of 48 V.
        let emf = &plan.runs[4];
        assert!((emf.speed_rad_s - 22.439).abs() < 1e-9 && emf.name == "run-5-emf-22.439rad_s", "{emf:?}");
        assert!(emf.reason.contains("back-EMF") && emf.reason.contains("v_a_v"), "{}", emf.reason);
        assert!(speeds[0] > 0.0 && speeds[1] < 0.0 && (speeds[2] / speeds[0] - 1.6).abs() < 1e-12);
        assert!(speeds[2] / speeds[0] >= crate::fit::SPEED_RATIO, "the fit must see two speed levels");
        // Stiffness margin: J ω_b² ≥ 2 S.
        let wb = TAU * plan.servo_bandwidth_hz;
        assert!(p.motor.inertia_kg_m2 * wb * wb >= 2.0 * plan.detent_stiffness_nm_per_rad * 0.999);
        // Count rates: the slow run's the margin × ω_b, the fast run's 2 ω_b.
        let rate = |w: f64| w * 4000.0 / TAU;
        assert!((rate(speeds[0]) - SLOW_COUNT_RATE_MARGIN * wb).abs() < 1e-6 * wb);
        assert!((rate(speeds[2]) - FAST_COUNT_RATE_PER_BANDWIDTH * wb).abs() < 1e-6 * wb);
        assert!(plan.runs[..4].iter().all(|r| !r.reason.is_empty() && r.duration_s > 2.0));
        assert!((emf.duration_s - 1.3).abs() < 1e-12);
        let text = plan.to_string();
        assert!(text.contains("why") && text.contains("run-4-rev"), "{text}");
        assert!(
            text.ends_with(&format!(
                "total {:.1} s of logging; record t_s, theta_fb_rad, i_q_a (or i_a_a, i_b_a) every control period, and i_a_a, i_b_a, v_a_v, v_b_v in the back-EMF run (v: the mean winding voltage actually applied over the period)",
                plan.total_s()
            )),
            "{text}"
        );
    }

    #[test]
    fn the_plan_as_csv_has_the_documented_columns_and_one_row_per_run() {
        let plan = plan(&Profile::preset("patent-motor").unwrap(), &PlanOptions::default()).unwrap();
        let csv = runs_csv(&plan.runs).unwrap();
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some(RUNS_CSV_HEADER));
        for (line, r) in lines.zip(&plan.runs) {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!((f[0], f[1], f[6]), (r.name.as_str(), "servo", ""));
            let v: Vec<f64> = f[2..6].iter().chain(&f[7..]).map(|x| x.parse().unwrap()).collect();
            let fb = plan.servo_bandwidth_hz;
            assert_eq!(v, [r.speed_rad_s, r.duration_s, r.dwell_s, r.ramp_s, 0.0, fb, plan.velocity_filter_hz]);
            assert_eq!(r.drive, RunDrive::Servo { servo_bandwidth_hz: fb, velocity_filter_hz: fb, d_current_a: 0.0 });
        }
        assert_eq!(csv.lines().count(), plan.runs.len() + 1);
    }

    #[test]
    fn a_profile_without_detent_plans_with_typical_values() {
        let p = Profile::preset("nema17-17hs4401").unwrap().edited("no detent", |p| p.motor.detent.clear()).unwrap();
        let plan = plan(&p, &PlanOptions::default()).unwrap();
        assert!(!plan.detent_from_profile && plan.detent_stiffness_nm_per_rad > 0.0);
        assert!(plan.servo_reason.contains("typical"));
    }
}
