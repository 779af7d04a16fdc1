//! The steps of the route for one harmonic and direction at one run current: the bench
//! that captures, the averaging, the first step with a trial or a carried influence, the
//! Newton step (the route: the module doc of `family.rs`).

use super::{
    MAX_REPEATS, MAX_TRIAL_EFFECT, PERIODS_PER_BLOCK, SECANT_SHIFT_SHARE, SECOND_TRIAL_FACTOR, SNR_K, TARGET_DB,
};
use stepdamp_accel::influence::{harmonic_response, influence, table_item, table_shift};
use stepdamp_accel::plan::MAX_TRIAL_MAG;
use stepdamp_accel::{AccelCapture, Complex, Gcode, Response, TrialSweep, read_captures};
use stepdamp_export::prusa::{SHIFT_LIMIT, Spectrum};
use stepdamp_printer::SimulatedPrinter;

/// A printer and the noise seeds it has used.
pub(super) struct Bench {
    pub(super) printer: SimulatedPrinter,
    pub(super) next_seed: u64,
}

impl Bench {
    /// `g` captured with a fresh noise seed, read back as a host would.
    pub(super) fn capture(&mut self, g: Gcode) -> AccelCapture {
        self.next_seed += 1;
        let p = SimulatedPrinter { seed: self.next_seed, ..self.printer.clone() };
        let mut v = read_captures(p.capture(&g).unwrap().as_bytes(), "family").unwrap();
        assert_eq!(v.len(), 1);
        v.remove(0).with_gcode(g)
    }

    pub(super) fn response(&self, c: &AccelCapture, h: u32) -> Response {
        harmonic_response(c, &self.printer.reconstruction(), h, PERIODS_PER_BLOCK).unwrap()
    }

    /// The table of `g`'s direction (`R > 0`: backward).
    pub(super) fn table(&mut self, g: Gcode) -> &mut Spectrum {
        let c = &mut self.printer.correction;
        if g.phase_direction() < 0.0 { &mut c.backward } else { &mut c.forward }
    }

    /// Item `h` of `g`'s table as a shift phasor (rad).
    pub(super) fn item(&mut self, g: Gcode, h: u32) -> Complex {
        let scale = self.printer.correction.firmware.scale();
        let s = self.table(g);
        table_shift(f64::from(s.mag[h as usize]), f64::from(s.pha[h as usize]), scale)
    }

    pub(super) fn set_item(&mut self, g: Gcode, h: u32, u: Complex) {
        let (mag, pha) = table_item(u, self.printer.correction.firmware.scale());
        let s = self.table(g);
        s.mag[h as usize] = mag as f32;
        s.pha[h as usize] = pha as f32;
    }
}

/// The mean of responses of the same harmonic, speed and direction; the 95 % radius of the
/// mean, `√(Σ r_k²)/N` (independent noise).
pub(super) fn mean(ys: &[Response]) -> Response {
    let n = ys.len() as f64;
    let value = ys.iter().fold(Complex::default(), |s, y| s + y.value).scale(1.0 / n);
    let radius95 = ys.iter().map(|y| y.radius95 * y.radius95).sum::<f64>().sqrt() / n;
    Response { value, radius95, ..ys[0] }
}

/// What the route did for one harmonic and direction.
pub(super) struct Route {
    /// The harmonic.
    pub(super) h: u32,
    /// The planned baseline `M973` (no trial) of this harmonic and direction.
    pub(super) base: Gcode,
    /// Captures averaged per measurement ([`repeats`]).
    pub(super) repeats: usize,
    /// Trial settings captured (an `M973` with a known trial): the planned one and a second
    /// after a jump or within the noise.
    pub(super) trials: usize,
    /// Whether the second step (a Newton step, no trial) was taken.
    pub(super) newton: bool,
    /// Item `h` of the table before the route (rad, as a shift phasor).
    pub(super) in_use: Complex,
    /// The route's own baseline.
    pub(super) y0: Response,
    /// The shift in the table now (on top of `in_use`) and the response measured with it.
    pub(super) now: (Complex, Response),
    /// The secant influence through the baseline and the first correction (m/s² per rad).
    pub(super) secant: Complex,
    /// The trial's influence coefficient (m/s² per rad).
    pub(super) influence: Complex,
    /// The sizes of the trial's shift and of the first correction's (rad): the larger one
    /// defines its coefficient better ([`Route::wanted`]).
    pub(super) sizes: (f64, f64),
    /// The baseline and each correction's response, as measured (m/s²).
    pub(super) steps: Vec<f64>,
    /// Whether a shift had to be scaled down to keep the table within ±127.
    pub(super) table_full: bool,
}

