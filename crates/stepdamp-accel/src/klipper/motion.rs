//! The stepper's motion from its step queue: the `stepq:<stepper>` messages decoded into
//! step times and MCU positions (motion_report.py:46–68, expanded as readlog.py:370–392
//! does), and the commanded position between steps, smoothed as readlog.py:166–194 smooths
//! it (`docs/files.md#klippers-motion-analysis-logs`).

use super::{KlipperError, MAX_STEPS};
use serde_json::Value;

/// readlog.py's default `smooth_time` (s, readlog.py:157): steps closer than this are joined
/// by straight lines through their half-way positions; farther apart, the position ramps over
/// half of it on each side of a step and holds between.
pub const SMOOTH_S: f64 = 0.010;

/// The MCU's `queue_step` fields (klippy/stepper.py:120, src/stepper.c:290): `interval` a
/// `u32`, `count` a `u16` (its sign in the log is the direction), `add` an `i16`.
const COUNT_MAX: i64 = 65_535;

/// One step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Step {
    /// Print time (s).
    t: f64,
    /// The MCU position after the step (microsteps).
    pos: i64,
    /// +1 or −1.
    dir: i8,
}

impl Step {
    /// The position half-way through the step, where the commanded position is at its time.
    fn half(&self) -> f64 {
        self.pos as f64 - 0.5 * f64::from(self.dir)
    }
}

/// Every step of one stepper, in time order.
#[derive(Debug, Clone, Default)]
pub(crate) struct Steps {
    steps: Vec<Step>,
    /// The MCU position before the first step.
    start: Option<i64>,
}

/// Where an error is: the source and the record.
pub(crate) struct At<'a> {
    pub(crate) file: &'a str,
    pub(crate) record: u64,
    pub(crate) key: &'a str,
}

impl At<'_> {
    pub(crate) fn bad(&self, field: &str, value: &Value, expected: &str) -> KlipperError {
        KlipperError::Record {
            file: self.file.into(),
            record: self.record,
            key: super::message_text(&if field.is_empty() { self.key.into() } else { format!("{}.{field}", self.key) }),
            value: super::shown(value),
            expected: expected.into(),
        }
    }

    pub(crate) fn int(&self, v: &Value, field: &str, lo: i64, hi: i64) -> Result<i64, KlipperError> {
        let x = v.get(field).unwrap_or(&Value::Null);
        x.as_i64()
            .filter(|n| (lo..=hi).contains(n))
            .ok_or_else(|| self.bad(field, x, &format!("an integer in {lo}..={hi}")))
    }

    pub(crate) fn float(&self, v: &Value, field: &str) -> Result<f64, KlipperError> {
        let x = v.get(field).unwrap_or(&Value::Null);
        x.as_f64().filter(|f| f.is_finite()).ok_or_else(|| self.bad(field, x, "a finite number"))
    }
}

impl Steps {
    /// The number of steps.
    pub(crate) fn len(&self) -> usize {
        self.steps.len()
    }

