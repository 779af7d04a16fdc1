//! An independent generator of sensorless open-loop run logs.
//!
//! Written without any code of `stepdamp-sim` or `stepdamp-core`, so that the sensorless
//! route is tested on logs this repository's simulator did not write. Its own models:
//!
//! * **Flux linkage** per unit of `Km/Nr`, `θe = Nr·θ`: the motor's [`FluxShape`]
//!   `(λ_a, λ_b)` ([`super::flux`]: odd harmonics and phase b's gain `g`; the sine motor
//!   `(cos θe, sin θe)` is [`FluxShape::sine`]). Torque and back-EMF come from the same `λ`.
//! * **Windings** (two phases): `L·di_x/dt = v_x − R·i_x − Km·ω·λ_x'` (`'` = `d/dθe`; for the
//!   sine motor `L·di_a/dt = v_a − R·i_a + Km·ω·sin θe`, `L·di_b/dt = v_b − R·i_b − Km·ω·cos θe`).
//! * **Rotor**: `J·dω/dt = Km·(i_a·λ_a' + i_b·λ_b') − Σ A_k sin(k·θe + φ_k) − F(ω) − D·ω`.
//! * **Friction** `F`: smooth Coulomb `Fs·tanh(ω/ω_ε)`, or Karnopp: `Fs·sgn ω` while
//!   sliding; the rotor sticks (`ω = 0`) when its speed crosses zero or falls below
//!   [`STICK_RAD_S`] while the other torques stay within `±Fs`, and breaks away when they
//!   exceed it.
//! * **Bridge**: one H-bridge per winding, bipolar, centre-aligned PWM at 20 kHz: winding
//!   voltage `+V_bus` for the duty `(1 + v/V_bus)/2` of the period centred in it, `−V_bus`
//!   otherwise (so the mean over the period is `v`). The switching is simulated edge by edge
//!   ([`Drive::switching`]; off: the mean voltage over the period, for comparison).
//! * **Integration**: classical RK4 of `(i_a, i_b, θ, ω)` on each interval between switching
//!   edges, in sub-steps of at most [`MAX_STEP_S`]; the Karnopp stick test between sub-steps.
//! * **Drive**: samples both phase currents at the period start (the centre of the
//!   `−V_bus` pulse, where the triangular ripple crosses its mean) with Gaussian sensor noise
//!   and optional offsets;
//!   a PI current loop in the frame of the commanded electrical angle `θe_cmd = Nr·θ_cmd`
//!   (`i_d* = I_hold`, `i_q* = 0`) tuned by pole-zero cancellation on its own nominal `R`
//!   and `L` (`Kp = L·ω_c`, `Ki = R·ω_c`), the output rotated ahead by 1.5 periods of the
//!   commanded electrical speed (the computation delay plus half the period), clamped to
//!   `±V_bus` per winding (integration stops while clamped). The voltage computed from the
//!   sample at `t_k` is applied over `[t_{k+1}, t_{k+2})` (one period of computation delay).
//! * **Log**: per period, `t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v, v_b_v` with the noisy
//!   currents the loop saw at `t_s` and the mean voltage applied over `[t_s, t_s + Ts)`
//!   (computed the period before).
//! * **Runs**: exactly a row of the sensorless plan CSV (`run,mode,speed_rad_s,duration_s,
//!   standstill_s,ramp_s`): at rest holding `I_hold` at `θ_cmd = 0` for `standstill_s`, a
//!   constant-acceleration ramp to the speed over `ramp_s`, the speed to `duration_s`; the
//!   log from `t = 0`. The drive starts with zero current, the rotor at rest a little off the
//!   commanded angle.

#![allow(dead_code)] // each test binary uses a part of it

use super::flux::FluxShape;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;
use std::fmt::Write as _;

/// Longest integration sub-step, s.
pub const MAX_STEP_S: f64 = 6.25e-6;

/// Below this speed (rad/s) a Karnopp rotor may stick.
pub const STICK_RAD_S: f64 = 1e-4;

/// Friction law of a generated motor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Friction {
    /// `Fs·tanh(ω/ω_ε)`.
    Smooth {
        /// Creep speed `ω_ε`, rad/s.
        creep_rad_s: f64,
    },
    /// Karnopp stick-slip at level `Fs`.
    Karnopp,
}

