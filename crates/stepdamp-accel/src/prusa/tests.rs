use super::*;
use crate::capture::{Axis, TrialSweep};
use proptest::prelude::*;

/// A capture exactly as firmware v6.3.1 prints it for `M973 X F2 R10 H2 A0.5 B0.5 C0.01
/// D0.01`: samples by `snprintf("%d, %.5f\n")` (M97x.cpp:492, LF only), annotations by
/// `SERIAL_ECHO(key)` + `SERIAL_ECHOLN(value)` (M97x.cpp:390–405: floats with 2 decimals,
/// CR LF from `Print::println`). The times are the plan's rounded: 0.20, 5.848 → 5.85, 0.428
/// → 0.43, 5.428 → 5.43.
const PLAIN: &str = "0, 0.01532\n1, -0.04597\n2, 0.00000\n3, 9.80665\n\
sampling_freq: 1344.52\r\nmovement_ok: true\r\naccel_error: 0\r\nstart_marker: 0.20\r\n\
end_marker: 5.85\r\nsignal_start: 0.43\r\nsignal_end: 5.43\r\n";

/// The same through OctoPrint: `Recv: ` before every line, CR LF, the command it sent, its
/// temperature polls (one between the command and the capture) and their replies in between.
const OCTOPRINT: &str = "Send: N3 M973 X F2 R10 H2 A0.5 B0.5 C0.01 D0.01*12\r\n\
Send: N4 M105*35\r\nRecv: echo:busy: processing\r\nRecv: 0, 0.01532\r\nRecv: 1, -0.04597\r\nSend: M105\r\n\
Recv: 2, 0.00000\r\nRecv: T:25.0 /0.0 B:60.0 /60.0 @:0 B@:0\r\nRecv: 3, 9.80665\r\n\
Recv: sampling_freq: 1344.52\r\nRecv: movement_ok: true\r\nRecv: accel_error: 0\r\n\
Recv: start_marker: 0.20\r\nRecv: ok\r\nRecv: end_marker: 5.85\r\nRecv: signal_start: 0.43\r\n\
Recv: signal_end: 5.43\r\nRecv: ok\r\n";

fn read(text: &str) -> Result<Vec<AccelCapture>, ReadError> {
    read_captures(text.as_bytes(), "log.txt")
}

fn err(text: &str) -> String {
    read(text).unwrap_err().to_string()
}

fn gcode() -> Gcode {
    let trial = TrialSweep { harmonic: 2, pha_start: 0.5, pha_end: 0.5, mag_start: 0.01, mag_end: 0.01 };
    Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs: 10.0, trial }
}

#[test]
fn a_capture_through_octoprint_reads_as_the_plain_one() {
    let plain = read(PLAIN).unwrap();
    let octo = read(OCTOPRINT).unwrap();
    assert_eq!(plain.len(), 1);
    assert_eq!(plain[0].samples, [0.01532, -0.04597, 0.0, 9.80665]);
    assert_eq!(plain[0].annotations.sampling_freq_hz, 1344.52);
    assert!(plain[0].annotations.is_valid());
    assert_eq!(plain[0].gcode, None, "a plain capture does not say its G-code");
    assert_eq!(octo[0].gcode, Some(gcode()), "OctoPrint logged the command it sent");
    let mut want = plain[0].clone().with_gcode(gcode());
    want.line = octo[0].line;
    assert_eq!(octo[0], want);
    // And the printed times are the ones the G-code plans.
    octo[0].check_annotations().unwrap();
}

#[test]
fn a_session_log_gives_every_capture_in_order() {
    let second = PLAIN.replace("1344.52", "1343.90").replace("movement_ok: true", "movement_ok: false");
    let log = format!("Send: M974 Y A1 B3 R8\n{PLAIN}Recv: ok\n>>> M973 X F2 R10 H2 A0.5 B0.5 C0.01 D0.01\n{second}");
    let c = read(&log).unwrap();
    assert_eq!(c.len(), 2);
    assert!(matches!(c[0].gcode, Some(Gcode::SpeedSweep { axis: Axis::Y, .. })));
    assert_eq!(c[1].gcode, Some(gcode()));
    assert_eq!((c[0].line, c[1].line), (2, 15));
    assert_eq!(c[1].annotations.sampling_freq_hz, 1343.9);
    assert!(!c[1].annotations.is_valid());
}

