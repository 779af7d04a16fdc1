//! What hosts add around the printer's output, and the calibration G-code a host echoed.
//!
//! OctoPrint logs `Recv: <line>` and `Send: N12 M973 X F2*93` (its `serial.log` adds a
//! timestamp and ` - ` before them); Pronterface shows `SENDING:M973 …` and `>>> M973 …`;
//! plain serial has neither. All end lines with CR LF or LF.

use crate::capture::{Axis, Gcode, MAX_HARMONIC, TrialSweep};

/// A line of a log, sorted.
#[derive(Debug, PartialEq)]
pub(crate) enum Line<'a> {
    /// Nothing (blank).
    Blank,
    /// A calibration G-code (`M973`, `M974`) the host sent: `Some` if the firmware accepts
    /// it, `None` if it refuses it (with an `Error:` line, capturing nothing). Other
    /// commands a host sends (its `M105` polls) are [`Line::Blank`].
    Sent(Option<Gcode>),
    /// What the printer printed, without the host's prefix and the line end.
    Printed(&'a str),
}

/// Sorts one line (without its `\n`).
pub(crate) fn classify(line: &str) -> Line<'_> {
    let mut l = line.trim();
    // OctoPrint's serial.log: "2025-01-01 12:00:00,123 - Recv: …".
    for tag in ["Recv:", "Send:"] {
        if let Some(i) = l.find(tag) {
            if i == 0 || l[..i].ends_with(" - ") {
                l = &l[i..];
                break;
            }
        }
    }
    for sent in ["Send:", "SENDING:", ">>>"] {
        if let Some(rest) = l.strip_prefix(sent) {
            return if is_calibration(rest) { Line::Sent(gcode(rest)) } else { Line::Blank };
        }
    }
    if let Some(rest) = l.strip_prefix("Recv:") {
        l = rest.trim();
    }
    if l.is_empty() {
        return Line::Blank;
    }
    if is_calibration(l) {
        // The command itself in a plain log (a terminal that echoes what was typed).
        return Line::Sent(gcode(l));
    }
    Line::Printed(l)
}

/// The words of a sent line without its line number `N…`, checksum `*…` and comment `;…`.
fn words(sent: &str) -> impl Iterator<Item = &str> {
    let l = sent.split([';', '*']).next().unwrap_or("");
    let mut w = l.split_whitespace().peekable();
    if w.peek().is_some_and(|x| x.len() > 1 && x.starts_with('N') && x[1..].chars().all(|c| c.is_ascii_digit())) {
        w.next();
    }
    w
}

/// Whether a sent line is `M973` or `M974`.
fn is_calibration(sent: &str) -> bool {
    matches!(words(sent).next(), Some("M973" | "M974"))
}

/// Whether a printed line is what firmware and hosts say besides a capture: `ok`, `echo:`,
/// `busy:`, `wait`, host actions (`//`), temperature reports (`T:…`, `T0:…`, `B:…`).
pub(crate) fn is_chatter(l: &str) -> bool {
    let temp = |p: &str| {
        l.strip_prefix(p)
            .and_then(|r| r.split_once(':'))
            .is_some_and(|(idx, _)| idx.chars().all(|c| c.is_ascii_digit()) && idx.len() <= 2)
    };
    l == "ok"
        || l.starts_with("ok ")
        || l.starts_with("echo:")
        || l.starts_with("busy:")
        || l.starts_with("//")
        || l == "wait"
        || temp("T")
        || temp("B")
}