/// A two-phase hybrid stepper.
#[derive(Clone, Debug)]
pub struct Motor {
    /// Rotor pole pairs `Nr`.
    pub nr: u16,
    /// Torque constant, N·m/A (the back-EMF constant, V·s/rad).
    pub km: f64,
    /// Phase resistance, Ω.
    pub r: f64,
    /// Phase inductance, H.
    pub l: f64,
    /// Inertia, kg·m².
    pub j: f64,
    /// Viscous friction, N·m·s/rad.
    pub d: f64,
    /// Coulomb friction, N·m.
    pub fs: f64,
    /// Friction law.
    pub friction: Friction,
    /// Detent harmonics `(order, amplitude N·m, phase rad)`: torque on the rotor
    /// `−A sin(k·θe + φ)`.
    pub detent: Vec<(u16, f64, f64)>,
    /// The magnet's flux shape ([`FluxShape::sine`]: the sine motor).
    pub flux: FluxShape,
}

/// The drive.
#[derive(Clone, Debug)]
pub struct Drive {
    /// PWM (control and log) rate, Hz.
    pub pwm_hz: f64,
    /// Bus voltage, V.
    pub bus_v: f64,
    /// Holding current, A.
    pub hold_a: f64,
    /// Current-loop bandwidth, Hz.
    pub current_hz: f64,
    /// The resistance the current loop was tuned for, Ω.
    pub r_nominal: f64,
    /// The inductance the current loop was tuned for, H.
    pub l_nominal: f64,
    /// Standard deviation of the current-sensor noise, A.
    pub noise_a: f64,
    /// Current-sensor offsets of phases A and B, A (added to every sample).
    pub offset_a: [f64; 2],
    /// Simulate the PWM edges (else the period's mean voltage).
    pub switching: bool,
}

/// The drive of the independent sensorless tests: patent-motor's bridge and holding current
/// (48 V, 20 kHz, `I_hold` 1.9 A), its own current-loop tuning (1.2 kHz on the datasheet's
/// `R` 0.9 Ω and `L` 2.5 mH), 5 mA of sensor noise, (+3, −2) mA offsets, PWM edges
/// simulated.
pub fn patent_drive() -> Drive {
    Drive {
        pwm_hz: 20_000.0,
        bus_v: 48.0,
        hold_a: 1.9,
        current_hz: 1200.0,
        r_nominal: 0.9,
        l_nominal: 2.5e-3,
        noise_a: 0.005,
        offset_a: [0.003, -0.002],
        switching: true,
    }
}

/// One row of the sensorless plan CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanRow {
    /// Run name.
    pub run: String,
    /// How the drive runs it (`open-loop` for this simulator).
    pub mode: String,
    /// Speed, rad/s (sign = direction).
    pub speed_rad_s: f64,
    /// Whole run, s.
    pub duration_s: f64,
    /// Standstill at the start, s.
    pub standstill_s: f64,
    /// Ramp, s.
    pub ramp_s: f64,
    /// The open-loop current-vector magnitude, A.
    pub holding_current_a: f64,
}

/// The header the plan CSV must have.
pub const PLAN_HEADER: &str = "run,mode,speed_rad_s,duration_s,standstill_s,ramp_s,holding_current_a,d_current_a,servo_bandwidth_hz,velocity_filter_hz";

/// Parses the text of a sensorless plan CSV (header [`PLAN_HEADER`]): open-loop rows only,
/// the servo's columns empty.
pub fn parse_plan(text: &str) -> Result<Vec<PlanRow>, String> {
    let mut lines = text.lines();
    let header = lines.next().ok_or("empty plan")?;
    if header.trim() != PLAN_HEADER {
        return Err(format!("plan header {header:?}, expected {PLAN_HEADER:?}"));
    }
    let width = PLAN_HEADER.split(',').count();
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            if f.len() != width {
                return Err(format!("plan row {l:?}: {} fields, expected {width}", f.len()));
            }
            let num = |i: usize| {
                f[i].trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("plan row {l:?}: field {i} ({}) is not a finite number", f[i]))
            };
            if f[1] != "open-loop" || f[7..].iter().any(|x| !x.is_empty()) {
                return Err(format!("plan row {l:?}: not an open-loop run"));
            }
            let row = PlanRow {
                run: f[0].trim().to_string(),
                mode: f[1].to_string(),
                speed_rad_s: num(2)?,
                duration_s: num(3)?,
                standstill_s: num(4)?,
                ramp_s: num(5)?,
                holding_current_a: num(6)?,
            };
            if row.run.is_empty()
                || row.standstill_s < 0.0
                || row.ramp_s < 0.0
                || row.duration_s < row.standstill_s + row.ramp_s
                || row.holding_current_a <= 0.0
            {
                return Err(format!("plan row {l:?}: inconsistent times or current"));
            }
            Ok(row)
        })
        .collect()
}