#[test]
fn an_accelerometer_failure_without_samples_is_a_capture() {
    let text = "sampling_freq: 0.00\r\nmovement_ok: true\r\naccel_error: 1\r\nstart_marker: 0.20\r\n\
end_marker: 5.85\r\nsignal_start: 0.43\r\nsignal_end: 5.43\r\n";
    let c = read(text).unwrap();
    assert!(c[0].samples.is_empty() && c[0].annotations.accel_error == 1 && !c[0].annotations.is_valid());
}

#[test]
fn a_sample_that_is_not_a_number_is_refused_with_its_line() {
    let e = err(&PLAIN.replace("1, -0.04597", "1, -0.0x597"));
    assert_eq!(e, "log.txt:2: `1, -0.0x597`: expected a sample `<index>, <value>` (`%d, %.5f`)");
    // A temperature report written into the middle of a sample line (interleaved output).
    let e = err(&PLAIN.replace("2, 0.00000", "2, 0.0T:25.0 /0.0"));
    assert!(e.starts_with("log.txt:3: `2, 0.0T:25.0 /0.0`"), "{e}");
}

#[test]
fn a_lost_or_repeated_sample_line_is_refused() {
    let e = err(&PLAIN.replace("2, 0.00000\n", ""));
    assert!(e.starts_with("log.txt:3: `3, 9.80665`: expected sample 2 (a line was lost"), "{e}");
    let e = err(&PLAIN.replace("0, 0.01532\n", ""));
    assert!(e.contains("log.txt:1: `1, -0.04597`") && e.contains("starts at sample 0"), "{e}");
}

#[test]
fn annotations_out_of_order_or_malformed_are_refused() {
    let e = err(&PLAIN.replace("sampling_freq: 1344.52\r\n", ""));
    assert!(e.starts_with("log.txt:5: `movement_ok: true`: expected sample `4, <value>` or `sampling_freq"), "{e}");
    let e = err(&PLAIN.replace("movement_ok: true", "movement_ok: yes"));
    assert_eq!(e, "log.txt:6: `movement_ok: yes`: expected `movement_ok: true|false`");
    let e = err(&PLAIN.replace("signal_start: 0.43", "signal_start: nan"));
    assert!(e.starts_with("log.txt:10: `signal_start: nan`: expected `signal_start: <s ≥ 0>`"), "{e}");
    let e = err("start_marker: 0.20\n");
    assert!(e.contains("expected a capture's samples first"), "{e}");
    let e = err(&PLAIN.replace("accel_error: 0\r\n", "accel_error: 0\r\n7, 0.1\n"));
    assert!(e.starts_with("log.txt:8: `7, 0.1`: expected `start_marker: <s ≥ 0>`"), "{e}");
}

#[test]
fn an_unknown_line_inside_a_capture_is_refused_and_shown_escaped() {
    let e = err(&PLAIN.replace("2, 0.00000\n", "\x1b[2Jgarbage\n"));
    assert_eq!(e, "log.txt:3: `\\u{1b}[2Jgarbage`: expected sample `2, <value>` or `sampling_freq: <Hz>`");
    let e = err(&PLAIN.replace("2, 0.00000\n", "Error:Printer halted\n"));
    assert!(e.contains("not a firmware error"), "{e}");
    let long = format!("0, 0.1\n{}\n", "x".repeat(300));
    let e = err(&long);
    assert!(e.ends_with("…`: expected sample `1, <value>` or `sampling_freq: <Hz>`"), "{e}");
}

