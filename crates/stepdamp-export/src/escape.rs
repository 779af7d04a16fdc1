//! Escaping for every writer: text from a profile (its name above all) that goes into a
//! file another program reads, or onto a terminal, passes through one of these functions.
//! Profiles are shared between users, so a name is hostile until escaped: a newline in a
//! Klipper comment starts a live config section, an ESC byte drives the terminal, `*/`
//! ends a C comment. The profile loader also refuses such names; the writers do not
//! count on it.
//!
//! Every function returns **one line** of printable text (no control character, no line
//! or paragraph separator, no bidirectional-override character), with what it removed
//! shown as a visible escape (`\n`, `\x1b`, `\u{202e}`), and a backslash as `\\` so the
//! escape is unambiguous. Format rules on top (see `docs/exporters.md#escaping`):
//!
//! - [`line()`]: the terminal, Klipper config comments (`#` to the end of the line), G-code
//!   comments (`;` to the end of the line).
//! - [`gcode_comment`]: [`line()`] restricted to ASCII (printer firmware reads bytes).
//! - [`c_comment`]: inside `/* … */` or `//`: additionally no `*/`, `/*`, `??` (trigraphs),
//!   and a backslash only to start an escape, never at the end (a `\` at the end of a `//`
//!   line continues the comment onto the next line): ASCII only, others as `\xHH` /
//!   `\u{…}`.
//! - [`c_identifier`]: a C identifier (`[A-Za-z_][A-Za-z0-9_]*`) from any text.
//! - [`xml_text`]: [`line()`], then the five XML specials as entities.
//! - [`csv_field`]: [`line()`], then RFC 4180 quoting where needed, and a leading `'` before
//!   `=`, `+`, `-`, `@` (spreadsheets run such a cell as a formula).

use std::fmt::Write;

/// Whether `c` must not be written raw into one line of text: control characters (C0, DEL,
/// C1), the Unicode line and paragraph separators, and the bidirectional controls that can
/// make text display in an order other than the one a program reads it in.
pub fn is_unsafe(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{2028}' | '\u{2029}' | '\u{200e}' | '\u{200f}' | '\u{061c}')
        || ('\u{202a}'..='\u{202e}').contains(&c)
        || ('\u{2066}'..='\u{2069}').contains(&c)
        || c == '\u{feff}'
}

fn push_escaped(out: &mut String, c: char) {
    match c {
        '\n' => out.push_str("\\n"),
        '\r' => out.push_str("\\r"),
        '\t' => out.push_str("\\t"),
        '\\' => out.push_str("\\\\"),
        c if (c as u32) < 0x80 => {
            let _ = write!(out, "\\x{:02x}", c as u32);
        }
        c => {
            let _ = write!(out, "\\u{{{:x}}}", c as u32);
        }
    }
}

/// One printable line: unsafe characters ([`is_unsafe`]) and `\` shown as escapes.
pub fn line(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if is_unsafe(c) || c == '\\' {
            push_escaped(&mut out, c);
        } else {
            out.push(c);
        }
    }
    out
}

/// Text for a G-code comment (after `;`): [`line()`], ASCII only.
pub fn gcode_comment(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if is_unsafe(c) || c == '\\' || !c.is_ascii() {
            push_escaped(&mut out, c);
        } else {
            out.push(c);
        }
    }
    out
}

/// Text for a C or C++ comment (`/* … */` or `//`): printable ASCII without `\`, with the
/// second character of `*/`, `/*` and `??` escaped, so the text can neither end the
/// comment, open a nested one (a `-Wcomment` error under `-Werror`), form a trigraph, nor
/// continue onto the next line. Escapes are written `\xHH` / `\u{…}` (never ending in `\`).
pub fn c_comment(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut prev = '\0';
    for c in s.chars() {
        let pair = matches!((prev, c), ('*', '/') | ('/', '*') | ('?', '?'));
        if is_unsafe(c) || !c.is_ascii() || c == '\\' || pair {
            if (c as u32) < 0x80 {
                let _ = write!(out, "\\x{:02x}", c as u32);
            } else {
                let _ = write!(out, "\\u{{{:x}}}", c as u32);
            }
            prev = '\0';
        } else {
            out.push(c);
            prev = c;
        }
    }
    out
}

/// Largest length of a generated C identifier stem, characters (C99 guarantees 63
/// significant characters of an internal identifier; suffixes such as `_PARAMS` fit).
pub const C_IDENT_MAX: usize = 48;

