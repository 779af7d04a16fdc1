//! The moves to record for the Trinamic table step on a Klipper printer
//! (`docs/accelerometer.md#refining-a-trinamic-table`): one motor alone, back and forth at one
//! steady speed, enough times for [`KlipperPlanOptions::steady_s`] of steady motion each way
//! once the reader has cut the ramps and [`SETTLE_S`] at each end. Printed as Klipper G-code
//! with the reason for every number: numbers and fixed words only.

use super::Kinematics;
use super::segment::MIN_SEGMENT_S;
use crate::capture::{Axis, SETTLE_S};
use crate::plan::MAX_BAND_FRACTION;
use std::fmt;

/// The least a move keeps (s): the reader's [`MIN_SEGMENT_S`] and 0.1 s for the ends its
/// acceleration estimate (±10 ms) and the sampling move.
pub const MIN_KEPT_S: f64 = MIN_SEGMENT_S + 0.1;

/// What to plan for.
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperPlanOptions {
    /// The printer's kinematics.
    pub kinematics: Kinematics,
    /// The motor: `stepper_x` (X, CoreXY A) or `stepper_y` (Y, CoreXY B).
    pub axis: Axis,
    /// Klipper's `rotation_distance` of that stepper: belt travel per motor revolution, mm.
    pub rotation_distance_mm: f64,
    /// Electrical periods per revolution (`full_steps_per_rotation / 4`, 50 for 200 steps).
    pub pole_pairs: u32,
    /// The steady speed, motor rev/s (the Prusa route's 2 rev/s puts order 4 at 400 Hz).
    pub speed_rev_s: f64,
    /// The harmonic measured (its frequency must stay within [`MAX_BAND_FRACTION`] of the rate).
    pub harmonic: u32,
    /// The accelerometer's rate, Hz (Klipper's ADXL345 default: 3200).
    pub rate_hz: f64,
    /// How far the head may go from where it starts, mm: along X (cartesian) or along X and
    /// Y each (CoreXY, where one motor alone moves the head diagonally).
    pub travel_mm: f64,
    /// The toolhead acceleration for the moves, mm/s² (`SET_VELOCITY_LIMIT ACCEL`).
    pub accel_mm_s2: f64,
    /// Steady motion wanted per direction, s (what the reader keeps).
    pub steady_s: f64,
}

impl KlipperPlanOptions {
    /// Cartesian `stepper_x`, 40 mm per revolution (GT2, 20 teeth), 50 pole pairs, 2 rev/s,
    /// order 4, 3200 Hz, 100 mm of travel, 1000 mm/s², 3 s each way.
    pub fn new(kinematics: Kinematics, axis: Axis) -> Self {
        KlipperPlanOptions {
            kinematics,
            axis,
            rotation_distance_mm: 40.0,
            pole_pairs: 50,
            speed_rev_s: 2.0,
            harmonic: 4,
            rate_hz: 3200.0,
            travel_mm: 100.0,
            accel_mm_s2: 1000.0,
            steady_s: 3.0,
        }
    }
}

/// One move of the head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KlipperMove {
    /// Relative move along X and Y, mm.
    pub dx_mm: f64,
    /// See [`Self::dx_mm`].
    pub dy_mm: f64,
    /// `F`: the toolhead's speed along its path, mm/min.
    pub feed_mm_min: f64,
    /// The motor's revolutions (signed: forward counts up).
    pub motor_revs: f64,
    /// What the reader keeps of it, s.
    pub kept_s: f64,
}

/// The plan: the moves of one log (the same for the log with the table in use and the one
/// with the trial table), and the toolhead acceleration to set.
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperPlan {
    /// The options planned for.
    pub options: KlipperPlanOptions,
    /// Back and forth, forward first.
    pub moves: Vec<KlipperMove>,
}

/// Why a plan cannot be made: one line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct KlipperPlanError(String);

