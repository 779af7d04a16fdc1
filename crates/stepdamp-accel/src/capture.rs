//! One accelerometer capture of Prusa's phase-stepping calibration G-codes, and the commanded
//! motor angle and speed at each of its samples, rebuilt from the move the firmware plans.
//!
//! Everything here was read in prusa3d/Prusa-Firmware-Buddy at tag `v6.3.1` (the files named
//! are the same at `v6.3.2`); see `docs/accelerometer.md#accelerometer-captures`.
//!
//! **What is printed** (`lib/Marlin/Marlin/src/gcode/feature/phase_stepping/M97x.cpp`): one
//! `"%d, %.5f\n"` line per sample (`M973` at line 492, `M974` at line 581), then seven
//! `key: value` annotations (`dump_samples_annotation`, lines 390–405). **What is not**: the
//! G-code's own parameters (a host log may echo the command; [`AccelCapture::gcode`] holds
//! them when it did), where the motor's electrical angle was when the move began, when the
//! first sample was taken relative to the planned move, and the belt travel per revolution.
//! [`Reconstruction`] makes each of these an explicit parameter.

use std::f64::consts::TAU;
use std::fmt;

/// `VIBRATION_SETTLE_TIME` (s): the length of each settle block, and the time cut from each
/// end of `M973`'s constant-speed block (calibration.cpp:30 at `v6.3.1`).
pub const SETTLE_S: f64 = 0.2;
/// `NO_MOVEMENT_SPEED` (mm/s): the peak speed of a settle block, which the firmware plans as
/// a tiny triangular move (calibration.cpp:877 at `v6.3.1`).
pub const SETTLE_PEAK_MM_S: f64 = 0.1;
/// `MARKER_SPEED` (rev/s): a marker runs 0 → +2 → 0 → −2 → 0 rev/s (calibration.cpp:1037).
pub const MARKER_SPEED_REV_S: f64 = 2.0;
/// `MAKER_ACCEL` (rev/s²) of the marker's four ramps (calibration.cpp:1038 at `v6.3.1`).
pub const MARKER_ACCEL_REV_S2: f64 = 1000.0;
/// The default `accel` of `plan_accel_block` (rev/s²): every ramp to and from the measured
/// speed (calibration.cpp:935 at `v6.3.1`).
pub const RAMP_ACCEL_REV_S2: f64 = 100.0;
/// The largest harmonic `M973` accepts (`H` in 1..=16, M97x.cpp:464 at `v6.3.1`).
pub const MAX_HARMONIC: u32 = 16;

/// The axis a capture moved (`X` or `Y`: the firmware's `SUPPORTED_AXES`). On CoreXY
/// printers (XL, Core One) it names the motor (`A` = `X`, `B` = `Y`), not a Cartesian axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// The X (CoreXY: A) motor.
    X,
    /// The Y (CoreXY: B) motor.
    Y,
}

/// The correction `M973` adds to the axis's table while it sweeps: harmonic `H`, phase from
/// `A` to `B` (rad), magnitude from `C` to `D` (table units, each in −1..=1), linear in the
/// distance travelled over the middle `R` revolutions of the constant-speed block and held
/// at the end values outside them (`compute_calibration_tweak`, phase_stepping.cpp:642–654;
/// `get_current_for_calibration` adds it to the table's own shift, lut.cpp:138–140, both at
/// `v6.3.1`). A table item `(mag, pha)` turns the current vector by `4·mag·sin(n·θ + pha)` rad
/// in firmware ≥ 6.3.1 (lut.cpp:115, common.hpp:17–18; see
/// `docs/exporters.md#the-table-and-its-scale`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialSweep {
    /// `H`: the harmonic of the electrical angle, 1..=16.
    pub harmonic: u32,
    /// `A`: the phase at the start of the sweep (rad).
    pub pha_start: f64,
    /// `B`: the phase at its end (rad).
    pub pha_end: f64,
    /// `C`: the magnitude at the start (table units).
    pub mag_start: f64,
    /// `D`: the magnitude at the end (table units).
    pub mag_end: f64,
}

impl TrialSweep {
    /// `(mag, pha)` when the trial is the same over the whole sweep (`A = B`, `C = D`), the
    /// form an influence-coefficient step needs; `None` for a sweep.
    pub fn constant(&self) -> Option<(f64, f64)> {
        (self.pha_start == self.pha_end && self.mag_start == self.mag_end).then_some((self.mag_start, self.pha_start))
    }
}

