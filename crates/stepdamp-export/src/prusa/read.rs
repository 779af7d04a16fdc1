//! Reading what a printer prints back: the `M971` read-back of firmware ≥ 6.3.1
//! (`M971 X F I0 M0.00877 P-1.10000`, one line per item, 5 decimals: `SERIAL_DECIMALS` in
//! `include/buddy/phase_stepping_opts.h`, print code in `M97x.cpp` at v6.3.1), the 6.2
//! `M972` print (`X, F, 0, 0.00000, 0.00000`), `M973` lines, and the 168-byte files.
//!
//! Lines may come from a host's terminal log: OctoPrint's `Recv: ` prefix is removed, its
//! `Send: ` lines (what the host sent, not what the printer holds) are skipped, as are `ok`,
//! `echo:` and any other line; a line number `N…`, a checksum `*…`, a `;` comment and CR/LF
//! line ends are tolerated. Input is bounded: [`MAX_BYTES`].

use super::{FILE_BYTES, Firmware, ITEMS, PrusaCorrection, Spectrum, decode_file};
use crate::ExportError;
use std::path::Path;

/// The largest input read: 1 MiB, for every correction table read (a Prusa read-back, file
/// or `M973` lines, a Klipper block: `import prusa`, `sweep --table`); a full read-back of
/// both axes is under 3 kB and a Klipper block under 1 kB, so anything larger is a wrong
/// path (`/dev/zero`, a log), refused after reading this much (docs/files.md#size-limits).
pub const MAX_BYTES: usize = 1 << 20;

/// Reads at most [`MAX_BYTES`] of `path` in one pass ([`stepdamp_out::input::read_bounded`]);
/// a longer input (or `/dev/zero`, or a FIFO that does not end) is refused after reading
/// `MAX_BYTES + 1` bytes.
pub fn read_capped(path: &Path) -> Result<Vec<u8>, ExportError> {
    // Escaped: a path is the user's text, and the message goes to a terminal.
    let what = crate::escape::line(&path.display().to_string());
    let bad = |reason: String| ExportError::Parse { what: what.clone(), reason };
    stepdamp_out::input::read_bounded(path, MAX_BYTES as u64).map_err(|e| match e.kind() {
        std::io::ErrorKind::InvalidData => bad(format!(
            "more than {MAX_BYTES} bytes (1 MiB): not a correction table (an M971 read-back prints 34 short lines per axis, a Klipper block is under 1 kB)"
        )),
        _ => bad(format!("cannot read: {e}")),
    })
}

/// A correction read from bytes: a 168-byte file (interpreted for `file_firmware`: the
/// format is the same in 6.2 and 6.3.1, the magnitude scale is not) or text ([`parse_text`]).
/// Returns the correction and what it was read from.
pub fn parse_bytes(
    bytes: &[u8],
    axis: Option<char>,
    what: &str,
    file_firmware: Firmware,
) -> Result<(PrusaCorrection, String), ExportError> {
    if bytes.len() > MAX_BYTES {
        return Err(ExportError::Parse { what: what.to_string(), reason: format!("more than {MAX_BYTES} bytes") });
    }
    if bytes.len() == FILE_BYTES && bytes[..32].iter().all(|&b| b == 0) {
        let s = decode_file(bytes, what)?;
        let c = PrusaCorrection { forward: s, backward: s, firmware: file_firmware };
        return Ok((c, format!("Prusa correction file, firmware {} scale (both directions)", file_firmware.label())));
    }
    let text = std::str::from_utf8(bytes).map_err(|_| ExportError::Parse {
        what: what.to_string(),
        reason: format!("neither a {FILE_BYTES}-byte Prusa correction file nor text"),
    })?;
    parse_text(text, axis, what)
}

/// Text in any of the printer's forms: `M971` read-back or our export (≥ 6.3.1), else `M973`
/// lines, else the 6.2 `M972` print.
pub fn parse_text(text: &str, axis: Option<char>, what: &str) -> Result<(PrusaCorrection, String), ExportError> {
    let lines = || text.lines().filter_map(clean_line);
    if lines().any(|l| m971_body(l).is_some()) {
        return parse_m971(text, axis, what);
    }
    if lines().any(|l| l.starts_with("M973 ")) {
        return Ok((parse_m973(text, axis, what)?, "Prusa M973 lines (firmware 6.2)".to_string()));
    }
    if lines().any(|l| l.split(',').count() == 5) {
        return Ok((parse_m972(text, axis, what)?, "Prusa M972 print (firmware 6.2)".to_string()));
    }
    Err(ExportError::Parse {
        what: what.to_string(),
        reason: "no M971 read-back (`M971 X F I0 M… P…`), M973 lines or 6.2 M972 print found".into(),
    })
}

