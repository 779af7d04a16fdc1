//! One influence-coefficient step from recorded captures (docs/accelerometer.md#refining-from-captures):
//! the `M973` captures of a session grouped by harmonic, speed and direction, each group's
//! baseline (no trial) and constant trial giving the influence coefficient and the shift that
//! cancels the baseline, added to the table item that was in use while they were recorded.

use crate::capture::{AccelCapture, Reconstruction};
use crate::influence::{Complex, Influence, InfluenceError, Response, harmonic_response, influence};
use crate::influence::{table_item, table_shift};
use crate::timing::estimate_first_sample;

/// Items of a Prusa table per direction (orders 0..=16).
pub const TABLE_ITEMS: usize = 17;

/// The latest planned time (s) the first sample may have: the firmware waits up to 300 ms for
/// the move to start before it reads the accelerometer (calibration.cpp:1059–1073 at `v6.3.1`).
pub const MAX_FIRST_SAMPLE_S: f64 = 0.3;

/// How each capture's [`Reconstruction::first_sample_s`] is obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timing {
    /// From the capture's two marker moves ([`estimate_first_sample`] over
    /// `0..=`[`MAX_FIRST_SAMPLE_S`]).
    Markers,
    /// 0: the firmware's own assumption, that sampling starts with the planned move.
    Planned,
}

/// The choices of a refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// Electrical periods per motor revolution (50 for a 1.8° motor).
    pub periods_per_rev: u32,
    /// Belt travel per motor revolution, mm (32 for a GT2 belt on a 16-tooth pulley).
    pub mm_per_rev: f64,
    /// Whole electrical periods per lock-in block ([`harmonic_response`]).
    pub periods_per_block: u32,
    /// The firmware's table scale (4 for ≥ 6.3.1: `stepdamp_export::prusa::Firmware::scale`).
    pub scale: f64,
    /// How the time of each capture's first sample is found.
    pub timing: Timing,
}

/// The table items `(mag, pha)` in use while the captures were recorded, per direction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InUse {
    /// The forward table (phase increasing).
    pub forward: [(f64, f64); TABLE_ITEMS],
    /// The backward table.
    pub backward: [(f64, f64); TABLE_ITEMS],
}

/// One refined table item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// The harmonic `n`.
    pub harmonic: u32,
    /// +1: the forward table (phase increasing); −1: the backward one.
    pub phase_direction: f64,
    /// The speed of the captures, rev/s (signed like the electrical angle).
    pub speed_rev_s: f64,
    /// The baseline's response.
    pub baseline: Response,
    /// The trial's response.
    pub trial: Response,
    /// The influence coefficient and the shift that cancels the baseline.
    pub influence: Influence,
    /// The item in use, `(mag, pha)`.
    pub in_use: (f64, f64),
    /// The new item, `(mag, pha)`: in use plus the cancelling shift.
    pub item: (f64, f64),
    /// 95 % radius of the new item's phasor, table units.
    pub item_radius95: f64,
    /// What the linear model expects of the response with the new item: within this
    /// radius of zero (m/s², `|C|·` the cancelling shift's 95 % radius). An expectation to
    /// measure, not a simulation.
    pub expected_residual95: f64,
}

/// The constant trial `(H, F, sign of R, mag, pha)` of an `M973`, or why the capture is not one.
fn constant_trial(c: &AccelCapture) -> Result<(u32, f64, f64, f64, f64), InfluenceError> {
    let (h, speed, revs, mag, pha) = c.constant_trial("a refinement")?;
    Ok((h, speed, revs.signum(), mag, pha))
}

/// The reconstruction of capture `c` under `o`.
fn reconstruction(c: &AccelCapture, o: &RefineOptions) -> Result<Reconstruction, InfluenceError> {
    let mut r = Reconstruction {
        periods_per_rev: o.periods_per_rev,
        start_angle_rad: 0.0,
        first_sample_s: 0.0,
        mm_per_rev: o.mm_per_rev,
    };
    if o.timing == Timing::Markers {
        r.first_sample_s = estimate_first_sample(c, &r, 0.0, MAX_FIRST_SAMPLE_S)?.first_sample_s;
    }
    Ok(r)
}