/// The calibration G-code that made a capture, with its parameters as sent (speeds in motor
/// revolutions per second, distances in motor revolutions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gcode {
    /// `M974 X|Y A<rev/s> B<rev/s> R<revs>`: a speed sweep from `A` to `B` over `|R|/2`
    /// revolutions and back to `A` over `|R|/2` (`capture_speed_sweep_samples`,
    /// calibration.cpp:1162–1209 at `v6.3.1`).
    SpeedSweep {
        /// The motor.
        axis: Axis,
        /// `A` (rev/s, ≥ 0).
        start_speed: f64,
        /// `B` (rev/s, ≥ 0).
        end_speed: f64,
        /// `R` (revolutions, non-zero; its sign is the direction).
        revs: f64,
    },
    /// `M973 X|Y F<rev/s> R<revs> H A B C D`: `|R|` revolutions at constant speed `F` while one
    /// harmonic's correction is swept (`capture_param_sweep_samples`, calibration.cpp:1107–1160).
    ParamSweep {
        /// The motor.
        axis: Axis,
        /// `F` (rev/s, > 0).
        speed: f64,
        /// `R` (revolutions; its sign is the direction).
        revs: f64,
        /// `H`, `A`, `B`, `C`, `D`.
        trial: TrialSweep,
    },
}

impl Gcode {
    /// The motor.
    pub fn axis(&self) -> Axis {
        match *self {
            Gcode::SpeedSweep { axis, .. } | Gcode::ParamSweep { axis, .. } => axis,
        }
    }

    /// `R` (revolutions, signed).
    pub fn revs(&self) -> f64 {
        match *self {
            Gcode::SpeedSweep { revs, .. } | Gcode::ParamSweep { revs, .. } => revs,
        }
    }

    /// The sign of the motor's electrical angle during the move: `R > 0` runs the phase
    /// **down** and uses the backward (`B`) table, `R ≤ 0` runs it up with the forward (`F`)
    /// table, whether or not the axis is inverted: `direction` is flipped once for an inverted
    /// axis (calibration.cpp:1115–1118) and once more where position becomes motor phase
    /// (`resolve_axis_inversion`, phase_stepping.cpp:117–123, 727–736), and the table follows
    /// the sign of the physical speed (phase_stepping.cpp:125–129, 730–734), all at `v6.3.1`.
    pub fn phase_direction(&self) -> f64 {
        if self.revs() > 0.0 { -1.0 } else { 1.0 }
    }

    /// The move as planned: its segments and the times the firmware annotates.
    pub(crate) fn plan(&self, mm_per_rev: f64) -> Result<crate::timeline::Plan, CaptureError> {
        crate::timeline::plan(self, mm_per_rev)
    }

    /// The annotation times the firmware computes for this G-code (s from the start of the
    /// first settle block), as it prints them but unrounded: what [`AccelCapture::check_annotations`]
    /// compares the printed ones with. Independent of the belt (`mm_per_rev`).
    pub fn planned_times(&self) -> Result<PlannedTimes, CaptureError> {
        Ok(self.plan(1.0)?.times)
    }
}

impl fmt::Display for Gcode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ax = |a: Axis| if a == Axis::X { 'X' } else { 'Y' };
        match *self {
            Gcode::SpeedSweep { axis, start_speed, end_speed, revs } => {
                write!(f, "M974 {} A{start_speed} B{end_speed} R{revs}", ax(axis))
            }
            Gcode::ParamSweep { axis, speed, revs, trial: t } => write!(
                f,
                "M973 {} F{speed} R{revs} H{} A{} B{} C{} D{}",
                ax(axis),
                t.harmonic,
                t.pha_start,
                t.pha_end,
                t.mag_start,
                t.mag_end
            ),
        }
    }
}

/// The times a capture's annotations name, in seconds from the start of the move's first
/// settle block (the firmware's "planned times", calibration.hpp:26–30 at `v6.3.1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedTimes {
    /// `start_marker`: the first marker move begins.
    pub start_marker: f64,
    /// `end_marker`: the second marker move begins.
    pub end_marker: f64,
    /// `signal_start`: the analysed part begins (`M973`: 0.2 s into the constant-speed block;
    /// `M974`: the sweep from `A` begins).
    pub signal_start: f64,
    /// `signal_end`: the analysed part ends (`M973`: 0.2 s before the constant-speed block
    /// ends; `M974`: the sweep is back at `A`).
    pub signal_end: f64,
}

