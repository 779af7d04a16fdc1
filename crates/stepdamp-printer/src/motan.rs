//! The simulated printer as a Klipper printer: its moves recorded as
//! `scripts/motan/data_logger.py` records them, a `.json.gz` log and its `.index.gz`
//! (`docs/files.md#klippers-motion-analysis-logs`), for the Klipper side of the accelerometer
//! route (`docs/accelerometer.md#klippers-motion-analysis-logs`).
//!
//! **The moves** are the simulated printer's (each a `M973`/`M974` plan, here just a move
//! shape), one after the other with [`KlipperSetup::gap_s`] of rest between them. Between two
//! moves the stepper steps slowly to the next position whose phase is the move's start
//! (`θe ≡ 0`), since every simulated move starts the rotor at electrical angle 0.
//! **The steps** are where the commanded position crosses the half-way point between two
//! microsteps (as Klipper's step generation places them), on the MCU clock
//! ([`KlipperSetup::clock_hz`]); `stepq` batches of 0.5 s (bulk_sensor.py:20).
//! **The accelerometer** is an ADXL345 as Klipper sets it up: [`ADXL345_RATE_HZ`] (times
//! the seeded rate error of [`crate::AccelModel`]), 13-bit at ±16 g, [`ADXL345_LSB_MM_S2`]
//! per count, values rounded to 6 decimals (adxl345.py:268–271), batches of 0.1 s; the
//! belt's acceleration is put on `x`/`y` as the kinematics moves the head (CoreXY: half on
//! each), with the noise of [`crate::AccelModel::noise_rms_m_s2`] on every axis and 1 g on z.

mod gzip;

use crate::printer::{PrinterError, SimulatedPrinter, Trace};
use gzip::GzLog;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::f64::consts::TAU;
use stepdamp_accel::klipper::Kinematics;
use stepdamp_accel::{Axis, Gcode};

/// Klipper's default ADXL345 rate (Hz, `rate: 3200`, adxl345.py:207).
pub const ADXL345_RATE_HZ: f64 = 3200.0;
/// One count (mm/s²): Klipper's `SCALE_XY`, 0.003774 g (adxl345.py:26–27) in full resolution
/// at ±16 g (`DATA_FORMAT` 0x0B, adxl345.py:287).
pub const ADXL345_LSB_MM_S2: f64 = 0.003774 * 9806.65;
/// The MCU position (microsteps) the log starts at.
const START_POSITION: f64 = 100_000.0;
/// The 13-bit counts' range: −4096..=4095.
const COUNTS: f64 = 4096.0;
/// Klipper's batch of accelerometer samples (s, adxl345.py:199) and of steps (bulk_sensor.py:20).
const ACCEL_BATCH_S: f64 = 0.1;
const STEP_BATCH_S: f64 = 0.5;
/// How often data_logger.py writes an index record (s of print time here; data_logger.py:9).
const INDEX_S: f64 = 5.0;

/// The Klipper side of the simulated printer.
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperSetup {
    /// `printer.kinematics`.
    pub kinematics: Kinematics,
    /// The motor moved: `stepper_x` (X, CoreXY A) or `stepper_y` (Y, CoreXY B).
    pub axis: Axis,
    /// `microsteps` (16 is the common setting).
    pub microsteps: u32,
    /// The TMC driver's `mcu_phase_offset` (0..4·microsteps).
    pub mcu_phase_offset: i64,
    /// The MCU clock (Hz, an integer: 72 MHz on an STM32F103... any).
    pub clock_hz: u64,
    /// Print time of the first move's start (s).
    pub start_s: f64,
    /// Rest before, between and after the moves (s).
    pub gap_s: f64,
}

impl Default for KlipperSetup {
    /// Cartesian, `stepper_x`, 16 microsteps, phase offset 7, 72 MHz, from 100 s, 0.5 s rests.
    fn default() -> Self {
        KlipperSetup {
            kinematics: Kinematics::Cartesian,
            axis: Axis::X,
            microsteps: 16,
            mcu_phase_offset: 7,
            clock_hz: 72_000_000,
            start_s: 100.0,
            gap_s: 0.5,
        }
    }
}

/// One accelerometer sample as written, and the commanded angle the simulation ran at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrittenSample {
    /// Print time (s), as written.
    pub t_s: f64,
    /// `x`, `y`, `z` (mm/s²), as written.
    pub xyz: [f64; 3],
    /// The simulated commanded electrical angle at `t_s` in the log's convention
    /// (`2π·(position + mcu_phase_offset)/(4·microsteps)`, rad).
    pub planned_rad: f64,
}

