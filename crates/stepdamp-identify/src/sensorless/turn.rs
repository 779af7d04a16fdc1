//! The split of the flux's third and fifth from the plan's turn runs
//! (docs/sensorless.md#the-split-from-a-fast-run).
//!
//! The estimated angle is the flux linkage's direction, which the harmonics turn by
//! `Im[(X₅ − X₃)·e^{j4θe}]` (docs/sensorless.md#the-flux-shape-without-a-sensor). Estimated
//! with a shape whose `X₅ − X₃` is off by `D`, the angle is turned by `Im[D·e^{j4θe}]`. Far
//! above the open-loop resonance the rotor hardly follows order-4 torques, so the order-4
//! part of `θe_est − θe_cmd` (against `θe_est`, electrical rad) is that turn plus a small
//! motion of the rotor. That motion is predicted from the identified profile: its ripple at
//! `(I_hold, 0)`, torque on the rotor `−A·sin(4θe + φ)`, moves the rotor by
//! `A·Nr/(J·(Ω² − ω_n²))·sin(4θe + φ)` at `Ω = 4ω_e`, and is taken off. Keeping the sum the
//! radius gave, the third then gets `−D/2` and the fifth `+D/2`.
//!
//! Each turn run gives its own `D`; their spread gives the 95 % interval (Student's t), as
//! for the sum ([`super::shape`]).

use super::Estimated;
use super::log::SensorlessLog;
use super::plan::natural_rad_s;
use super::shape::{add_harmonic, fit_orders, mean_phasor};
use crate::emf::{AMPLITUDE_TEST, stands_out};
use crate::fit::Estimate;
use stepdamp_profile::Profile;
use stepdamp_profile::flux::FluxSection;

/// A log whose steady electrical speed is at least this multiple of the base's open-loop
/// natural frequency `ω_n` is a turn run: order 4 at 4 `ω_n` or more, where the rotor's
/// order-4 motion is at most 1/15 of the static one (1/63 at the plan's 2 `ω_n`).
pub const TURN_MIN_SPEED: f64 = 1.0;

/// Share of a turn run's steady part left out at its start (the ramp's transient).
pub const SETTLE_FRACTION: f64 = 0.2;

/// The widest spread of `θe_est − θe_cmd` (electrical rad) over a turn run's steady part
/// that is taken as the rotor following the command: a quarter of an electrical period. A
/// rotor that stalled on the ramp through the open-loop resonances falls behind by whole
/// periods; its order-4 error would read as a large, wrong `X₅ − X₃`.
pub const MAX_FOLLOW_SPREAD_RAD: f64 = core::f64::consts::FRAC_PI_2;

/// The commanded speed at the end of `log` (rad/s, mechanical) and the first sample from
/// which the command runs at it (within 0.1 %); `None` at rest or with fewer than 3 samples.
fn steady_speed(log: &SensorlessLog) -> Option<(f64, usize)> {
    let n = log.len();
    if n < 3 {
        return None;
    }
    let w = |k: usize| (log.theta_cmd_rad[k + 1] - log.theta_cmd_rad[k]) / (log.t_s[k + 1] - log.t_s[k]);
    let wf = w(n - 2);
    if !(wf.is_finite() && wf != 0.0) {
        return None;
    }
    let mut k = n - 2;
    while k > 0 && (w(k - 1) - wf).abs() <= 1e-3 * wf.abs() {
        k -= 1;
    }
    Some((wf, k))
}

/// Whether `log` is a turn run for a motor described by `base` ([`TURN_MIN_SPEED`]).
pub fn is_turn_run(log: &SensorlessLog, base: &Profile) -> bool {
    steady_speed(log)
        .is_some_and(|(w, _)| w.abs() * f64::from(base.motor.pole_pairs) >= TURN_MIN_SPEED * natural_rad_s(base))
}

/// The order-4 part of `y` against `theta` (electrical rad) as the `D` of
/// `Im[D·e^{j4θ}] = D_re·sin 4θ + D_im·cos 4θ`, from the least-squares fit of the radius
/// (a constant and `cos kθ`, `sin kθ` for `k` = 1, 2, 4, 8); `None` when the samples do not
/// determine it.
pub fn order4(theta: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let s = fit_orders(theta, y)?;
    (s[5].is_finite() && s[6].is_finite()).then_some((s[6], s[5]))
}