/// How many captures a measurement of a response `y0` with a single capture's 95 % radius
/// `r0` averages: `⌈(K·r0/|y0|)²⌉` with `K` = [`SNR_K`], at most [`MAX_REPEATS`]. With it
/// the noise of the averaged response is at most `|y0|/K` (95 %): a residual 20 dB below
/// `y0` is measured to within a quarter of itself.
pub(super) fn repeats(y0: &Response) -> usize {
    let n = (SNR_K * y0.radius95 / y0.value.abs()).powi(2).ceil();
    (n as usize).clamp(1, MAX_REPEATS)
}

/// `g` measured `n` times (fresh noise each), harmonic `h`, averaged.
pub(super) fn measure(b: &mut Bench, g: Gcode, h: u32, n: usize) -> Response {
    let ys: Vec<Response> = (0..n)
        .map(|_| {
            let c = b.capture(g);
            b.response(&c, h)
        })
        .collect();
    mean(&ys)
}

/// The trial `g` measured at least `n` times, and as often as [`repeats`] asks for the
/// change it makes to `y0` (the influence coefficient then within `1/K` of itself, 95 %);
/// returns the mean and the count that change asks for.
pub(super) fn measure_trial(b: &mut Bench, g: Gcode, h: u32, y0: &Response, n: usize) -> (Response, usize) {
    let first = measure(b, g, h, 1);
    let needed = repeats(&Response { value: first.value - y0.value, ..first });
    let more: Vec<Response> = (1..needed.max(n)).map(|_| measure(b, g, h, 1)).collect();
    (mean(&[&[first][..], &more].concat()), needed)
}

/// Puts `in_use + shift` as item `h` of `g`'s table, the shift scaled down (bisection) if the
/// table would pass the firmware's ±[`SHIFT_LIMIT`] (it would wrap on the chip); returns the
/// shift written and whether it was scaled.
pub(super) fn put(b: &mut Bench, g: Gcode, h: u32, in_use: Complex, shift: Complex) -> (Complex, bool) {
    let fw = b.printer.correction.firmware;
    let fits = |b: &mut Bench, k: f64| {
        b.set_item(g, h, in_use + shift.scale(k));
        b.table(g).peak_shift(fw).is_some_and(|p| p <= SHIFT_LIMIT)
    };
    if fits(b, 1.0) {
        return (shift, false);
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if fits(b, mid) { lo = mid } else { hi = mid }
    }
    assert!(fits(b, lo), "the table in use already passes the limit");
    (shift.scale(lo), true)
}

/// The first step for harmonic `h` in the direction of `base`: the planned baseline and
/// trial (a second, smaller trial after a jump), the cancelling shift, a capture with it.
pub(super) fn first_step(b: &mut Bench, h: u32, (base, trial): (Gcode, Gcode)) -> Route {
    let scale = b.printer.correction.firmware.scale();
    let in_use = b.item(base, h);
    let mut ys0 = vec![measure(b, base, h, 1)];
    let mut n = repeats(&ys0[0]);
    let Gcode::ParamSweep { axis, speed, revs, trial: t } = trial else { unreachable!("M973") };
    let mut trials = 0;
    let mut mag = t.mag_start;
    let (y0, y1) = loop {
        ys0.extend((ys0.len()..n).map(|_| measure(b, base, h, 1)).collect::<Vec<_>>());
        let y0 = mean(&ys0);
        let g = Gcode::ParamSweep { axis, speed, revs, trial: TrialSweep { mag_start: mag, mag_end: mag, ..t } };
        let (y1, needed) = measure_trial(b, g, h, &y0, n);
        trials += 1;
        let change = (y1.value - y0.value).abs();
        if trials == 2 {
            break (y0, y1);
        }
        if change > MAX_TRIAL_EFFECT * y0.value.abs() {
            // The trial moved the response far more than by its own size: the rotor left its
            // linear range (an open-loop resonance), or the model's correction is far larger
            // than this motor's. The second trial: a quarter of the first.
            mag *= SECOND_TRIAL_FACTOR;
        } else if change <= y0.radius95.hypot(y1.radius95) {
            // Within the noise: the second trial four times larger (at most the plan's
            // largest), both measured as often as the change asks.
            mag = (mag / SECOND_TRIAL_FACTOR).min(MAX_TRIAL_MAG);
            n = n.max(needed);
        } else {
            break (y0, y1);
        }
    };
    let inf = influence(&y0, &y1, table_shift(mag, t.pha_start, scale)).unwrap();
    let (u1, table_full) = put(b, base, h, in_use, inf.cancelling);
    let y2 = measure(b, base, h, n);
    let secant = (y2.value - y0.value) / u1;
    let steps = vec![y0.value.abs(), y2.value.abs()];
    let (influence, sizes) = (inf.coefficient, (table_shift(mag, t.pha_start, scale).abs(), u1.abs()));
    let newton = false;
    Route {
        h,
        base,
        repeats: n,
        trials,
        newton,
        in_use,
        y0,
        now: (u1, y2),
        secant,
        influence,
        sizes,
        steps,
        table_full,
    }
}