/// A C identifier from any text: every character outside `[A-Za-z0-9_]` becomes `_`, runs
/// of `_` collapse to one, leading and trailing `_` go (a leading `_` is reserved at file
/// scope), a leading digit gets the prefix `sd_`, at most [`C_IDENT_MAX`] characters; an
/// empty result is `None`.
pub fn c_identifier(s: &str) -> Option<String> {
    let mut out = String::new();
    for c in s.chars() {
        let c = if c.is_ascii_alphanumeric() { c } else { '_' };
        if !(c == '_' && (out.is_empty() || out.ends_with('_'))) {
            out.push(c);
        }
    }
    let mut out = out.trim_end_matches('_').to_string();
    if out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert_str(0, "sd_");
    }
    out.truncate(C_IDENT_MAX);
    let out = out.trim_end_matches('_').to_string();
    (!out.is_empty()).then_some(out)
}

/// Text for XML character data or an attribute value: [`line()`], then `& < > " '` as
/// entities. (XML 1.0 cannot carry most control characters even as `&#…;`, hence the
/// visible escapes.)
pub fn xml_text(s: &str) -> String {
    let mut out = String::new();
    for c in line(s).chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// One CSV field (RFC 4180): [`line()`]; a leading `=`, `+`, `-` or `@` gets a `'` before it;
/// quoted (with `"` doubled) when it holds `,`, `;`, `"` or starts or ends with a space.
pub fn csv_field(s: &str) -> String {
    let mut t = line(s);
    if t.starts_with(['=', '+', '-', '@']) {
        t.insert(0, '\'');
    }
    if t.contains([',', ';', '"']) || t.starts_with(' ') || t.ends_with(' ') {
        format!("\"{}\"", t.replace('"', "\"\""))
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hostile names every writer is tested with.
    const HOSTILE: [&str; 4] = ["m\n[gcode_macro PWNED]\ngcode: M112", "esc\x1b[2Jx", "*/ int x; /*", "<script>&"];

    #[test]
    fn line_keeps_one_printable_line_and_shows_what_it_escaped() {
        assert_eq!(line(HOSTILE[0]), "m\\n[gcode_macro PWNED]\\ngcode: M112");
        assert_eq!(line(HOSTILE[1]), "esc\\x1b[2Jx");
        assert_eq!(line("a\\b\u{202e}c\u{85}"), "a\\\\b\\u{202e}c\\u{85}");
        assert_eq!(line("patent-motor (N·m)"), "patent-motor (N·m)");
        for h in HOSTILE {
            assert!(!line(h).chars().any(is_unsafe), "{h:?}");
        }
    }

    #[test]
    fn c_comment_cannot_end_nest_splice_or_form_trigraphs() {
        for h in HOSTILE.iter().chain(&["a*/b", "/*", "x\\", "??/", "???/", "*//*", "é*/"]) {
            let t = c_comment(h);
            assert!(!t.contains("*/") && !t.contains("/*") && !t.contains("??"), "{h:?} -> {t:?}");
            assert!(!t.contains('\\') || !t.ends_with('\\'), "{h:?} -> {t:?}");
            assert!(t.chars().all(|c| c.is_ascii() && !c.is_control()), "{h:?} -> {t:?}");
        }
        assert_eq!(c_comment("*/ int x; /*"), "*\\x2f int x; /\\x2a");
        assert_eq!(c_comment("a\\"), "a\\x5c");
    }

    #[test]
    fn c_identifier_is_a_valid_identifier_or_none() {
        assert_eq!(c_identifier("x_axis").as_deref(), Some("x_axis"));
        assert_eq!(c_identifier("motor-params.v2").as_deref(), Some("motor_params_v2"));
        assert_eq!(c_identifier("2nd axis").as_deref(), Some("sd_2nd_axis"));
        assert_eq!(c_identifier("__x__").as_deref(), Some("x"));
        assert_eq!(c_identifier("*/ int x; /*").as_deref(), Some("int_x"));
        assert_eq!(c_identifier("ü.-"), None);
        assert!(c_identifier(&"a".repeat(500)).unwrap().len() == C_IDENT_MAX);
    }

    #[test]
    fn xml_and_csv_escape_their_specials() {
        assert_eq!(xml_text("<script>&\x1b'\""), "&lt;script&gt;&amp;\\x1b&apos;&quot;");
        assert_eq!(csv_field("a,b\"c"), "\"a,b\"\"c\"");
        assert_eq!(csv_field("=cmd()"), "'=cmd()");
        assert_eq!(csv_field("m\n[x]"), "m\\n[x]");
        assert_eq!(csv_field("plain"), "plain");
    }

    #[test]
    fn gcode_comment_is_ascii() {
        assert_eq!(gcode_comment("N·m\n;G28"), "N\\u{b7}m\\n;G28");
    }
}
