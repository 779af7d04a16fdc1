//! Load-angle observer for open loop: where the rotor is, without an encoder.
//!
//! In open loop the rotor lags the commanded electrical angle `θc` by the load angle
//! `δ = θc − θe`, which grows with load torque and swings at resonance. In the frame of
//! `θc` (rotating at `ωe = Nr·ω_cmd`) the back-EMF is
//!
//! ```text
//! e_d = Km·ω·sin δ,   e_q = Km·ω·cos δ      ⇒   δ = atan2(e_d, e_q)   (ω > 0)
//! ```
//!
//! which does not depend on `Km`. The back-EMF comes from the winding equations in that
//! frame over the last PWM period, with the average voltage the drive applied and the
//! mean of the two current samples, both rotated to the frame at mid-period:
//!
//! ```text
//! ê_d = v_d − R̂·ī_d − L·Δi_d*/Ts + ωe·L·ī_q
//! ê_q = v_q − R̂·ī_q − L·Δi_q*/Ts − ωe·L·ī_d
//! ```
//!
//! The `L·di/dt` terms use the change of the
//! *commanded* currents `i*`, which the current loop follows: differentiating the noisy
//! samples would multiply sensor noise by `L/Ts` (50 Ω for the patent motor), while here
//! it enters only through `R̂` and `ωe·L` (a few Ω).
//!
//! Two filters of `ê` give two estimates: `δ_slow` (5 Hz: the load angle, nearly free of
//! sensor noise) and `δ_fast` (`bandwidth_hz`, 500 Hz by default: it follows the swing of
//! the rotor at resonance, about 130 Hz for the patent motor). They are blended as
//! `δ̂ = δ_slow + w·(δ_fast − δ_slow)` with the Wiener weight
//! `w = 1 − var(noise of δ_fast) / var(δ_fast − δ_slow)` (clamped to [0, 1]), both
//! variances tracked online at 5 Hz: the noise from the residual `ê − ê_fast`, scaled by
//! the fast filter's noise gain `α/(2−α)` and by `1/|ê|²`. A real swing makes the
//! difference large and `w → 1`; when the difference is only noise, `w → 0`.
//!
//! `R` drifts with temperature and drive voltage errors look like resistance: while the
//! command is at standstill (and the current has settled on its command) the observer
//! trims `R̂` until the back-EMF along the current vanishes, so the low-speed estimate
//! does not carry a `ΔR·I_hold` bias. At low speed the back-EMF is weak: the estimate is
//! shrunk towards `δ = 0` (the patent's law) by `|ê|²/(|ê|² + e_floor²)`.
//!
//! The magnitude `|ê| = Km·|ω|` measures the torque constant too: when the command
//! implies more than `KM_MIN_EMF_FLOORS·e_floor` of back-EMF the observer tracks
//! `K̂m = LP(|ê|/|ω_cmd|)` (5 Hz, each sample bounded to `[0.5, 2]·Km`), and the compensation current is scaled by `Km/K̂m`, so a mis-identified
//! `Km` does not turn into a wrong compensation amplitude. The current loop's integral
//! gain follows `R̂` as well (`Ki = R̂·ωc`), which keeps the loop first order.
//!
//! A real motor's back-EMF is off its rotor's q axis by an angle `ε(θe)` that the estimated
//! law gives ([`ObserverState::emf_angle_error_rad`]); the observer turns each period's
//! back-EMF back by it. `ε` is evaluated where the rotor is: the fast filter delays `δ̂`, so the
//! observer also tracks that delay's size ([`ObserverState::delta_lead_rad`], the estimate's
//! change per period through a 1 kHz filter times the fast filter's lag in periods)
//! (docs/design.md#the-back-emfs-angle-where-the-rotor-is).
//!
//! Assumptions: `L` known; `R` known or trimmed at standstill; the applied voltage equals
//! the commanded one (no dead time). Cost while the motor runs: two `libm::atan2f`
//! (single precision throughout, FPU only: `atanf`'s polynomial in `f32`, checked by
//! `firmware/qemu-m4/check-symbols.sh`), one `libm::sqrtf`, about 60 flops per period;
//! the step adds one [`crate::trig::sin_cos_rad`] of `δ̂`. About 590 instructions of the
//! estimated-angle step on the Cortex-M4F (the medians in `firmware/qemu-m4/instructions.txt`:
//! 1,116 against 530 for the patent's open loop).

use crate::lowpass::LowPass;
use crate::park::{Ab, Dq};
use crate::pi::Pi;

/// What the observer is built from ([`LoadAngleObserver::new`]): the motor, the drive's
/// timing and the observer's own tuning. [`crate::Config::new`] fills it from the
/// validated parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverSettings {
    /// Winding resistance `R` (the trim's starting value and its reference), Ω.
    pub resistance_ohm: f32,
    /// Winding inductance `L`, H.
    pub inductance_h: f32,
    /// Configured torque constant `Km` (the reference of `K̂m`), N·m/A.
    pub km_nm_per_a: f32,
    /// Control period `Ts`, s.
    pub period_s: f32,
    /// Corner of the fast back-EMF filter (`δ_fast`), Hz.
    pub bandwidth_hz: f32,
    /// Back-EMF below which the estimate is shrunk towards `δ = 0`, V.
    pub emf_floor_v: f32,
    /// Periods between computing a voltage and its being applied (0 or 1; more is
    /// treated as 1).
    pub delay_periods: u8,
    /// Bandwidth of the closed current loop, Hz (sets how long a command change takes to
    /// settle before the standstill resistance trim runs).
    pub current_loop_bandwidth_hz: f32,
}