/// The rotor's order-4 motion at electrical speed `w_e` (rad/s) predicted from `p` (module
/// documentation), as a `D`; `None` when `p` has no ripple at `(I_hold, 0)`.
fn rotor_motion(p: &Profile, w_e: f64) -> Option<(f64, f64)> {
    let m = &p.motor;
    let i = p.drive.holding_current_a;
    let r = stepdamp_profile::ripple::ripple(p, i, 0.0).ok()?;
    let Some(h) = r.harmonics.iter().find(|h| h.order == 4) else { return Some((0.0, 0.0)) };
    let k = f64::from(m.pole_pairs) / (m.inertia_kg_m2 * ((4.0 * w_e).powi(2) - natural_rad_s(p).powi(2)));
    Some((h.amplitude_nm * k * h.phase_rad.cos(), h.amplitude_nm * k * h.phase_rad.sin()))
}

/// `X₅ − X₃` missing from the shape the turn runs' angles were estimated with.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TurnFit {
    /// `|D|` per unit of the fundamental.
    pub ratio: Estimate,
    /// `arg D`, rad.
    pub phase_rad: Estimate,
    /// Turn runs the intervals come from.
    pub logs: usize,
}

/// The steady part of a turn run as `(θe_est, θe_est − θe_cmd)`, electrical rad, with its
/// commanded mechanical speed (rad/s); `None` at rest.
fn steady_error(log: &SensorlessLog, theta_fb_rad: &[f64], nr: f64) -> Option<(Vec<f64>, Vec<f64>, f64)> {
    let (w, k) = steady_speed(log)?;
    let k0 = k + (SETTLE_FRACTION * (log.len() - k) as f64) as usize;
    let th: Vec<f64> = theta_fb_rad.get(k0..)?.iter().map(|t| t * nr).collect();
    let e: Vec<f64> = th.iter().zip(&log.theta_cmd_rad[k0..]).map(|(a, c)| a - c * nr).collect();
    Some((th, e, w))
}

/// Whether the estimated angle of turn run `log` (its mechanical angle `theta_fb_rad`, rad,
/// sample for sample) followed the command over the steady part: `θe_est − θe_cmd` spans at
/// most [`MAX_FOLLOW_SPREAD_RAD`] there. `false` also when the run has no steady part.
pub fn followed(log: &SensorlessLog, theta_fb_rad: &[f64], nr: f64) -> bool {
    let Some((_, e, _)) = steady_error(log, theta_fb_rad, nr) else { return false };
    let (lo, hi) = e.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    !e.is_empty() && hi - lo <= MAX_FOLLOW_SPREAD_RAD
}

impl TurnFit {
    /// The measurement from turn runs `logs` and their angles `est` (the same order),
    /// with the rotor's motion predicted from `id` (the identified profile); `None` with
    /// fewer than two runs that determine it.
    pub fn of(logs: &[SensorlessLog], est: &Estimated, id: &Profile) -> Option<TurnFit> {
        let nr = f64::from(id.motor.pole_pairs);
        let (mut re, mut im) = (Vec::new(), Vec::new());
        for (log, run) in logs.iter().zip(&est.logs) {
            let Some((th, e, w)) = steady_error(log, &run.theta_fb_rad, nr) else { continue };
            let (Some(d), Some(y)) = (order4(&th, &e), rotor_motion(id, w.abs() * nr)) else { continue };
            re.push(d.0 - y.0);
            im.push(d.1 - y.1);
        }
        if re.len() < 2 {
            return None;
        }
        let (ratio, phase_rad) = mean_phasor(&re, &im);
        Some(TurnFit { ratio, phase_rad, logs: re.len() })
    }

    /// Whether `D` stands out of the noise (the χ²₂ test of `crate::emf`).
    pub fn stands_out(&self) -> bool {
        stands_out(&self.ratio, AMPLITUDE_TEST)
    }

