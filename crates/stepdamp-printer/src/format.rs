//! The capture as the firmware prints it (`docs/accelerometer.md#the-format-as-printed`):
//! samples by `snprintf("%d, %.5f\n")`, then seven annotations by Arduino's
//! `Print::println`: floats with 2 decimals, rounded half up, and CR LF.

use std::fmt::Write;
use stepdamp_accel::Annotations;

/// Arduino's `Print::printFloat(number, digits)` (`lib/Arduino_Core_Buddy/cores/arduino/
/// Print.cpp:198–247` at `v6.3.1`): `nan`, `inf`, `ovf` beyond ±4294967040, else the sign,
/// `number + 0.5·10^−digits` truncated, and the fraction digit by digit.
pub(crate) fn arduino_float(number: f64, digits: u32) -> String {
    if number.is_nan() {
        return "nan".into();
    }
    if number.is_infinite() {
        return "inf".into();
    }
    if number.abs() > 4_294_967_040.0 {
        return "ovf".into();
    }
    let mut out = String::new();
    let mut x = number;
    if x < 0.0 {
        out.push('-');
        x = -x;
    }
    x += 0.5 / 10f64.powi(digits as i32);
    let int_part = x as u64;
    let mut rem = x - int_part as f64;
    let _ = write!(out, "{int_part}");
    if digits > 0 {
        out.push('.');
    }
    for _ in 0..digits {
        rem *= 10.0;
        let d = rem as u64;
        let _ = write!(out, "{d}");
        rem -= d as f64;
    }
    out
}

/// The whole capture: one `"%d, %.5f\n"` line per sample (Rust's `{:.5}` rounds the exact
/// binary value to nearest, as C's `printf` does), then the seven annotations.
pub(crate) fn capture_text(samples: &[f64], a: &Annotations) -> String {
    let mut s = String::with_capacity(samples.len() * 14 + 200);
    for (k, y) in samples.iter().enumerate() {
        let _ = writeln!(s, "{k}, {y:.5}");
    }
    let f = |x: f64| arduino_float(x, 2);
    let t = a.times;
    let lines = [
        format!("sampling_freq: {}", f(a.sampling_freq_hz)),
        format!("movement_ok: {}", a.movement_ok),
        format!("accel_error: {}", a.accel_error),
        format!("start_marker: {}", f(t.start_marker)),
        format!("end_marker: {}", f(t.end_marker)),
        format!("signal_start: {}", f(t.signal_start)),
        format!("signal_end: {}", f(t.signal_end)),
    ];
    for l in lines {
        s.push_str(&l);
        s.push_str("\r\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_print_as_arduino_prints_them() {
        assert_eq!(arduino_float(1344.516, 2), "1344.52");
        assert_eq!(arduino_float(0.2, 2), "0.20");
        assert_eq!(arduino_float(0.428, 2), "0.43");
        assert_eq!(arduino_float(-1.234, 2), "-1.23");
        assert_eq!(arduino_float(5.0, 2), "5.00");
        assert_eq!(arduino_float(f64::NAN, 2), "nan");
    }
}