/// A simulated log.
#[derive(Debug, Clone)]
pub struct MotanLog {
    /// The `.json.gz` file.
    pub json_gz: Vec<u8>,
    /// The `.index.gz` file.
    pub index_gz: Vec<u8>,
    /// The samples written.
    pub samples: Vec<WrittenSample>,
    /// The steps written.
    pub steps: usize,
}

/// The commanded position (microsteps, continuous) over print time: points joined by lines.
struct Path {
    points: Vec<(f64, f64)>,
}

impl Path {
    fn at(&self, t: f64) -> f64 {
        let p = &self.points;
        let i = p.partition_point(|x| x.0 <= t);
        match (i.checked_sub(1).map(|k| p[k]), p.get(i)) {
            (Some(a), Some(b)) => a.1 + (t - a.0) * (b.1 - a.1) / (b.0 - a.0),
            (Some(a), None) => a.1,
            (None, Some(b)) => b.1,
            (None, None) => 0.0,
        }
    }
}

impl SimulatedPrinter {
    /// `moves` simulated one after the other and recorded as data_logger.py records them
    /// with `-s accelerometer:adxl345` (module doc).
    pub fn motan_log(&self, moves: &[Gcode], k: &KlipperSetup) -> Result<MotanLog, PrinterError> {
        let phases = 4 * i64::from(k.microsteps);
        if !(1..=256).contains(&k.microsteps) || !(0..phases).contains(&k.mcu_phase_offset) {
            let value = format!("{} microsteps, offset {}", k.microsteps, k.mcu_phase_offset);
            return Err(PrinterError::Parameter {
                what: "KlipperSetup",
                value,
                allowed: "1..=256 microsteps, offset in 0..4·microsteps".into(),
            });
        }
        let per_rad = phases as f64 / TAU;
        let mut path = Path { points: vec![(k.start_s - k.gap_s, START_POSITION)] };
        let mut heads: Vec<(f64, Trace)> = Vec::new();
        let mut t = k.start_s;
        for g in moves {
            let trace = self.simulate(g)?;
            // The next position with phase 0, reached slowly in the rest before the move.
            let here = path.points.last().expect("starts with one").1;
            let p0 = here + (-(here as i64 + k.mcu_phase_offset)).rem_euclid(phases) as f64;
            path.points.push((t - 0.4 * k.gap_s, here));
            path.points.push((t - 0.1 * k.gap_s, p0));
            path.points.push((t, p0));
            path.points.extend(trace.mid_s.iter().zip(&trace.planned_rad).map(|(&m, &q)| (t + m, p0 + q * per_rad)));
            let end = t + trace.period_s * trace.head_m_s2.len() as f64;
            heads.push((t, trace));
            t = end + k.gap_s;
        }
        let steps = steps_of(&path, k);
        let samples = self.accel_samples(&path, &heads, k, t)?;
        Ok(write(k, self, START_POSITION as i64, &steps, &samples))
    }

    /// The ADXL345's samples from the first rest to `end_s` (module doc).
    fn accel_samples(
        &self,
        path: &Path,
        heads: &[(f64, Trace)],
        k: &KlipperSetup,
        end_s: f64,
    ) -> Result<Vec<WrittenSample>, PrinterError> {
        let a = &self.accel;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let delta = if a.rate_spread > 0.0 { rng.random_range(-a.rate_spread..=a.rate_spread) } else { 0.0 };
        let rate = ADXL345_RATE_HZ * (1.0 + delta);
        let t0 = k.start_s - k.gap_s;
        let n = ((end_s - t0) * rate) as usize;
        let (wx, wy) = match (k.kinematics, k.axis) {
            (Kinematics::CoreXy, Axis::X) => (0.5, 0.5),
            (Kinematics::CoreXy, Axis::Y) => (0.5, -0.5),
            (Kinematics::Cartesian, Axis::X) => (1.0, 0.0),
            (Kinematics::Cartesian, Axis::Y) => (0.0, 1.0),
        };
        let phases = 4.0 * f64::from(k.microsteps);
        let mut rounded = |v: f64| {
            let noise: f64 = StandardNormal.sample(&mut rng);
            let counts =
                ((v + 1e3 * a.noise_rms_m_s2 * noise) / ADXL345_LSB_MM_S2).round().clamp(-COUNTS, COUNTS - 1.0);
            round6(counts * ADXL345_LSB_MM_S2)
        };
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let t = round6(t0 + i as f64 / rate);
            let belt = 1e3 * head_at(heads, t);
            let xyz = [rounded(wx * belt), rounded(wy * belt), rounded(9806.65)];
            let planned_rad = TAU * (path.at(t) + k.mcu_phase_offset as f64) / phases;
            out.push(WrittenSample { t_s: t, xyz, planned_rad });
        }
        Ok(out)
    }
}

