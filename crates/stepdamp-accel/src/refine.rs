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
    /// Where the influence coefficient comes from: this session's trial, or an earlier
    /// session's group carried to this run current.
    pub source: InfluenceSource,
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

/// Where a [`Refined`] item's influence coefficient comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InfluenceSource {
    /// This session's constant trial, with its response.
    Trial(Response),
    /// An earlier session's influence of the same harmonic, speed and direction, times the
    /// ratio `I/I_earlier` of the run currents ([`Earlier`]).
    Carried {
        /// `I/I_earlier`.
        current_ratio: f64,
    },
}

/// The largest ratio of run currents (either way) over which [`refine_with`] carries an
/// influence: the torque per rad of shift is `Km·I·cos λ`, so the coefficient scales with the
/// current, but the head's response to that torque changes with the rotor's magnetic
/// stiffness (`∝ I`); over the family of simulated printers the route carried it over 1.0–1.52×
/// (docs/accelerometer.md#a-family-of-simulated-printers). Past 2× record a trial.
pub const MAX_CURRENT_RATIO: f64 = 2.0;

/// `now_a/then_a`, the ratio of the run currents (any unit) over which [`refine_with`] carries
/// an influence; refused (one line) outside `1/`[`MAX_CURRENT_RATIO`]`..=`[`MAX_CURRENT_RATIO`]
/// or not finite.
pub fn current_ratio(now_a: f64, then_a: f64) -> Result<f64, InfluenceError> {
    let r = now_a / then_a;
    if r.is_finite() && (1.0 / MAX_CURRENT_RATIO..=MAX_CURRENT_RATIO).contains(&r) {
        return Ok(r);
    }
    Err(InfluenceError::Indeterminate(format!(
        "a run current {r:.4e}× the earlier session's ({now_a:.4e} A against {then_a:.4e} A, peak): an influence \
         is carried over at most {MAX_CURRENT_RATIO}× either way; record a trial at this current"
    )))
}

/// The steps of an earlier session, whose influence coefficients a group of this session that
/// has a baseline and no trial takes, in proportion to the current.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Earlier<'a> {
    /// The earlier session's steps ([`refine`] of its captures; its table in use does not
    /// matter: the coefficient does not depend on it).
    pub steps: &'a [Refined],
    /// `I/I_earlier`: this session's run current over the earlier one's, within
    /// `1/`[`MAX_CURRENT_RATIO`]`..=`[`MAX_CURRENT_RATIO`].
    pub current_ratio: f64,
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
    refine_with(captures, o, in_use, None)
}

/// [`refine`], where a group with a baseline and no trial takes the influence of the
/// `earlier` step of the same harmonic, speed and direction, times the ratio of the run
/// currents: the step at a raised run current without a new trial, or a second step at the
/// same current (ratio 1) from a baseline recorded with the refined table loaded
/// (docs/accelerometer.md#a-step-without-a-trial). The cancelling shift's 95 % radius then adds
/// the baseline's and the carried coefficient's radii in quadrature, to first order; it leaves
/// out the error of carrying in proportion to the current (the head's response to the torque
/// changes with the rotor's stiffness too), so past a ratio of 1 it is a lower bound. Refuses a ratio
/// outside `1/`[`MAX_CURRENT_RATIO`]`..=`[`MAX_CURRENT_RATIO`] or not finite, and a group
/// without a trial that `earlier` has no step for.
pub fn refine_with(
    captures: &[AccelCapture],
    o: &RefineOptions,
    in_use: &InUse,
    earlier: Option<&Earlier<'_>>,
) -> Result<Vec<Refined>, InfluenceError> {
    if let Some(e) = earlier {
        current_ratio(e.current_ratio, 1.0)?;
    }
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
        match (base, trial, earlier) {
            (Some(b), Some(t), _) => out.push(refine_pair(&captures[b], &captures[t], o, in_use)?),
            (Some(b), None, Some(e)) => out.push(refine_carried(&captures[b], o, in_use, e)?),
            _ => {
                let c = &captures[base.or(trial).unwrap_or(0)];
                let missing = if base.is_none() { "baseline (C0 D0)" } else { "constant trial" };
                return Err(InfluenceError::Indeterminate(format!(
                    "{}:{}: harmonic {n} has no {missing} at the same speed and direction",
                    c.source, c.line
                )));
            }
        }
    }
    Ok(out)
}

/// The new item of `base`'s group from the earlier step of its harmonic, speed and direction.
fn refine_carried(
    base: &AccelCapture,
    o: &RefineOptions,
    in_use: &InUse,
    earlier: &Earlier<'_>,
) -> Result<Refined, InfluenceError> {
    let (n, _, _, _, _) = constant_trial(base)?;
    let y0 = harmonic_response(base, &reconstruction(base, o)?, n, o.periods_per_block)?;
    let direction = base.require_gcode()?.phase_direction();
    let Some(from) = earlier
        .steps
        .iter()
        .find(|s| s.harmonic == n && s.phase_direction == direction && s.speed_rev_s == y0.speed_rev_s)
    else {
        return Err(InfluenceError::Indeterminate(format!(
            "{}:{}: harmonic {n} has no constant trial at the same speed and direction, and the earlier session no \
             step there to take the influence from",
            base.source, base.line
        )));
    };
    let ratio = earlier.current_ratio;
    let c = from.influence.coefficient.scale(ratio);
    let c_r = from.influence.coefficient_radius95 * ratio;
    let u = -y0.value / c;
    // δU* = −δY₀/C + (Y₀/C²)·δC to first order, the two discs in quadrature (finite for Y₀ = 0).
    let u_r = y0.radius95.hypot(u.abs() * c_r) / c.abs();
    let influence = Influence { coefficient: c, coefficient_radius95: c_r, cancelling: u, cancelling_radius95: u_r };
    Ok(step(n, direction, y0, InfluenceSource::Carried { current_ratio: ratio }, influence, in_use, o))
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
    Ok(step(n, direction, y0, InfluenceSource::Trial(y1), inf, in_use, o))
}