/// A line with a host's prefix, line number, checksum, comment and CR removed; `None` for
/// lines that say nothing about the printer's table (blank, or what a host sent).
pub fn clean_line(raw: &str) -> Option<&str> {
    let mut l = raw.trim();
    if ["Send:", "SENDING:", ">>>"].iter().any(|p| l.starts_with(p)) {
        return None;
    }
    if let Some(r) = l.strip_prefix("Recv:") {
        l = r.trim_start();
    }
    if let Some(i) = l.find(';') {
        l = &l[..i];
    }
    if let Some(i) = l.find('*') {
        l = &l[..i];
    }
    if let Some(rest) = l.strip_prefix('N') {
        let after = rest.trim_start_matches(|c: char| c.is_ascii_digit());
        if after.len() < rest.len() {
            l = after;
        }
    }
    let l = l.trim();
    (!l.is_empty()).then_some(l)
}

/// The parameter part of an `M971` line (`M971` not followed by another digit), if it is one.
fn m971_body(l: &str) -> Option<&str> {
    let rest = l.strip_prefix("M971")?;
    (!rest.starts_with(|c: char| c.is_ascii_digit() || c == '.')).then_some(rest)
}

/// The firmware's `GCodeParser2` on a parameter part: an upper-case letter, optional spaces,
/// a value of `0123456789+-.,` (≤ 31 characters); each letter once.
fn params(body: &str) -> Result<[Option<&str>; 26], String> {
    let mut out: [Option<&str>; 26] = [None; 26];
    let b = body.as_bytes();
    let mut i = 0;
    loop {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        if i == b.len() {
            return Ok(out);
        }
        if !b[i].is_ascii_uppercase() {
            return Err(format!("expected an upper-case parameter letter at {:?}", &body[i..]));
        }
        let letter = usize::from(b[i] - b'A');
        i += 1;
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < b.len() && b"0123456789+-.,".contains(&b[i]) {
            i += 1;
        }
        if out[letter].is_some() {
            return Err(format!("parameter {} given twice", char::from(b'A' + letter as u8)));
        }
        if i - start > 31 {
            return Err(format!("value {:?} longer than the firmware's 31 characters", &body[start..i]));
        }
        out[letter] = Some(&body[start..i]);
    }
}

fn flag(p: &[Option<&str>; 26], c: char) -> Result<bool, String> {
    match p[usize::from(c as u8 - b'A')] {
        None | Some("0") => Ok(false),
        Some("" | "1") => Ok(true),
        Some(v) => Err(format!("{c}{v}: expected {c}, {c}1 or {c}0")),
    }
}

/// One `M971` item: `(axis, direction, index, mag, pha)`.
type Item = (char, char, usize, f32, f32);

/// One `M971` item, or `None` for a read command
/// (`M971 X F`, no `I`, `M`, `P`).
fn m971_item(body: &str) -> Result<Option<Item>, String> {
    let p = params(body)?;
    if let Some(c) =
        (b'A'..=b'Z').map(char::from).find(|c| p[usize::from(*c as u8 - b'A')].is_some() && !"XYFBIMP".contains(*c))
    {
        return Err(format!("parameter {c}: a read-back item has X|Y F|B I M P only"));
    }
    let get = |c: char| p[usize::from(c as u8 - b'A')];
    let (i, m, ph) = (get('I'), get('M'), get('P'));
    if i.is_none() && m.is_none() && ph.is_none() {
        return Ok(None);
    }
    let (Some(i), Some(m), Some(ph)) = (i, m, ph) else {
        return Err("an item needs all of I, M and P".into());
    };
    let axis = match (flag(&p, 'X')?, flag(&p, 'Y')?) {
        (true, false) => 'X',
        (false, true) => 'Y',
        _ => return Err("an item names exactly one axis, X or Y".into()),
    };
    let dir = match (flag(&p, 'F')?, flag(&p, 'B')?) {
        (true, false) => 'F',
        (false, true) => 'B',
        _ => return Err("an item names exactly one direction, F or B".into()),
    };
    let n: usize = i.parse().ok().filter(|&n| n < ITEMS).ok_or_else(|| format!("I{i}: the index must be 0..=16"))?;
    let num = |c: char, v: &str| {
        v.parse::<f32>().ok().filter(|x| x.is_finite()).ok_or_else(|| format!("{c}{v}: not a finite number"))
    };
    Ok(Some((axis, dir, n, num('M', m)?, num('P', ph)?)))
}