/// The commanded mechanical angle at `t` of a plan row: 0 until the standstill ends, then
/// constant acceleration to the speed over the ramp, then the speed.
pub fn command(p: &PlanRow, t: f64) -> (f64, f64) {
    let u = t - p.standstill_s;
    if u <= 0.0 {
        (0.0, 0.0)
    } else if u < p.ramp_s {
        let a = p.speed_rad_s / p.ramp_s;
        (0.5 * a * u * u, a * u)
    } else {
        (p.speed_rad_s * (0.5 * p.ramp_s + (u - p.ramp_s)), p.speed_rad_s)
    }
}

/// The plant state.
#[derive(Clone, Copy, Debug)]
struct State {
    ia: f64,
    ib: f64,
    theta: f64,
    w: f64,
    stuck: bool,
}

impl Motor {
    fn detent_torque(&self, te: f64) -> f64 {
        -self.detent.iter().map(|&(k, a, p)| a * (f64::from(k) * te + p).sin()).sum::<f64>()
    }

    /// Torque on the rotor without friction (motor + detent) at the electrical angle `te`
    /// and phase currents `i_a`, `i_b` (A), N·m.
    pub fn torque(&self, te: f64, ia: f64, ib: f64) -> f64 {
        let (da, db) = self.flux.slopes(te);
        self.km * (ia * da + ib * db) + self.detent_torque(te)
    }

    /// Torque on the rotor without friction at the mechanical angle `theta`, N·m.
    fn drive_torque(&self, ia: f64, ib: f64, theta: f64) -> f64 {
        self.torque(f64::from(self.nr) * theta, ia, ib)
    }

    /// The torque ripple at rotor-frame currents `(i_d, i_q)`, A ([`super::flux::ripple`] of
    /// [`Self::torque`]): `(order, A, φ)`, torque on the rotor `−Σ A sin(k·θe + φ)`.
    pub fn ripple(&self, i_d: f64, i_q: f64, max_order: u16, points: usize) -> Vec<(u16, f64, f64)> {
        super::flux::ripple(|te, ia, ib| self.torque(te, ia, ib), i_d, i_q, max_order, points)
    }

    /// Time derivative of `(i_a, i_b, θ, ω)`; `slide` is the Karnopp sliding direction
    /// (`None`: stuck, `ω` held at 0).
    fn deriv(&self, x: [f64; 4], va: f64, vb: f64, slide: Option<f64>) -> [f64; 4] {
        let [ia, ib, theta, w] = x;
        let te = f64::from(self.nr) * theta;
        let (da, db) = self.flux.slopes(te);
        let dia = (va - self.r * ia - self.km * w * da) / self.l;
        let dib = (vb - self.r * ib - self.km * w * db) / self.l;
        let tau = self.km * (ia * da + ib * db) + self.detent_torque(te);
        let dw = match (self.friction, slide) {
            (Friction::Smooth { creep_rad_s }, _) => (tau - self.fs * (w / creep_rad_s).tanh() - self.d * w) / self.j,
            (Friction::Karnopp, Some(dir)) => (tau - self.fs * dir - self.d * w) / self.j,
            (Friction::Karnopp, None) => 0.0,
        };
        [dia, dib, w, dw]
    }

