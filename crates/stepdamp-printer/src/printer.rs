//! A simulated printer axis that answers `M973` and `M974` with an accelerometer capture, as
//! Prusa's firmware (≥ 6.3.1) prints it (`docs/accelerometer.md#simulated-printer`).
//!
//! **The move** is the one `calibration.cpp` plans, taken from [`stepdamp_accel`]'s own plan
//! (the commanded speed at the middle of every control period, from
//! [`AccelCapture::commanded`]): settle, marker, (`M974`: settle,) ramp at 100 rev/s², the
//! constant-speed block or the two sweeps, ramp down, settle, marker, settle. The motor runs
//! in **open loop** at the run current, replaying the Prusa table of the direction in use
//! (`R > 0`: the backward table, the phase running down), with `M973`'s constant trial added
//! to harmonic `H`'s item. Left out of the firmware's move: the planner's own step timing
//! (the simulator's command advances once per control period, 50 µs at 20 kHz) and input
//! shaping. The settle blocks' 0.01 mm triangles are converted at the head's belt travel,
//! `2π·r` per revolution.
//!
//! **The head** is [`HeadModel`]'s: rigid coupling for the motor (`m·r²` added to `J`), the
//! belt mode as a low-pass from `r·α` to the head. **The accelerometer** samples the head's
//! acceleration at its measured rate (nominal 1344 Hz times a seeded error), adds seeded
//! Gaussian noise and quantises as the LIS2DH12 in 10-bit mode at ±2 g; sample 0 is taken
//! at [`AccelModel::first_sample_s`] of planned time. It has no anti-alias filter here.

use crate::format::capture_text;
use crate::head::{BeltFilter, HeadError, HeadModel};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::TAU;
use stepdamp_accel::capture::{MARKER_ACCEL_REV_S2, MARKER_SPEED_REV_S, MAX_HARMONIC, SETTLE_S};
use stepdamp_accel::klipper::Kinematics;
use stepdamp_accel::{AccelCapture, Annotations, Axis, CaptureError, Gcode, Reconstruction, TrialSweep};
use stepdamp_export::prusa::PrusaCorrection;
use stepdamp_sim::{ClosedLoop, Compensation, CorrectionTable, Mode, Profile, SimOptions};

/// Standard gravity (m/s²), the firmware's `2·9.80665/max` scale (`accelerometer_utils.cpp`).
pub const STANDARD_GRAVITY: f64 = 9.80665;
/// The LIS2DH12's nominal rate at the firmware's setting (Hz): 1344 Hz
/// (`LIS2DH12_ODR_5kHz376_LP_1kHz344_NM_HP`, `docs/accelerometer.md#the-format-as-printed`).
pub const NOMINAL_RATE_HZ: f64 = 1344.0;
/// One count of the LIS2DH12 in 10-bit (normal) mode at ±2 g (m/s²): `4 g / 1024`.
pub const LSB_10_BIT_2G: f64 = 4.0 * STANDARD_GRAVITY / 1024.0;

/// The accelerometer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelModel {
    /// Nominal sample rate (Hz), [`NOMINAL_RATE_HZ`].
    pub nominal_rate_hz: f64,
    /// The measured rate's relative error: each capture's rate is
    /// `nominal·(1 + δ)`, `δ` uniform in `±rate_spread` (seeded), and the firmware prints
    /// that measured rate. Default 0.001, an **assumption** (the example in the docs is
    /// 1344.52 Hz, 0.04 % off).
    pub rate_spread: f64,
    /// Gaussian noise added to each sample (m/s² RMS). Default 0.3, an **assumption** (the
    /// level of the accel crate's synthetic captures: sensor noise and a running fan).
    pub noise_rms_m_s2: f64,
    /// Quantisation step (m/s²): [`LSB_10_BIT_2G`]; the samples clip at ±2 g (−512…511
    /// counts). 0 turns quantisation and clipping off.
    pub lsb_m_s2: f64,
    /// Planned time of sample 0 (s from the start of the move): the firmware starts reading
    /// once the move runs (`docs/accelerometer.md#what-the-output-does-not-say`). Default 0.
    pub first_sample_s: f64,
}