/// Refines every group of `captures` (same harmonic, speed and direction) that has exactly
/// one baseline (`C = D = 0`) and one constant trial: the influence step, the new item
/// `in_use + U*` in table form. The start angle is taken as 0 for every capture: a shared
/// start angle turns baseline and influence alike and leaves `U*` unchanged (captures started
/// at the same position share it). Refuses a capture that is not a constant-trial `M973`, a
/// group with two baselines or two trials (an iteration's later steps: not supported yet),
/// a group without a baseline or without a trial, and a harmonic above 16.
pub fn refine(captures: &[AccelCapture], o: &RefineOptions, in_use: &InUse) -> Result<Vec<Refined>, InfluenceError> {
    type Key = (u32, u64, i8);
    let mut groups: Vec<(Key, Option<usize>, Option<usize>)> = Vec::new();
    for (i, c) in captures.iter().enumerate() {
        let (n, speed, dir, mag, _) = constant_trial(c)?;
        if n as usize >= TABLE_ITEMS {
            return Err(c.unusable(format!("harmonic {n}: the table holds 1..=16")).into());
        }
        let key = (n, speed.to_bits(), dir as i8);
        let slot = match groups.iter().position(|g| g.0 == key) {
            Some(s) => s,
            None => {
                groups.push((key, None, None));
                groups.len() - 1
            }
        };
        let place = if mag == 0.0 { &mut groups[slot].1 } else { &mut groups[slot].2 };
        if let Some(first) = place.replace(i) {
            let what = if mag == 0.0 { "baseline" } else { "trial" };
            return Err(InfluenceError::Indeterminate(format!(
                "{}:{} and {}:{}: a second {what} for harmonic {n} at {speed} rev/s in one direction (one baseline and one trial each; iterations are not supported yet)",
                captures[first].source, captures[first].line, c.source, c.line
            )));
        }
    }
    let mut out = Vec::with_capacity(groups.len());
    for ((n, _, _), base, trial) in groups {
        let (Some(b), Some(t)) = (base, trial) else {
            let c = &captures[base.or(trial).unwrap_or(0)];
            let missing = if base.is_none() { "baseline (C0 D0)" } else { "constant trial" };
            return Err(InfluenceError::Indeterminate(format!(
                "{}:{}: harmonic {n} has no {missing} at the same speed and direction",
                c.source, c.line
            )));
        };
        out.push(refine_pair(&captures[b], &captures[t], o, in_use)?);
    }
    Ok(out)
}