/// One period's inputs of [`LoadAngleObserver::update`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverInput {
    /// This period's current sample, A.
    pub current: Ab,
    /// `sin θc` of the command's electrical angle.
    pub sin: f32,
    /// `cos θc` of the command's electrical angle.
    pub cos: f32,
    /// The command's electrical advance per period, rad.
    pub dtheta_e_rad: f32,
    /// The commanded speed, rad/s (mechanical; its sign is the direction of rotation,
    /// 0 is standstill).
    pub speed_rad_s: f32,
}

/// Observer gains, fixed at configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadAngleObserver {
    pub(crate) r_ohm: f32,
    pub(crate) l_h: f32,
    pub(crate) l_over_ts: f32,
    pub(crate) period_s: f32,
    pub(crate) filter: LowPass,
    /// The slow (5 Hz) filter: estimate and variance trackers.
    pub(crate) slow: LowPass,
    /// White-noise power gain of the fast filter, `α/(2−α)`.
    pub(crate) fast_noise_gain: f32,
    /// Back-EMF below which the estimate is shrunk towards zero, V.
    pub(crate) e_floor_v: f32,
    /// Fraction of the resistance error corrected per period at standstill.
    pub(crate) r_trim_gain: f32,
    /// Periods between computing a voltage and its being applied (0 or 1).
    pub(crate) delay_periods: u8,
    /// The configured torque constant, N·m/A.
    pub(crate) km: f32,
    /// Periods the current command must have held still before the standstill trim of
    /// `R̂` runs: five time constants of the current loop plus the computation delay.
    pub(crate) settle_periods: u16,
    /// Filter of the torque-constant estimate.
    pub(crate) km_filter: LowPass,
    /// Filter of the load-angle estimate's change per period ([`LEAD_RATE_HZ`]).
    pub(crate) rate_filter: LowPass,
    /// The fast filter's lag in periods at low frequency, `(1 − α)/α`: the estimate's
    /// filtered change per period times this is how far the load angle is ahead of it.
    pub(crate) lag_periods: f32,
}

/// Corner of the slow estimate and of the variance trackers, Hz.
const SLOW_HZ: f32 = 5.0;

/// Corner of the filter of the estimate's rate of change, Hz: twice the fast filter's
/// (500 Hz), so it passes the swing at resonance (130 Hz for the patent motor, up to about
/// 200 Hz on the real-motor family) but not the sample-to-sample noise that its unfiltered
/// difference would multiply by the lag in periods (6 at 500 Hz and 20 kHz). Measured on
/// motor 0 of the independent real-motor family
/// (docs/design.md#the-back-emfs-angle-where-the-rotor-is): unfiltered, the lead made the
/// parametric resonance worse at one speed of five; at 1 and 2 kHz it removed it at all five.
const LEAD_RATE_HZ: f32 = 1000.0;

/// Bound of [`ObserverState::delta_lead_rad`], electrical rad. A swing of `A` rad at `f`
/// leads the 500 Hz filter by about `A·f/500 Hz`: 0.1 rad is a 0.25 rad swing at the
/// family's fastest resonance (200 Hz), beyond which the motor is close to losing steps
/// and `ε` is not what fails. A jump of the estimate (a slip) is not a delay,
/// and must not move `ε`'s evaluation point by radians.
const LEAD_LIMIT_RAD: f32 = 0.1;

/// Back-EMF, in units of the floor, above which `K̂m` is tracked.
const KM_MIN_EMF_FLOORS: f32 = 20.0;

/// Observer state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ObserverState {
    last_current: Ab,
    /// Voltages computed in the last two periods, newest first.
    voltage_history: [Ab; 2],
    /// Current commands (in their own `θc` frame) of the last two periods, newest first.
    command_history: [Dq; 2],
    started: bool,
    /// Back-EMF in the `θc` frame through the fast filter, V.
    pub e_dq: Dq,
    /// Back-EMF in the `θc` frame through the slow filter, V.
    pub e_dq_slow: Dq,
    /// Power of the residual `ê − ê_fast`, V².
    pub residual_power_v2: f32,
    /// Mean square of `δ_fast − δ_slow`, rad².
    pub swing_power_rad2: f32,
    /// Weight of the fast estimate in `δ̂`.
    pub fast_weight: f32,
    /// Resistance estimate, Ω (0 until the first period: then the configured value).
    pub r_hat_ohm: f32,
    /// Load angle estimate `δ̂ = θc − θ̂e`, electrical rad.
    pub delta_rad: f32,
    /// Torque-constant estimate, N·m/A (the configured value until the motor runs).
    pub km_hat: f32,
    /// Periods since the current command last changed (saturating).
    pub command_steady_periods: u16,
    /// The angle of a real motor's back-EMF from its rotor's q axis (towards +d) at the rotor
    /// angle of the last period, electrical rad: `atan2(τ_d, τ_q) ≈ −cd/(1 − cq)` from the
    /// ripple per ampere ([`crate::ripple`]; the back-EMF per rad/s is the torque per
    /// ampere), set by the estimated law; the back-EMF is turned back by it before both
    /// filters. 0 for a pure-sine motor (docs/design.md#real-motors-flux-harmonics).
    pub emf_angle_error_rad: f32,
    /// The last load-angle estimate, electrical rad (for its rate of change).
    delta_prev_rad: f32,
    /// The estimate's change per period through the rate filter, electrical rad.
    delta_rate_rad: f32,
    /// The direction (±1, 0 at standstill) of the last period: `δ̂` is a history for the rate
    /// only in the same direction (at standstill it is forced to 0; a reversal turns the
    /// back-EMF it is read from).
    lead_direction: f32,
    /// How far the load angle is ahead of the estimate `δ̂` that the fast filter delays,
    /// electrical rad: the filtered rate times the filter's lag in periods. The estimated
    /// law evaluates `ε` (above) at the rotor angle this much further behind; evaluated at
    /// the delayed angle, `ε`'s error made the parametric resonance grow on one motor of the
    /// real-motor family (docs/design.md#the-back-emfs-angle-where-the-rotor-is). Not applied
    /// to the compensation's own angle, where it made that resonance worse at each of the four
    /// speeds (of the five) it was tried at. 0 at standstill; within ±0.1 rad (`LEAD_LIMIT_RAD`).
    pub delta_lead_rad: f32,
}

