//! The G-code a printer takes: `M970`/`M971` for firmware ≥ 6.3.1, `M973` for 6.2.
//!
//! Rules read from the firmware at tag v6.3.1 (and unchanged at v6.3.2):
//! - `lib/Marlin/Marlin/src/gcode/feature/phase_stepping/M97x.cpp`: `M971 X|Y F|B I<index>
//!   M<magnitude> P<phase>` writes one item (index 0…16) of one axis and direction and saves
//!   that direction's file; it is refused with "Phase-stepping must be disabled to modify its
//!   parameters." while the axis has phase stepping on, hence `M970 X0` before and `M970 X1`
//!   after. `M971 … R` only deletes the file and leaves the table in RAM (which the next
//!   write saves again), so every item is written, the zero ones too: an item of an earlier
//!   correction never survives.
//! - `src/common/gcode/gcode_parser.cpp` (`GCodeParser2`): a parameter is an upper-case
//!   letter, optional spaces, then a value of the characters `0123456789+-.,` only (no
//!   exponent: `1e-5` would fail on the `e`), at most 31 characters, each letter once; a
//!   letter without value is a true flag.
//! - `include/marlin/Configuration_{COREONE,iX,MK4}_adv.h`: `MAX_CMD_SIZE 96`, and
//!   `lib/Marlin/Marlin/src/gcode/queue.cpp` drops every character past `MAX_CMD_SIZE − 1`:
//!   a line of more than [`LINE_LIMIT`] characters is cut (the XL has 256).

use super::{Firmware, Fitted, ITEMS, SHIFT_LIMIT, SIN_PERIOD, Spectrum};
use crate::{ExportError, RunCurrent};

/// Characters of a G-code line the printer keeps (`MAX_CMD_SIZE − 1`).
pub const LINE_LIMIT: usize = 95;
/// What a host may add to a line it sends: a line number `N12345 ` (7) and a checksum
/// `*123` (4).
pub const HOST_MARGIN: usize = 11;
/// The longest line we write: [`LINE_LIMIT`] − [`HOST_MARGIN`] = 84 characters.
pub const CONTENT_LIMIT: usize = LINE_LIMIT - HOST_MARGIN;
/// Decimals of a magnitude (1e-6; the 6.3.1 firmware's own step is 2π/(4096·256) = 6e-6).
pub const MAG_DECIMALS: usize = 6;
/// Decimals of a phase (1e-5 rad; the firmware rounds to 2π/4096 = 1.5e-3 rad).
pub const PHA_DECIMALS: usize = 5;

/// `v` with `decimals` decimals, trailing zeros dropped, never an exponent or `-0`.
pub fn number(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    if s == "-0" { "0".to_string() } else { s }
}

/// The f32 the firmware reads from [`number`]`(v, decimals)`.
pub fn quantize(v: f64, decimals: usize) -> f32 {
    number(v, decimals).parse().unwrap_or(0.0)
}

/// `s` for a `;` comment: [`crate::escape::gcode_comment`] (one line of printable ASCII,
/// anything else as a visible escape), `*` (a checksum's mark) as `\x2a`, and at most `max`
/// characters (cut with `...`).
pub fn comment_text(s: &str, max: usize) -> String {
    let clean = crate::escape::gcode_comment(s).replace('*', "\\x2a");
    if clean.len() <= max { clean } else { format!("{}...", &clean[..max.saturating_sub(3)]) }
}

/// What the comment lines of an exported file state.
#[derive(Clone, Debug)]
pub struct Header<'a> {
    /// The profile's name (escaped on output).
    pub profile: &'a str,
    /// The run current the correction was computed for.
    pub current: RunCurrent,
}

