//! An independent generator of servo-mode run logs for testing identification.
//!
//! Written without any code of `stepdamp-sim` or `stepdamp-core`, so that identification is
//! tested on logs this repository's simulator did not write. It models the class of motor
//! and drive of the stress family in its own, simple way:
//!
//! * **Rotor**: `J·dω/dt = Km·i_q·cos(Nr·(θ − θ_fb)) − Σ A_k sin(k·Nr·θ + φ_k) − F(ω) − D·ω`,
//!   integrated with a semi-implicit Euler step at 4 sub-steps per control period: `ω` is
//!   implicit in the friction (solved by safeguarded Newton — the friction is stiff near
//!   zero speed), `θ` explicit with the new `ω`. (The `cos` factor: the drive puts the
//!   current in the frame of its quantised angle.)
//! * **Friction** `F(ω) = (Fs + (Fs_static − Fs)·exp(−(ω/ω_s)²))·tanh(ω/ω_ε)`: with
//!   `Fs_static = Fs` the smooth Coulomb law that creeps at `|ω| ≲ ω_ε` instead of sticking;
//!   with `Fs_static > Fs` the Stribeck law (break-away torque `Fs_static`, Stribeck speed
//!   `ω_s`) that makes the rotor stick and slip.
//! * **Current loop**: first order at 1.5 kHz after one control period of delay, limited to
//!   ±3 A. The phase currents are sampled with Gaussian noise, and the logged `i_q`, `i_d`
//!   are the Park transform of the noisy samples at the encoder's electrical angle.
//! * **Drive**: a position PID run at 20 kHz on the encoder angle (4000 counts/rev, logged as
//!   the centre of the count, as the log format asks) and a speed estimate from the count
//!   differences through a first-order filter at 5× the bandwidth. Its own tuning rule (not
//!   this repository's plan): all three closed-loop poles at `−2π·f_b` for the drive's
//!   inertia, i.e. `Kp = 3·J·ω_b²`, `Kd = 3·J·ω_b`, `Ki = J·ω_b³`, torque to current by `Km`.
//! * **Runs**: 50 ms at rest, a 0.1 s ramp, then constant speed.
//!
//! The output is a CSV run log with the columns of the repository's log format.
//!
//! [`open_loop`] is its counterpart for the sensorless route: an open-loop drive
//! (PWM bridge, PI current loop) that performs the sensorless plan CSV and logs currents and
//! applied voltages; [`servo_real`] the servo drive of a real motor (flux harmonics, windings,
//! applied voltages) that performs the encoder plan CSV; [`flux`] the flux shape and torque
//! ripple both take their torque and back-EMF from (the sine motor a special case);
//! [`truth`] the true motor as a profile and the ripple comparison the tests make.

#![allow(dead_code)] // each test binary uses a part of it

pub mod flux;
pub mod open_loop;
pub mod servo_real;
pub mod truth;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;

/// Friction law of a generated motor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Friction {
    /// `Fs·tanh(ω/ω_ε)`: creeps instead of sticking.
    SmoothCreep,
    /// Stribeck: break-away `fs_static_nm` decaying to `Fs` over `stribeck_rad_s`.
    Stribeck {
        /// Break-away torque, N·m.
        fs_static_nm: f64,
        /// Stribeck speed, rad/s.
        stribeck_rad_s: f64,
    },
}

/// A motor of the class.
#[derive(Clone, Debug)]
pub struct Motor {
    /// Rotor pole pairs.
    pub nr: u16,
    /// Torque constant, N·m/A.
    pub km: f64,
    /// Inertia, kg·m².
    pub j: f64,
    /// Viscous friction, N·m·s/rad.
    pub d: f64,
    /// Coulomb friction (sliding), N·m.
    pub fs: f64,
    /// Creep speed `ω_ε` of the tanh, rad/s.
    pub creep_rad_s: f64,
    /// Friction law.
    pub friction: Friction,
    /// Detent harmonics `(order, amplitude N·m, phase rad)`; the torque on the rotor is
    /// `−A sin(k·Nr·θ + φ)`.
    pub detent: Vec<(u16, f64, f64)>,
    /// Encoder counts per revolution.
    pub cpr: u32,
}