impl ObserverState {
    /// Every estimate and filter state is finite and `K̂m > 0` (else the observer
    /// restarts).
    #[inline(always)]
    fn is_sound(&self) -> bool {
        self.delta_rad.is_finite()
            && self.residual_power_v2.is_finite()
            && self.swing_power_rad2.is_finite()
            && self.e_dq_slow.d.is_finite()
            && self.e_dq_slow.q.is_finite()
            && self.e_dq.d.is_finite()
            && self.e_dq.q.is_finite()
            && self.r_hat_ohm.is_finite()
            && self.km_hat.is_finite()
            && self.km_hat > 0.0
            && self.delta_rate_rad.is_finite()
    }
}

impl LoadAngleObserver {
    /// An observer for the winding, drive timing and tuning in `s` (see
    /// [`ObserverSettings`]), behind a first-order current loop.
    pub fn new(s: &ObserverSettings) -> Self {
        let ObserverSettings {
            resistance_ohm: r_ohm,
            inductance_h: l_h,
            km_nm_per_a: km,
            period_s,
            bandwidth_hz,
            emf_floor_v: e_floor_v,
            delay_periods,
            current_loop_bandwidth_hz,
        } = *s;
        LoadAngleObserver {
            r_ohm,
            l_h,
            l_over_ts: l_h / period_s,
            period_s,
            filter: LowPass::new(bandwidth_hz, period_s),
            slow: LowPass::new(SLOW_HZ, period_s),
            fast_noise_gain: {
                let a = LowPass::new(bandwidth_hz, period_s).alpha();
                a / (2.0 - a)
            },
            e_floor_v,
            // Time constant 100 periods: 5 ms at 20 kHz.
            r_trim_gain: 1e-2,
            delay_periods: delay_periods.min(1),
            km,
            km_filter: LowPass::new(5.0, period_s),
            rate_filter: LowPass::new(LEAD_RATE_HZ, period_s),
            lag_periods: {
                let a = LowPass::new(bandwidth_hz, period_s).alpha();
                if a > 0.0 { (1.0 - a) / a } else { 0.0 }
            },
            settle_periods: {
                let tau_periods = 1.0 / (core::f32::consts::TAU * current_loop_bandwidth_hz * period_s);
                // `as` saturates (and maps NaN to 0): the bound keeps it meaningful.
                (5.0 * tau_periods + delay_periods.min(1) as f32 + 1.0).min(f32::from(u16::MAX)) as u16
            },
        }
    }

    /// The current-loop gains with `Ki` rescaled from the configured `R` to `R̂`.
    #[inline]
    pub fn current_pi(&self, pi: &Pi, st: &ObserverState) -> Pi {
        let scale = if st.r_hat_ohm > 0.0 { st.r_hat_ohm / self.r_ohm } else { 1.0 };
        Pi { kp: pi.kp, ki_ts: pi.ki_ts * scale }
    }

    /// `Km / K̂m`: the factor that corrects a compensation current computed with the
    /// configured `Km` (bounded to `[0.5, 2]`).
    #[inline]
    pub fn km_correction(&self, st: &ObserverState) -> f32 {
        // Before the first period (and right after a restart) there is no estimate yet:
        // no correction, rather than the bound that `Km/0` would hit.
        if st.km_hat > 0.0 { crate::bound(self.km / st.km_hat, 0.5, 2.0) } else { 1.0 }
    }