    /// Advances `x` by `h` with constant winding voltages.
    fn step(&self, x: &mut State, va: f64, vb: f64, h: f64) {
        let slide = match self.friction {
            Friction::Smooth { .. } => Some(0.0),
            Friction::Karnopp if x.stuck => None,
            Friction::Karnopp => {
                let dir = if x.w != 0.0 { x.w.signum() } else { self.drive_torque(x.ia, x.ib, x.theta).signum() };
                Some(dir)
            }
        };
        let y = [x.ia, x.ib, x.theta, x.w];
        let add =
            |a: [f64; 4], b: [f64; 4], k: f64| [a[0] + k * b[0], a[1] + k * b[1], a[2] + k * b[2], a[3] + k * b[3]];
        let k1 = self.deriv(y, va, vb, slide);
        let k2 = self.deriv(add(y, k1, 0.5 * h), va, vb, slide);
        let k3 = self.deriv(add(y, k2, 0.5 * h), va, vb, slide);
        let k4 = self.deriv(add(y, k3, h), va, vb, slide);
        let mut n = y;
        for i in 0..4 {
            n[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        [x.ia, x.ib, x.theta, x.w] = n;
        if self.friction == Friction::Karnopp {
            let free = self.drive_torque(x.ia, x.ib, x.theta).abs() > self.fs;
            match slide {
                None => x.stuck = !free,
                Some(dir) => {
                    // Crossed zero: stop, and stick unless the torque breaks away; nearly
                    // stopped: stick unless the torque breaks away.
                    if x.w * dir < 0.0 {
                        x.w = 0.0;
                        x.stuck = !free;
                    } else if x.w.abs() < STICK_RAD_S && !free {
                        x.stuck = true;
                    }
                }
            }
            if x.stuck {
                x.w = 0.0;
            }
        }
    }

    /// Advances over `[0, dt)` with constant voltages, in sub-steps of at most [`MAX_STEP_S`].
    fn advance(&self, x: &mut State, va: f64, vb: f64, dt: f64) {
        if dt <= 0.0 {
            return;
        }
        let n = (dt / MAX_STEP_S).ceil().max(1.0);
        let h = dt / n;
        for _ in 0..n as usize {
            self.step(x, va, vb, h);
        }
    }
}

/// What a run left besides the log (for the test's print-out).
#[derive(Clone, Copy, Debug)]
pub struct RunStats {
    /// Largest `|θe_cmd − θe|` over the steady part, electrical rad.
    pub max_load_angle_rad: f64,
    /// Share of the steady part with the rotor stuck (Karnopp).
    pub stuck_fraction: f64,
}

/// Performs plan row `p` on motor `m` with drive `d`: the CSV text of the log.
pub fn run(m: &Motor, d: &Drive, p: &PlanRow, seed: u64) -> (String, RunStats) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ts = 1.0 / d.pwm_hz;
    let n = (p.duration_s * d.pwm_hz).round() as usize;
    let nr = f64::from(m.nr);
    let wc = TAU * d.current_hz;
    let (kp, ki) = (d.l_nominal * wc, d.r_nominal * wc);
    // The rotor at rest up to ±0.3 electrical rad off the command.
    let mut x = State { ia: 0.0, ib: 0.0, theta: rng.random_range(-0.3..0.3) / nr, w: 0.0, stuck: false };
    let (mut xd, mut xq) = (0.0, 0.0); // PI integrators, V
    let mut v_now = (0.0, 0.0); // applied over the current period
    let mut out = String::with_capacity(n * 80);
    out.push_str("t_s,theta_cmd_rad,i_a_a,i_b_a,v_a_v,v_b_v\n");
    let (mut max_delta, mut stuck, mut steady) = (0.0f64, 0usize, 0usize);
    for k in 0..n {
        let t = k as f64 / d.pwm_hz;
        let (th_cmd, w_cmd) = command(p, t);
        // Sample.
        let ia_m = x.ia + d.offset_a[0] + d.noise_a * gauss(&mut rng);
        let ib_m = x.ib + d.offset_a[1] + d.noise_a * gauss(&mut rng);
        let _ = writeln!(out, "{t:.6},{th_cmd:.12},{ia_m:.6},{ib_m:.6},{:.6},{:.6}", v_now.0, v_now.1);
        if t >= p.standstill_s + p.ramp_s {
            steady += 1;
            max_delta = max_delta.max(wrap(nr * (th_cmd - x.theta)).abs());
            stuck += usize::from(x.stuck);
        }
        // Current loop in the command frame.
        let te = nr * th_cmd;
        let (s, c) = te.sin_cos();
        let (id, iq) = (ia_m * c + ib_m * s, -ia_m * s + ib_m * c);
        let (ed, eq) = (d.hold_a - id, -iq);
        let (vd, vq) = (kp * ed + xd, kp * eq + xq);
        let (s2, c2) = (te + 1.5 * ts * nr * w_cmd).sin_cos();
        let (va, vb) = (vd * c2 - vq * s2, vd * s2 + vq * c2);
        let clamp = |v: f64| v.clamp(-d.bus_v, d.bus_v);
        let v_next = (clamp(va), clamp(vb));
        if v_next == (va, vb) {
            xd += ki * ts * ed;
            xq += ki * ts * eq;
        }
        // The plant over [t, t + Ts) under the voltage computed a period ago.
        if d.switching {
            let duty = |v: f64| 0.5 * (1.0 + v / d.bus_v);
            let (da, db) = (duty(v_now.0), duty(v_now.1));
            let mut edges = [0.0, 0.5 * (1.0 - da), 0.5 * (1.0 + da), 0.5 * (1.0 - db), 0.5 * (1.0 + db), 1.0];
            edges.sort_by(f64::total_cmp);
            for w in edges.windows(2) {
                let mid = 0.5 * (w[0] + w[1]);
                let level = |dd: f64| if (mid - 0.5).abs() < 0.5 * dd { d.bus_v } else { -d.bus_v };
                m.advance(&mut x, level(da), level(db), (w[1] - w[0]) * ts);
            }
        } else {
            m.advance(&mut x, v_now.0, v_now.1, ts);
        }
        v_now = v_next;
    }
    (out, RunStats { max_load_angle_rad: max_delta, stuck_fraction: stuck as f64 / steady.max(1) as f64 })
}

/// `x` wrapped into `(−π, π]`.
fn wrap(x: f64) -> f64 {
    x - TAU * (x / TAU).round()
}

/// Standard normal sample (Box–Muller).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}