impl Default for AccelModel {
    fn default() -> Self {
        AccelModel {
            nominal_rate_hz: NOMINAL_RATE_HZ,
            rate_spread: 0.001,
            noise_rms_m_s2: 0.3,
            lsb_m_s2: LSB_10_BIT_2G,
            first_sample_s: 0.0,
        }
    }
}

impl AccelModel {
    /// A perfect sensor: the nominal rate exactly, no noise, no quantisation.
    pub fn ideal() -> Self {
        AccelModel { rate_spread: 0.0, noise_rms_m_s2: 0.0, lsb_m_s2: 0.0, ..AccelModel::default() }
    }
}

/// Why a capture cannot be simulated; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrinterError {
    /// A head parameter is out of range.
    #[error(transparent)]
    Head(#[from] HeadError),
    /// The G-code is refused (as the firmware or the reader would refuse it).
    #[error(transparent)]
    Gcode(#[from] CaptureError),
    /// A printer parameter is out of range.
    #[error("{what} = {value}: must be {allowed}")]
    Parameter {
        /// The parameter.
        what: &'static str,
        /// Its value as given.
        value: String,
        /// The allowed range.
        allowed: String,
    },
    /// The motor profile or the simulator refused the setup, or the run diverged.
    #[error("{0}")]
    Sim(String),
}

/// A printer axis: motor, drive, table, head and accelerometer.
#[derive(Debug, Clone)]
pub struct SimulatedPrinter {
    /// The motor and drive (its holding current is replaced by [`Self::run_current_a`]).
    pub profile: Profile,
    /// The mechanics from the rotor to the accelerometer.
    pub head: HeadModel,
    /// The run current (A, **peak**: the current vector's magnitude).
    pub run_current_a: f64,
    /// The phase-stepping table in use, both directions (`Firmware::V6_3_1` for ≥ 6.3.1).
    pub correction: PrusaCorrection,
    /// A Trinamic driver's wave table in place of phase stepping (the replay table of
    /// `stepdamp_export::tmc::table`, the same both ways): the Klipper side
    /// ([`Self::motan_log`]). With it, [`Self::correction`] is not used and an `M973` must carry
    /// no trial (`C0 D0`): the trial is the table's.
    pub driver_table: Option<CorrectionTable>,
    /// The accelerometer.
    pub accel: AccelModel,
    /// The printer's kinematics: the firmware prints `stepdamp_accel::prusa::sensor_gain` of
    /// the belt's acceleration (cartesian 1; CoreXY `+1/√2` on X, `−1/√2` on Y, the XL's
    /// projection). Klipper logs ([`Self::motan_log`]) take theirs from their own setup.
    pub kinematics: Kinematics,
    /// Seed of the capture's rate error and noise: the same seed repeats a capture exactly;
    /// set another for each capture that should have its own noise.
    pub seed: u64,
}

/// What a simulated move did, at the control rate and at the accelerometer's samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Control period (s).
    pub period_s: f64,
    /// Per period `j`, the middle of the period `(j + ½)·period_s` (s).
    pub mid_s: Vec<f64>,
    /// The planned electrical angle at each middle (rad, as [`stepdamp_accel::Commanded`]).
    pub planned_rad: Vec<f64>,
    /// The rotor's electrical angle `Nr·θ` at each middle (rad, mean of the period's ends).
    pub rotor_rad: Vec<f64>,
    /// The head's acceleration at the **end** of each period, `(j + 1)·period_s` (m/s²).
    pub head_m_s2: Vec<f64>,
    /// The accelerometer's rate over this capture (Hz, before printing).
    pub rate_hz: f64,
    /// The head's acceleration at the sample times, before noise and quantisation (m/s²).
    pub clean_m_s2: Vec<f64>,
    /// The samples as the sensor gives them (m/s²).
    pub samples_m_s2: Vec<f64>,
    /// The annotations.
    pub annotations: Annotations,
}

impl SimulatedPrinter {
    /// A printer with the default head and accelerometer, no correction (all items 0, for
    /// firmware ≥ 6.3.1) and seed 1.
    pub fn new(profile: Profile, run_current_a: f64) -> Self {
        let zero = stepdamp_export::prusa::Spectrum::default();
        SimulatedPrinter {
            profile,
            head: HeadModel::default(),
            run_current_a,
            correction: PrusaCorrection {
                forward: zero,
                backward: zero,
                firmware: stepdamp_export::prusa::Firmware::V6_3_1,
            },
            driver_table: None,
            accel: AccelModel::default(),
            kinematics: Kinematics::Cartesian,
            seed: 1,
        }
    }