#[test]
fn lines_outside_captures_are_skipped_but_a_log_without_one_is_refused() {
    let log = format!("start\nFIRMWARE_NAME:Prusa-Firmware-Buddy 6.3.1\n{PLAIN}Not SD printing\n");
    assert_eq!(read(&log).unwrap().len(), 1);
    assert_eq!(
        err("ok\nT:25 /0\n"),
        "log.txt: no M973/M974 capture (`<index>, <value>` lines, then `sampling_freq: …` … `signal_end: …`)"
    );
}

#[test]
fn a_capture_cut_short_is_refused() {
    let cut = &PLAIN[..PLAIN.find("end_marker").unwrap()];
    assert_eq!(err(cut), "log.txt:8: the input ends inside the capture of line 1: expected `end_marker: <s ≥ 0>`");
}

#[test]
fn a_source_name_with_control_characters_is_shown_escaped() {
    let e = read_captures(&b"nothing\n"[..], "evil\n\x1b[2J.txt").unwrap_err().to_string();
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.starts_with("evil\\u{a}\\u{1b}[2J.txt: no M973/M974 capture"), "{e}");
}

#[test]
fn a_missing_file_whose_name_has_control_characters_is_named_escaped() {
    let path = std::env::temp_dir().join(format!("stepdamp-missing-{}\n\x1b[2J.txt", std::process::id()));
    let e = read_file(&path).unwrap_err().to_string();
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(!e.chars().any(char::is_control), "{e}");
    assert!(e.contains("\\u{a}\\u{1b}[2J.txt: cannot read: "), "{e}");
}

#[test]
fn bytes_that_are_not_text_are_refused() {
    let e = read_captures(&b"0, 0.1\n\xff\xfe\n"[..], "b.bin").unwrap_err().to_string();
    assert_eq!(e, "b.bin:2: `\u{fffd}\u{fffd}`: expected UTF-8 text (a host's log)");
}

#[test]
fn an_endless_input_is_refused_quickly_with_bounded_memory() {
    let e = read_captures(std::io::repeat(0), "/dev/zero").unwrap_err();
    assert_eq!(e, ReadError::LineTooLong { file: "/dev/zero".into(), line: 1, limit: MAX_LINE_BYTES });
    if let Ok(f) = std::fs::File::open("/dev/zero") {
        assert!(matches!(read_captures(f, "/dev/zero"), Err(ReadError::LineTooLong { .. })));
    }
    let e = read_captures(std::io::repeat(b'\n'), "blank").unwrap_err();
    assert!(matches!(e, ReadError::TooMany { what: "lines", line, .. } if line == MAX_LINES + 1), "{e}");
}

#[test]
fn too_many_samples_in_one_capture_are_refused() {
    struct Samples(u64, Vec<u8>);
    impl std::io::Read for Samples {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.1.is_empty() {
                self.1 = format!("{}, 0.00000\n", self.0).into_bytes();
                self.0 += 1;
            }
            let n = buf.len().min(self.1.len());
            buf[..n].copy_from_slice(&self.1[..n]);
            self.1.drain(..n);
            Ok(n)
        }
    }
    let e = read_captures(Samples(0, Vec::new()), "s").unwrap_err();
    assert!(matches!(e, ReadError::TooMany { what: "samples in one capture", .. }), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]
    #[test]
    fn the_reader_never_panics_and_speaks_one_line(bytes in proptest::collection::vec(any::<u8>(), 0..600),
                                                  cut in 0usize..400) {
        for input in [bytes.clone(), [PLAIN.as_bytes(), &bytes].concat(), [&PLAIN.as_bytes()[..cut.min(PLAIN.len())], &bytes].concat()] {
            match read_captures(&input[..], "p") {
                Ok(c) => prop_assert!(c.iter().all(|c| c.samples.iter().all(|v| v.is_finite()))),
                Err(e) => prop_assert!(!e.to_string().chars().any(char::is_control), "{}", e),
            }
        }
    }
}
