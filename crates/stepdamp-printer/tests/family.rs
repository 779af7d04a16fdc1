//! The accelerometer route on a family of random simulated printers, both directions
//! (`docs/accelerometer.md#a-family-of-simulated-printers`).
//!
//! For each printer ([`family_printer`]) and each direction (`R < 0`: the forward table;
//! `R > 0`: the backward table), as a user with the plan of `stepdamp identify plan --accel`
//! would do it (`plan_captures`, trials from the user's model, not the printer's motor):
//!
//! 1. The speed: a planned baseline at 2 rev/s and one at [`FASTER_SPEED_REV_S`], each way;
//!    a speed *clips* if one reaches the sensor's ±2 g in its analysed window ([`clips`]).
//!    Harmonic 1 runs at the faster speed, 2 and 4 at the planned one, each at the other if
//!    its own clips and the other does not.
//! 2. For each harmonic of [`HARMONICS`], largest response first ([`order`]), the first step
//!    ([`first_step`]): the baseline, averaged over as many captures as its size over the
//!    noise asks ([`repeats`]); the planned trial (a second, smaller trial if it moved the
//!    response by more than [`MAX_TRIAL_EFFECT`] times itself); `influence`; the cancelling
//!    shift added to the item in use (scaled down if the table would pass ±127, [`put`]);
//!    a capture with it.
//! 3. Once every harmonic has its first correction, the second step ([`second_step`]): the
//!    response with the whole table; only if it is short of [`TARGET_DB`] and no second trial
//!    was taken, one Newton step with the secant influence, kept if it measures lower. At
//!    one current, at most two captures with a trial or a Newton step per harmonic.
//! 4. Where the table that would cancel what was measured passes ±127 (`Route::wanted`), the
//!    route again from an empty table at the run current where the measured tables say it
//!    fits (`TableVsCurrent`, the advice `accel refine` prints), or [`BLIND_RAISE`] higher
//!    where they show none; at most [`MAX_CURRENT_RAISES`] times (each with its own trials).
//!
//! The score compares the planned baseline with no correction and with the final table, at
//! the current the route ends at, each measured with fresh noise seeds (captures the route
//! did not use), averaged as often as the route averaged that harmonic, through the sensor
//! without its ±2 g clipping and 10-bit steps (the head's vibration, not the sensor's).

use stepdamp_accel::influence::{harmonic_response, influence, table_item, table_shift};
use stepdamp_accel::plan::{CapturePlanOptions, MAX_TRIAL_MAG, plan_captures};
use stepdamp_accel::{AccelCapture, Axis, Complex, Gcode, Response, TrialSweep, read_captures};
use stepdamp_export::Correction;
use stepdamp_export::prusa::headroom::{lowest_fitting_current_a, whole_ma_rms_at_or_above};
use stepdamp_export::prusa::measured::{MeasuredTable, TableVsCurrent};
use stepdamp_export::prusa::{Firmware, SHIFT_LIMIT, Spectrum, fit};
use stepdamp_printer::printer::LSB_10_BIT_2G;
use stepdamp_printer::{SimulatedPrinter, family_printer};
use stepdamp_sim::Profile;

/// The harmonics corrected: the detent's orders 4, 2 and 1, which the flux harmonics'
/// ripple (orders 2 and 4) and the phase imbalance (order 2) add to.
const HARMONICS: [u32; 3] = [4, 2, 1];
/// The reduction asked of every harmonic and direction (dB).
const TARGET_DB: f64 = 20.0;
/// Electrical periods per lock-in block.
const PERIODS_PER_BLOCK: u32 = 20;
/// The response's size over its noise that a measurement is averaged to reach ([`repeats`]).
const SNR_K: f64 = 25.0;
/// The largest change of the response a planned trial may make, in units of the baseline
/// response: the trial is the size of the model's correction, which changes it by about its
/// own size; more is a rotor out of its linear range or a model far off ([`first_step`]).
const MAX_TRIAL_EFFECT: f64 = 4.0;
/// The second trial's size against the first, after a trial out of the linear range.
const SECOND_TRIAL_FACTOR: f64 = 0.25;
/// The speed of harmonic 1's captures, and of every capture when the planned one does not
/// repeat (rev/s): the electrical frequency at 130 Hz, 30 % above the planned 100 Hz;
/// harmonic 4 then at 520 Hz, inside the plan's band (0.4 of 1344 Hz).
const FASTER_SPEED_REV_S: f64 = 2.6;
/// The most captures averaged per measurement.
const MAX_REPEATS: usize = 64;