    /// What the printed capture does not say, as this printer has it: `Nr` electrical periods
    /// per revolution, the move starting at electrical angle 0, sample 0 at
    /// [`AccelModel::first_sample_s`], and `2π·r` of belt per revolution.
    pub fn reconstruction(&self) -> Reconstruction {
        Reconstruction {
            periods_per_rev: u32::from(self.profile.motor.pole_pairs),
            start_angle_rad: 0.0,
            first_sample_s: self.accel.first_sample_s,
            mm_per_rev: TAU * self.head.pulley_radius_m * 1e3,
        }
    }

    /// `M973 <axis> F<speed> R<revs> H<harmonic> A<pha> B<pha> C<mag> D<mag>` with a constant
    /// trial `(mag, pha)` (`C = D`, `A = B`): the capture as printed.
    pub fn capture_m973(
        &self,
        axis: Axis,
        speed_rev_s: f64,
        revs: f64,
        harmonic: u32,
        trial: (f64, f64),
    ) -> Result<String, PrinterError> {
        let (mag, pha) = trial;
        let trial = TrialSweep { harmonic, pha_start: pha, pha_end: pha, mag_start: mag, mag_end: mag };
        self.capture(&Gcode::ParamSweep { axis, speed: speed_rev_s, revs, trial })
    }

    /// `M974 <axis> A<start> B<end> R<revs>`: the capture as printed.
    pub fn capture_m974(
        &self,
        axis: Axis,
        start_rev_s: f64,
        end_rev_s: f64,
        revs: f64,
    ) -> Result<String, PrinterError> {
        self.capture(&Gcode::SpeedSweep { axis, start_speed: start_rev_s, end_speed: end_rev_s, revs })
    }

    /// The capture of `g` as printed (an `M973` needs a constant trial).
    pub fn capture(&self, g: &Gcode) -> Result<String, PrinterError> {
        Ok(self.print(&self.simulate(g)?))
    }

    /// A simulated move's capture as the firmware prints it: its samples and annotations.
    pub fn print(&self, t: &Trace) -> String {
        capture_text(&t.samples_m_s2, &t.annotations)
    }

    /// The table in use for `g`'s direction with `M973`'s constant trial added to item `H`
    /// (the firmware adds the trial's shift to the table's, lut.cpp:138–140; here the two
    /// items are added as phasors, the same sum before the table's 2π/4096 rounding).
    /// Refuses items whose table the firmware cannot compute.
    fn correction_for(&self, g: &Gcode) -> Result<PrusaCorrection, PrinterError> {
        let c = self.with_trial(g)?;
        c.check_replay("the table in use (with the trial)").map_err(|e| PrinterError::Sim(e.to_string()))?;
        Ok(c)
    }

    /// The table the drive replays for `g`: [`Self::driver_table`] if set (refusing an `M973`
    /// trial, which only phase stepping applies), else [`Self::correction_for`]'s.
    fn table_for(&self, g: &Gcode) -> Result<CorrectionTable, PrinterError> {
        let Some(t) = self.driver_table else { return Ok(self.correction_for(g)?.table()) };
        if let Gcode::ParamSweep { trial, .. } = *g {
            if trial.constant().is_none_or(|(mag, _)| mag != 0.0) {
                return Err(PrinterError::Parameter {
                    what: "M973 C/D with a driver table",
                    value: format!("{g}"),
                    allowed: "C0 D0: the trial is the driver's table".into(),
                });
            }
        }
        Ok(t)
    }