    /// Appends one `stepq` message's `params`: `data` `[[interval, count, add], …]` and
    /// `start_mcu_position`, `first_clock`, `first_step_time`, `last_clock`,
    /// `last_step_time` (motion_report.py:65–68). Step `j`'s clock is `first_clock −
    /// data[0][0]` plus the intervals so far, each interval growing by `add` after each step;
    /// its time `first_step_time + (clock − first_clock)·(last_step_time −
    /// first_step_time)/(last_clock − first_clock)` (readlog.py:370–390).
    pub(crate) fn add_block(&mut self, p: &Value, at: &At<'_>) -> Result<(), KlipperError> {
        let first_clock = at.int(p, "first_clock", 0, i64::MAX / 4)?;
        let last_clock = at.int(p, "last_clock", first_clock, i64::MAX / 4)?;
        let (t0, t1) = (at.float(p, "first_step_time")?, at.float(p, "last_step_time")?);
        if t1 < t0 {
            return Err(at.bad("last_step_time", &p["last_step_time"], &format!("at least first_step_time ({t0})")));
        }
        let mut pos = at.int(p, "start_mcu_position", i64::from(i32::MIN), i64::from(i32::MAX))?;
        let data = p.get("data").and_then(Value::as_array).filter(|d| !d.is_empty());
        let Some(data) = data else {
            return Err(at.bad(
                "data",
                p.get("data").unwrap_or(&Value::Null),
                "a non-empty list of [interval, count, add]",
            ));
        };
        let cdiff = last_clock - first_clock;
        let inv_freq = if cdiff > 0 { (t1 - t0) / cdiff as f64 } else { 0.0 };
        if let Some(last) = self.steps.last().filter(|s| s.t > t0) {
            let v = &p["first_step_time"];
            return Err(at.bad(
                "first_step_time",
                v,
                &format!("at least the last step's time {} (steps in order)", last.t),
            ));
        }
        self.start.get_or_insert(pos);
        let mut clock: Option<i64> = None;
        for (i, e) in data.iter().enumerate() {
            let field = format!("data[{i}]");
            let triple = e.as_array().filter(|a| a.len() == 3);
            let bad = || {
                at.bad(
                    &field,
                    e,
                    "[interval, count, add]: interval 0..=4294967295, |count| ≤ 65535, add −32768..=32767",
                )
            };
            let Some(t) = triple else { return Err(bad()) };
            let (Some(mut interval), Some(count), Some(add)) = (t[0].as_i64(), t[1].as_i64(), t[2].as_i64()) else {
                return Err(bad());
            };
            if !((0..=i64::from(u32::MAX)).contains(&interval)
                && (-COUNT_MAX..=COUNT_MAX).contains(&count)
                && (i64::from(i16::MIN)..=i64::from(i16::MAX)).contains(&add))
            {
                return Err(bad());
            }
            let c = clock.get_or_insert(first_clock - interval);
            let dir: i8 = if count < 0 { -1 } else { 1 };
            for _ in 0..count.abs() {
                *c += interval;
                interval += add;
                if *c < first_clock || *c > last_clock {
                    return Err(at.bad(
                        &field,
                        e,
                        &format!("steps within first_clock..=last_clock ({first_clock}..={last_clock})"),
                    ));
                }
                if self.steps.len() >= MAX_STEPS {
                    return Err(KlipperError::TooMany {
                        file: at.file.into(),
                        record: at.record,
                        what: "steps",
                        limit: MAX_STEPS as u64,
                        why: "the reader's memory bound (minutes of fast moves)",
                    });
                }
                pos += i64::from(dir);
                self.steps.push(Step { t: t0 + (*c - first_clock) as f64 * inv_freq, pos, dir });
            }
        }
        Ok(())
    }

    /// The commanded MCU position (microsteps) at print time `t` (s) and its rate
    /// (microsteps/s), readlog.py:166–194's smoothing with [`SMOOTH_S`]: before the first step
    /// the block's start position, after the last the last position.
    pub(crate) fn position(&self, t: f64) -> (f64, f64) {
        let Some(start) = self.start else { return (0.0, 0.0) };
        let s = &self.steps;
        let i = s.partition_point(|x| x.t <= t);
        let half = 0.5 * SMOOTH_S;
        let (lt, lhalf, lpos) = match i.checked_sub(1).map(|k| s[k]) {
            Some(l) => (l.t, l.half(), l.pos as f64),
            None => (f64::NEG_INFINITY, start as f64, start as f64),
        };
        let Some(n) = s.get(i) else {
            return if t - lt < half { ramp(lhalf, lpos, t - lt, half) } else { (lpos, 0.0) };
        };
        let stime = n.t - lt;
        if stime <= SMOOTH_S {
            return ramp(lhalf, n.half(), t - lt, stime);
        }
        if t - lt < half {
            return ramp(lhalf, lpos, t - lt, half);
        }
        if n.t - t < half {
            return ramp(lpos, n.half(), half - (n.t - t), half);
        }
        (lpos, 0.0)
    }
}

/// The straight line from `a` to `b` over `span` (s), at `dt` into it: value and slope.
fn ramp(a: f64, b: f64, dt: f64, span: f64) -> (f64, f64) {
    let slope = (b - a) / span;
    (a + dt * slope, slope)
}