/// The model the user plans with: the docs' `patent-motor-real`, not the printer's motor.
fn user_model() -> Profile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");
    Profile::from_file(std::path::Path::new(path)).unwrap()
}

/// The plan of `identify plan --accel` for harmonic `h` at `run_a` A peak: the model's
/// correction at the run current in the table's form is the trial. Returns the
/// (baseline, trial) G-codes of each direction, forward first.
fn plan(model: &Profile, h: u32, run_a: f64, max_speed_rev_s: f64) -> [(Gcode, Gcode); 2] {
    let c = Correction::from_profile(model, Some(run_a)).unwrap();
    let s = fit(&c, Firmware::V6_3_1).unwrap().correction.backward;
    let (mag, pha) = (f64::from(s.mag[h as usize]), f64::from(s.pha[h as usize]));
    let o = CapturePlanOptions {
        harmonics: vec![(h, (mag > 0.0).then_some((mag, pha)))],
        max_speed_rev_s,
        ..CapturePlanOptions::new(Axis::X, model.motor.pole_pairs)
    };
    let g: Vec<Gcode> = plan_captures(&o).unwrap().captures.iter().map(|c| c.gcode).collect();
    [(g[0], g[1]), (g[2], g[3])]
}

/// A printer and the noise seeds it has used.
struct Bench {
    printer: SimulatedPrinter,
    next_seed: u64,
}

impl Bench {
    /// `g` captured with a fresh noise seed, read back as a host would.
    fn capture(&mut self, g: Gcode) -> AccelCapture {
        self.next_seed += 1;
        let p = SimulatedPrinter { seed: self.next_seed, ..self.printer.clone() };
        let mut v = read_captures(p.capture(&g).unwrap().as_bytes(), "family").unwrap();
        assert_eq!(v.len(), 1);
        v.remove(0).with_gcode(g)
    }

    fn response(&self, c: &AccelCapture, h: u32) -> Response {
        harmonic_response(c, &self.printer.reconstruction(), h, PERIODS_PER_BLOCK).unwrap()
    }

    /// The table of `g`'s direction (`R > 0`: backward).
    fn table(&mut self, g: Gcode) -> &mut Spectrum {
        let c = &mut self.printer.correction;
        if g.phase_direction() < 0.0 { &mut c.backward } else { &mut c.forward }
    }

    /// Item `h` of `g`'s table as a shift phasor (rad).
    fn item(&mut self, g: Gcode, h: u32) -> Complex {
        let scale = self.printer.correction.firmware.scale();
        let s = self.table(g);
        table_shift(f64::from(s.mag[h as usize]), f64::from(s.pha[h as usize]), scale)
    }

    fn set_item(&mut self, g: Gcode, h: u32, u: Complex) {
        let (mag, pha) = table_item(u, self.printer.correction.firmware.scale());
        let s = self.table(g);
        s.mag[h as usize] = mag as f32;
        s.pha[h as usize] = pha as f32;
    }
}

/// The mean of responses of the same harmonic, speed and direction; the 95 % radius of the
/// mean, `√(Σ r_k²)/N` (independent noise).
fn mean(ys: &[Response]) -> Response {
    let n = ys.len() as f64;
    let value = ys.iter().fold(Complex::default(), |s, y| s + y.value).scale(1.0 / n);
    let radius95 = ys.iter().map(|y| y.radius95 * y.radius95).sum::<f64>().sqrt() / n;
    Response { value, radius95, ..ys[0] }
}