    /// [`Self::correction`] with `M973`'s constant trial added to item `H` of the table in use.
    fn with_trial(&self, g: &Gcode) -> Result<PrusaCorrection, PrinterError> {
        let mut c = self.correction;
        let Gcode::ParamSweep { trial, .. } = *g else { return Ok(c) };
        let bad = |what, value: String, allowed: &str| PrinterError::Parameter { what, value, allowed: allowed.into() };
        let Some((mag, pha)) = trial.constant() else {
            return Err(bad("M973 A/B/C/D", format!("{g}"), "a constant trial (A = B, C = D)"));
        };
        let h = trial.harmonic;
        if !(1..=MAX_HARMONIC).contains(&h) {
            return Err(bad("M973 H", h.to_string(), "1..=16"));
        }
        if !(mag.is_finite() && pha.is_finite() && (-1.0..=1.0).contains(&mag)) {
            return Err(bad("M973 C/A", format!("C{mag} A{pha}"), "C in -1..=1, A finite"));
        }
        let s = if g.phase_direction() < 0.0 { &mut c.backward } else { &mut c.forward };
        let (m0, p0) = (f64::from(s.mag[h as usize]), f64::from(s.pha[h as usize]));
        let (re, im) = (m0 * p0.cos() + mag * pha.cos(), m0 * p0.sin() + mag * pha.sin());
        s.mag[h as usize] = re.hypot(im) as f32;
        s.pha[h as usize] = im.atan2(re) as f32;
        Ok(c)
    }

    /// The motor as simulated: the run current as holding current, `J + m·r²`.
    fn motor(&self) -> Result<Profile, PrinterError> {
        let i = self.run_current_a;
        if !(i.is_finite() && i > 0.0 && i <= self.profile.drive.current_limit_a) {
            return Err(PrinterError::Parameter {
                what: "run_current_a",
                value: i.to_string(),
                allowed: format!(
                    "in (0, {}] A (the profile's drive.current_limit_a)",
                    self.profile.drive.current_limit_a
                ),
            });
        }
        let extra = self.head.reflected_inertia_kg_m2();
        self.profile
            .edited(&self.profile.name, |d| {
                d.drive.holding_current_a = i;
                d.motor.inertia_kg_m2 += extra;
            })
            .map_err(|e| PrinterError::Sim(e.to_string()))
    }

    /// Simulates `g` and samples it: everything [`Self::capture`] prints, and more.
    pub fn simulate(&self, g: &Gcode) -> Result<Trace, PrinterError> {
        self.head.check()?;
        self.check_accel()?;
        let times = g.planned_times()?;
        let motor = self.motor()?;
        let table = self.table_for(g)?;
        let cfg = motor
            .controller_config(Mode::OpenLoop, Compensation::Table, Some(&table))
            .map_err(|e| PrinterError::Sim(e.to_string()))?;
        let mut lp = ClosedLoop::with_config(&motor, cfg, &SimOptions::default())
            .map_err(|e| PrinterError::Sim(e.to_string()))?;
        let pwm = motor.drive.pwm_hz;
        let ts = 1.0 / pwm;
        // The move ends with the last marker (four ramps) and a settle block.
        let end_s = times.end_marker + 4.0 * MARKER_SPEED_REV_S / MARKER_ACCEL_REV_S2 + SETTLE_S;
        let n = (end_s * pwm).ceil() as usize;
        let plan = self.plan_at_midpoints(g, times, n, pwm)?;
        let max = stepdamp_sim::max_speed_rad_s(pwm, motor.motor.pole_pairs);
        let nr = f64::from(motor.motor.pole_pairs);
        let mut belt = BeltFilter::new(&self.head);
        let mut trace = Trace {
            period_s: ts,
            mid_s: Vec::with_capacity(n),
            planned_rad: Vec::with_capacity(n),
            rotor_rad: Vec::with_capacity(n),
            head_m_s2: Vec::with_capacity(n),
            rate_hz: 0.0,
            clean_m_s2: Vec::new(),
            samples_m_s2: Vec::new(),
            annotations: Annotations { sampling_freq_hz: 0.0, movement_ok: true, accel_error: 0, times },
        };
        for (j, c) in plan.iter().enumerate() {
            let w = TAU * c.speed_rev_s;
            if w.abs() > max {
                let v = c.speed_rev_s;
                return Err(PrinterError::Sim(format!(
                    "`{g}` commands {v} rev/s: beyond the simulator's {:.1} rev/s at {pwm} Hz",
                    max / TAU
                )));
            }
            let before = *lp.plant_state();
            lp.period(w);
            let after = *lp.plant_state();
            let alpha = (after.omega - before.omega) / ts;
            let head = belt.step(alpha, ts);
            if !(head.is_finite() && after.theta.is_finite()) {
                return Err(PrinterError::Sim(format!("`{g}`: the simulation diverged at {:.4} s", j as f64 * ts)));
            }
            trace.mid_s.push(c.t_s);
            trace.planned_rad.push(c.electrical_rad);
            trace.rotor_rad.push(nr * 0.5 * (before.theta + after.theta));
            trace.head_m_s2.push(head);
        }
        self.sample(&mut trace, end_s, stepdamp_accel::prusa::sensor_gain(self.kinematics, g.axis()));
        Ok(trace)
    }