/// An influence measured at an earlier run current (m/s² per rad), to be carried to a higher
/// one in proportion to the current: the torque per rad of shift is `Km·I·cos λ`; the head's
/// response to that torque changes with the rotor's magnetic stiffness, which the secant
/// through the first correction then measures ([`second_step`]).
#[derive(Clone, Copy)]
pub(super) struct Carried {
    pub(super) dir: usize,
    pub(super) k: usize,
    pub(super) base: Gcode,
    pub(super) influence: Complex,
    pub(super) current_a: f64,
}

/// The first step at a raised current without a trial: the baseline, the shift that cancels
/// it through the carried influence `predicted`, a capture with it; the secant through the
/// two is the influence the second step uses.
pub(super) fn carried_step(b: &mut Bench, h: u32, base: Gcode, predicted: Complex) -> Route {
    let in_use = b.item(base, h);
    let first = measure(b, base, h, 1);
    let n = repeats(&first);
    let more: Vec<Response> = (1..n).map(|_| measure(b, base, h, 1)).collect();
    let y0 = mean(&[&[first][..], &more].concat());
    let wanted = -y0.value / predicted;
    let (u1, table_full) = put(b, base, h, in_use, wanted);
    let y2 = measure(b, base, h, n);
    let secant = (y2.value - y0.value) / u1;
    Route {
        h,
        base,
        repeats: n,
        trials: 0,
        newton: false,
        in_use,
        y0,
        now: (u1, y2),
        secant,
        influence: predicted,
        sizes: (wanted.abs(), u1.abs()),
        steps: vec![y0.value.abs(), y2.value.abs()],
        table_full,
    }
}

impl Route {
    /// The item that would cancel the last response, unscaled: the item in use plus the shift
    /// now, less the last response over an influence: the secant's, through the first
    /// correction, where that correction is at least [`SECANT_SHIFT_SHARE`] of the trial's
    /// size, else the trial's. A smaller shift is the more linear one (printer 15's harmonic 4:
    /// 5.5 m/s² per rad through a 0.024 rad correction, 0.8 through the 0.12 rad trial), but
    /// a correction scaled to almost nothing to fit a full table gives a secant of noise
    /// (printer 29's: 1.2·10⁻⁵ rad).
    pub(super) fn wanted(&self) -> Complex {
        self.in_use + self.now.0 - self.now.1.value / self.best_influence()
    }

    /// The influence [`Route::wanted`] uses (m/s² per rad): the secant's or the trial's.
    pub(super) fn best_influence(&self) -> Complex {
        let secant_ok =
            self.secant.is_finite() && self.secant.abs() > 0.0 && self.sizes.1 >= SECANT_SHIFT_SHARE * self.sizes.0;
        if secant_ok { self.secant } else { self.influence }
    }
}

/// The second step, once every harmonic of both directions has its first correction: the
/// response with the whole table; if it is short of [`TARGET_DB`] below the baseline (its 95 %
/// disc included) and it took at most one trial setting here, the Newton step with the secant influence
/// (`U₂ = U₁ − Y/C`), kept if it measures lower.
pub(super) fn second_step(b: &mut Bench, r: &mut Route) {
    let y = measure(b, r.base, r.h, r.repeats);
    r.now.1 = y;
    r.steps.push(y.value.abs());
    let short = 20.0 * (r.y0.value.abs() / (y.value.abs() + y.radius95)).log10() < TARGET_DB;
    if !short || r.trials >= 2 || r.newton || !r.secant.is_finite() || r.secant.abs() == 0.0 {
        return;
    }
    r.newton = true;
    let (u2, full) = put(b, r.base, r.h, r.in_use, r.now.0 - y.value / r.secant);
    r.table_full |= full;
    let y3 = measure(b, r.base, r.h, r.repeats);
    r.steps.push(y3.value.abs());
    if y3.value.abs() < y.value.abs() {
        r.now = (u2, y3);
    } else {
        b.set_item(r.base, r.h, r.in_use + r.now.0);
    }
}
