//! An independent generator of servo-mode logs of a **real** motor: flux harmonics, a
//! phase imbalance and a winding model that writes the applied voltages.
//!
//! Written without any code of `stepdamp-sim`, `stepdamp-core` or `stepdamp-profile`'s flux
//! and ripple code. It reads the encoder plan CSV (`identify plan --format csv`) as text and
//! performs every servo row of it, the back-EMF run included. Its own models:
//!
//! * **Flux linkage** of the magnet in each winding, per unit of `Km/Nr`, `θe = Nr·θ`: the
//!   motor's [`FluxShape`] ([`super::flux`]: `λ_a(θe) = cos θe + Σ_n h_n·cos(n·θe + a_n)`,
//!   `λ_b(θe) = (1 + g)·[sin θe + Σ_n h_n·cos(n·θe + a_n − n·π/2)]`).
//! * **Energy**: with the magnet flux linked to winding `x`, `ψ_x = (Km/Nr)·λ_x(θe)`, the
//!   magnetic co-energy is `W' = i_a·ψ_a + i_b·ψ_b + W_m(θ)` (`W_m` the magnet's own
//!   energy, whose derivative is the detent). The torque on the rotor is `∂W'/∂θ` at
//!   constant currents, `τ_m = Km·(i_a·λ_a' + i_b·λ_b')` (`'` = `d/dθe`), and the voltage the
//!   rotor induces is `e_x = dψ_x/dt = Km·ω·λ_x'`, so that `e_a·i_a + e_b·i_b = τ_m·ω`: the
//!   electrical power the back-EMF takes is the mechanical power the rotor gets.
//! * **Windings**: `L·di_x/dt = v_x − R·i_x − e_x`, integrated exactly over each sub-step
//!   with `e_x` taken at the middle of the sub-step (the rotor's predicted angle).
//! * **Rotor**: `J·dω/dt = τ_m − Σ A_k sin(k·θe + φ_k) − F(ω) − D·ω`, the friction law and
//!   the semi-implicit step of [`super`] (implicit in `ω`, `θ` with the new `ω`).
//! * **Drive**, at the PWM rate, on the encoder (centre of the count): the position PID and
//!   speed filter of [`super`] (all three poles at `−2π·f_b` for the inertia it was tuned
//!   for; `f_b` the plan row's `servo_bandwidth_hz`) gives `i_q*`; a PI current loop in the
//!   encoder's frame (`i_d*` the row's `d_current_a`), tuned by pole-zero cancellation on its
//!   nominal `R`, `L` (`Kp = L·ω_c`, `Ki = R·ω_c`), turns the sampled `i_d`, `i_q` errors into `v_d`, `v_q`,
//!   rotated into the phases at the encoder angle advanced by 1.5 periods of the estimated
//!   electrical speed, limited to `±V_bus` per winding (integration stops while limited),
//!   applied over the next period (one period of computation delay) as its mean voltage.
//! * **Log**: per period `t_s, theta_fb_rad, i_a_a, i_b_a, i_q_a, iq_cmd_a, v_a_v, v_b_v`:
//!   the noisy phase currents sampled at `t_s`, their Park transform at the encoder angle,
//!   the command, and the mean voltage applied over `[t_s, t_s + Ts)`.

use super::flux::FluxShape;
use super::open_loop::{PLAN_HEADER, PlanRow, command};
use super::{Motor, gauss, implicit_speed};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::TAU;
use std::fmt::Write as _;

/// Integration sub-steps per control period.
pub const SUB_STEPS: u32 = 8;

/// A real motor: the mechanical motor of [`super`] plus windings and a flux shape.
#[derive(Clone, Debug)]
pub struct RealMotor {
    /// Rotor, friction, detent and encoder ([`Motor::km`] is the flux fundamental).
    pub mech: Motor,
    /// Phase resistance, Ω.
    pub r: f64,
    /// Phase inductance, H.
    pub l: f64,
    /// The magnet's flux shape: odd harmonics of phase a and phase b's gain `g`.
    pub flux: FluxShape,
}