/// The G-code of a fitted correction for `axis` (`X` or `Y`): comments, then for 6.3.1
/// `M970 <axis>0`, 17 `M971` lines per direction, `M970 <axis>1`; for 6.2 one `M973` line
/// per direction (items after the last non-zero one left out: the firmware sets them to 0).
/// Refused when a line would be longer than [`CONTENT_LIMIT`].
pub fn write(f: &Fitted, axis: char, h: &Header<'_>) -> Result<String, ExportError> {
    if !matches!(axis, 'X' | 'Y') {
        return Err(ExportError::Invalid(format!("axis {axis:?}: Prusa phase stepping has axes X and Y")));
    }
    let c = &f.correction;
    let unit = std::f64::consts::TAU / f64::from(SIN_PERIOD);
    let codes = match c.firmware {
        Firmware::V6_2 => "M973",
        Firmware::V6_3_1 => "M970, M971",
    };
    let dirs = if c.forward == c.backward { "the same correction" } else { "each its own correction" };
    let mut lines = vec![
        format!("; stepdamp export prusa: Prusa-Firmware-Buddy {} ({codes}), axis {axis}", c.firmware.label()),
        format!("; profile: {}", comment_text(h.profile, CONTENT_LIMIT - 11)),
        format!("; directions F (forward) and B (backward): {dirs}"),
        format!("; run current {}", h.current),
        format!(
            "; correction kept: {:.1} %, peak shift {:.4} rad (int8 table: +-{:.4})",
            100.0 * f.kept,
            f.peak_shift as f64 * unit,
            SHIFT_LIMIT as f64 * unit
        ),
        format!("; lines <= {CONTENT_LIMIT} chars: <= {LINE_LIMIT} with a host's \"N12345 \" and \"*123\""),
    ];
    match c.firmware {
        Firmware::V6_3_1 => {
            lines.push(format!("M970 {axis}0"));
            for (d, s) in [('F', &c.forward), ('B', &c.backward)] {
                for n in 0..ITEMS {
                    lines.push(format!(
                        "M971 {axis} {d} I{n} M{} P{}",
                        number(f64::from(s.mag[n]), MAG_DECIMALS),
                        number(f64::from(s.pha[n]), PHA_DECIMALS)
                    ));
                }
            }
            lines.push(format!("M970 {axis}1"));
        }
        Firmware::V6_2 => {
            for (d, s) in [('F', &c.forward), ('B', &c.backward)] {
                lines.push(m973_line(axis, d, s));
            }
        }
    }
    if let Some(l) = lines.iter().find(|l| l.len() > CONTENT_LIMIT) {
        return Err(ExportError::Invalid(format!(
            "a line of {} characters ({:?}…): the printer keeps {LINE_LIMIT}, {HOST_MARGIN} of them for a host's \
             line number and checksum{}",
            l.len(),
            &l[..24.min(l.len())],
            if c.firmware == Firmware::V6_2 { "; firmware >= 6.3.1 writes one item per line" } else { "" }
        )));
    }
    Ok(lines.join("\n") + "\n")
}

/// `M973 <axis><dir><mag>,<pha> …` up to the last non-zero item (6.2's `parse_pairs`: pairs
/// separated by one space, `strtod` each).
fn m973_line(axis: char, dir: char, s: &Spectrum) -> String {
    let last = (0..ITEMS).rev().find(|&n| s.mag[n] != 0.0).unwrap_or(0);
    let pairs: Vec<String> = (0..=last)
        .map(|n| format!("{},{}", number(f64::from(s.mag[n]), MAG_DECIMALS), number(f64::from(s.pha[n]), PHA_DECIMALS)))
        .collect();
    format!("M973 {axis}{dir}{}", pairs.join(" "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_never_use_an_exponent_or_negative_zero() {
        assert_eq!(number(1e-9, 6), "0");
        assert_eq!(number(-1e-9, 6), "0");
        assert_eq!(number(0.0087719, 6), "0.008772");
        assert_eq!(number(-1.1, 5), "-1.1");
        assert_eq!(number(3.0, 5), "3");
        assert_eq!(quantize(0.0087719, 6), 0.008772f32);
    }

    #[test]
    fn comments_carry_no_control_characters_and_stay_short() {
        let t = comment_text("a\nM970 X1\r\u{7}*\\é", 80);
        assert_eq!(t, "a\\nM970 X1\\r\\x07\\x2a\\\\\\u{e9}");
        assert_eq!(comment_text(&"x".repeat(200), 20).len(), 20);
    }
}
