//! What a profile's `name` may be: one printable line of bounded length, without the
//! characters that open or close a comment, a section, a string or a template in the files
//! the name is written into.
//!
//! Why refuse at load (the exporters escape as well): profiles are shared between users,
//! and a name goes into Klipper configurations, G-code, C headers, SVG, CSV and the
//! terminal. A name with a newline and `[gcode_macro X]` would be a live section of a
//! Klipper configuration, `*/` would end a C comment, `{…}` is evaluated by Klipper's
//! Jinja templates, an ESC byte drives the terminal. A motor's name needs none of them.

/// Longest name, in characters (Unicode scalar values): 64, longer than any catalogue
/// part number with its maker's name, short enough for one line of any generated file.
pub const NAME_MAX_CHARS: usize = 64;

/// Characters a name may not contain besides control and formatting characters, each
/// with the format in which it is special. Allowed on purpose: `(`, `)` (common in motor
/// names; a G-code comment in parentheses is escaped by the exporter that writes one),
/// `:` and `=` (without a line break they cannot start a key), `<`, `>`, `&` (SVG and XML
/// escape them).
pub const NAME_FORBIDDEN: [(char, &str); 8] = [
    (';', "a comment in G-code and Klipper/INI files"),
    ('#', "a comment in Klipper/INI files and TOML"),
    ('[', "a section header in Klipper/INI files"),
    (']', "a section header in Klipper/INI files"),
    ('{', "a Jinja template in Klipper's G-code macros"),
    ('}', "a Jinja template in Klipper's G-code macros"),
    ('"', "the end of a C string or an XML attribute"),
    ('\\', "an escape in C strings and a line continuation of C comments"),
];

/// The rule as one phrase (what an error message states), from [`NAME_MAX_CHARS`] and
/// [`NAME_FORBIDDEN`].
pub fn name_rule() -> String {
    let chars: Vec<String> = NAME_FORBIDDEN.iter().map(|(c, _)| format!("`{c}`")).collect();
    format!(
        "must be one printable line of 1 to {NAME_MAX_CHARS} characters, without control or formatting \
         characters, {}, `/*` or `*/`",
        chars.join(", ")
    )
}

/// Unicode characters that change how text is shown without being control characters:
/// line and paragraph separators (a new line for many editors), the bidirectional
/// overrides and isolates (text shown in another order than it is read, "Trojan
/// source"), zero-width characters and the byte-order mark.
fn is_format_char(c: char) -> bool {
    matches!(c, '\u{2028}' | '\u{2029}' | '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2060}'..='\u{206f}' | '\u{feff}')
}

/// Why `name` is not an acceptable profile name (the first reason found), or `None`.
pub fn name_problem(name: &str) -> Option<String> {
    if name.trim().is_empty() {
        return Some("must not be empty".into());
    }
    let n = name.chars().count();
    if n > NAME_MAX_CHARS {
        return Some(format!("is {n} characters long: at most {NAME_MAX_CHARS}"));
    }
    if let Some(c) = name.chars().find(|&c| c.is_control() || is_format_char(c)) {
        let what = if c == '\n' || c == '\r' || c == '\u{2028}' || c == '\u{2029}' {
            "a line break"
        } else {
            "a control or formatting character"
        };
        return Some(format!("contains {what} ({}): {}", c.escape_unicode(), name_rule()));
    }
    if let Some((c, why)) = NAME_FORBIDDEN.iter().find(|(c, _)| name.contains(*c)) {
        return Some(format!("contains `{c}`, {why}: {}", name_rule()));
    }
    for pair in ["/*", "*/"] {
        if name.contains(pair) {
            return Some(format!("contains `{pair}`, a C comment delimiter: {}", name_rule()));
        }
    }
    None
}

/// The name of a profile derived from one named `base`: `base` followed by `suffix`
/// (e.g. `" variant 7"`), with `base` cut (ending in `…`) so that the result stays within
/// [`NAME_MAX_CHARS`]. `suffix` itself must follow the rule.
pub fn derived_name(base: &str, suffix: &str) -> String {
    let room = NAME_MAX_CHARS.saturating_sub(suffix.chars().count());
    if base.chars().count() <= room {
        return format!("{base}{suffix}");
    }
    let cut: String = base.chars().take(room.saturating_sub(1)).collect();
    format!("{}…{suffix}", cut.trim_end())
}

/// `name` quoted and escaped for a message: control and formatting characters as
/// `\u{..}`, at most 80 characters shown (then `…`).
pub fn quoted_name(name: &str) -> String {
    let mut out = String::from("\"");
    for (i, c) in name.chars().enumerate() {
        if i == 80 {
            out.push('…');
            break;
        }
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            c if c.is_control() || is_format_char(c) => out.extend(c.escape_unicode()),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordinary_motor_names_are_accepted() {
        for ok in
            ["patent-motor", "NEMA 17 17HS4401 (Bigtreetech)", "Schrittmotor Größe 23", "步进电机 42", "a/b_c.d+e"]
        {
            assert_eq!(name_problem(ok), None, "{ok}");
        }
        assert_eq!(name_problem(&"x".repeat(NAME_MAX_CHARS)), None);
    }

    #[test]
    fn a_newline_with_a_klipper_section_is_refused_as_a_line_break() {
        let e = name_problem("m\n[gcode_macro PWNED]\ngcode: M112").unwrap();
        assert!(e.contains("a line break") && e.contains("\\u{a}"), "{e}");
    }

    #[test]
    fn escape_bidi_overrides_and_separators_are_refused() {
        for bad in ["m\u{1b}[31m", "m\u{202e}x", "m\u{2028}x", "m\u{0}", "m\rx", "m\u{feff}"] {
            assert!(name_problem(bad).is_some(), "{bad:?}");
        }
    }

    #[test]
    fn comment_section_string_and_template_characters_are_refused() {
        for bad in ["m */ int x; /*", "m;G28", "m # x", "[m]", "m{x}", "m\"x", "m\\", "m /* x"] {
            let e = name_problem(bad).unwrap_or_else(|| panic!("{bad:?} accepted"));
            assert!(e.contains("contains `"), "{e}");
        }
    }

    #[test]
    fn an_empty_or_overlong_name_is_refused_with_its_length() {
        assert_eq!(name_problem(" ").unwrap(), "must not be empty");
        let e = name_problem(&"é".repeat(NAME_MAX_CHARS + 1)).unwrap();
        assert!(e.contains("65 characters") && e.contains("at most 64"), "{e}");
    }

    #[test]
    fn a_derived_name_stays_within_the_limit_and_keeps_its_suffix() {
        assert_eq!(derived_name("m", " variant 7"), "m variant 7");
        let long = "x".repeat(NAME_MAX_CHARS);
        let d = derived_name(&long, " controller model 123456");
        assert_eq!(d.chars().count(), NAME_MAX_CHARS);
        assert!(d.ends_with("x… controller model 123456") && name_problem(&d).is_none(), "{d}");
    }

    #[test]
    fn a_quoted_name_shows_control_characters_escaped_and_is_cut() {
        assert_eq!(quoted_name("a\n[b]\u{1b}\"c"), "\"a\\u{a}[b]\\u{1b}\\\"c\"");
        assert!(quoted_name(&"x".repeat(1000)).ends_with("x…\""));
        assert_eq!(quoted_name(&"x".repeat(1000)).chars().count(), 83);
    }
}