    /// Takes this period's inputs (see [`ObserverInput`]) and returns the load-angle
    /// estimate `δ̂`, electrical rad. Call [`LoadAngleObserver::record`] with the voltage
    /// computed in this period afterwards.
    ///
    /// Stages: the first period only starts the histories; then the back-EMF of the last
    /// period through both filters ([`Self::filter_back_emf`]); at standstill the
    /// resistance trim ([`Self::trim_resistance`]), while running the angle and `K̂m`
    /// ([`Self::estimate_angle`]); a state that went non-finite restarts.
    #[inline]
    pub fn update(&self, st: &mut ObserverState, input: &ObserverInput) -> f32 {
        let direction = if input.speed_rad_s > 0.0 {
            1.0
        } else if input.speed_rad_s < 0.0 {
            -1.0
        } else {
            0.0
        };
        if !st.started {
            self.start(st, input.current);
            return 0.0;
        }
        self.filter_back_emf(st, input);
        if direction == 0.0 {
            self.trim_resistance(st);
            st.delta_rad = 0.0;
        } else {
            self.estimate_angle(st, direction, input.speed_rad_s);
        }
        self.track_lead(st, direction);
        if !st.is_sound() {
            self.restart(st);
        }
        st.delta_rad
    }

    /// The first period (at power-on or after a restart): no history yet, so only the
    /// current sample is kept, and `R̂`, `K̂m` start from the configured values (a restart
    /// kept the learnt ones).
    #[inline(always)]
    fn start(&self, st: &mut ObserverState, i: Ab) {
        st.started = true;
        st.last_current = i;
        if st.r_hat_ohm <= 0.0 {
            st.r_hat_ohm = self.r_ohm;
        }
        if st.km_hat <= 0.0 {
            st.km_hat = self.km;
        }
    }

    /// The back-EMF `ê` of the last period in the `θc` frame at mid-period (the module's
    /// winding equations), through the fast and slow filters, and the power of the fast
    /// filter's residual.
    #[inline(always)]
    fn filter_back_emf(&self, st: &mut ObserverState, input: &ObserverInput) {
        let ObserverInput { current: i, sin, cos, dtheta_e_rad: dtheta_e, .. } = *input;
        // `& 1`: delay_periods is 0 or 1 (see `new`), and the mask lets the compiler drop the
        // bounds check (and its panic path) from the step.
        let v = st.voltage_history[usize::from(self.delay_periods & 1)];
        let (ia, ib) = (0.5 * (i.a + st.last_current.a), 0.5 * (i.b + st.last_current.b));
        st.last_current = i;
        // The frame at the middle of the period: θc − ½Δ (small-angle rotation).
        let h = 0.5 * dtheta_e;
        let (s, c) = (sin - h * cos, cos + h * sin);
        let (vd, vq) = (v.a * c + v.b * s, -v.a * s + v.b * c);
        let (id, iq) = (ia * c + ib * s, -ia * s + ib * c);
        // The commands that drove the current over the last period, one delay older.
        let di = Dq {
            d: st.command_history[0].d - st.command_history[1].d,
            q: st.command_history[0].q - st.command_history[1].q,
        };
        let wl = dtheta_e / self.period_s * self.l_h;
        let ed = vd - st.r_hat_ohm * id - self.l_over_ts * di.d + wl * iq;
        let eq = vq - st.r_hat_ohm * iq - self.l_over_ts * di.q - wl * id;
        // A real motor's back-EMF is `ε` (small) off the rotor's q axis: turned back by it
        // before both filters, so that they see the rotor's angle (skipped for a pure sine:
        // the same bits).
        let eps = st.emf_angle_error_rad;
        let (ed, eq) = if eps != 0.0 { (ed - eps * eq, eq + eps * ed) } else { (ed, eq) };
        self.filter.update(&mut st.e_dq.d, ed);
        self.filter.update(&mut st.e_dq.q, eq);
        self.slow.update(&mut st.e_dq_slow.d, ed);
        self.slow.update(&mut st.e_dq_slow.q, eq);
        let (rd, rq) = (ed - st.e_dq.d, eq - st.e_dq.q);
        self.slow.update(&mut st.residual_power_v2, rd * rd + rq * rq);
    }

    /// Standstill: no back-EMF, so what remains along the current is resistance error;
    /// trimmed once the current has settled on its command, which the loop does within
    /// `settle_periods` of the command's last change.
    #[inline(always)]
    fn trim_resistance(&self, st: &mut ObserverState) {
        // A rotor still settling after a stop makes back-EMF too, mostly across the
        // current (δ is small); a resistance error makes it only along the current. So
        // trim only while the fast back-EMF across the current is within the floor plus
        // three standard deviations of the fast filter's noise (sensor noise must not
        // stop the trim).
        // Only the command and the filtered back-EMF enter, never the sample: with the
        // sample, its noise (which the loop's reaction puts into the voltage too) made
        // both the gate and the product `ê·i` biased, and 20 mA of noise moved R̂ enough
        // to make the estimate worse than θ_cmd at the lowest resonance.
        let cmd = st.command_history[0];
        let settled = st.command_steady_periods >= self.settle_periods;
        let c2 = cmd.d * cmd.d + cmd.q * cmd.q;
        let across = st.e_dq.q * cmd.d - st.e_dq.d * cmd.q;
        let quiet = self.e_floor_v * self.e_floor_v + 9.0 * self.fast_noise_gain * st.residual_power_v2;
        if settled && c2 > 1e-4 && across * across < quiet * c2 {
            let de = (st.e_dq.d * cmd.d + st.e_dq.q * cmd.q) / c2;
            st.r_hat_ohm = crate::bound(st.r_hat_ohm + self.r_trim_gain * de, 0.25 * self.r_ohm, 4.0 * self.r_ohm);
        }
    }