/// The seven `key: value` lines after the samples (M97x.cpp:390–405 at `v6.3.1`). Floats are
/// printed by Arduino's `Print::println(double)` with **2 decimals** and CR LF
/// (`lib/Arduino_Core_Buddy/cores/arduino/Print.h:97`, `Print.cpp:111–112`), so the times are
/// rounded to 10 ms and the rate to 0.01 Hz.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Annotations {
    /// `sampling_freq` (Hz): the rate the accelerometer measured over this capture, not the
    /// nominal one (LIS2DH12 at 1344 Hz: `src/puppy/dwarf/accelerometer.cpp:114` (XL),
    /// `src/hw/lis2dh12_poller.hpp:150` (local); measured in `measured_sampling_rate`,
    /// accelerometer.cpp:206–212, and `get_sampling_rate`, lis2dh12_poller.hpp:192). `0.00`
    /// when the accelerometer failed.
    pub sampling_freq_hz: f64,
    /// `movement_ok`: the move started within 300 ms and the planner was idle again within
    /// 1.5 × `end_marker` of that (`capture_movement_samples`, calibration.cpp:1056–1105;
    /// the timeout at 1148 and 1197).
    pub movement_ok: bool,
    /// `accel_error`: `PrusaAccelerometer::Error` as an integer (accelerometer.h:32–47). `0`
    /// is none; the other codes depend on the printer, which the output does not say: with
    /// the accelerometer on the board (MK4, Core One) 1 = communication, 2 = sensor
    /// overflow; on the XL's tool (remote) 1 = communication, 2 = no active tool, 3 = busy,
    /// 4 = sensor overflow, 5 = overflow on the board, 6 = overflow on the tool,
    /// 7 = possible overflow.
    pub accel_error: i64,
    /// The planned times (s).
    pub times: PlannedTimes,
}

impl Annotations {
    /// What the firmware itself requires of a capture (`SamplesAnnotation::is_valid`,
    /// calibration.hpp:32–34): the move ran, no accelerometer error, a positive rate.
    pub fn is_valid(&self) -> bool {
        self.movement_ok && self.accel_error == 0 && self.sampling_freq_hz > 0.0
    }
}

/// One capture as printed.
#[derive(Debug, Clone, PartialEq)]
pub struct AccelCapture {
    /// Where it was read from (a path or a name).
    pub source: String,
    /// The line (1-based) of its first sample, or of its first annotation if it has none.
    pub line: u64,
    /// The G-code and its parameters, if the log echoed the command (`Send: M973 …`), or as
    /// set by the caller ([`AccelCapture::with_gcode`]); `None` otherwise.
    pub gcode: Option<Gcode>,
    /// The samples in **m/s²**, in the order printed (index 0, 1, …): the acceleration
    /// projected on the moving axis (`project_to_axis`, calibration.cpp:240–269: Core One one
    /// sensor axis, other CoreXY printers `(x + y)/√2` for `X` and `(y − x)/√2` for `Y`,
    /// the rest one axis), from raw counts scaled by
    /// `2·9.80665/max` (±2 g range; accelerometer_local.cpp:69–73 and
    /// accelerometer_utils.cpp:8–22 at `v6.3.1`), printed with 5 decimals.
    pub samples: Vec<f64>,
    /// The annotations.
    pub annotations: Annotations,
}

/// What the printed output does not say, each given explicitly (see
/// `docs/accelerometer.md#accelerometer-captures`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reconstruction {
    /// Electrical periods per motor revolution, the rotor's pole pairs (`Nr` in
    /// `docs/design.md#the-plant`): full steps per revolution / 4 (the firmware's
    /// `motor_steps / 4`, calibration.cpp:393): 50 for a 200-step (1.8°) motor, 100 for a
    /// 400-step one (XL option, axes.cpp:31).
    pub periods_per_rev: u32,
    /// The commanded electrical angle (rad) at the start of the first settle block: the
    /// firmware's motor phase `zero_rotor_phase + pos_to_phase(position)`
    /// (phase_stepping.cpp:736) × 2π/1024, which depends on where the head stood and is not
    /// printed. Two captures started at the same position (or positions a whole electrical
    /// period apart) share it; a wrong value then turns every response of harmonic `n` by the
    /// same `n·δ`, which cancels out of an influence-coefficient step.
    pub start_angle_rad: f64,
    /// The planned time (s, from the start of the first settle block) of sample 0. The
    /// firmware starts reading the accelerometer once the move is running (it waits up to
    /// 300 ms for that, calibration.cpp:1059–1073) and assumes 0, then finds the marker within
    /// ±50 ms by its energy (`locate_signal_markers`, calibration.cpp:293–318). An error `δt`
    /// turns harmonic `n` at speed `v` by `2π·n·P·v·δt` rad (`P` = [`Self::periods_per_rev`]),
    /// which differs from capture to capture. [`crate::timing::estimate_first_sample`]
    /// estimates it from the markers.
    pub first_sample_s: f64,
    /// Belt travel per motor revolution (mm, the firmware's `rev_to_mm`, axes.cpp:22), used
    /// only for the settle blocks, which the firmware plans in mm (0.01 mm each).
    pub mm_per_rev: f64,
}