impl Motor {
    /// Friction torque at speed `w` (without the viscous part).
    pub fn friction(&self, w: f64) -> f64 {
        let level = match self.friction {
            Friction::SmoothCreep => self.fs,
            Friction::Stribeck { fs_static_nm, stribeck_rad_s } => {
                self.fs + (fs_static_nm - self.fs) * (-(w / stribeck_rad_s).powi(2)).exp()
            }
        };
        level * (w / self.creep_rad_s).tanh()
    }

    /// `dF/dω`.
    fn friction_slope(&self, w: f64) -> f64 {
        let h = 1e-7 * (1.0 + w.abs());
        (self.friction(w + h) - self.friction(w - h)) / (2.0 * h)
    }

    /// `Σ A_k sin(k·Nr·θ + φ_k)` at the mechanical angle `theta` (the torque on the rotor is its negative), N·m.
    pub fn detent(&self, theta: f64) -> f64 {
        let te = f64::from(self.nr) * theta;
        self.detent.iter().map(|&(k, a, p)| a * (f64::from(k) * te + p).sin()).sum()
    }
}

/// The drive.
#[derive(Clone, Debug)]
pub struct Drive {
    /// Control (and log) rate, Hz.
    pub rate_hz: f64,
    /// Position-loop bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Inertia the drive was tuned for, kg·m².
    pub j_tuned: f64,
    /// Current-loop bandwidth, Hz.
    pub current_hz: f64,
    /// Current limit, A.
    pub current_limit_a: f64,
    /// Standard deviation of the phase-current sensor noise, A.
    pub current_noise_a: f64,
}

/// The stress family: motor `seed` (orders 1, 2, 4 at 4–30 mN·m with random
/// phases, `Fs` 5–20 mN·m, `J` ×0.5–3 of 4e-5 kg·m², `Km` 0.3 N·m/A, `Nr` 50, `D` 1e-3
/// N·m·s/rad), smooth creep for even seeds, Stribeck for odd ones; and its drive (bandwidth
/// 40–80 Hz, tuned for the true `J`, current noise 0.01 A).
pub fn stress_motor(seed: u64) -> (Motor, Drive) {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0000 + seed);
    let j = 4.0e-5 * rng.random_range(0.5..3.0);
    let fs = rng.random_range(0.005..0.020);
    let detent = [1u16, 2, 4].iter().map(|&k| (k, rng.random_range(0.004..0.030), rng.random_range(-PI..PI))).collect();
    let friction = stress_friction(seed, fs, &mut rng);
    let creep_rad_s = rng.random_range(0.002..0.01);
    let bandwidth_hz = rng.random_range(40.0..80.0);
    let motor = Motor { nr: 50, km: 0.3, j, d: 1.0e-3, fs, creep_rad_s, friction, detent, cpr: 4000 };
    let drive = Drive {
        rate_hz: 20_000.0,
        bandwidth_hz,
        j_tuned: j,
        current_hz: 1500.0,
        current_limit_a: 3.0,
        current_noise_a: 0.01,
    };
    (motor, drive)
}

/// The stress family's friction law for motor `seed` at sliding level `fs` (N·m): smooth
/// creep for even seeds; Stribeck for odd ones, break-away 1.2–1.8× `fs`, Stribeck speed
/// 0.01–0.05 rad/s, drawn from `rng`.
pub fn stress_friction(seed: u64, fs: f64, rng: &mut ChaCha8Rng) -> Friction {
    if seed % 2 == 0 {
        Friction::SmoothCreep
    } else {
        Friction::Stribeck {
            fs_static_nm: fs * rng.random_range(1.2..1.8),
            stribeck_rad_s: rng.random_range(0.01..0.05),
        }
    }
}