/// Picks the axis: the one asked for, else the only one present.
fn pick_axis(seen: &[char], axis: Option<char>, what: &str, kind: &str) -> Result<char, ExportError> {
    let bad = |reason: String| ExportError::Parse { what: what.to_string(), reason };
    match axis {
        Some(a) if seen.contains(&a) => Ok(a),
        Some(a) => Err(bad(format!("no {kind} lines for axis {a}"))),
        None => match seen {
            [a] => Ok(*a),
            [] => Err(bad(format!("no {kind} lines"))),
            _ => Err(bad("axes X and Y both present: choose one with --axis".to_string())),
        },
    }
}

/// Parses `M971` read-back lines (or an exported file) of one axis. Every item 0…16 of each
/// direction present must be there (the read-back prints all 17); a direction read alone
/// (`M971 X F`) stands for both. A later line for the same item wins, as in the firmware.
pub fn parse_m971(text: &str, axis: Option<char>, what: &str) -> Result<(PrusaCorrection, String), ExportError> {
    let mut items: Vec<Item> = Vec::new();
    for (no, raw) in text.lines().enumerate() {
        let Some(body) = clean_line(raw).and_then(m971_body) else { continue };
        match m971_item(body) {
            Ok(Some(it)) => items.push(it),
            Ok(None) => {}
            Err(reason) => return Err(ExportError::Parse { what: format!("{what}:{}", no + 1), reason }),
        }
    }
    let mut axes: Vec<char> = items.iter().map(|it| it.0).collect();
    axes.sort_unstable();
    axes.dedup();
    let ax = pick_axis(&axes, axis, what, "M971 item")?;
    let mut got = [[None::<(f32, f32)>; ITEMS]; 2];
    for &(_, d, n, m, p) in items.iter().filter(|it| it.0 == ax) {
        got[usize::from(d == 'B')][n] = Some((m, p));
    }
    let mut spec = [None::<Spectrum>; 2];
    for (d, name) in [(0, 'F'), (1, 'B')] {
        if got[d].iter().all(Option::is_none) {
            continue;
        }
        let mut s = Spectrum::default();
        for (n, item) in got[d].iter().enumerate() {
            let (m, p) = item.ok_or_else(|| ExportError::Parse {
                what: what.to_string(),
                reason: format!(
                    "axis {ax} direction {name} item {n} is missing (`M971 {ax} {name}` prints items 0..=16)"
                ),
            })?;
            s.mag[n] = m;
            s.pha[n] = p;
        }
        spec[d] = Some(s);
    }
    let (forward, backward, dirs) = match spec {
        [Some(f), Some(b)] => (f, b, "F and B"),
        [Some(f), None] => (f, f, "F only, used for both directions"),
        [None, Some(b)] => (b, b, "B only, used for both directions"),
        [None, None] => {
            return Err(ExportError::Parse { what: what.to_string(), reason: format!("no M971 items for axis {ax}") });
        }
    };
    Ok((
        PrusaCorrection { forward, backward, firmware: Firmware::V6_3_1 },
        format!("Prusa M971 read-back (firmware >= 6.3.1), axis {ax}, {dirs}"),
    ))
}

/// Parses the 6.2 firmware's `M972` print: lines `<axis>, <F|B>, <n>, <mag>, <pha>` (other lines, such as
/// `ok`, are skipped). `axis` picks one axis when the output has several; all 17 items of
/// both directions must be present.
pub fn parse_m972(text: &str, axis: Option<char>, what: &str) -> Result<PrusaCorrection, ExportError> {
    let bad = |line: usize, reason: String| ExportError::Parse { what: format!("{what}:{line}"), reason };
    let mut out =
        PrusaCorrection { forward: Spectrum::default(), backward: Spectrum::default(), firmware: Firmware::V6_2 };
    let mut seen = [[false; ITEMS]; 2];
    let mut axis_seen: Option<char> = axis;
    for (no, line) in text.lines().enumerate() {
        let Some(line) = clean_line(line) else { continue };
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 5 || !matches!(f[0], "X" | "Y") || !matches!(f[1], "F" | "B") {
            continue;
        }
        let ax = f[0].chars().next().unwrap_or(' ');
        match axis_seen {
            None => axis_seen = Some(ax),
            Some(a) if a != ax => {
                if axis.is_none() {
                    return Err(bad(no + 1, format!("axes {a} and {ax} both present: choose one with --axis")));
                }
                continue;
            }
            _ => {}
        }
        let n: usize = f[2].parse().map_err(|_| bad(no + 1, format!("index {:?} is not a number", f[2])))?;
        if n >= ITEMS {
            return Err(bad(no + 1, format!("index {n}: must be in 0..=16")));
        }
        let num = |s: &str| -> Result<f32, ExportError> {
            s.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(no + 1, format!("{s:?} is not a finite number")))
        };
        let (d, spec) = if f[1] == "F" { (0, &mut out.forward) } else { (1, &mut out.backward) };
        spec.mag[n] = num(f[3])?;
        spec.pha[n] = num(f[4])?;
        seen[d][n] = true;
    }
    for (d, name) in [(0, "F"), (1, "B")] {
        if let Some(n) = seen[d].iter().position(|s| !s) {
            return Err(ExportError::Parse {
                what: what.to_string(),
                reason: format!("direction {name} item {n} is missing (M972 prints 17 items per direction)"),
            });
        }
    }
    Ok(out)
}