/// The moves: each the whole travel, at the speed, ramps at the acceleration; as many pairs as
/// the steady time asks (each move keeps `travel/v − v/a − 2·SETTLE_S`, at least
/// [`MIN_KEPT_S`]). Refuses values out of range, a harmonic beyond the band, and a travel
/// too short to keep a stretch.
pub fn plan_klipper(o: &KlipperPlanOptions) -> Result<KlipperPlan, KlipperPlanError> {
    let bad = |s: String| Err(KlipperPlanError(s));
    let checks = [
        ("rotation distance", o.rotation_distance_mm, 1.0, 1000.0, "mm"),
        ("speed", o.speed_rev_s, 0.1, 20.0, "rev/s"),
        ("rate", o.rate_hz, 100.0, 100_000.0, "Hz"),
        ("travel", o.travel_mm, 10.0, 2000.0, "mm"),
        ("acceleration", o.accel_mm_s2, 50.0, 100_000.0, "mm/s²"),
        ("steady time", o.steady_s, 0.5, 60.0, "s"),
    ];
    for (what, v, lo, hi, unit) in checks {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            return bad(format!("{what}: {v:?} must be in {lo}..={hi} {unit}"));
        }
    }
    let hz = f64::from(o.harmonic) * f64::from(o.pole_pairs) * o.speed_rev_s;
    if o.harmonic == 0 || o.pole_pairs == 0 || hz > MAX_BAND_FRACTION * o.rate_hz {
        return bad(format!(
            "harmonic {} at {} rev/s is {hz:.0} Hz: beyond {:.0} % of the {} Hz rate (a lower speed)",
            o.harmonic,
            o.speed_rev_s,
            100.0 * MAX_BAND_FRACTION,
            o.rate_hz
        ));
    }
    // One motor alone: cartesian moves the head with the belt; CoreXY moves it diagonally,
    // x and y each by half the belt's travel (a = x + y, b = x − y), at 1/√2 of its speed.
    let (belt_mm, path_per_belt) = match o.kinematics {
        Kinematics::Cartesian => (o.travel_mm, 1.0),
        Kinematics::CoreXy => (2.0 * o.travel_mm, std::f64::consts::FRAC_1_SQRT_2),
    };
    let v = o.speed_rev_s * o.rotation_distance_mm; // belt, mm/s
    let a = o.accel_mm_s2 / path_per_belt; // belt, mm/s²
    let kept = belt_mm / v - v / a - 2.0 * SETTLE_S;
    if kept < MIN_KEPT_S {
        let need = v * (MIN_KEPT_S + 2.0 * SETTLE_S + v / a);
        return bad(format!(
            "travel: {} mm keeps {kept:.2} s of each move at {} rev/s, the plan asks {MIN_KEPT_S} s: at least {:.0} mm",
            o.travel_mm,
            o.speed_rev_s,
            (need / (belt_mm / o.travel_mm)).ceil()
        ));
    }
    let pairs = (o.steady_s / kept).ceil() as usize;
    let revs = belt_mm / o.rotation_distance_mm;
    let feed_mm_min = 60.0 * v * path_per_belt;
    let step = |sign: f64| {
        let d = sign * belt_mm;
        let (dx_mm, dy_mm) = match (o.kinematics, o.axis) {
            (Kinematics::Cartesian, Axis::X) => (d, 0.0),
            (Kinematics::Cartesian, Axis::Y) => (0.0, d),
            (Kinematics::CoreXy, Axis::X) => (d / 2.0, d / 2.0),
            (Kinematics::CoreXy, Axis::Y) => (d / 2.0, -d / 2.0),
        };
        KlipperMove { dx_mm, dy_mm, feed_mm_min, motor_revs: sign * revs, kept_s: kept }
    };
    let moves = (0..pairs).flat_map(|_| [step(1.0), step(-1.0)]).collect();
    Ok(KlipperPlan { options: o.clone(), moves })
}