/// The random part of a real motor of the real-motor family
/// (docs/identification.md#the-real-motor-family), as both independent real-motor tests
/// draw it.
#[derive(Clone, Debug)]
pub struct RealDraw {
    /// Inertia, kg·m²: ×0.5–2 of the base's.
    pub j: f64,
    /// Coulomb friction, N·m: 5–20 mN·m.
    pub fs: f64,
    /// Detent orders 4, 2, 1 `(order, A N·m, φ rad)`: 4–30 mN·m at random phases.
    pub detent: Vec<(u16, f64, f64)>,
    /// A third flux harmonic of 0–2 % and a fifth of 0–1 % at random phases, `g` ±5 %.
    pub flux: flux::FluxShape,
}

/// Draws a [`RealDraw`] from `rng` for a base of inertia `j_base` (kg·m²); the caller draws
/// the friction law from `rng` after it.
pub fn real_draw(rng: &mut ChaCha8Rng, j_base: f64) -> RealDraw {
    let mut phase = || rng.random_range(-PI..PI);
    let (p4, p2, p1, a3, a5) = (phase(), phase(), phase(), phase(), phase());
    let j = j_base * rng.random_range(0.5..2.0);
    let fs = rng.random_range(0.005..0.020);
    let detent = [(4u16, p4), (2, p2), (1, p1)].iter().map(|&(k, p)| (k, rng.random_range(0.004..0.030), p)).collect();
    let g = rng.random_range(-0.05..0.05);
    let harmonics = vec![(3, rng.random_range(0.0..0.02), a3), (5, rng.random_range(0.0..0.01), a5)];
    RealDraw { j, fs, detent, flux: flux::FluxShape { harmonics, g } }
}