/// The step of harmonic `n` in `direction`: the item in use plus the cancelling shift.
fn step(
    n: u32,
    direction: f64,
    y0: Response,
    source: InfluenceSource,
    inf: Influence,
    in_use: &InUse,
    o: &RefineOptions,
) -> Refined {
    let table = if direction > 0.0 { &in_use.forward } else { &in_use.backward };
    let old = table[n as usize];
    let new: Complex = table_shift(old.0, old.1, o.scale) + inf.cancelling;
    Refined {
        harmonic: n,
        phase_direction: direction,
        speed_rev_s: y0.speed_rev_s,
        baseline: y0,
        source,
        influence: inf,
        in_use: old,
        item: table_item(new, o.scale),
        item_radius95: inf.cancelling_radius95 / o.scale,
        expected_residual95: inf.coefficient.abs() * inf.cancelling_radius95,
    }
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
    fn a_baseline_without_a_trial_takes_the_earlier_influence_times_the_current_ratio() {
        // The earlier session at I: baseline and trial forward. This one at 1.3·I: a baseline
        // alone, whose true influence is 1.3× the earlier one (the torque per rad ∝ I).
        let truth = recon(0.0);
        let c_true = Complex::from_polar(25.0, -0.7);
        let (mag, pha) = (0.004, 0.5);
        let y_then = Complex::from_polar(0.9, 2.0);
        let earlier_caps = vec![
            synthetic(m973(-12.0, 0.0, 0.0), y_then, 0.2, 1, &truth),
            synthetic(m973(-12.0, mag, pha), y_then + c_true * table_shift(mag, pha, 4.0), 0.2, 2, &truth),
        ];
        let steps = refine(&earlier_caps, &options(), &InUse::default()).unwrap();
        let y_now = Complex::from_polar(0.5, -1.0);
        let now = vec![synthetic(m973(-12.0, 0.0, 0.0), y_now, 0.2, 3, &truth)];
        let mut in_use = InUse::default();
        in_use.forward[2] = (0.003, 0.2);
        let earlier = Earlier { steps: &steps, current_ratio: 1.3 };
        let r = refine_with(&now, &options(), &in_use, Some(&earlier)).unwrap();
        assert_eq!(r.len(), 1);
        let x = &r[0];
        assert_eq!(x.source, InfluenceSource::Carried { current_ratio: 1.3 });
        assert_eq!(x.influence.coefficient, steps[0].influence.coefficient.scale(1.3));
        assert_eq!(x.in_use, (0.003, 0.2));
        // The new item cancels the baseline through the true influence at this current.
        let want = table_shift(0.003, 0.2, 4.0) - y_now / c_true.scale(1.3);
        let got = table_shift(x.item.0, x.item.1, 4.0);
        assert!((got - want).abs() <= 2.0 * 4.0 * x.item_radius95, "{x:?}: want {want:?}");
        assert!(x.item_radius95 > 0.0 && x.item_radius95 < 0.1 * x.item.0, "{x:?}");
        // Without `earlier` the lone baseline is refused as before.
        let e = refine(&now, &options(), &in_use).unwrap_err().to_string();
        assert!(e.contains("harmonic 2 has no constant trial"), "{e}");
    }

    #[test]
    fn a_carried_influence_is_refused_past_twice_the_current_or_without_a_matching_step() {
        let truth = recon(0.0);
        let y = Complex::from_polar(0.9, 2.0);
        let (mag, pha) = (0.004, 0.5);
        let earlier_caps = vec![
            synthetic(m973(-12.0, 0.0, 0.0), y, 0.2, 1, &truth),
            synthetic(
                m973(-12.0, mag, pha),
                y + Complex::from_polar(25.0, -0.7) * table_shift(mag, pha, 4.0),
                0.2,
                2,
                &truth,
            ),
        ];
        let steps = refine(&earlier_caps, &options(), &InUse::default()).unwrap();
        let forward = vec![synthetic(m973(-12.0, 0.0, 0.0), y, 0.2, 3, &truth)];
        for ratio in [2.01, 0.49, f64::NAN, f64::INFINITY] {
            let earlier = Earlier { steps: &steps, current_ratio: ratio };
            let e = refine_with(&forward, &options(), &InUse::default(), Some(&earlier)).unwrap_err().to_string();
            assert!(e.contains("at most 2× either way"), "{ratio}: {e}");
        }
        for ratio in [2.0, 0.5] {
            let earlier = Earlier { steps: &steps, current_ratio: ratio };
            assert!(refine_with(&forward, &options(), &InUse::default(), Some(&earlier)).is_ok(), "{ratio}");
        }
        // The earlier session measured forward only: a backward baseline has nothing to take.
        let backward = vec![synthetic(m973(12.0, 0.0, 0.0), y, 0.2, 4, &truth)];
        let earlier = Earlier { steps: &steps, current_ratio: 1.0 };
        let e = refine_with(&backward, &options(), &InUse::default(), Some(&earlier)).unwrap_err().to_string();
        assert!(e.contains("and the earlier session no step there"), "{e}");
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