/// One group's step.
fn refine_pair(
    base: &AccelCapture,
    trial: &AccelCapture,
    o: &RefineOptions,
    in_use: &InUse,
) -> Result<Refined, InfluenceError> {
    let (n, _, _, mag, pha) = constant_trial(trial)?;
    let y0 = harmonic_response(base, &reconstruction(base, o)?, n, o.periods_per_block)?;
    let y1 = harmonic_response(trial, &reconstruction(trial, o)?, n, o.periods_per_block)?;
    let inf = influence(&y0, &y1, table_shift(mag, pha, o.scale))?;
    let direction = base.require_gcode()?.phase_direction();
    let table = if direction > 0.0 { &in_use.forward } else { &in_use.backward };
    let old = table[n as usize];
    let new: Complex = table_shift(old.0, old.1, o.scale) + inf.cancelling;
    Ok(Refined {
        harmonic: n,
        phase_direction: direction,
        speed_rev_s: y0.speed_rev_s,
        baseline: y0,
        trial: y1,
        influence: inf,
        in_use: old,
        item: table_item(new, o.scale),
        item_radius95: inf.cancelling_radius95 / o.scale,
        expected_residual95: inf.coefficient.abs() * inf.cancelling_radius95,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{Axis, Gcode, TrialSweep};
    use crate::influence::tests::{recon, synthetic};

    /// The synthetic captures' harmonic 2 at 1.5 rev/s, 12 revolutions (`revs` signed).
    fn m973(revs: f64, mag: f64, pha: f64) -> Gcode {
        let trial = TrialSweep { harmonic: 2, pha_start: pha, pha_end: pha, mag_start: mag, mag_end: mag };
        Gcode::ParamSweep { axis: Axis::X, speed: 1.5, revs, trial }
    }

    fn options() -> RefineOptions {
        RefineOptions {
            periods_per_rev: 50,
            mm_per_rev: 40.0,
            periods_per_block: 20,
            scale: 4.0,
            timing: Timing::Planned,
        }
    }

    #[test]
    fn a_baseline_and_a_trial_per_direction_give_the_items_that_cancel_each_direction() {
        // Each direction its own response and influence; a table already in use backward.
        let truth = recon(0.0);
        let c_true = Complex::from_polar(25.0, -0.7);
        let (y_fwd, y_bwd) = (Complex::from_polar(0.9, 2.0), Complex::from_polar(0.6, -1.0));
        let (mag, pha) = (0.004, 0.5);
        let u_t = table_shift(mag, pha, 4.0);
        let caps = vec![
            synthetic(m973(-12.0, 0.0, 0.0), y_fwd, 0.2, 1, &truth),
            synthetic(m973(12.0, 0.0, 0.0), y_bwd, 0.2, 2, &truth),
            synthetic(m973(-12.0, mag, pha), y_fwd + c_true * u_t, 0.2, 3, &truth),
            synthetic(m973(12.0, mag, pha), y_bwd + c_true * u_t, 0.2, 4, &truth),
        ];
        let mut in_use = InUse::default();
        in_use.backward[2] = (0.002, 0.3);
        let r = refine(&caps, &options(), &in_use).unwrap();
        assert_eq!(r.len(), 2);
        for x in &r {
            let y0 = if x.phase_direction > 0.0 { y_fwd } else { y_bwd };
            let want_shift = -y0 / c_true;
            let old = if x.phase_direction > 0.0 { (0.0, 0.0) } else { (0.002, 0.3) };
            let want = table_shift(old.0, old.1, 4.0) + want_shift;
            let got = table_shift(x.item.0, x.item.1, 4.0);
            // Within twice the 95 % radius (the disc's 2× is beyond 99.99 % for 2-D Gaussian
            // errors), in shift units: the item's radius times the scale.
            assert!((got - want).abs() <= 2.0 * 4.0 * x.item_radius95, "{x:?}: want {want:?}");
            assert!(x.item_radius95 < 0.1 * x.item.0, "a tight interval: {x:?}");
            assert_eq!(x.in_use, old);
        }
    }

    #[test]
    fn groups_that_cannot_give_a_step_are_refused_naming_the_captures() {
        let truth = recon(0.0);
        let y = Complex::from_polar(0.9, 2.0);
        let base = synthetic(m973(12.0, 0.0, 0.0), y, 0.2, 1, &truth);
        let e = refine(std::slice::from_ref(&base), &options(), &InUse::default()).unwrap_err().to_string();
        assert!(e.contains("harmonic 2 has no constant trial at the same speed and direction"), "{e}");
        let e = refine(&[base.clone(), base.clone()], &options(), &InUse::default()).unwrap_err().to_string();
        assert!(e.contains("a second baseline for harmonic 2 at 1.5 rev/s"), "{e}");
        let trial = synthetic(m973(12.0, 0.004, 0.5), y, 0.2, 2, &truth);
        let e = refine(&[trial], &options(), &InUse::default()).unwrap_err().to_string();
        assert!(e.contains("harmonic 2 has no baseline (C0 D0)"), "{e}");
        let sweep = synthetic(m973(12.0, 0.0, 0.0), y, 0.2, 1, &truth).with_gcode(Gcode::ParamSweep {
            axis: Axis::X,
            speed: 1.5,
            revs: 12.0,
            trial: TrialSweep { harmonic: 2, pha_start: 0.0, pha_end: 1.0, mag_start: 0.0, mag_end: 0.01 },
        });
        let e = refine(&[sweep], &options(), &InUse::default()).unwrap_err().to_string();
        assert!(e.contains("sweeps its trial"), "{e}");
    }
}