/// What the route did for one harmonic and direction.
struct Route {
    /// The harmonic.
    h: u32,
    /// The planned baseline `M973` (no trial) of this harmonic and direction.
    base: Gcode,
    /// Captures averaged per measurement ([`repeats`]).
    repeats: usize,
    /// Trial settings captured (an `M973` with a known trial): the planned one and a second
    /// after a jump or within the noise.
    trials: usize,
    /// Whether the second step (a Newton step, no trial) was taken.
    newton: bool,
    /// Item `h` of the table before the route (rad, as a shift phasor).
    in_use: Complex,
    /// The route's own baseline.
    y0: Response,
    /// The shift in the table now (on top of `in_use`) and the response measured with it.
    now: (Complex, Response),
    /// The secant influence through the baseline and the first correction (m/s² per rad).
    secant: Complex,
    /// The trial's influence coefficient (m/s² per rad).
    influence: Complex,
    /// The sizes of the trial's shift and of the first correction's (rad): the larger one
    /// defines its coefficient better ([`Route::wanted`]).
    sizes: (f64, f64),
    /// The baseline and each correction's response, as measured (m/s²).
    steps: Vec<f64>,
    /// Whether a shift had to be scaled down to keep the table within ±127.
    table_full: bool,
}

/// How many captures a measurement of a response `y0` with a single capture's 95 % radius
/// `r0` averages: `⌈(K·r0/|y0|)²⌉` with `K` = [`SNR_K`], at most [`MAX_REPEATS`]. With it
/// the noise of the averaged response is at most `|y0|/K` (95 %): a residual 20 dB below
/// `y0` is measured to within a quarter of itself.
fn repeats(y0: &Response) -> usize {
    let n = (SNR_K * y0.radius95 / y0.value.abs()).powi(2).ceil();
    (n as usize).clamp(1, MAX_REPEATS)
}