/// The calibration G-code in a sent line, if it is one the firmware runs: line number,
/// checksum and comment removed; parameters as Marlin's parser reads them (a letter, then
/// a number or nothing). The firmware's own checks (M97x.cpp:441–482 and 535–571 at
/// `v6.3.1`) decide: a command it refuses captures nothing, so it is `None`.
pub(crate) fn gcode(sent: &str) -> Option<Gcode> {
    let mut words = words(sent);
    let code = words.next()?;
    let mut p: [Option<f64>; 26] = [None; 26];
    let mut seen = [false; 26];
    for w in words {
        let c = w.chars().next()?;
        if !c.is_ascii_uppercase() {
            return None;
        }
        let i = usize::from(c as u8 - b'A');
        seen[i] = true;
        let v = &w[1..];
        if !v.is_empty() {
            p[i] = Some(v.parse::<f64>().ok().filter(|x| x.is_finite())?);
        }
    }
    let get = |c: char| p[usize::from(c as u8 - b'A')].unwrap_or(0.0);
    let axis = match (seen[usize::from(b'X' - b'A')], seen[usize::from(b'Y' - b'A')]) {
        (true, false) => Axis::X,
        (false, true) => Axis::Y,
        _ => return None,
    };
    match code {
        "M973" => {
            let h = get('H');
            let trial = TrialSweep {
                harmonic: if h.fract() == 0.0 && (1.0..=f64::from(MAX_HARMONIC)).contains(&h) {
                    h as u32
                } else {
                    return None;
                },
                pha_start: get('A'),
                pha_end: get('B'),
                mag_start: get('C'),
                mag_end: get('D'),
            };
            let mags_ok = [trial.mag_start, trial.mag_end].iter().all(|m| (-1.0..=1.0).contains(m));
            let speed = get('F');
            (mags_ok && speed > 0.0).then_some(Gcode::ParamSweep { axis, speed, revs: get('R'), trial })
        }
        "M974" => {
            let (a, b, revs) = (get('A'), get('B'), get('R'));
            let ok = a >= 0.0 && b >= 0.0 && !(a == 0.0 && b == 0.0) && revs != 0.0;
            ok.then_some(Gcode::SpeedSweep { axis, start_speed: a, end_speed: b, revs })
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_prefixes_are_removed_and_sent_commands_parsed() {
        assert_eq!(classify("Recv: 12, 0.12345\r"), Line::Printed("12, 0.12345"));
        assert_eq!(classify("2025-03-31 10:00:00,001 - Recv: ok"), Line::Printed("ok"));
        let Line::Sent(Some(g)) = classify("Send: N5 M973 X F2 R10 H4 A1 B1 C0.02 D0.02*77") else { panic!() };
        assert_eq!(g.to_string(), "M973 X F2 R10 H4 A1 B1 C0.02 D0.02");
        let Line::Sent(Some(g)) = classify(">>> M974 Y A0.5 B4 R-6") else { panic!() };
        assert_eq!(g.to_string(), "M974 Y A0.5 B4 R-6");
        assert_eq!(classify("SENDING:M105"), Line::Blank, "a host's poll is not a calibration command");
        assert_eq!(classify("Send: N7 M973 X F2 H40*3"), Line::Sent(None), "refused by the firmware");
        assert_eq!(classify("M9731 X"), Line::Printed("M9731 X"));
        assert_eq!(classify("  \r"), Line::Blank);
    }

    #[test]
    fn commands_the_firmware_refuses_capture_nothing() {
        assert_eq!(gcode("M973 X Y F2 H4"), None, "two axes");
        assert_eq!(gcode("M973 X F2 H17"), None, "harmonic beyond 16");
        assert_eq!(gcode("M973 X F2 H4 C1.5"), None, "magnitude beyond 1");
        assert_eq!(gcode("M973 X F0 H4"), None, "speed not positive");
        assert_eq!(gcode("M974 X A0 B0 R5"), None, "both speeds zero");
        assert_eq!(gcode("M974 X A1 B2"), None, "no revolutions");
        assert!(gcode("M974 X A1 B2 R5 ; sweep").is_some());
    }

    #[test]
    fn chatter_is_recognised_and_samples_are_not_chatter() {
        for l in ["ok", "ok T:25.0 /0.0", "echo:busy", "busy: processing", "T:24.9 /0.0 B:25.1 /0.0 @:0", "T0:25 /0"] {
            assert!(is_chatter(l), "{l}");
        }
        for l in ["0, 0.12345", "sampling_freq: 1344.52", "Error:Speed must be positive", "Tool 1"] {
            assert!(!is_chatter(l), "{l}");
        }
    }
}