impl RealMotor {
    /// Back-EMF `(e_a, e_b) = Km·ω·(λ_a', λ_b')` at `θe` and speed `ω` (rad/s), V.
    pub fn back_emf(&self, te: f64, w: f64) -> (f64, f64) {
        let (da, db) = self.flux.slopes(te);
        (self.mech.km * w * da, self.mech.km * w * db)
    }

    /// Torque on the rotor at `θe` and phase currents `i_a`, `i_b` (motor and detent), N·m.
    pub fn torque(&self, te: f64, ia: f64, ib: f64) -> f64 {
        let (da, db) = self.flux.slopes(te);
        self.mech.km * (ia * da + ib * db) - self.mech.detent(te / f64::from(self.mech.nr))
    }

    /// The torque ripple at rotor-frame currents `(i_d, i_q)`, A ([`super::flux::ripple`] of
    /// [`Self::torque`]): `(order, A, φ)`, torque on the rotor `−Σ A sin(k·θe + φ)`.
    pub fn ripple(&self, i_d: f64, i_q: f64, max_order: u16, points: usize) -> Vec<(u16, f64, f64)> {
        super::flux::ripple(|te, ia, ib| self.torque(te, ia, ib), i_d, i_q, max_order, points)
    }
}

/// The drive.
#[derive(Clone, Debug)]
pub struct ServoDrive {
    /// PWM (control and log) rate, Hz.
    pub pwm_hz: f64,
    /// Bus voltage, V.
    pub bus_v: f64,
    /// Inertia the position loop was tuned for, kg·m².
    pub j_tuned: f64,
    /// Current-loop bandwidth, Hz.
    pub current_hz: f64,
    /// The resistance and inductance the current loop was tuned for, Ω and H.
    pub r_nominal: f64,
    /// See [`Self::r_nominal`].
    pub l_nominal: f64,
    /// `i_q*` limit, A.
    pub current_limit_a: f64,
    /// Standard deviation of the phase-current sensor noise, A.
    pub noise_a: f64,
}

/// A servo row of the encoder plan CSV: its times and the position-loop bandwidth, Hz.
#[derive(Clone, Debug)]
pub struct ServoRow {
    /// Name, speed and times (`holding_current_a` unused, 0).
    pub row: PlanRow,
    /// `servo_bandwidth_hz`.
    pub bandwidth_hz: f64,
    /// `d_current_a`: the d current the current loop holds, A.
    pub d_current_a: f64,
}

/// Parses the servo rows of an encoder plan CSV (header [`PLAN_HEADER`]); any other row is
/// an error.
pub fn parse_servo_plan(text: &str) -> Result<Vec<ServoRow>, String> {
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some(PLAN_HEADER) {
        return Err(format!("plan header is not {PLAN_HEADER:?}"));
    }
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split(',').map(str::trim).collect();
            let num = |i: usize| {
                f.get(i)
                    .and_then(|x| x.parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("plan row {l:?}: field {i} is not a finite number"))
            };
            if f.len() != 10 || f[1] != "servo" {
                return Err(format!("plan row {l:?}: not a servo run"));
            }
            let row = PlanRow {
                run: f[0].to_string(),
                mode: f[1].to_string(),
                speed_rad_s: num(2)?,
                duration_s: num(3)?,
                standstill_s: num(4)?,
                ramp_s: num(5)?,
                holding_current_a: 0.0,
            };
            Ok(ServoRow { row, bandwidth_hz: num(8)?, d_current_a: num(7)? })
        })
        .collect()
}

/// The plant state: phase currents `(i_a, i_b)` (A), angle (rad), speed (rad/s).
#[derive(Clone, Copy, Debug)]
struct State {
    i: (f64, f64),
    theta: f64,
    w: f64,
}

impl RealMotor {
    /// Advances `x` by `h` under constant winding voltages `v`.
    fn step(&self, x: &mut State, v: (f64, f64), h: f64) {
        let nr = f64::from(self.mech.nr);
        let te_mid = nr * (x.theta + 0.5 * h * x.w);
        let (da, db) = self.flux.slopes(te_mid);
        let (ea, eb) = self.back_emf(te_mid, x.w);
        let decay = (-self.r * h / self.l).exp();
        let settle = |i: f64, v: f64, e: f64| (v - e) / self.r + (i - (v - e) / self.r) * decay;
        let (ia, ib) = (settle(x.i.0, v.0, ea), settle(x.i.1, v.1, eb));
        let motor = self.mech.km * (0.5 * (x.i.0 + ia) * da + 0.5 * (x.i.1 + ib) * db);
        let rhs = motor - self.mech.detent(te_mid / nr);
        x.w = implicit_speed(&self.mech, x.w, rhs, h);
        x.theta += h * x.w;
        x.i = (ia, ib);
    }
}