/// Parses `M973 <axis><F|B><mag>,<pha> …` lines (as the firmware's `parse_pairs` reads
/// them: pairs separated by one space; missing items are zero). Both directions must be
/// given; `axis` picks one when several are present.
pub fn parse_m973(text: &str, axis: Option<char>, what: &str) -> Result<PrusaCorrection, ExportError> {
    let mut out =
        PrusaCorrection { forward: Spectrum::default(), backward: Spectrum::default(), firmware: Firmware::V6_2 };
    let mut seen = [false; 2];
    let mut axis_seen = axis;
    for (no, line) in text.lines().enumerate() {
        let Some(rest) = clean_line(line).and_then(|l| l.strip_prefix("M973 ")) else { continue };
        let bad = |reason: String| ExportError::Parse { what: format!("{what}:{}", no + 1), reason };
        let mut chars = rest.chars();
        let (ax, dir) = (chars.next().unwrap_or(' '), chars.next().unwrap_or(' '));
        if !matches!(ax, 'X' | 'Y') || !matches!(dir, 'F' | 'B') {
            return Err(bad(format!("{rest:?}: expected <X|Y><F|B> then mag,pha pairs")));
        }
        match axis_seen {
            None => axis_seen = Some(ax),
            Some(a) if a != ax => {
                if axis.is_none() {
                    return Err(bad(format!("axes {a} and {ax} both present: choose one with --axis")));
                }
                continue;
            }
            _ => {}
        }
        let mut s = Spectrum::default();
        let pairs: Vec<&str> = chars.as_str().trim().split(' ').filter(|p| !p.is_empty()).collect();
        if pairs.len() > ITEMS {
            return Err(bad(format!("{} pairs: at most {ITEMS}", pairs.len())));
        }
        for (n, p) in pairs.iter().enumerate() {
            let (m, ph) = p.split_once(',').ok_or_else(|| bad(format!("{p:?}: expected mag,pha")))?;
            let num = |v: &str| {
                v.parse::<f32>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(format!("{v:?} is not a finite number")))
            };
            s.mag[n] = num(m)?;
            s.pha[n] = num(ph)?;
        }
        let d = usize::from(dir == 'B');
        seen[d] = true;
        if d == 0 {
            out.forward = s;
        } else {
            out.backward = s;
        }
    }
    if let Some(d) = seen.iter().position(|s| !s) {
        return Err(ExportError::Parse {
            what: what.to_string(),
            reason: format!("no M973 line for direction {}", if d == 0 { 'F' } else { 'B' }),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn item_lines(axis: char, dir: char, m4: &str) -> String {
        (0..ITEMS)
            .map(|n| format!("M971 {axis} {dir} I{n} M{} P0.00000\n", if n == 4 { m4 } else { "0.00000" }))
            .collect()
    }

    #[test]
    fn an_endless_table_file_is_refused_after_the_limit() {
        let e = crate::load_table_file(Path::new("/dev/zero"), None).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains(&MAX_BYTES.to_string()), "{e}");
    }

    #[test]
    fn read_back_through_octoprint_with_crlf_echo_and_ok_lines() {
        let mut t = String::from("Send: N5 M971 X F*33\r\necho:busy: processing\r\n");
        for l in item_lines('X', 'F', "0.00877").lines() {
            t += &format!("Recv: {l}\r\n");
        }
        t += "Recv: ok\r\nok\r\n";
        let (c, kind) = parse_text(&t, None, "log").unwrap();
        assert_eq!(kind, "Prusa M971 read-back (firmware >= 6.3.1), axis X, F only, used for both directions");
        assert_eq!(c.forward.mag[4], 0.00877);
        assert_eq!(c.backward, c.forward);
        assert_eq!(c.firmware, Firmware::V6_3_1);
        // Our own export with line numbers and checksums, as a host sends it, reads too.
        let sent: String =
            item_lines('Y', 'B', "-0.001").lines().enumerate().map(|(i, l)| format!("N{i} {l}*12\n")).collect();
        let (c, _) = parse_text(&sent, None, "sent").unwrap();
        assert_eq!(c.backward.mag[4], -0.001);
    }

    #[test]
    fn read_back_problems_are_named_with_the_line() {
        let both = item_lines('X', 'F', "0.1") + &item_lines('Y', 'F', "0.2");
        assert!(parse_text(&both, None, "f").unwrap_err().to_string().contains("axes X and Y both present"));
        assert_eq!(parse_text(&both, Some('Y'), "f").unwrap().0.forward.mag[4], 0.2);
        let short: String =
            item_lines('X', 'F', "0.1").lines().filter(|l| !l.contains(" I7 ")).map(|l| format!("{l}\n")).collect();
        let e = parse_text(&short, None, "f").unwrap_err().to_string();
        assert!(e.contains("direction F item 7 is missing"), "{e}");
        for (bad, want) in [
            ("M971 X F I3 M1e-5 P0", "upper-case parameter letter"),
            ("M971 X F I17 M0 P0", "I17: the index must be 0..=16"),
            ("M971 X F I3 M0", "all of I, M and P"),
            ("M971 X Y F I3 M0 P0", "exactly one axis"),
            ("M971 X F B I3 M0 P0", "exactly one direction"),
            ("M971 X F I3 M0 P0 P1", "given twice"),
            ("M971 X F I3 M. P0", "M.: not a finite number"),
            ("M971 X F R I3 M0 P0", "parameter R"),
        ] {
            let e = parse_text(&format!("ok\n{bad}\r\n"), None, "rb").unwrap_err().to_string();
            assert!(e.starts_with("rb:2: ") && e.contains(want), "{bad}: {e}");
        }
        assert!(parse_text("ok\nM9710 X F\n", None, "x").unwrap_err().to_string().contains("no M971 read-back"));
    }

    #[test]
    fn the_6_2_print_and_m973_lines_read_in_the_6_2_scale() {
        let print: String = ['F', 'B']
            .iter()
            .flat_map(|d| {
                (0..ITEMS).map(move |n| {
                    format!("Recv: X, {d}, {n}, {}, 0.30000\r\n", if n == 4 { "0.03509" } else { "0.00000" })
                })
            })
            .collect();
        let (c, kind) = parse_text(&print, None, "p").unwrap();
        assert!(kind.contains("M972 print (firmware 6.2)"), "{kind}");
        assert_eq!((c.firmware, c.forward.mag[4], c.backward.pha[3]), (Firmware::V6_2, 0.03509, 0.3));
        // Found by the fuzzer: a print line of another "axis" (here ESC) is not the printer's.
        let esc = format!("{print}\u{1b}, F, 4, 0.03590, 0.20000\n");
        assert_eq!(parse_text(&esc, None, "p").unwrap().0, c);
        let (c, _) = parse_text("M973 XF0,0 0,0 0,0 0,0 0.5,1\nM973 XB0,0\n", None, "m").unwrap();

        assert_eq!((c.firmware, c.forward.mag[4], c.backward.mag[4]), (Firmware::V6_2, 0.5, 0.0));
    }

    const TOKENS: [&str; 24] = [
        "M971", "M972", "M973 ", "M970", " X", " Y", " F", " B", " I", " M", " P", "Recv: ", "Send: ", "ok", "\r\n",
        "\n", ", ", "0.00877", "-1.1", "16", "17", ";", "*", "\u{1b}",
    ];

    proptest::proptest! {
        #[test]
        fn any_mix_of_read_back_tokens_reads_or_fails_with_a_clean_message(
            picks in proptest::collection::vec(0usize..TOKENS.len(), 0..400),
            axis in 0usize..3,
        ) {
            let text: String = picks.iter().map(|&i| TOKENS[i]).collect();
            match parse_bytes(text.as_bytes(), [None, Some('X'), Some('Y')][axis], "t", Firmware::V6_3_1) {
                Ok((c, _)) => proptest::prop_assert!(c.forward.mag.iter().chain(&c.backward.pha).all(|v| v.is_finite())),
                Err(e) => proptest::prop_assert!(!e.to_string().chars().any(char::is_control), "{}", e),
            }
        }
    }
}