impl fmt::Display for KlipperPlan {
    /// G-code for Klipper's console or a macro: the reasons as `;` comments, then
    /// `SET_VELOCITY_LIMIT`, relative moves with a pause after each, and back to absolute.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let o = &self.options;
        let m = self.moves.first();
        let kept = m.map_or(0.0, |m| m.kept_s);
        let stepper = if o.axis == Axis::X { "stepper_x" } else { "stepper_y" };
        writeln!(
            f,
            "; stepdamp: moves for harmonic {} of {stepper} ({}), {} rev/s ({:.0} Hz, {:.0} % of the {} Hz rate)",
            o.harmonic,
            o.kinematics.name(),
            o.speed_rev_s,
            f64::from(o.harmonic) * f64::from(o.pole_pairs) * o.speed_rev_s,
            100.0 * f64::from(o.harmonic) * f64::from(o.pole_pairs) * o.speed_rev_s / o.rate_hz,
            o.rate_hz
        )?;
        writeln!(
            f,
            "; {} moves, each keeps {kept:.2} s at speed after the ramps and {SETTLE_S} s at each end: {:.1} s each way",
            self.moves.len(),
            kept * self.moves.len() as f64 / 2.0
        )?;
        writeln!(
            f,
            "; record it twice with data_logger.py (docs/accelerometer.md#recording-a-log), Ctrl-C after each:"
        )?;
        writeln!(f, ";   base:  the driver's table in use;")?;
        writeln!(f, ";   trial: with `stepdamp accel klipper-trial`'s block included (FIRMWARE_RESTART, home first);")?;
        writeln!(
            f,
            ";   then `stepdamp accel klipper-refine --log base.json.gz --log trial.json.gz --klipper-trial ...`"
        )?;
        writeln!(f, "; start with the head where it can move {} mm the way of the first move and back", o.travel_mm)?;
        writeln!(f, "SET_VELOCITY_LIMIT ACCEL={}", o.accel_mm_s2)?;
        writeln!(f, "G91")?;
        for m in &self.moves {
            let axes = match (m.dx_mm != 0.0, m.dy_mm != 0.0) {
                (true, true) => format!("X{} Y{}", num(m.dx_mm), num(m.dy_mm)),
                (true, false) => format!("X{}", num(m.dx_mm)),
                _ => format!("Y{}", num(m.dy_mm)),
            };
            writeln!(f, "G1 {axes} F{}", num(m.feed_mm_min))?;
            writeln!(f, "G4 P300")?;
        }
        writeln!(f, "G90")?;
        writeln!(f, "; restore your acceleration: SET_VELOCITY_LIMIT ACCEL=<printer.cfg's max_accel>")
    }
}

/// A G-code number: at most 3 decimals, no trailing zeros.
fn num(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cartesian_moves_run_the_motor_at_the_speed_for_the_steady_time() {
        let p = plan_klipper(&KlipperPlanOptions::new(Kinematics::Cartesian, Axis::X)).unwrap();
        // 100 mm at 80 mm/s: 1.25 s, less 80/1000 s of ramps and 0.4 s: 0.77 s kept, 4 pairs.
        assert_eq!(p.moves.len(), 8);
        let m = p.moves[0];
        assert_eq!((m.dx_mm, m.dy_mm, m.feed_mm_min, m.motor_revs), (100.0, 0.0, 4800.0, 2.5));
        assert!((m.kept_s - 0.77).abs() < 1e-9, "{m:?}");
        assert_eq!(p.moves[1].motor_revs, -2.5);
        let text = p.to_string();
        assert!(text.contains("G1 X100 F4800\nG4 P300\nG1 X-100 F4800\n"), "{text}");
        assert!(text.lines().all(|l| l.is_ascii() || l.starts_with(';')), "{text}");
    }

    #[test]
    fn corexy_moves_one_motor_alone_diagonally() {
        let o = KlipperPlanOptions::new(Kinematics::CoreXy, Axis::Y);
        let m = plan_klipper(&o).unwrap().moves[0];
        // B = x − y moves by 200 mm (5 rev) with x = +100, y = −100; the head's path is
        // 141.4 mm at 80/√2 mm/s.
        assert_eq!((m.dx_mm, m.dy_mm, m.motor_revs), (100.0, -100.0, 5.0));
        let belt_speed = m.feed_mm_min / 60.0 * std::f64::consts::SQRT_2;
        assert!((belt_speed - 80.0).abs() < 1e-9, "{m:?}");
    }

    #[test]
    fn a_short_travel_or_a_harmonic_beyond_the_band_is_refused_with_what_would_do() {
        let base = KlipperPlanOptions::new(Kinematics::Cartesian, Axis::X);
        let e = plan_klipper(&KlipperPlanOptions { travel_mm: 50.0, ..base.clone() }).unwrap_err().to_string();
        assert!(e.starts_with("travel: 50 mm keeps") && e.ends_with("at least 87 mm"), "{e}");
        let e = plan_klipper(&KlipperPlanOptions { speed_rev_s: 8.0, ..base.clone() }).unwrap_err().to_string();
        assert!(e.contains("1600 Hz: beyond 40 % of the 3200 Hz rate"), "{e}");
        let e = plan_klipper(&KlipperPlanOptions { rotation_distance_mm: f64::NAN, ..base }).unwrap_err().to_string();
        assert_eq!(e, "rotation distance: NaN must be in 1..=1000 mm");
    }
}