/// The commanded motion at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Commanded {
    /// The sample's planned time (s, from the start of the first settle block).
    pub t_s: f64,
    /// The motor angle (revolutions) from its start, signed like the electrical angle.
    pub motor_rev: f64,
    /// The commanded electrical angle (rad, not wrapped): `start_angle_rad + 2π·P·motor_rev`.
    pub electrical_rad: f64,
    /// The commanded speed (rev/s), signed like the electrical angle.
    pub speed_rev_s: f64,
    /// The commanded acceleration (rev/s²), signed like the electrical angle.
    pub accel_rev_s2: f64,
}

/// Why a capture cannot be analysed; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CaptureError {
    /// The G-code is not known.
    #[error("{file}:{line}: the capture's G-code is unknown (the log did not echo `M973 …`/`M974 …`): give it")]
    NoGcode {
        /// The source.
        file: String,
        /// The capture's line.
        line: u64,
    },
    /// A parameter is outside what the firmware or the reconstruction accepts.
    #[error("{what} = {value}: {allowed}")]
    Parameter {
        /// The parameter.
        what: &'static str,
        /// Its value as given.
        value: String,
        /// The allowed range, and why.
        allowed: String,
    },
    /// The printed annotation does not match the G-code: a wrong G-code, or another firmware.
    #[error(
        "{file}:{line}: {key} printed {printed} but `{gcode}` plans {planned:.4} s (firmware v6.3.1/v6.3.2 rounds to 0.01 s)"
    )]
    Mismatch {
        /// The source.
        file: String,
        /// The capture's line.
        line: u64,
        /// The annotation's key.
        key: &'static str,
        /// Its printed value.
        printed: f64,
        /// The planned value.
        planned: f64,
        /// The G-code.
        gcode: String,
    },
    /// The capture cannot give what was asked.
    #[error("{file}:{line}: {reason}")]
    Unusable {
        /// The source.
        file: String,
        /// The capture's line.
        line: u64,
        /// Why.
        reason: String,
    },
}

impl AccelCapture {
    /// The same capture with its G-code set by the caller (when the log did not echo it).
    pub fn with_gcode(mut self, gcode: Gcode) -> Self {
        self.gcode = Some(gcode);
        self
    }

    /// The G-code, or [`CaptureError::NoGcode`].
    pub fn require_gcode(&self) -> Result<Gcode, CaptureError> {
        self.gcode.ok_or_else(|| CaptureError::NoGcode { file: self.source.clone(), line: self.line })
    }

    /// The `M973` constant trial of this capture, `(H, F, R, mag, pha)`, or why it is not
    /// one (an unknown G-code, a speed sweep, a swept trial), naming `purpose` in the message.
    pub fn constant_trial(&self, purpose: &str) -> Result<(u32, f64, f64, f64, f64), CaptureError> {
        let g = self.require_gcode()?;
        match g {
            Gcode::ParamSweep { speed, revs, trial, .. } => match trial.constant() {
                Some((mag, pha)) => Ok((trial.harmonic, speed, revs, mag, pha)),
                None => Err(self.unusable(format!("`{g}` sweeps its trial: {purpose} needs A = B and C = D"))),
            },
            Gcode::SpeedSweep { .. } => Err(self.unusable(format!("`{g}` sweeps the speed: {purpose} needs M973"))),
        }
    }

    /// A [`CaptureError::Unusable`] for this capture.
    pub(crate) fn unusable(&self, reason: String) -> CaptureError {
        CaptureError::Unusable { file: self.source.clone(), line: self.line, reason }
    }

