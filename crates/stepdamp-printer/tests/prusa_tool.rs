//! A capture printed by the simulated printer, read by the rules of Prusa's own analysis tool
//! (`utils/phase_stepping/phase_stepping.py` at `v6.3.1`), as written in
//! `docs/accelerometer.md#checked-against-prusas-analysis-tool`: a parser written from that
//! description (not the tool's code, and not `stepdamp_accel`'s reader) gives the same
//! samples, rate and markers as [`read_captures`].

use stepdamp_accel::{Axis, Gcode, TrialSweep, read_captures};
use stepdamp_printer::{SimulatedPrinter, family_printer};

/// What the tool keeps of one command's response.
#[derive(Debug, Clone, PartialEq)]
struct ToolCapture {
    samples: Vec<f64>,
    sampling_freq: f64,
    movement_ok: bool,
    accel_error: i64,
    start_marker: f64,
    end_marker: f64,
    signal_start: f64,
    signal_end: f64,
}

/// Rule 1, the transport: each line as received, whitespace stripped at both ends (CR LF
/// goes); an empty line ends the response (the tool takes it for a time-out); a line ending
/// in `ok` ends it, the text before `ok` kept as a last line if any.
fn response_lines(received: &str) -> Vec<String> {
    let mut out = Vec::new();
    for raw in received.split('\n') {
        let line = raw.trim();
        if line.is_empty() {
            break;
        }
        if let Some(before) = line.strip_suffix("ok") {
            if !before.is_empty() {
                out.push(before.to_string());
            }
            break;
        }
        out.push(line.to_string());
    }
    out
}

/// The text between the first and the second `sep` (Python's `split(sep)[1]`).
fn second_field(line: &str, sep: char) -> &str {
    line.split(sep).nth(1).expect("the tool would raise IndexError")
}

/// Python's `float()` of a field: surrounding whitespace allowed.
fn py_float(s: &str) -> f64 {
    s.trim().parse().expect("the tool would raise ValueError")
}

/// Rule 2, the parse: a line starting with one of the seven keys and a colon sets that
/// field from the text after the first colon (`movement_ok`: true iff it reads `true`,
/// any case); otherwise a line whose first character is a digit is a sample, the text after
/// its first comma (the index is not read); any other line is skipped. Missing keys keep
/// 0, false, 0.
fn tool_parse(received: &str) -> ToolCapture {
    let mut c = ToolCapture {
        samples: Vec::new(),
        sampling_freq: 0.0,
        movement_ok: false,
        accel_error: 0,
        start_marker: 0.0,
        end_marker: 0.0,
        signal_start: 0.0,
        signal_end: 0.0,
    };
    for line in response_lines(received) {
        let value = || second_field(&line, ':');
        if line.starts_with("sampling_freq:") {
            c.sampling_freq = py_float(value());
        } else if line.starts_with("movement_ok:") {
            c.movement_ok = value().trim().to_lowercase() == "true";
        } else if line.starts_with("accel_error:") {
            c.accel_error = value().trim().parse().expect("the tool would raise ValueError");
        } else if line.starts_with("start_marker:") {
            c.start_marker = py_float(value());
        } else if line.starts_with("end_marker:") {
            c.end_marker = py_float(value());
        } else if line.starts_with("signal_start:") {
            c.signal_start = py_float(value());
        } else if line.starts_with("signal_end:") {
            c.signal_end = py_float(value());
        } else if line.chars().next().is_some_and(|ch| ch.is_ascii_digit()) {
            c.samples.push(py_float(second_field(&line, ',')));
        }
    }
    c
}

/// Rule 3, the markers: the 5 ms running energy (`int(0.005·fs)` samples; the first value the
/// window's sum of squares, each next one adding the new sample's square and dropping the
/// square `win` samples back) over `±50 ms` of `start_marker`, plus the same over the window
/// shifted by `int((end_marker − start_marker)·fs)`; the start marker is the first index
/// where that sum exceeds its mean, the end marker that index plus the shift. Returns the
/// two sample indices.
fn tool_markers(c: &ToolCapture) -> (usize, usize) {
    let fs = c.sampling_freq;
    let win = (0.005 * fs) as usize;
    let offset = ((c.end_marker - c.start_marker) * fs) as usize;
    let (from, to) = (((c.start_marker - 0.05) * fs) as usize, ((c.start_marker + 0.05) * fs) as usize);
    let energy = |start: usize, end: usize| {
        let s = &c.samples;
        let mut e = vec![s[start..start + win].iter().map(|x| x * x).sum::<f64>()];
        for i in start + 1..end {
            let last = e[e.len() - 1];
            e.push(last + s[i] * s[i] - s[i - win] * s[i - win]);
        }
        e
    };
    let combined: Vec<f64> =
        energy(from, to).iter().zip(energy(from + offset, to + offset)).map(|(a, b)| a + b).collect();
    let mean = combined.iter().sum::<f64>() / combined.len() as f64;
    let first = combined.iter().position(|&e| e > mean).unwrap_or(0);
    (from + first, from + first + offset)
}