/// Rounded to 6 decimals, as adxl345.py:268–271 rounds.
fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// The belt's acceleration (m/s²) at print time `t`: the move's head acceleration (given at
/// the end of each control period), 0 at rest.
fn head_at(heads: &[(f64, Trace)], t: f64) -> f64 {
    let i = heads.partition_point(|h| h.0 <= t);
    let Some((start, tr)) = i.checked_sub(1).map(|j| &heads[j]) else { return 0.0 };
    let x = (t - start) / tr.period_s - 1.0;
    if x < 0.0 {
        return 0.0;
    }
    let j = x.floor() as usize;
    match (tr.head_m_s2.get(j), tr.head_m_s2.get(j + 1)) {
        (Some(&a), Some(&b)) => a + (x - j as f64) * (b - a),
        _ => 0.0,
    }
}

/// The steps (MCU clock, position after the step) where the path crosses half-way points.
fn steps_of(path: &Path, k: &KlipperSetup) -> Vec<(u64, i64)> {
    let mut out = Vec::new();
    let p = &path.points;
    let mut n = START_POSITION as i64;
    let clock = |t: f64| ((t - (k.start_s - k.gap_s)) * k.clock_hz as f64).round() as u64;
    for w in p.windows(2) {
        let ((ta, pa), (tb, pb)) = (w[0], w[1]);
        let cross = |h: f64| ta + (h - pa) / (pb - pa) * (tb - ta);
        while pb > n as f64 + 0.5 {
            out.push((clock(cross(n as f64 + 0.5)), n + 1));
            n += 1;
        }
        while pb < n as f64 - 0.5 {
            out.push((clock(cross(n as f64 - 0.5)), n - 1));
            n -= 1;
        }
    }
    out
}