    /// Running (`direction` ±1, the sign of `speed_rad_s`): the load angle `δ̂` from the
    /// blend of the fast and slow back-EMF angles, and `K̂m` from the back-EMF's magnitude.
    #[inline(always)]
    fn estimate_angle(&self, st: &mut ObserverState, direction: f32, speed_rad_s: f32) {
        let (d, q) = (direction * st.e_dq.d, direction * st.e_dq.q);
        let (ds, qs) = (direction * st.e_dq_slow.d, direction * st.e_dq_slow.q);
        let fast = libm::atan2f(d, q);
        let slow = libm::atan2f(ds, qs);
        let e2 = d * d + q * q;
        let swing = fast - slow;
        self.slow.update(&mut st.swing_power_rad2, swing * swing);
        let noise = self.fast_noise_gain * st.residual_power_v2 / crate::at_least(e2, 1e-12);
        st.fast_weight = crate::bound(1.0 - noise / crate::at_least(st.swing_power_rad2, 1e-12), 0.0, 1.0);
        // Weak back-EMF at low speed: shrink towards the patent's law (δ = 0).
        let w = e2 / (e2 + self.e_floor_v * self.e_floor_v);
        // `--cfg stepdamp_ablate_load_angle` (scripts/ablation.sh only, never a drive):
        // everything else runs, but the compensation is evaluated at θ_cmd.
        st.delta_rad = if cfg!(stepdamp_ablate_load_angle) { 0.0 } else { w * (slow + st.fast_weight * swing) };
        // Gate on the back-EMF the command implies (a transient |ê| at a low command
        // speed would make the ratio explode), and bound each sample.
        let speed = speed_rad_s.abs();
        if self.km * speed > KM_MIN_EMF_FLOORS * self.e_floor_v {
            let ratio = crate::bound(libm::sqrtf(e2) / speed, 0.5 * self.km, 2.0 * self.km);
            self.km_filter.update(&mut st.km_hat, ratio);
        }
    }

    /// The estimate's lead ([`ObserverState::delta_lead_rad`]) from its filtered change,
    /// within ±[`LEAD_LIMIT_RAD`]. At standstill (`δ̂` forced to 0) and in the first period
    /// running or after a reversal (`direction`, ±1 or 0) it is 0 and the history restarts,
    /// so neither a stop, a start nor a reversal is read as a swing; a change across ±π (an
    /// estimate that wrapped) is taken the short way round.
    #[inline(always)]
    fn track_lead(&self, st: &mut ObserverState, direction: f32) {
        if direction == 0.0 || direction != st.lead_direction {
            // A stop, a start or a reversal: no history, so no rate yet.
            st.lead_direction = direction;
            st.delta_prev_rad = st.delta_rad;
            st.delta_rate_rad = 0.0;
            st.delta_lead_rad = 0.0;
            return;
        }
        let mut change = st.delta_rad - st.delta_prev_rad;
        if change > core::f32::consts::PI {
            change -= core::f32::consts::TAU;
        } else if change < -core::f32::consts::PI {
            change += core::f32::consts::TAU;
        }
        self.rate_filter.update(&mut st.delta_rate_rad, change);
        st.delta_prev_rad = st.delta_rad;
        st.delta_lead_rad = crate::bound(self.lag_periods * st.delta_rate_rad, -LEAD_LIMIT_RAD, LEAD_LIMIT_RAD);
    }

    /// Restarts the filters and the histories (a broken sample or voltage history), but
    /// keeps what was learnt of the motor if it is sound: the standstill trim of `R̂` cannot
    /// be redone while the motor runs. An unsound `R̂` or `K̂m` falls back to the configured
    /// value.
    pub fn restart(&self, st: &mut ObserverState) {
        let keep = |x: f32, nominal: f32| if x.is_finite() && x > 0.0 { x } else { nominal };
        *st = ObserverState {
            r_hat_ohm: keep(st.r_hat_ohm, self.r_ohm),
            km_hat: keep(st.km_hat, self.km),
            ..ObserverState::default()
        };
    }