/// `g` measured `n` times (fresh noise each), harmonic `h`, averaged.
fn measure(b: &mut Bench, g: Gcode, h: u32, n: usize) -> Response {
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
fn measure_trial(b: &mut Bench, g: Gcode, h: u32, y0: &Response, n: usize) -> (Response, usize) {
    let first = measure(b, g, h, 1);
    let needed = repeats(&Response { value: first.value - y0.value, ..first });
    let more: Vec<Response> = (1..needed.max(n)).map(|_| measure(b, g, h, 1)).collect();
    (mean(&[&[first][..], &more].concat()), needed)
}

/// Puts `in_use + shift` as item `h` of `g`'s table, the shift scaled down (bisection) if the
/// table would pass the firmware's ±[`SHIFT_LIMIT`] (it would wrap on the chip); returns the
/// shift written and whether it was scaled.
fn put(b: &mut Bench, g: Gcode, h: u32, in_use: Complex, shift: Complex) -> (Complex, bool) {
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
fn first_step(b: &mut Bench, h: u32, (base, trial): (Gcode, Gcode)) -> Route {
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

impl Route {
    /// The item that would cancel the last response, unscaled: the item in use plus the shift
    /// now, less the last response over an influence: the secant's, through the first
    /// correction, where that correction is at least [`SECANT_SHIFT_SHARE`] of the trial's
    /// size, else the trial's. A smaller shift is the more linear one (printer 15's harmonic 4:
    /// 5.5 m/s² per rad through a 0.024 rad correction, 0.8 through the 0.12 rad trial), but
    /// a correction scaled to almost nothing to fit a full table gives a secant of noise
    /// (printer 29's: 1.2·10⁻⁵ rad).
    fn wanted(&self) -> Complex {
        self.in_use + self.now.0 - self.now.1.value / self.best_influence()
    }

    /// The influence [`Route::wanted`] uses (m/s² per rad): the secant's or the trial's.
    fn best_influence(&self) -> Complex {
        let secant_ok =
            self.secant.is_finite() && self.secant.abs() > 0.0 && self.sizes.1 >= SECANT_SHIFT_SHARE * self.sizes.0;
        if secant_ok { self.secant } else { self.influence }
    }
}

/// The second step, once every harmonic of both directions has its first correction: the
/// response with the whole table; if it is short of [`TARGET_DB`] below the baseline (its 95 %
/// disc included) and the route has a trial left, the Newton step with the secant influence
/// (`U₂ = U₁ − Y/C`), kept if it measures lower.
fn second_step(b: &mut Bench, r: &mut Route) {
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

/// Whether a capture of `base` reaches the accelerometer's full scale (±2 g, the 10-bit
/// counts −512 and 511) in its analysed window (the markers clip on every printer): its
/// responses are then not the head's.
fn clips(b: &mut Bench, base: Gcode) -> bool {
    let full = 511.0 * LSB_10_BIT_2G - 0.5 * LSB_10_BIT_2G;
    let c = b.capture(base);
    let t = c.annotations.times;
    let fs = c.annotations.sampling_freq_hz;
    let window = (t.signal_start * fs) as usize..(t.signal_end * fs) as usize;
    c.samples[window].iter().any(|y| y.abs() >= full)
}

/// The harmonics of `HARMONICS` in the order to correct them in the direction of `base`: the
/// largest response first (one capture without a trial), so that the smaller ones are
/// measured once the large rotor motion that mixes harmonics is gone.
fn order(b: &mut Bench, base: Gcode) -> Vec<usize> {
    let c = b.capture(base);
    let size: Vec<f64> = HARMONICS.iter().map(|&h| b.response(&c, h).value.abs()).collect();
    let mut k: Vec<usize> = (0..HARMONICS.len()).collect();
    k.sort_by(|&i, &j| size[j].total_cmp(&size[i]));
    k
}

/// The rotor's own resonance on the magnetic stiffness `Km·I·Nr` with `J + m·r²` (Hz).
fn rotor_hz(p: &SimulatedPrinter) -> f64 {
    let m = &p.profile.motor;
    let k = m.km_nm_per_a * p.run_current_a * f64::from(m.pole_pairs);
    (k / (m.inertia_kg_m2 + p.head.reflected_inertia_kg_m2())).sqrt() / std::f64::consts::TAU
}

/// The route at one run current: the plans, the routes, the printer before and after.
struct AtCurrent {
    plans: Vec<[(Gcode, Gcode); 2]>,
    routes: Vec<(usize, usize, Route)>,
    untouched: SimulatedPrinter,
    corrected: SimulatedPrinter,
    /// The next noise seed: the captures after the route's have noise it did not use.
    next_seed: u64,
}

impl AtCurrent {
    /// Whether the table that would cancel what was measured fits.
    fn fits(&self) -> bool {
        let w = self.wanted();
        TableVsCurrent::fit(&[w]).unwrap().fits_at(w.peak_a)
    }

    /// The table that would cancel every harmonic as measured, unscaled ([`Route::wanted`]).
    fn wanted(&self) -> MeasuredTable {
        let mut table = self.corrected.correction;
        let scale = table.firmware.scale();
        for (dir, _, r) in &self.routes {
            let s = if *dir == 0 { &mut table.forward } else { &mut table.backward };
            let (mag, pha) = table_item(r.wanted(), scale);
            s.mag[r.h as usize] = mag as f32;
            s.pha[r.h as usize] = pha as f32;
        }
        MeasuredTable { peak_a: self.corrected.run_current_a, table }
    }
}

/// The route on `printer` at its run current, both directions, every harmonic, its noise
/// seeds counted on from `next_seed`.
fn route_at(text: &mut String, seed: u64, printer: SimulatedPrinter, next_seed: u64) -> AtCurrent {
    use std::fmt::Write;
    let model = user_model();
    let mut b = Bench { printer, next_seed };
    let p = &b.printer;
    let _ = writeln!(
        text,
        "printer {seed}: J {:.0} g·cm², {:.3} A, pulley r {:.2} mm, carriage {:.2} kg, belt {:.0} Hz ζ {:.3}, \
         rotor on the magnetic stiffness {:.0} Hz",
        p.profile.motor.inertia_kg_m2 * 1e7,
        p.run_current_a,
        p.head.pulley_radius_m * 1e3,
        p.head.carriage_mass_kg,
        p.head.belt_hz(),
        p.head.belt_damping_ratio,
        rotor_hz(p)
    );
    let run_a = b.printer.run_current_a;
    let planned = CapturePlanOptions::new(Axis::X, 50).max_speed_rev_s;
    // A speed clips if a baseline there reaches ±2 g in either direction (a harmonic on the
    // belt mode or the rotor's resonance): its responses are not the head's.
    let mut clipped = |v: f64| plan(&model, 4, run_a, v).iter().any(|&(base, _)| clips(&mut b, base));
    let (clips_planned, clips_faster) = (clipped(planned), clipped(FASTER_SPEED_REV_S));
    // Harmonic 1 at the faster speed: at 2 rev/s it is at 100 Hz, on the rotor's own
    // resonance (52–97 Hz over the family), where its ripple swings the rotor beyond the
    // linear range. Each harmonic at its own speed unless that one clips and the other not.
    let speed = |h: u32| {
        let (first, other, clips_first, clips_other) = if h == 1 {
            (FASTER_SPEED_REV_S, planned, clips_faster, clips_planned)
        } else {
            (planned, FASTER_SPEED_REV_S, clips_planned, clips_faster)
        };
        if clips_first && !clips_other { other } else { first }
    };
    let plans: Vec<_> = HARMONICS.iter().map(|&h| plan(&model, h, run_a, speed(h))).collect();
    let clip_note =
        format!(" (clips at ±2 g: {planned} rev/s {clips_planned}, {FASTER_SPEED_REV_S} rev/s {clips_faster})");
    let speeds: Vec<String> = plans.iter().map(|p| p[0].0.to_string()).collect();
    let _ = writeln!(text, "  baselines {speeds:?}{clip_note}");
    let untouched = b.printer.clone();
    let mut routes = Vec::new();
    for dir in [0, 1] {
        // The order from one capture at harmonic 4's planned baseline.
        for k in order(&mut b, plans[0][dir].0) {
            routes.push((dir, k, first_step(&mut b, HARMONICS[k], plans[k][dir])));
        }
    }
    // The second steps also where the table cannot hold what the first steps ask for: the
    // wanted table from the first steps alone misled the current raise (printer 27 crept
    // from 1.138 to 1.167 A and ended at 10.5 dB).
    for (_, _, r) in &mut routes {
        second_step(&mut b, r);
    }
    AtCurrent { plans, routes, untouched, corrected: b.printer, next_seed: b.next_seed }
}

/// At most this many times the route moves to a higher run current when its table is full.
const MAX_CURRENT_RAISES: usize = 4;
/// The smallest first correction, as a share of the trial, whose secant [`Route::wanted`] uses.
const SECANT_SHIFT_SHARE: f64 = 0.1;
/// The factor on the run current when the measured tables show no current up to the drive's
/// limit that fits (an influence measured off its linear range can make a wanted table
/// several times too large): the route records again that much higher.
const BLIND_RAISE: f64 = 1.25;

/// One printer: the route in both directions for every harmonic at its run current; where a
/// shift had to be scaled to fit the table, at the current where the measured tables say it
/// fits ([`TableVsCurrent`], the advice `accel refine` prints: the last two tables, in whole
/// mA of RMS as `M906` takes it), again from an empty table; then the score at the last one.
/// Returns the seed, the worst reduction (dB), whether the true motor's correction fits the
/// table at the last current (its peak within ±[`SHIFT_LIMIT`]) and a line per direction and
/// harmonic.
fn printer_score(seed: u64) -> (u64, f64, bool, String) {
    use std::fmt::Write;
    let mut text = String::new();
    let mut printer = family_printer(seed);
    let mut measured: Vec<MeasuredTable> = Vec::new();
    let mut at = route_at(&mut text, seed, printer.clone(), seed * 1000);
    // Trial settings per (direction, harmonic index) over every current.
    let mut trials: Vec<((usize, usize), usize)> = Vec::new();
    let mut count = |at: &AtCurrent| {
        for (dir, k, r) in &at.routes {
            match trials.iter_mut().find(|t| t.0 == (*dir, *k)) {
                Some(t) => t.1 += r.trials,
                None => trials.push(((*dir, *k), r.trials)),
            }
        }
    };
    count(&at);
    for _ in 0..MAX_CURRENT_RAISES {
        if at.fits() {
            break;
        }
        let wanted = at.wanted();
        measured.push(wanted);
        // The last two tables where their currents differ enough for the model, else the last.
        let n = measured.len();
        let two_apart = n >= 2 && TableVsCurrent::fit(&measured[n - 2..]).is_ok();
        let last_two = &measured[if two_apart { n - 2 } else { n - 1 }..];
        let limit = printer.profile.drive.current_limit_a;
        let next = TableVsCurrent::fit(last_two).unwrap().lowest_fitting_current_a(limit).unwrap();
        let wanted = measured.last().unwrap().table;
        let fw = wanted.firmware;
        let _ = writeln!(
            text,
            "  the measured table needs {:?} / {:?} of 127 at {:.3} A: it fits from {next:.3?} A ({} table(s))",
            wanted.forward.peak_shift(fw),
            wanted.backward.peak_shift(fw),
            printer.run_current_a,
            last_two.len()
        );
        let limit_a = printer.profile.drive.current_limit_a;
        let next = match next {
            Some(i) => i,
            None if printer.run_current_a < limit_a => (BLIND_RAISE * printer.run_current_a).min(limit_a),
            None => break,
        };
        let Some(typed) = whole_ma_rms_at_or_above(next, limit_a).unwrap() else { break };
        printer.run_current_a = typed.peak_a();
        at = route_at(&mut text, seed, printer.clone(), at.next_seed);
        count(&at);
    }
    let AtCurrent { plans, routes, untouched, corrected, next_seed } = at;
    // The score's sensor: the printer's noise and rate without its ±2 g clipping and 10-bit
    // steps. The route measured through the real one; the score is the head's vibration,
    // which a clipped capture does not show (printer 22 at 1.278 A clips at both speeds: its
    // uncorrected harmonic 4 backward read 0.44 m/s² through the real sensor, 1.58 with the
    // other harmonics corrected).
    let [untouched, corrected] = [untouched, corrected].map(|mut p| {
        p.accel.lsb_m_s2 = 0.0;
        p
    });
    let mut b = Bench { printer: corrected.clone(), next_seed };
    let fw = corrected.correction.firmware;
    let truth = fit(&Correction::from_profile(&corrected.profile, Some(corrected.run_current_a)).unwrap(), fw).unwrap();
    let _ = writeln!(
        text,
        "  peak shift forward {:?} backward {:?} (of 127); the true motor's correction needs {:.0}",
        corrected.correction.forward.peak_shift(fw),
        corrected.correction.backward.peak_shift(fw),
        truth.wanted_peak_shift
    );
    let mut worst = f64::INFINITY;
    for (dir, k, r) in routes {
        let (h, base) = (HARMONICS[k], plans[k][dir].0);
        b.printer = untouched.clone();
        let before = measure(&mut b, base, h, r.repeats);
        b.printer = corrected.clone();
        let after = measure(&mut b, base, h, r.repeats);
        let db = 20.0 * (before.value.abs() / after.value.abs()).log10();
        worst = worst.min(db);
        let name = if dir == 0 { "forward " } else { "backward" };
        let _ = writeln!(
            text,
            "  {name} H{h}: route x{} trials {}{} {:.4?}{}, score {:.4} -> {:.4} ± {:.4} m/s²: {db:.1} dB",
            r.repeats,
            trials.iter().find(|t| t.0 == (dir, k)).map_or(0, |t| t.1),
            if r.newton { " newton" } else { "" },
            r.steps,
            if r.table_full { " (table full)" } else { "" },
            before.value.abs(),
            after.value.abs(),
            after.radius95
        );
    }
    // Whether the true motor's correction fits the table at a current from the printer's own
    // up to the drive's limit: where it does, the route must find it.
    let own = family_printer(seed);
    let fits_somewhere =
        lowest_fitting_current_a(&own.profile, own.run_current_a, own.profile.drive.current_limit_a, fw).unwrap();
    let _ = writeln!(text, "  the true motor's correction fits from {fits_somewhere:.3?} A");
    (seed, worst, fits_somewhere.is_some(), text)
}

/// The worst reduction of every printer of `seeds` (dB), and whether it is asserted: the true
/// motor's correction fits the firmware's table at a current up to the drive's limit
/// (printed, one line per printer).
fn family(seeds: std::ops::RangeInclusive<u64>) -> Vec<(u64, f64, bool)> {
    let seeds: Vec<u64> = seeds.collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(seeds.len());
    let chunks: Vec<Vec<u64>> =
        (0..threads).map(|i| seeds.iter().copied().skip(i).step_by(threads).collect()).collect();
    let mut out: Vec<(u64, f64, bool, String)> = std::thread::scope(|s| {
        let handles: Vec<_> =
            chunks.iter().map(|c| s.spawn(move || c.iter().map(|&k| printer_score(k)).collect::<Vec<_>>())).collect();
        handles.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    out.sort_by_key(|o| o.0);
    for o in &out {
        print!("{}", o.3);
    }
    out.into_iter().map(|(k, db, fits, _)| (k, db, fits)).collect()
}

/// Asserts `TARGET_DB` on every printer of [`family`]'s asserted ones; prints the others.
fn assert_family(seeds: std::ops::RangeInclusive<u64>) {
    let f = family(seeds);
    let (fit, beyond): (Vec<&(u64, f64, bool)>, Vec<_>) = f.iter().partition(|o| o.2);
    let worst = fit.iter().map(|o| o.1).fold(f64::INFINITY, f64::min);
    println!(
        "worst reduction over the {} printers whose correction fits the table at a current up to the drive's \
         limit: {worst:.1} dB",
        fit.len()
    );
    println!("printers whose correction fits at no such current (not asserted): {beyond:.1?}");
    let failed: Vec<_> = fit.iter().filter(|o| o.1 < TARGET_DB).collect();
    assert!(failed.is_empty(), "below {TARGET_DB} dB: {failed:.1?}");
}

#[test]
fn family_route_lowers_every_harmonic_by_20_db_in_both_directions() {
    assert_family(1..=5);
}

/// The larger family: `cargo test --release -p stepdamp-printer --test family -- --ignored`;
/// with `FAMILY_SEED=k` in the environment, printer `k` alone.
#[test]
#[ignore = "the larger family: about a minute in release"]
fn larger_family_route_lowers_every_harmonic_by_20_db_in_both_directions() {
    if let Ok(one) = std::env::var("FAMILY_SEED") {
        let k: u64 = one.parse().unwrap();
        assert_family(k..=k);
        return;
    }
    assert_family(1..=30);
}