    /// Checks the printed times against the ones the G-code plans, to the printed rounding
    /// (±0.005 s, and 0.1 ms for the firmware's `f32` sums): a wrong G-code (or a firmware
    /// that plans differently) is refused instead of rebuilding a move that did not happen.
    pub fn check_annotations(&self) -> Result<(), CaptureError> {
        let g = self.require_gcode()?;
        let planned = g.planned_times()?;
        let printed = self.annotations.times;
        let pairs = [
            ("start_marker", printed.start_marker, planned.start_marker),
            ("end_marker", printed.end_marker, planned.end_marker),
            ("signal_start", printed.signal_start, planned.signal_start),
            ("signal_end", printed.signal_end, planned.signal_end),
        ];
        for (key, p, q) in pairs {
            if (p - q).abs() > 0.0051 {
                return Err(CaptureError::Mismatch {
                    file: self.source.clone(),
                    line: self.line,
                    key,
                    printed: p,
                    planned: q,
                    gcode: g.to_string(),
                });
            }
        }
        Ok(())
    }

    /// The commanded motor angle, electrical angle and speed at every sample, from the move
    /// as `calibration.cpp` plans it: settle block (a 0.01 mm triangle, 0.2 s), marker
    /// (±2 rev/s at 1000 rev/s²), `M974` another settle block, ramp at 100 rev/s², the
    /// constant-speed block (`M973`) or the two constant-acceleration sweeps (`M974`), ramp
    /// down, settle, marker, settle. Sample `k` is at `first_sample_s + k / sampling_freq`.
    ///
    /// Assumes the planner runs the blocks as planned (the firmware's own analysis assumes
    /// it too); input shaping, if active, delays the commanded position, which at constant
    /// speed is a constant angle (the same for captures at the same speed). Refuses a
    /// capture whose annotations do not match its G-code ([`Self::check_annotations`]).
    pub fn commanded(&self, r: &Reconstruction) -> Result<Vec<Commanded>, CaptureError> {
        let g = self.require_gcode()?;
        check_reconstruction(r)?;
        let fs = self.annotations.sampling_freq_hz;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(self.unusable(format!("sampling_freq {fs}: no sample times (the accelerometer failed)")));
        }
        self.check_annotations()?;
        let plan = g.plan(r.mm_per_rev)?;
        let sign = g.phase_direction();
        let scale = TAU * f64::from(r.periods_per_rev);
        let mut cursor = plan.cursor();
        Ok((0..self.samples.len())
            .map(|k| {
                let t_s = r.first_sample_s + k as f64 / fs;
                let (d, v, a) = cursor.at(t_s);
                Commanded {
                    t_s,
                    motor_rev: sign * d,
                    electrical_rad: r.start_angle_rad + scale * sign * d,
                    speed_rev_s: sign * v,
                    accel_rev_s2: sign * a,
                }
            })
            .collect())
    }
}