    /// The plan's commanded motion at the middle of each of `n` control periods at `pwm` Hz.
    fn plan_at_midpoints(
        &self,
        g: &Gcode,
        times: stepdamp_accel::capture::PlannedTimes,
        n: usize,
        pwm: f64,
    ) -> Result<Vec<stepdamp_accel::Commanded>, PrinterError> {
        let annotations = Annotations { sampling_freq_hz: pwm, movement_ok: true, accel_error: 0, times };
        let grid = AccelCapture {
            source: "the planned move".into(),
            line: 0,
            gcode: Some(*g),
            samples: vec![0.0; n],
            annotations,
        };
        let r = Reconstruction { first_sample_s: 0.5 / pwm, ..self.reconstruction() };
        Ok(grid.commanded(&r)?)
    }

    /// Refuses an accelerometer the sampling cannot use.
    fn check_accel(&self) -> Result<(), PrinterError> {
        let a = &self.accel;
        let checks: [(&'static str, f64, bool, &str); 5] = [
            (
                "accel.nominal_rate_hz",
                a.nominal_rate_hz,
                a.nominal_rate_hz > 0.0 && a.nominal_rate_hz <= 10_000.0,
                "in (0, 10000] Hz",
            ),
            ("accel.rate_spread", a.rate_spread, (0.0..0.5).contains(&a.rate_spread), "in [0, 0.5)"),
            ("accel.noise_rms_m_s2", a.noise_rms_m_s2, (0.0..=100.0).contains(&a.noise_rms_m_s2), "in [0, 100] m/s²"),
            ("accel.lsb_m_s2", a.lsb_m_s2, (0.0..=10.0).contains(&a.lsb_m_s2), "in [0, 10] m/s²"),
            ("accel.first_sample_s", a.first_sample_s, (-0.1..=0.3).contains(&a.first_sample_s), "in [-0.1, 0.3] s"),
        ];
        for (what, v, ok, allowed) in checks {
            if !(v.is_finite() && ok) {
                return Err(PrinterError::Parameter { what, value: v.to_string(), allowed: allowed.into() });
            }
        }
        Ok(())
    }

    /// Samples the head's acceleration from `first_sample_s` to `end_s` at the capture's
    /// rate (linear interpolation between the periods' ends) times the firmware's projection
    /// `gain`, then noise and quantisation.
    fn sample(&self, t: &mut Trace, end_s: f64, gain: f64) {
        let a = &self.accel;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let delta = if a.rate_spread > 0.0 { rng.random_range(-a.rate_spread..=a.rate_spread) } else { 0.0 };
        let rate = a.nominal_rate_hz * (1.0 + delta);
        let count = ((end_s - a.first_sample_s) * rate).floor().max(0.0) as usize + 1;
        let at = |time: f64| {
            let x = time / t.period_s - 1.0;
            if x < 0.0 {
                return 0.0; // before the first period's end the head has not moved
            }
            let i = x.floor() as usize;
            let f = x - i as f64;
            match (t.head_m_s2.get(i), t.head_m_s2.get(i + 1)) {
                (Some(&y0), Some(&y1)) => gain * (y0 + f * (y1 - y0)),
                (Some(&y0), None) => gain * y0,
                _ => 0.0,
            }
        };
        let clean: Vec<f64> = (0..count).map(|k| at(a.first_sample_s + k as f64 / rate)).collect();
        let half = 512.0;
        let samples = clean
            .iter()
            .map(|&y| {
                let noise: f64 = StandardNormal.sample(&mut rng);
                let v = y + a.noise_rms_m_s2 * noise;
                if a.lsb_m_s2 > 0.0 { (v / a.lsb_m_s2).round().clamp(-half, half - 1.0) * a.lsb_m_s2 } else { v }
            })
            .collect();
        t.rate_hz = rate;
        t.annotations.sampling_freq_hz = rate;
        t.clean_m_s2 = clean;
        t.samples_m_s2 = samples;
    }
}
