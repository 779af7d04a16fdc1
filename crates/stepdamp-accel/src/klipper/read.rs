//! The reader: records in order, the configuration from the `objects/subscribe` answer, the
//! accelerometer's samples and the stepper's steps, then the commanded motion at every
//! sample (`docs/files.md#klippers-motion-analysis-logs`).

use super::frame::Records;
use super::motion::{At, Steps};
use super::{Kinematics, KlipperError, KlipperOptions, Log, MAX_SAMPLES};
use crate::capture::{Axis, Commanded};
use serde_json::Value;
use std::f64::consts::TAU;
use std::io::Read;

/// The half-width (s) of the second difference that estimates the commanded acceleration.
pub(crate) const ACCEL_SPAN_S: f64 = 0.010;

/// The configuration the route needs, from `configfile.settings` and the driver's status.
#[derive(Debug, Clone)]
struct Config {
    kinematics: Kinematics,
    microsteps: u32,
    full_steps: u32,
    /// The TMC driver's status key (`tmc2209 stepper_x`), if any.
    driver: Option<String>,
    phase_offset: Option<i64>,
}

/// The reader's state between records.
struct Reader<'a> {
    file: &'a str,
    o: &'a KlipperOptions,
    stepper: &'static str,
    config: Option<Config>,
    accel: Option<String>,
    times: Vec<f64>,
    accel_m_s2: Vec<f64>,
    steps: Steps,
    record: u64,
    skipped: u64,
    errors: u64,
    overflows: u64,
}

/// The log in `input` (the `.json.gz` file's bytes); `file` names it in messages. Streams:
/// memory stays within [`super::MAX_RECORD_BYTES`] per message, [`MAX_SAMPLES`] samples and
/// [`super::MAX_STEPS`] steps, and at most [`super::MAX_DECOMPRESSED_BYTES`] are read.
pub fn read_log<R: Read>(input: R, file: &str, o: &KlipperOptions) -> Result<Log, KlipperError> {
    let file = &stepdamp_out::input::printable(file.as_bytes(), crate::prusa::MAX_NAME_CHARS);
    if let Some(t) = o.trial {
        let ok = (1..=crate::capture::MAX_HARMONIC).contains(&t.harmonic)
            && (0.0..=1.0).contains(&t.amplitude_rad)
            && t.phase_rad.is_finite();
        if !ok {
            return Err(KlipperError::Missing {
                file: file.clone(),
                what: format!(
                    "trial (H, U, PHI) = ({}, {}, {}): harmonic 1..=16, amplitude 0..=1 rad, a finite phase",
                    t.harmonic, t.amplitude_rad, t.phase_rad
                ),
            });
        }
    }
    let stepper = if o.axis == Axis::X { "stepper_x" } else { "stepper_y" };
    let mut r = Reader {
        file,
        o,
        stepper,
        config: None,
        accel: None,
        times: Vec::new(),
        accel_m_s2: Vec::new(),
        steps: Steps::default(),
        record: 0,
        skipped: 0,
        errors: 0,
        overflows: 0,
    };
    let mut records = Records::new(input, file);
    while let Some(bytes) = records.next_record()? {
        r.record += 1;
        r.take(bytes)?;
    }
    r.finish()
}

/// [`read_log`] of the file at `path`.
pub fn read_file(path: &std::path::Path, o: &KlipperOptions) -> Result<Log, KlipperError> {
    let name = path.display().to_string();
    let shown_name = stepdamp_out::input::printable(name.as_bytes(), crate::prusa::MAX_NAME_CHARS);
    let f = std::fs::File::open(path).map_err(|e| KlipperError::Io { file: shown_name, message: e.to_string() })?;
    read_log(f, &name, o)
}