/// Refuses parameters the reconstruction cannot use.
fn check_reconstruction(r: &Reconstruction) -> Result<(), CaptureError> {
    let bad =
        |what, value: String, allowed: &str| Err(CaptureError::Parameter { what, value, allowed: allowed.into() });
    if r.periods_per_rev == 0 {
        return bad("periods_per_rev", "0".into(), "at least 1 (50 for a 200-step motor)");
    }
    if !r.start_angle_rad.is_finite() {
        return bad("start_angle_rad", r.start_angle_rad.to_string(), "a finite angle");
    }
    if !r.first_sample_s.is_finite() {
        return bad("first_sample_s", r.first_sample_s.to_string(), "a finite time");
    }
    if !(r.mm_per_rev.is_finite() && r.mm_per_rev > 0.0) {
        return bad("mm_per_rev", r.mm_per_rev.to_string(), "positive (40 for a 20-tooth GT2 pulley)");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m973(revs: f64) -> Gcode {
        let trial = TrialSweep { harmonic: 2, pha_start: 0.5, pha_end: 0.5, mag_start: 0.01, mag_end: 0.01 };
        Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs, trial }
    }

    fn capture(g: Gcode, n: usize, fs: f64) -> AccelCapture {
        let times = g.planned_times().unwrap();
        let annotations = Annotations { sampling_freq_hz: fs, movement_ok: true, accel_error: 0, times };
        AccelCapture { source: "t".into(), line: 1, gcode: Some(g), samples: vec![0.0; n], annotations }
    }

    const R: Reconstruction =
        Reconstruction { periods_per_rev: 50, start_angle_rad: 0.3, first_sample_s: 0.0, mm_per_rev: 40.0 };

    #[test]
    fn m973_plans_the_firmware_times() {
        // 0.2 settle, 8 ms marker, 20 ms ramp, 5 s + 0.4 s constant, cut 0.2 s each end.
        let t = m973(10.0).planned_times().unwrap();
        assert!((t.start_marker - 0.2).abs() < 1e-12);
        assert!((t.signal_start - (0.2 + 0.008 + 0.02 + 0.2)).abs() < 1e-12);
        assert!((t.signal_end - (0.228 + 5.4 - 0.2)).abs() < 1e-12);
        assert!((t.end_marker - (0.228 + 5.4 + 0.02 + 0.2)).abs() < 1e-12);
    }

    #[test]
    fn the_constant_speed_window_turns_the_angle_at_the_commanded_speed() {
        let c = capture(m973(10.0), 8000, 1344.0);
        let s = c.commanded(&R).unwrap();
        let t = c.annotations.times;
        let inside: Vec<_> = s.iter().filter(|x| x.t_s > t.signal_start && x.t_s < t.signal_end).collect();
        assert!(inside.iter().all(|x| (x.speed_rev_s + 2.0).abs() < 1e-12), "R > 0 runs the phase down");
        let (a, b) = (inside[0], inside[inside.len() - 1]);
        let rate = (b.electrical_rad - a.electrical_rad) / (b.t_s - a.t_s);
        assert!((rate + TAU * 50.0 * 2.0).abs() < 1e-6, "{rate}");
    }

    #[test]
    fn the_move_returns_to_rest_and_markers_cancel() {
        let c = capture(m973(-10.0), 9000, 1344.0);
        let s = c.commanded(&R).unwrap();
        let last = s.last().unwrap();
        assert_eq!(last.speed_rev_s, 0.0);
        // 10 revs + 2·0.2·2 revs + two ramps of 0.02 rev + three settle blocks of 0.01 mm.
        let want = 10.0 + 0.8 + 0.04 + 3.0 * 0.01 / 40.0;
        assert!((last.motor_rev - want).abs() < 1e-9, "{}", last.motor_rev);
    }

    #[test]
    fn a_speed_sweep_runs_from_a_to_b_and_back_at_constant_acceleration() {
        let g = Gcode::SpeedSweep { axis: Axis::Y, start_speed: 1.0, end_speed: 3.0, revs: -8.0 };
        let t = g.planned_times().unwrap();
        let c = capture(g, 9000, 1000.0);
        let s = c.commanded(&R).unwrap();
        let at = |time: f64| s[((time - R.first_sample_s) * 1000.0).round() as usize];
        let mid = 0.5 * (t.signal_start + t.signal_end);
        // R < 0 runs the phase up; 4 revs from 1 to 3 rev/s take 2 s, and 2 s back.
        assert!((t.signal_end - t.signal_start - 4.0).abs() < 1e-12);
        assert!((at(mid).speed_rev_s - 3.0).abs() < 2e-3, "{:?}", at(mid));
        assert!((at(t.signal_start + 1.0).speed_rev_s - 2.0).abs() < 2e-3);
        assert!((at(mid).motor_rev - at(t.signal_start).motor_rev - 4.0).abs() < 5e-3);
    }

    #[test]
    fn annotations_that_do_not_match_the_gcode_are_refused() {
        let mut c = capture(m973(10.0), 10, 1344.0);
        c.annotations.times.signal_end += 0.02;
        let e = c.commanded(&R).unwrap_err().to_string();
        assert!(e.contains("signal_end printed") && e.contains("M973 X F2 R10"), "{e}");
        let c = capture(m973(10.0), 10, 1344.0);
        let mut r = R;
        r.mm_per_rev = 0.0;
        assert!(c.commanded(&r).unwrap_err().to_string().contains("mm_per_rev = 0"));
    }

    #[test]
    fn a_speed_sweep_with_equal_speeds_is_refused_as_the_firmware_asserts() {
        let g = Gcode::SpeedSweep { axis: Axis::Y, start_speed: 1.0, end_speed: 1.0, revs: 4.0 };
        assert!(g.planned_times().unwrap_err().to_string().contains("A = B"));
        let g = Gcode::SpeedSweep { axis: Axis::Y, start_speed: 0.0, end_speed: 4.0, revs: 8.0 };
        let t = g.planned_times().unwrap();
        // No ramp to A = 0; 4 revs at a mean 2 rev/s up and again down: 4 s.
        assert!((t.signal_end - t.signal_start - 4.0).abs() < 1e-12);
    }
}