/// Both files: the opening answers, then the batches in time order, index records every
/// [`INDEX_S`].
fn write(
    k: &KlipperSetup,
    p: &SimulatedPrinter,
    start_pos: i64,
    steps: &[(u64, i64)],
    samples: &[WrittenSample],
) -> MotanLog {
    let stepper = if k.axis == Axis::X { "stepper_x" } else { "stepper_y" };
    let status = status_json(k, p, stepper);
    let subs = format!(
        r#"{{"accelerometer:adxl345":{{"header":["time","x_acceleration","y_acceleration","z_acceleration"]}},"stepq:{stepper}":{{"header":["interval","count","add"]}}}}"#
    );
    let mut log = GzLog::new();
    let mut index = GzLog::new();
    log.add(r#"{"id":"info","result":{"state":"ready","state_message":"Printer is ready"}}"#);
    log.add(&format!(r#"{{"id":"status","result":{{"eventtime":1.0,"status":{status}}}}}"#));
    log.add(&format!(
        r#"{{"id":"accelerometer:adxl345","result":{}}}"#,
        r#"{"header":["time","x_acceleration","y_acceleration","z_acceleration"]}"#
    ));
    log.add(&format!(r#"{{"id":"stepq:{stepper}","result":{{"header":["interval","count","add"]}}}}"#));
    let at = log.flush();
    index.add(&format!(r#"{{"status":{status},"subscriptions":{subs},"file_position":{at}}}"#));
    let t0 = k.start_s - k.gap_s;
    let end = samples.last().map_or(t0, |s| s.t_s);
    let (mut si, mut ai, mut next_index) = (0, 0, t0 + INDEX_S);
    let mut batch_end = t0 + ACCEL_BATCH_S;
    let mut cur = Cursor { clock: None, pos: start_pos };
    let clock_s = |c: u64| t0 + c as f64 / k.clock_hz as f64;
    let full = 4 * u32::from(p.profile.motor.pole_pairs);
    // `rotation_distance` over the microsteps of a revolution (mm).
    let step_dist = TAU * p.head.pulley_radius_m * 1e3 / f64::from(full * k.microsteps);
    while ai < samples.len() || si < steps.len() {
        let n = samples[ai..].partition_point(|s| s.t_s < batch_end);
        if n > 0 {
            log.add(&accel_json(&samples[ai..ai + n]));
            ai += n;
        }
        let step_due = (batch_end - t0) / STEP_BATCH_S;
        if (step_due - step_due.round()).abs() < 1e-9 || batch_end > end {
            let m = steps[si..].partition_point(|s| clock_s(s.0) < batch_end);
            if m > 0 {
                log.add(&stepq_json(k, stepper, step_dist, &steps[si..si + m], &mut cur));
                si += m;
            }
        }
        if batch_end >= next_index {
            let at = log.flush();
            index.add(&format!(
                r#"{{"status":{{"toolhead":{{"estimated_print_time":{batch_end}}}}},"file_position":{at}}}"#
            ));
            next_index += INDEX_S;
        }
        batch_end += ACCEL_BATCH_S;
    }
    MotanLog { json_gz: log.finish(), index_gz: index.finish(), samples: samples.to_vec(), steps: steps.len() }
}

/// The `objects/subscribe` answer's status: configuration, driver, toolhead, motion report.
fn status_json(k: &KlipperSetup, p: &SimulatedPrinter, stepper: &str) -> String {
    let full = 4 * u32::from(p.profile.motor.pole_pairs);
    let rd = TAU * p.head.pulley_radius_m * 1e3;
    let rms = p.run_current_a / std::f64::consts::SQRT_2;
    format!(
        concat!(
            r#"{{"configfile":{{"settings":{{"printer":{{"kinematics":"{kin}"}},"#,
            r#""{st}":{{"microsteps":{ms},"full_steps_per_rotation":{full},"rotation_distance":{rd}}},"#,
            r#""tmc2209 {st}":{{"run_current":{rms}}},"adxl345":{{"rate":3200}}}}}},"#,
            r#""tmc2209 {st}":{{"mcu_phase_offset":{off},"run_current":{rms}}},"#,
            r#""toolhead":{{"estimated_print_time":{t0}}},"#,
            r#""motion_report":{{"steppers":["{st}"],"trapq":["toolhead"]}}}}"#
        ),
        kin = k.kinematics.name(),
        st = stepper,
        ms = k.microsteps,
        full = full,
        rd = rd,
        rms = rms,
        off = k.mcu_phase_offset,
        t0 = k.start_s - k.gap_s,
    )
}

/// One accelerometer batch (adxl345.py:310–311).
fn accel_json(s: &[WrittenSample]) -> String {
    let rows: Vec<String> = s.iter().map(|w| format!("[{},{},{},{}]", w.t_s, w.xyz[0], w.xyz[1], w.xyz[2])).collect();
    format!(r#"{{"q":"accelerometer:adxl345","params":{{"data":[{}],"errors":0,"overflows":0}}}}"#, rows.join(","))
}

/// The last step written: its clock (`None` before the first) and the position after it.
struct Cursor {
    clock: Option<u64>,
    pos: i64,
}

/// One step-queue batch (motion_report.py:64–68): runs of equal intervals in one direction
/// as one `[interval, ±count, 0]`.
fn stepq_json(k: &KlipperSetup, stepper: &str, step_dist: f64, s: &[(u64, i64)], cur: &mut Cursor) -> String {
    let start = cur.pos;
    let mut data: Vec<(u64, i64)> = Vec::new();
    for &(c, pos) in s {
        let dir = pos - cur.pos;
        let interval = cur.clock.map_or(0, |p| c - p);
        match data.last_mut() {
            Some((iv, n)) if *iv == interval && n.signum() == dir && n.abs() < 65_535 => *n += dir,
            _ => data.push((interval, dir)),
        }
        (cur.clock, cur.pos) = (Some(c), pos);
    }
    let time = |c: u64| k.start_s - k.gap_s + c as f64 / k.clock_hz as f64;
    let (c0, c1) = (s[0].0, s[s.len() - 1].0);
    let rows: Vec<String> = data.iter().map(|(i, n)| format!("[{i},{n},0]")).collect();
    format!(
        r#"{{"q":"stepq:{stepper}","params":{{"data":[{}],"start_position":{},"start_mcu_position":{start},"step_distance":{step_dist},"first_clock":{c0},"first_step_time":{},"last_clock":{c1},"last_step_time":{}}}}}"#,
        rows.join(","),
        start as f64 * step_dist,
        time(c0),
        time(c1)
    )
}