impl Reader<'_> {
    fn at<'k>(&'k self, key: &'k str) -> At<'k> {
        At { file: self.file, record: self.record, key }
    }

    fn missing(&self, what: String) -> KlipperError {
        KlipperError::Missing { file: self.file.into(), what: super::message_text(&what) }
    }

    /// Whether a record that is not JSON names what the route reads (then it is refused).
    fn names_what_is_read(&self, bytes: &[u8]) -> bool {
        let has = |s: &str| bytes.windows(s.len()).any(|w| w == s.as_bytes());
        has(&format!("\"stepq:{}\"", self.stepper))
            || has("\"accelerometer:")
            || has("\"adxl345:")
            || has("\"configfile\"")
    }

    fn take(&mut self, bytes: &[u8]) -> Result<(), KlipperError> {
        let v: Value = match serde_json::from_slice(bytes) {
            Ok(v) => v,
            Err(_) if !self.names_what_is_read(bytes) => {
                self.skipped += 1;
                return Ok(());
            }
            Err(e) => {
                let at = e.column().saturating_sub(1).min(bytes.len());
                let from = at.saturating_sub(20);
                return Err(KlipperError::Record {
                    file: self.file.into(),
                    record: self.record,
                    key: format!("(JSON at column {})", e.column()),
                    value: stepdamp_out::input::printable(&bytes[from..], super::MAX_SHOWN_CHARS),
                    expected: "JSON with finite numbers (Python writes NaN and Infinity, which JSON has not)".into(),
                });
            }
        };
        if let Some(q) = v.get("q").and_then(Value::as_str) {
            let params = v.get("params").unwrap_or(&Value::Null);
            if q == "status" {
                return self.status_update(params);
            }
            if q.strip_prefix("stepq:") == Some(self.stepper) {
                let key = format!("{q}.params");
                return self.steps.add_block(params, &At { file: self.file, record: self.record, key: &key });
            }
            if let Some(name) = q.strip_prefix("accelerometer:").or_else(|| q.strip_prefix("adxl345:")) {
                return self.samples(q, name, params);
            }
            return Ok(());
        }
        if v.get("id").and_then(Value::as_str) == Some("status") && self.config.is_none() {
            if let Some(status) = v.get("result").and_then(|r| r.get("status")) {
                self.config = Some(self.configuration(status)?);
            }
        }
        Ok(())
    }

    /// The configuration from the `objects/subscribe` answer's `status` (data_logger.py:209–212).
    fn configuration(&self, status: &Value) -> Result<Config, KlipperError> {
        let key = "result.status.configfile.settings";
        let settings = status.get("configfile").and_then(|c| c.get("settings")).and_then(Value::as_object);
        let Some(settings) = settings else {
            return Err(self.at(key).bad("", status.get("configfile").unwrap_or(&Value::Null), "an object"));
        };
        let kin = settings.get("printer").and_then(|p| p.get("kinematics")).unwrap_or(&Value::Null);
        let kinematics = match kin.as_str() {
            Some("cartesian") => Kinematics::Cartesian,
            Some("corexy") => Kinematics::CoreXy,
            _ => {
                return Err(self.at(key).bad("printer.kinematics", kin, "cartesian or corexy (the projections known)"));
            }
        };
        let Some(section) = settings.get(self.stepper) else {
            return Err(self.missing(format!("no [{}] in configfile.settings: not this printer's log", self.stepper)));
        };
        let skey = format!("{key}.{}", self.stepper);
        let at = self.at(&skey);
        let microsteps = at.int(section, "microsteps", 1, 256)? as u32;
        let full_steps = match section.get("full_steps_per_rotation") {
            None => 200,
            Some(_) => at.int(section, "full_steps_per_rotation", 4, 4000)? as u32,
        };
        if full_steps % 4 != 0 {
            let v = &section["full_steps_per_rotation"];
            return Err(at.bad("full_steps_per_rotation", v, "a multiple of 4 (4 full steps per electrical period)"));
        }
        // The driver's section, as readlog.py:256–260 finds it: `tmc… <stepper>`.
        let driver =
            settings.keys().find(|k| k.starts_with("tmc") && k.split_once(' ').map(|x| x.1) == Some(self.stepper));
        let offset =
            driver.and_then(|d| status.get(d.as_str()).and_then(|s| s.get("mcu_phase_offset")).map(|v| (d, v)));
        let phase_offset = match offset {
            None | Some((_, Value::Null)) => None,
            Some((d, _)) => {
                let dkey = format!("result.status.{d}");
                Some(self.at(&dkey).int(&status[d.as_str()], "mcu_phase_offset", 0, 1 << 20)?)
            }
        };
        Ok(Config { kinematics, microsteps, full_steps, driver: driver.cloned(), phase_offset })
    }

    /// A status update: refuses a change of the driver's phase offset (the angle would jump).
    fn status_update(&self, params: &Value) -> Result<(), KlipperError> {
        let Some(c) = &self.config else { return Ok(()) };
        let Some(d) = &c.driver else { return Ok(()) };
        let Some(v) = params.get("status").and_then(|s| s.get(d.as_str())).and_then(|x| x.get("mcu_phase_offset"))
        else {
            return Ok(());
        };
        if v.as_i64() != c.phase_offset {
            let key = format!("status.params.status.{d}");
            let was = c.phase_offset.map_or("null".to_string(), |p| p.to_string());
            let why = format!(
                "{was}, its value at the start: the driver's phase moved (motor disabled?): one log per enable"
            );
            return Err(self.at(&key).bad("mcu_phase_offset", v, &why));
        }
        Ok(())
    }

    /// One accelerometer batch: `data` `[[time, x, y, z], …]` (adxl345.py:229–231, 310–311).
    fn samples(&mut self, q: &str, name: &str, params: &Value) -> Result<(), KlipperError> {
        if self.o.accelerometer.as_deref().is_some_and(|want| want != name) {
            return Ok(());
        }
        match &self.accel {
            Some(a) if a != q => {
                return Err(self.missing(format!("two accelerometers ({a}, {q}): name the one on the head")));
            }
            None => self.accel = Some(q.to_string()),
            _ => {}
        }
        let Some(c) = &self.config else {
            return Err(self.missing(format!(
                "record {}: accelerometer data before the `objects/subscribe` answer: not data_logger.py's order",
                self.record
            )));
        };
        let (wx, wy) = c.kinematics.projection(self.o.axis);
        let key = format!("{q}.params");
        let at = At { file: self.file, record: self.record, key: &key };
        for (field, total) in [("errors", &mut self.errors), ("overflows", &mut self.overflows)] {
            if params.get(field).is_some() {
                *total = (*total).max(at.int(params, field, 0, i64::MAX)? as u64);
            }
        }
        let Some(data) = params.get("data").and_then(Value::as_array) else {
            return Err(at.bad("data", params.get("data").unwrap_or(&Value::Null), "a list of [time, x, y, z]"));
        };
        for (i, s) in data.iter().enumerate() {
            let field = format!("data[{i}]");
            let row = s.as_array().filter(|r| r.len() == 4).map(|r| r.iter().map(Value::as_f64).collect::<Vec<_>>());
            let Some([Some(t), Some(x), Some(y), Some(_z)]) = row.as_deref().map(|r| [r[0], r[1], r[2], r[3]]) else {
                return Err(at.bad(&field, s, "[time (s), x, y, z (mm/s²)], finite numbers"));
            };
            if let Some(&last) = self.times.last().filter(|&&last| t <= last) {
                return Err(at.bad(&field, s, &format!("a time after the previous sample's {last} s")));
            }
            if !(t.is_finite() && x.is_finite() && y.is_finite()) {
                return Err(at.bad(&field, s, "finite numbers"));
            }
            if self.times.len() >= MAX_SAMPLES {
                return Err(KlipperError::TooMany {
                    file: self.file.into(),
                    record: self.record,
                    what: "accelerometer samples",
                    limit: MAX_SAMPLES as u64,
                    why: "the reader's memory bound (11 minutes at 3200 Hz)",
                });
            }
            self.times.push(t);
            self.accel_m_s2.push((wx * x + wy * y) * 1e-3);
        }
        Ok(())
    }

    /// The log, with the commanded motion at every sample.
    fn finish(self) -> Result<Log, KlipperError> {
        let Some(c) = self.config.clone() else {
            return Err(self.missing(
                "no `objects/subscribe` answer with configfile.settings: not a log of data_logger.py".into(),
            ));
        };
        let Some(accelerometer) = self.accel.clone().filter(|_| !self.times.is_empty()) else {
            let which = self.o.accelerometer.as_deref().unwrap_or("<name>");
            return Err(self.missing(format!(
                "no accelerometer samples: log with `-s accelerometer:{which}` (docs/accelerometer.md#klippers-motion-analysis-logs)"
            )));
        };
        if self.steps.len() == 0 {
            return Err(self.missing(format!(
                "no steps of {0} (`stepq:{0}`): the motor did not move while logging, or --no-default left its queue out",
                self.stepper
            )));
        }
        let per_rev = f64::from(c.microsteps) * f64::from(c.full_steps);
        let phases = 4.0 * f64::from(c.microsteps);
        let offset = c.phase_offset.unwrap_or(0) as f64;
        let commanded = self
            .times
            .iter()
            .map(|&t| {
                let (p, v) = self.steps.position(t);
                let (before, after) =
                    (self.steps.position(t - ACCEL_SPAN_S).0, self.steps.position(t + ACCEL_SPAN_S).0);
                let a = (after - 2.0 * p + before) / (ACCEL_SPAN_S * ACCEL_SPAN_S);
                Commanded {
                    t_s: t,
                    motor_rev: p / per_rev,
                    electrical_rad: TAU * (p + offset) / phases,
                    speed_rev_s: v / per_rev,
                    accel_rev_s2: a / per_rev,
                }
            })
            .collect();
        Ok(Log {
            source: self.file.into(),
            stepper: self.stepper.into(),
            accelerometer,
            trial: self.o.trial,
            kinematics: c.kinematics,
            microsteps: c.microsteps,
            full_steps_per_rotation: c.full_steps,
            mcu_phase_offset: c.phase_offset,
            steps: self.steps.len(),
            times_s: self.times,
            accel_m_s2: self.accel_m_s2,
            commanded,
            records: self.record,
            skipped_records: self.skipped,
            accel_errors: self.errors,
            accel_overflows: self.overflows,
        })
    }
}