/// Rule 4, the analysed samples: from the start marker's index plus
/// `int((signal_start − start_marker)·fs)` to it plus `int((signal_end − start_marker)·fs)`.
fn tool_signal(c: &ToolCapture) -> (usize, usize) {
    let (start, _) = tool_markers(c);
    let at = |t: f64| start + ((t - c.start_marker) * c.sampling_freq) as usize;
    (at(c.signal_start), at(c.signal_end))
}

/// A capture as the firmware sends it over USB for `g`, with the `ok` that ends the command.
fn received(p: &SimulatedPrinter, g: &Gcode) -> String {
    p.capture(g).unwrap() + "ok\n"
}

#[test]
fn a_simulated_capture_gives_the_same_samples_rate_and_markers_by_prusas_tool_rules_and_the_reader() {
    let trial = TrialSweep { harmonic: 4, pha_start: 0.3, pha_end: 0.3, mag_start: 0.01, mag_end: 0.01 };
    let cases = [
        (family_printer(1), Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs: 6.0, trial }),
        (family_printer(2), Gcode::ParamSweep { axis: Axis::Y, speed: 1.5, revs: -4.5, trial }),
        (family_printer(3), Gcode::SpeedSweep { axis: Axis::X, start_speed: 0.5, end_speed: 3.0, revs: 8.0 }),
    ];
    for (p, g) in cases {
        let text = received(&p, &g);
        let tool = tool_parse(&text);
        let ours = read_captures(text.as_bytes(), "sim").unwrap();
        assert_eq!(ours.len(), 1, "{g}");
        let (c, a) = (&ours[0], ours[0].annotations);
        // The same decimal text, parsed to the nearest f64 by both: equal to the bit.
        assert_eq!(tool.samples, c.samples, "{g}");
        assert_eq!(tool.sampling_freq, a.sampling_freq_hz, "{g}");
        assert_eq!((tool.movement_ok, tool.accel_error), (a.movement_ok, a.accel_error), "{g}");
        let t = a.times;
        let times = [t.start_marker, t.end_marker, t.signal_start, t.signal_end];
        assert_eq!([tool.start_marker, tool.end_marker, tool.signal_start, tool.signal_end], times, "{g}");
        assert!(tool.movement_ok && tool.accel_error == 0 && tool.sampling_freq > 0.0, "the tool's is_ok: {g}");
        // The tool finds the markers by their energy; the simulated printer's sample 0 is the
        // move's start, so the markers begin at their planned times.
        let (start, end) = tool_markers(&tool);
        let fs = tool.sampling_freq;
        let (found, planned) = (start as f64 / fs, t.start_marker);
        println!("{g}: the tool's start marker at {found:.4} s (planned {planned:.2} s), end marker index {end}");
        assert!((found - planned).abs() <= 0.010, "{g}: {found} vs {planned}");
        let (s0, s1) = tool_signal(&tool);
        assert!(s1 <= tool.samples.len() && s0 < s1, "{g}: {s0}..{s1} of {}", tool.samples.len());
        assert!((s0 as f64 / fs - t.signal_start).abs() <= 0.011, "{g}: {s0}");
    }
}

#[test]
fn by_the_tools_rules_a_host_logged_capture_has_no_samples_while_the_reader_reads_it() {
    // The tool reads the serial port itself: a host's `Recv: ` prefix makes every line start
    // with a letter, which its rules skip. The reader strips the prefix.
    let p = family_printer(1);
    let trial = TrialSweep { harmonic: 2, pha_start: 0.0, pha_end: 0.0, mag_start: 0.0, mag_end: 0.0 };
    let g = Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs: 6.0, trial };
    let logged: String = received(&p, &g).lines().map(|l| format!("Recv: {l}\n")).collect();
    let tool = tool_parse(&logged);
    assert!(tool.samples.is_empty() && tool.sampling_freq == 0.0);
    let ours = read_captures(logged.as_bytes(), "octoprint").unwrap();
    assert_eq!(ours[0].samples, tool_parse(&received(&p, &g)).samples);
}