    /// Records the voltage computed in this period (after limiting) and the current
    /// command in the `θc` frame.
    #[inline]
    pub fn record(&self, st: &mut ObserverState, v: Ab, i_cmd: Dq) {
        st.voltage_history[1] = st.voltage_history[0];
        st.voltage_history[0] = v;
        let prev = st.command_history[0];
        let change = (i_cmd.d - prev.d).abs() + (i_cmd.q - prev.q).abs();
        // A change within float rounding of the command is no change; NaN is one.
        let still = change <= 1e-6 * (i_cmd.d.abs() + i_cmd.q.abs());
        st.command_steady_periods = if still { st.command_steady_periods.saturating_add(1) } else { 0 };
        st.command_history[1] = st.command_history[0];
        st.command_history[0] = i_cmd;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use core::f32::consts::TAU;

    const R: f32 = 0.9;
    const L: f32 = 2.5e-3;
    const KM: f32 = 0.3;
    const TS: f32 = 5e-5;

    fn observer(r: f32, km: f32) -> LoadAngleObserver {
        LoadAngleObserver::new(&ObserverSettings {
            resistance_ohm: r,
            inductance_h: L,
            km_nm_per_a: km,
            period_s: TS,
            bandwidth_hz: 500.0,
            emf_floor_v: 0.02 * r * 1.9,
            delay_periods: 0,
            current_loop_bandwidth_hz: 1500.0,
        })
    }

    /// The inputs of one period: current `i`, command angle `th`, advance `dth`, speed `w`.
    fn input(i: Ab, th: f32, dth: f32, w: f32) -> ObserverInput {
        let (sin, cos) = libm::sincosf(th);
        ObserverInput { current: i, sin, cos, dtheta_e_rad: dth, speed_rad_s: w }
    }

    fn rot(th: f32, x: Dq) -> Ab {
        let (s, c) = libm::sincosf(th);
        Ab { a: x.d * c - x.q * s, b: x.d * s + x.q * c }
    }

    /// Steady state in the command frame: constant i_dq, rotor `delta` behind at speed `w`;
    /// the voltages the winding equations require.
    fn run(obs: &LoadAngleObserver, st: &mut ObserverState, w: f32, delta: f32, r_true: f32, n: usize) {
        run_with_emf_lead(obs, st, w, delta, 0.0, r_true, n);
    }

    /// As [`run`], with a back-EMF turned `lead` rad off the rotor's q axis towards +d (a
    /// real motor's: docs/design.md#real-motors-flux-harmonics).
    fn run_with_emf_lead(
        obs: &LoadAngleObserver,
        st: &mut ObserverState,
        w: f32,
        delta: f32,
        lead: f32,
        r_true: f32,
        n: usize,
    ) {
        let i = Dq { d: 1.9, q: 0.0 };
        let we = 50.0 * w;
        let dth = we * TS;
        let mut th = 0.0f32;
        for _ in 0..n {
            obs.update(st, &input(rot(th, i), th, dth, w));
            // Voltage for the coming period, in the frame at its middle.
            let e = Dq { d: KM * w * libm::sinf(delta + lead), q: KM * w * libm::cosf(delta + lead) };
            let v = Dq { d: r_true * i.d + e.d - we * L * i.q, q: r_true * i.q + e.q + we * L * i.d };
            obs.record(st, rot(th + 0.5 * dth, v), i);
            th = (th + dth) % TAU;
        }
    }

    #[test]
    fn recovers_the_load_angle_from_back_emf() {
        for (w, delta) in [(5.0, 0.05), (20.0, 0.3), (-8.0, 0.2)] {
            let obs = observer(R, KM);
            let mut st = ObserverState::default();
            run(&obs, &mut st, w, delta, R, 20_000);
            assert!((st.delta_rad - delta).abs() < 0.01, "w {w}: {} vs {delta}", st.delta_rad);
        }
    }

    /// A back-EMF turned `ε` off the rotor's q axis towards +d reads as a load angle `δ + ε`;
    /// with `emf_angle_error_rad = ε` the observer turns it back and reads `δ` (the field's
    /// sign; the law's formula for `ε` is docs/design.md#real-motors-flux-harmonics).
    #[test]
    fn a_back_emf_lead_is_turned_back_by_the_emf_angle_error() {
        let (w, delta, lead) = (10.0, 0.2, 0.08);
        let obs = observer(R, KM);
        let mut plain = ObserverState::default();
        run_with_emf_lead(&obs, &mut plain, w, delta, lead, R, 20_000);
        assert!((plain.delta_rad - (delta + lead)).abs() < 0.01, "uncorrected {}", plain.delta_rad);
        let mut turned = ObserverState { emf_angle_error_rad: lead, ..ObserverState::default() };
        run_with_emf_lead(&obs, &mut turned, w, delta, lead, R, 20_000);
        assert_eq!(turned.emf_angle_error_rad, lead, "the observer keeps the law's value");
        assert!((turned.delta_rad - delta).abs() < 0.01, "corrected {}", turned.delta_rad);
    }

    /// A rotor swinging at `f_hz` around a load angle of 0.2 rad, 0.05 rad deep: the rms
    /// error of `δ̂` and of `δ̂ + lead` against the load angle one period ago (the estimate's
    /// back-EMF is the last period's), over the last 0.1 s of 0.3 s.
    fn swing_errors(f_hz: f32) -> (f32, f32) {
        let obs = observer(R, KM);
        let mut st = ObserverState::default();
        let (w, i) = (10.0, Dq { d: 1.9, q: 0.0 });
        let (we, mut th) = (50.0 * w, 0.0f32);
        let delta = |n: usize| 0.2 + 0.05 * libm::sinf(TAU * f_hz * n as f32 * TS);
        let (mut plain, mut led, mut count) = (0.0f32, 0.0f32, 0.0f32);
        for n in 0..6_000 {
            obs.update(&mut st, &input(rot(th, i), th, we * TS, w));
            if n >= 4_000 {
                let truth = delta(n - 1);
                plain += (st.delta_rad - truth).powi(2);
                led += (st.delta_rad + st.delta_lead_rad - truth).powi(2);
                count += 1.0;
            }
            let d = delta(n);
            let e = Dq { d: KM * w * libm::sinf(d), q: KM * w * libm::cosf(d) };
            let v = Dq { d: R * i.d + e.d, q: e.q + we * L * i.d };
            obs.record(&mut st, rot(th + 0.5 * we * TS, v), i);
            th = (th + we * TS) % TAU;
        }
        (libm::sqrtf(plain / count), libm::sqrtf(led / count))
    }

    #[test]
    fn the_lead_takes_the_fast_filters_delay_off_a_swinging_load_angle() {
        // At 110 Hz the 500 Hz filter lags 0.22 rad: 0.0075 rad rms of a 0.05 rad swing. The
        // lead must take most of it off, at the parametric resonance of motor 0 of the
        // independent family (110 Hz) and at the family's fastest (200 Hz). Measured: 23 % and
        // 15 % of it remain.
        for f in [110.0, 200.0] {
            let (plain, led) = swing_errors(f);
            assert!(plain > 0.006, "{f} Hz: the filter's delay is only {plain} rad: the test proves nothing");
            assert!(led < 0.3 * plain, "{f} Hz: rms error {led} rad with the lead, {plain} without");
        }
    }

    #[test]
    fn a_stop_and_a_restart_are_not_read_as_a_swing() {
        let obs = observer(R, KM);
        let mut st = ObserverState::default();
        run(&obs, &mut st, 10.0, 0.3, R, 20_000);
        assert!(st.delta_lead_rad.abs() < 1e-3, "steady: {}", st.delta_lead_rad);
        // δ̂ falls from 0.3 to 0 at the stop: without the reset that was a lead of −0.5 rad.
        run(&obs, &mut st, 0.0, 0.0, R, 3);
        assert_eq!((st.delta_rad, st.delta_lead_rad), (0.0, 0.0));
        // The filters still hold the running back-EMF: δ̂ is back near 0.3 in one period.
        run(&obs, &mut st, 10.0, 0.3, R, 1);
        assert!(st.delta_rad > 0.2, "{}", st.delta_rad);
        assert_eq!(st.delta_lead_rad, 0.0, "the first period running has no rate");
        run(&obs, &mut st, 10.0, 0.3, R, 200);
        assert!(st.delta_lead_rad.abs() < 0.01, "{}", st.delta_lead_rad);
    }

    #[test]
    fn a_reversal_without_a_standstill_period_is_not_read_as_a_swing() {
        let obs = observer(R, KM);
        let mut st = ObserverState { lead_direction: 1.0, delta_prev_rad: 0.3, delta_rad: 0.3, ..Default::default() };
        obs.track_lead(&mut st, 1.0);
        assert_eq!(st.delta_lead_rad, 0.0);
        // The speed's sign flips between two periods: δ̂ jumps, and that is no delay.
        st.delta_rad = -0.3;
        obs.track_lead(&mut st, -1.0);
        assert_eq!((st.delta_lead_rad, st.delta_rate_rad), (0.0, 0.0));
        obs.track_lead(&mut st, -1.0);
        assert_eq!(st.delta_lead_rad, 0.0, "steady in the new direction");
    }

    #[test]
    fn the_lead_takes_a_wrap_the_short_way_and_stays_bounded() {
        let obs = observer(R, KM);
        let mut st = ObserverState { lead_direction: 1.0, delta_prev_rad: 3.1, delta_rad: -3.1, ..Default::default() };
        obs.track_lead(&mut st, 1.0);
        // +0.083 rad the short way round, not −6.2 rad.
        assert!(st.delta_rate_rad > 0.0 && st.delta_rate_rad < 0.083, "{}", st.delta_rate_rad);
        // A jump of a radian (a slip) leads by at most the bound.
        let mut st = ObserverState { lead_direction: 1.0, delta_prev_rad: 0.0, delta_rad: 1.0, ..Default::default() };
        obs.track_lead(&mut st, 1.0);
        assert_eq!(st.delta_lead_rad, LEAD_LIMIT_RAD);
        st.delta_rad = -1.0;
        obs.track_lead(&mut st, 1.0);
        obs.track_lead(&mut st, 1.0);
        assert_eq!(st.delta_lead_rad, -LEAD_LIMIT_RAD);
    }

    #[test]
    fn the_ablation_build_forces_only_the_load_angle_to_zero() {
        // `--cfg stepdamp_ablate_load_angle` (scripts/ablation.sh): δ̂ = 0, but the rest of
        // the observer (here K̂m) runs as in the normal build.
        let obs = observer(R, 0.8 * KM);
        let mut st = ObserverState::default();
        run(&obs, &mut st, 20.0, 0.3, R, 20_000);
        if cfg!(stepdamp_ablate_load_angle) {
            assert_eq!(st.delta_rad, 0.0);
        } else {
            assert!((st.delta_rad - 0.3).abs() < 0.01, "{}", st.delta_rad);
        }
        assert!((st.km_hat - KM).abs() < 0.01 * KM, "{}", st.km_hat);
    }

    #[test]
    fn trims_a_20_percent_resistance_error_at_standstill() {
        let obs = observer(1.2 * R, KM);
        let mut st = ObserverState::default();
        run(&obs, &mut st, 0.0, 0.0, R, 1_000);
        assert!((st.r_hat_ohm - R).abs() < 0.001 * R, "{}", st.r_hat_ohm);
    }

    #[test]
    fn sensor_noise_in_a_closed_current_loop_does_not_bias_the_resistance_trim() {
        // A PI current loop (Kp = L·ωc, Ki = R·ωc, 1500 Hz) holds 1.9 A at standstill with
        // 20 mA of sensor noise on each axis: its reaction to the noise is in the voltage,
        // correlated with the samples. R̂ starts 10 % high and must settle on R.
        let obs = observer(1.1 * R, KM);
        let mut st = ObserverState::default();
        let wc = TAU * 1500.0;
        let (kp, ki_ts) = (L * wc, R * wc * TS);
        let cmd = Dq { d: 1.9, q: 0.0 };
        let (mut i, mut integ) = (Dq { d: 0.0, q: 0.0 }, Dq { d: 0.0, q: 0.0 });
        // xorshift64*; the sum of 12 uniforms is close enough to a normal of σ 1.
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut noise = || {
            let mut sum = -6.0f32;
            for _ in 0..12 {
                x ^= x >> 12;
                x ^= x << 25;
                x ^= x >> 27;
                sum += (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32;
            }
            0.02 * sum
        };
        let (mut sum, mut worst, mut count) = (0.0f32, 0.0f32, 0.0f32);
        for n in 0..40_000 {
            let meas = Dq { d: i.d + noise(), q: i.q + noise() };
            obs.update(&mut st, &input(rot(0.0, meas), 0.0, 0.0, 0.0));
            let e = Dq { d: cmd.d - meas.d, q: cmd.q - meas.q };
            integ = Dq { d: integ.d + ki_ts * e.d, q: integ.q + ki_ts * e.q };
            let v = Dq { d: kp * e.d + integ.d, q: kp * e.q + integ.q };
            obs.record(&mut st, rot(0.0, v), cmd);
            i = Dq { d: i.d + (v.d - R * i.d) * TS / L, q: i.q + (v.q - R * i.q) * TS / L };
            // After 0.5 s: R̂ settled.
            if n >= 10_000 {
                sum += st.r_hat_ohm - R;
                worst = worst.max((st.r_hat_ohm - R).abs());
                count += 1.0;
            }
        }
        let mean = sum / count;
        // 0.3 % of R is 5 mV of back-EMF at 1.9 A: 0.004 rad of load angle at the first
        // resonance of the patent motor (1.27 V).
        assert!(mean.abs() < 0.003 * R, "R̂ biased by {:+.3} % by sensor noise", 100.0 * mean / R);
        assert!(worst < 0.01 * R, "R̂ wanders {:.2} % with sensor noise", 100.0 * worst / R);
    }

    #[test]
    fn measures_the_torque_constant_from_back_emf_magnitude() {
        let obs = observer(R, 0.8 * KM);
        let mut st = ObserverState::default();
        run(&obs, &mut st, 20.0, 0.1, R, 20_000);
        assert!((st.km_hat - KM).abs() < 0.01 * KM, "{}", st.km_hat);
        assert!((obs.km_correction(&st) - 0.8).abs() < 0.01);
    }

    #[test]
    fn a_restart_keeps_the_trimmed_resistance_and_applies_no_km_correction() {
        let obs = observer(1.2 * R, KM);
        let mut st = ObserverState::default();
        run(&obs, &mut st, 0.0, 0.0, R, 1_000);
        assert!((st.r_hat_ohm - R).abs() < 0.001 * R, "{}", st.r_hat_ohm);
        obs.update(&mut st, &input(Ab { a: f32::NAN, b: 0.0 }, 0.0, 0.0, 0.0));
        assert!((st.r_hat_ohm - R).abs() < 0.001 * R, "restart lost R̂: {}", st.r_hat_ohm);
        assert_eq!(obs.km_correction(&st), 1.0);
        assert_eq!(obs.km_correction(&ObserverState::default()), 1.0);
    }

    #[test]
    fn a_rotor_settling_after_a_stop_does_not_corrupt_the_resistance_trim() {
        // The command is at standstill, but the rotor still creeps into place, 0.5 rad/s
        // decaying over 50 ms, 0.2 rad behind: its back-EMF, mostly across the current,
        // must not be read as resistance error.
        let obs = observer(R, KM);
        let mut st = ObserverState::default();
        // 0.5 s at standstill first: the power-on step of the current must have left the
        // noise tracker (5 Hz).
        run(&obs, &mut st, 0.0, 0.0, R, 10_000);
        let i = Dq { d: 1.9, q: 0.0 };
        let mut worst = 0.0f32;
        for n in 0..4_000 {
            let w = 0.5 * libm::expf(-(n as f32) * TS / 0.05);
            obs.update(&mut st, &input(rot(0.0, i), 0.0, 0.0, 0.0));
            let e = Dq { d: KM * w * libm::sinf(0.2), q: KM * w * libm::cosf(0.2) };
            obs.record(&mut st, rot(0.0, Dq { d: R * i.d + e.d, q: e.q }), i);
            worst = worst.max((st.r_hat_ohm - R).abs());
        }
        assert!(worst < 0.01 * R, "R̂ off by {:.2} % while the rotor settled", 100.0 * worst / R);
    }

    #[test]
    fn non_finite_samples_restart_the_observer_instead_of_poisoning_it() {
        let obs = observer(R, KM);
        let mut st = ObserverState::default();
        run(&obs, &mut st, 5.0, 0.05, R, 100);
        obs.update(&mut st, &input(Ab { a: f32::NAN, b: 0.0 }, 0.0, 0.01, 5.0));
        assert!(st.delta_rad.is_finite() && st.km_hat.is_finite() && st.r_hat_ohm.is_finite());
        run(&obs, &mut st, 5.0, 0.05, R, 20_000);
        assert!((st.delta_rad - 0.05).abs() < 0.01);
    }
}