    /// `section` with `D` split onto its third (`−D/2`) and fifth (`+D/2`), keeping their
    /// sum, when `D` stands out and the section has a third or a fifth (on a sine shape there
    /// is nothing to split); otherwise unchanged, bit for bit.
    pub fn corrected(&self, section: &FluxSection) -> FluxSection {
        let has = section.harmonics.iter().any(|h| h.order == 3 || h.order == 5);
        if !(has && self.stands_out()) {
            return section.clone();
        }
        let (s, c) = self.phase_rad.value.sin_cos();
        let (re, im) = (0.5 * self.ratio.value * c, 0.5 * self.ratio.value * s);
        let mut out = section.clone();
        add_harmonic(&mut out, 3, -re, -im);
        add_harmonic(&mut out, 5, re, im);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A turn `Im[D·e^{j4θ}]` on top of other orders reads back as `D`.
    #[test]
    fn the_order_4_fit_reads_back_a_turn() {
        let th: Vec<f64> = (0..5000).map(|i| 0.013 * f64::from(i)).collect();
        let d = (0.004, -0.007);
        let y: Vec<f64> = th
            .iter()
            .map(|&t| 0.1 + d.0 * (4.0 * t).sin() + d.1 * (4.0 * t).cos() + 0.01 * t.sin() + 0.003 * (2.0 * t).cos())
            .collect();
        let got = order4(&th, &y).unwrap();
        assert!((got.0 - d.0).abs() < 1e-12 && (got.1 - d.1).abs() < 1e-12, "{got:?}");
    }

    /// `D` that stands out moves the third by `−D/2` and the fifth by `+D/2`; on a section
    /// without either, or with `D` in the noise, nothing changes.
    #[test]
    fn a_measured_difference_splits_the_sum_and_keeps_it() {
        let f = FluxSection {
            phase_b_gain: 0.0,
            harmonics: vec![
                stepdamp_profile::flux::FluxHarmonic { order: 3, ratio: 0.0088, phase_rad: 0.0 },
                stepdamp_profile::flux::FluxHarmonic { order: 5, ratio: 0.0012, phase_rad: 0.0 },
            ],
        };
        let t = TurnFit {
            ratio: Estimate { value: 0.004, ci95: 0.0005 },
            phase_rad: Estimate { value: 0.0, ci95: 0.1 },
            logs: 2,
        };
        let c = t.corrected(&f);
        let r = |n: u16| c.harmonics.iter().find(|h| h.order == n).unwrap().ratio;
        assert!((r(3) - 0.0068).abs() < 1e-12 && (r(5) - 0.0032).abs() < 1e-12, "{c:?}");
        assert_eq!(t.corrected(&FluxSection::default()), FluxSection::default());
        let quiet = TurnFit { ratio: Estimate { value: 0.004, ci95: 0.004 }, ..t };
        assert_eq!(quiet.corrected(&f), f);
    }

    /// A log at constant commanded speed: 2000 samples at 10 kHz, 1 rad/s mechanical.
    fn steady_log() -> SensorlessLog {
        let t: Vec<f64> = (0..2000).map(|k| f64::from(k) * 1e-4).collect();
        SensorlessLog {
            source: "steady".into(),
            theta_cmd_rad: t.clone(),
            i_a_a: vec![0.0; t.len()],
            i_b_a: vec![0.0; t.len()],
            v_a_v: vec![0.0; t.len()],
            v_b_v: vec![0.0; t.len()],
            t_s: t,
            ignored_columns: Vec::new(),
        }
    }

    /// An angle that lags the command by a constant and ripples follows it; one that falls
    /// behind by half an electrical period over the log, or that has fewer
    /// samples than the log, does not.
    #[test]
    fn a_rotor_that_falls_behind_the_command_has_not_followed_it() {
        let (l, nr) = (steady_log(), 50.0);
        let lagging: Vec<f64> =
            l.theta_cmd_rad.iter().map(|c| c - 0.3 / nr + 0.2 / nr * (4.0 * nr * c).sin()).collect();
        assert!(followed(&l, &lagging, nr));
        let n = l.len() as f64;
        let slipping: Vec<f64> = l
            .theta_cmd_rad
            .iter()
            .enumerate()
            .map(|(k, c)| c - 0.3 / nr - (std::f64::consts::TAU / 2.0) / nr * k as f64 / n)
            .collect();
        assert!(!followed(&l, &slipping, nr));
        assert!(!followed(&l, &lagging[..10], nr));
    }
}