/// Performs servo row `p` on motor `m` with drive `d`: the CSV text of the log.
pub fn run(m: &RealMotor, d: &ServoDrive, p: &ServoRow, seed: u64) -> String {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ts = 1.0 / d.pwm_hz;
    let n = (p.row.duration_s * d.pwm_hz).round() as usize;
    let q = TAU / f64::from(m.mech.cpr);
    let nr = f64::from(m.mech.nr);
    let wb = TAU * p.bandwidth_hz;
    let (kp, kd, ki) = (3.0 * d.j_tuned * wb * wb, 3.0 * d.j_tuned * wb, d.j_tuned * wb * wb * wb);
    let filt = 1.0 - (-TAU * 5.0 * p.bandwidth_hz * ts).exp();
    let wc = TAU * d.current_hz;
    let (kpc, kic) = (d.l_nominal * wc, d.r_nominal * wc);
    let h = ts / f64::from(SUB_STEPS);
    let mut x = State { i: (0.0, 0.0), theta: rng.random_range(0.0..q), w: 0.0 };
    let fb = |th: f64| ((th / q).floor() + 0.5) * q;
    let theta0 = fb(x.theta);
    let (mut fb_prev, mut omega_fb, mut integ) = (theta0, 0.0, 0.0);
    let (mut xd, mut xq) = (0.0, 0.0); // current PI integrators, V
    let mut v_now = (0.0, 0.0);
    let mut out = String::with_capacity(n * 100);
    out.push_str("t_s,theta_fb_rad,i_a_a,i_b_a,i_q_a,iq_cmd_a,v_a_v,v_b_v\n");
    for k in 0..n {
        let t = k as f64 * ts;
        let (th_cmd, w_ref) = command(&p.row, t);
        let theta_ref = theta0 + th_cmd;
        // Sample: encoder and phase currents.
        let theta_fb = fb(x.theta);
        omega_fb += filt * ((theta_fb - fb_prev) / ts - omega_fb);
        fb_prev = theta_fb;
        let ia_m = x.i.0 + d.noise_a * gauss(&mut rng);
        let ib_m = x.i.1 + d.noise_a * gauss(&mut rng);
        let te_fb = nr * theta_fb;
        let (s, c) = te_fb.sin_cos();
        let (id_m, iq_m) = (ia_m * c + ib_m * s, -ia_m * s + ib_m * c);
        // Position PID.
        let e = theta_ref - theta_fb;
        integ += e * ts;
        let torque_cmd = kp * e + kd * (w_ref - omega_fb) + ki * integ;
        let iq_cmd = (torque_cmd / m.mech.km).clamp(-d.current_limit_a, d.current_limit_a);
        let _ = writeln!(
            out,
            "{t:.6},{theta_fb:.9},{ia_m:.6},{ib_m:.6},{iq_m:.6},{iq_cmd:.6},{:.6},{:.6}",
            v_now.0, v_now.1
        );
        // Current PI in the encoder frame, output advanced by 1.5 periods.
        let (ed, eq) = (p.d_current_a - id_m, iq_cmd - iq_m);
        let (vd, vq) = (kpc * ed + xd, kpc * eq + xq);
        let (s2, c2) = (te_fb + 1.5 * ts * nr * omega_fb).sin_cos();
        let (va, vb) = (vd * c2 - vq * s2, vd * s2 + vq * c2);
        let v_next = (va.clamp(-d.bus_v, d.bus_v), vb.clamp(-d.bus_v, d.bus_v));
        if v_next == (va, vb) {
            xd += kic * ts * ed;
            xq += kic * ts * eq;
        }
        for _ in 0..SUB_STEPS {
            m.step(&mut x, v_now, h);
        }
        v_now = v_next;
    }
    out
}