/// One run: `speed_rad_s` (sign = direction) held for `steady_s` after 50 ms at rest and a
/// 0.1 s ramp. Returns the CSV text of the log and the fraction of the steady part in which
/// the rotor was (nearly) stopped, `|ω| < 5 %` of the speed (for the test's print-out).
pub fn run(m: &Motor, d: &Drive, speed_rad_s: f64, steady_s: f64, seed: u64) -> (String, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (rest, ramp) = (0.05, 0.1);
    let ts = 1.0 / d.rate_hz;
    let n = ((rest + ramp + steady_s) * d.rate_hz).round() as usize;
    let q = TAU / f64::from(m.cpr);
    let nr = f64::from(m.nr);
    let wb = TAU * d.bandwidth_hz;
    let (kp, kd, ki) = (3.0 * d.j_tuned * wb * wb, 3.0 * d.j_tuned * wb, d.j_tuned * wb * wb * wb);
    let wf = TAU * 5.0 * d.bandwidth_hz;
    let filt = 1.0 - (-wf * ts).exp();
    let sub = 4;
    let h = ts / f64::from(sub);
    let wc = TAU * d.current_hz;
    let lag = 1.0 - (-wc * h).exp();
    // A start at rest at an angle where the detent is balanced would need a search; starting
    // anywhere, the rotor settles during the 50 ms rest.
    let (mut theta, mut w) = (rng.random_range(0.0..q), 0.0f64);
    let count = |th: f64| (th / q).floor();
    let mut theta_fb_prev = (count(theta) + 0.5) * q;
    let (mut omega_fb, mut integ, mut iq_act, mut iq_cmd_prev) = (0.0, 0.0, 0.0, 0.0);
    let mut te_cmd_frame = nr * theta_fb_prev;
    let mut out = String::with_capacity(n * 120);
    out.push_str("t_s,theta_cmd_rad,theta_fb_rad,omega_fb_rad_s,i_a_a,i_b_a,i_d_a,i_q_a,iq_cmd_a\n");
    let theta0 = theta_fb_prev;
    let (mut stopped, mut steady) = (0usize, 0usize);
    for k in 0..n {
        let t = k as f64 * ts;
        // Reference: rest, ramp, constant speed.
        let (theta_ref, w_ref) = if t < rest {
            (theta0, 0.0)
        } else if t < rest + ramp {
            let u = t - rest;
            (theta0 + 0.5 * speed_rad_s * u * u / ramp, speed_rad_s * u / ramp)
        } else {
            (theta0 + speed_rad_s * (0.5 * ramp + (t - rest - ramp)), speed_rad_s)
        };
        // Sample: encoder and currents.
        let theta_fb = (count(theta) + 0.5) * q;
        omega_fb += filt * ((theta_fb - theta_fb_prev) / ts - omega_fb);
        theta_fb_prev = theta_fb;
        let te_fb = nr * theta_fb;
        // Phase currents as applied (in the frame the drive set them), plus sensor noise.
        let (s_cmd, c_cmd) = te_cmd_frame.sin_cos();
        let (ia, ib) = (-iq_act * s_cmd, iq_act * c_cmd);
        let ia_m = ia + d.current_noise_a * gauss(&mut rng);
        let ib_m = ib + d.current_noise_a * gauss(&mut rng);
        let (s, c) = te_fb.sin_cos();
        let (id_m, iq_m) = (ia_m * c + ib_m * s, -ia_m * s + ib_m * c);
        // Position PID (all poles at −ω_b for the tuned J).
        let e = theta_ref - theta_fb;
        integ += e * ts;
        let torque_cmd = kp * e + kd * (w_ref - omega_fb) + ki * integ;
        let iq_cmd = (torque_cmd / m.km).clamp(-d.current_limit_a, d.current_limit_a);
        let _ = writeln!(
            out,
            "{t:.6},{theta_ref:.9},{theta_fb:.9},{omega_fb:.6},{ia_m:.6},{ib_m:.6},{id_m:.6},{iq_m:.6},{iq_cmd:.6}"
        );
        if t >= rest + ramp {
            steady += 1;
            if w.abs() < 0.05 * speed_rad_s.abs() {
                stopped += 1;
            }
        }
        // The plant over one period; the current loop acts on the command of one period ago.
        let target = iq_cmd_prev;
        iq_cmd_prev = iq_cmd;
        for _ in 0..sub {
            iq_act += lag * (target - iq_act);
            let motor_torque = m.km * iq_act * (nr * theta - te_cmd_frame).cos();
            let rhs = motor_torque - m.detent(theta);
            w = implicit_speed(m, w, rhs, h);
            theta += h * w;
        }
        te_cmd_frame = te_fb;
    }
    (out, stopped as f64 / steady.max(1) as f64)
}

/// Solves `J·(w1 − w0)/h + F(w1) + D·w1 = rhs` for `w1` (monotone in `w1` while `J/h`
/// exceeds the Stribeck law's negative slope, which holds here by a factor ≥ 5): Newton
/// from `w0`, kept inside a bracket, bisection when Newton leaves it.
fn implicit_speed(m: &Motor, w0: f64, rhs: f64, h: f64) -> f64 {
    let g = |w: f64| m.j * (w - w0) / h + m.friction(w) + m.d * w - rhs;
    // Bracket: F is bounded by the largest friction level, so w1 lies within
    // w0 + h·(|rhs| + Fmax)/J of w0 (plus the viscous part, which only pulls towards 0).
    let fmax = match m.friction {
        Friction::SmoothCreep => m.fs,
        Friction::Stribeck { fs_static_nm, .. } => fs_static_nm.max(m.fs),
    };
    let span = h * (rhs.abs() + fmax) / m.j + w0.abs() + 1e-9;
    let (mut lo, mut hi) = (w0 - span, w0 + span);
    let mut w = w0;
    for _ in 0..60 {
        let gw = g(w);
        if gw.abs() < 1e-13 {
            return w;
        }
        if gw > 0.0 {
            hi = w;
        } else {
            lo = w;
        }
        let slope = m.j / h + m.friction_slope(w) + m.d;
        let mut next = w - gw / slope;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - w).abs() < 1e-14 * (1.0 + w.abs()) {
            return next;
        }
        w = next;
    }
    w
}

/// Standard normal sample (Box–Muller).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}
