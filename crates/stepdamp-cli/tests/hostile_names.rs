//! Hostile profile names through every exporter, the SVG and the terminal; the Klipper
//! driver set; C headers of two axes in one translation unit; options that do nothing.
//!
//! The profile loader may refuse such names itself; the writers must not count on it, so
//! each test accepts either a refusal (non-zero exit, nothing written, the message
//! escaped) or an output in which the name stays inert.

use std::path::Path;
use std::process::{Command, Output};

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

/// The names of the red-team report: a Klipper section and G-code, an ESC sequence, the
/// end of a C comment, markup.
const HOSTILE: [&str; 4] = ["m\n[gcode_macro PWNED]\ngcode: M112", "esc\u{1b}[2Jx", "*/ int x; /*", "<script>&"];

/// patent-motor with `name` (TOML-escaped: the file itself is valid TOML).
fn hostile_profile(dir: &Path, i: usize, name: &str) -> String {
    let show = stepdamp(&["motor", "show", "patent-motor"]);
    let toml = String::from_utf8(show.stdout).unwrap();
    let quoted = format!("{name:?}").replace("\\u{1b}", "\\u001b");
    let t = toml.replacen("name = \"patent-motor\"", &format!("name = {quoted}"), 1);
    assert_ne!(t, toml, "the preset's name line is where the test expects it");
    let p = dir.join(format!("hostile{i}.toml"));
    std::fs::write(&p, t).unwrap();
    p.to_str().unwrap().to_string()
}

/// No control character but newline (and tab) reaches the terminal.
fn terminal_is_clean(o: &Output) {
    let t = text(o);
    assert!(!t.chars().any(|c| c.is_control() && c != '\n' && c != '\t'), "raw control character in {t:?}");
}

/// Runs an export; `Some(file text)` when it wrote, `None` when the name was refused.
fn export(fmt: &str, profile: &str, out: &Path, extra: &[&str]) -> Option<String> {
    let mut args = vec!["export", fmt, "--motor", profile, "--out", out.to_str().unwrap(), "--duration", "0"];
    if fmt != "simplefoc" {
        args.extend_from_slice(&["--current", "1.9"]);
    }
    args.extend_from_slice(extra);
    let o = stepdamp(&args);
    terminal_is_clean(&o);
    if o.status.success() {
        Some(String::from_utf8_lossy(&std::fs::read(out).unwrap()).into_owned())
    } else {
        assert!(text(&o).contains("name"), "refused for another reason: {}", text(&o));
        assert!(!out.exists());
        None
    }
}

#[test]
fn hostile_names_stay_inert_in_every_exported_format() {
    let dir = tempfile::tempdir().unwrap();
    for (i, name) in HOSTILE.iter().enumerate() {
        let prof = hostile_profile(dir.path(), i, name);
        let cfg = dir.path().join(format!("k{i}.cfg"));
        if let Some(k) = export("klipper-tmc", &prof, &cfg, &[]) {
            for l in k.lines() {
                assert!(
                    l.starts_with('#') || l == "[tmc5160 stepper_x]" || l.starts_with("driver_"),
                    "live Klipper line {l:?} for {name:?}"
                );
            }
        }
        for fmt in ["simplefoc", "c-header"] {
            let h = dir.path().join(format!("h{i}_{fmt}.h"));
            if let Some(h) = export(fmt, &prof, &h, &[]) {
                assert!(!h.contains('\u{1b}'), "{fmt}: {h}");
                // The name appears only inside the leading comment.
                let code: String = match fmt {
                    "c-header" => h.split_once("*/").unwrap().1.to_string(),
                    _ => h.lines().filter(|l| !l.starts_with("//")).collect::<Vec<_>>().join("\n"),
                };
                assert!(!code.contains("int x") && !code.contains("script") && !code.contains("PWNED"), "{fmt}: {h}");
            }
        }
        // Prusa: the name only inside its one `;` comment line, escaped to printable ASCII
        // without `*` (a checksum's mark); every other line a comment or M970/M971.
        let g = dir.path().join(format!("p{i}.gcode"));
        if let Some(g) = export("prusa", &prof, &g, &[]) {
            assert!(!g.contains('\u{1b}') && !g.contains("\nM112") && !g.contains("*/ int"), "{g}");
            for l in g.lines() {
                assert!(l.bytes().all(|b| (b' '..=b'~').contains(&b)), "{l:?}");
                let name_free = !l.contains("PWNED") && !l.contains("int x") && !l.contains("script");
                assert!(
                    l.starts_with("; profile: ") || (name_free && (l.starts_with("; ") || l.starts_with("M97"))),
                    "live G-code line {l:?} for {name:?}"
                );
            }
        }
    }
}

#[test]
fn hostile_names_give_a_well_formed_svg() {
    let dir = tempfile::tempdir().unwrap();
    for (i, name) in HOSTILE.iter().enumerate() {
        let prof = hostile_profile(dir.path(), i, name);
        let out = dir.path().join(format!("sweep{i}"));
        let o = stepdamp(&[
            "-q",
            "sweep",
            "--motor",
            &prof,
            "--mode",
            "open-loop",
            "--compensation",
            "off",
            "--from",
            "4",
            "--to",
            "5",
            "--points",
            "2",
            "--duration",
            "0.6",
            "--out",
            out.to_str().unwrap(),
        ]);
        // (The sweep's terminal summary is stepdamp-sim's; see the export tests for the
        // terminal of the exporters.)
        if !o.status.success() {
            assert!(text(&o).contains("name"), "{}", text(&o));
            continue;
        }
        let svg = std::fs::read_to_string(out.join("sweep.svg")).unwrap();
        if let Err(e) = well_formed(&svg) {
            panic!("sweep.svg for {name:?} is not well-formed XML: {e}");
        }
        assert!(!svg.contains("<script"), "{name:?}");
    }
}

/// A strict check of XML 1.0 well-formedness for what an SVG writer emits: only the
/// characters XML allows, every `&` an entity or character reference, `<` only opening a
/// tag, comment, declaration or processing instruction, attributes quoted, tags balanced.
fn well_formed(xml: &str) -> Result<(), String> {
    if let Some(c) = xml.chars().find(|&c| c.is_control() && !matches!(c, '\t' | '\n' | '\r')) {
        return Err(format!("control character {c:?}"));
    }
    let mut stack: Vec<String> = Vec::new();
    let mut rest = xml;
    while let Some(i) = rest.find(['<', '&']) {
        let (text, at) = rest.split_at(i);
        let _ = text;
        if at.starts_with('&') {
            let end = at.find(';').ok_or("& without ;")?;
            let ent = &at[1..end];
            let ok = matches!(ent, "amp" | "lt" | "gt" | "quot" | "apos")
                || ent.strip_prefix("#x").is_some_and(|h| u32::from_str_radix(h, 16).is_ok())
                || ent.strip_prefix('#').is_some_and(|d| d.parse::<u32>().is_ok());
            if !ok {
                return Err(format!("bad reference &{ent};"));
            }
            rest = &at[end + 1..];
            continue;
        }
        if let Some(r) = at.strip_prefix("<?") {
            rest = &r[r.find("?>").ok_or("unclosed <?")? + 2..];
            continue;
        }
        if let Some(r) = at.strip_prefix("<!--") {
            rest = &r[r.find("-->").ok_or("unclosed comment")? + 3..];
            continue;
        }
        if let Some(r) = at.strip_prefix("<!") {
            rest = &r[r.find('>').ok_or("unclosed <!")? + 1..];
            continue;
        }
        let close = at.starts_with("</");
        let body_start = if close { 2 } else { 1 };
        // Find the tag's end outside quoted attribute values.
        let mut quote = None;
        let mut end = None;
        for (j, c) in at.char_indices().skip(body_start) {
            match (quote, c) {
                (None, '"' | '\'') => quote = Some(c),
                (Some(q), c) if c == q => quote = None,
                (Some(_), '<') => return Err("< inside an attribute value".into()),
                (None, '>') => {
                    end = Some(j);
                    break;
                }
                _ => {}
            }
        }
        let end = end.ok_or("unclosed tag")?;
        let tag = &at[body_start..end];
        let self_closing = tag.ends_with('/');
        let name: String = tag.chars().take_while(|c| !c.is_whitespace() && *c != '/').collect();
        if name.is_empty() || !name.chars().all(|c| c.is_alphanumeric() || matches!(c, ':' | '-' | '_' | '.')) {
            return Err(format!("bad tag name in <{tag}>"));
        }
        if !close {
            // Attributes: name="value" pairs only.
            let attrs = tag[name.len()..].trim_end_matches('/');
            let mut a = attrs.trim_start();
            while !a.is_empty() {
                let eq = a.find('=').ok_or_else(|| format!("attribute without value in <{tag}>"))?;
                let v = a[eq + 1..].trim_start();
                let q = v.chars().next().filter(|c| matches!(c, '"' | '\'')).ok_or("unquoted attribute")?;
                let vend = v[1..].find(q).ok_or("unclosed attribute")? + 1;
                a = v[vend + 1..].trim_start();
            }
        }
        if close {
            if stack.pop().as_deref() != Some(name.as_str()) {
                return Err(format!("</{name}> does not close the open tag"));
            }
        } else if !self_closing {
            stack.push(name);
        }
        rest = &at[end + 1..];
    }
    if stack.is_empty() { Ok(()) } else { Err(format!("unclosed {stack:?}")) }
}

#[test]
fn the_well_formedness_check_catches_what_it_must() {
    assert!(well_formed("<svg a=\"1\"><text>a &amp; b</text></svg>").is_ok());
    assert!(well_formed("<svg><text>a & b</text></svg>").is_err());
    assert!(well_formed("<svg><text>\u{1b}</text></svg>").is_err());
    assert!(well_formed("<svg><text><script></text></svg>").is_err());
    assert!(well_formed("<svg a=1/>").is_err());
}

#[test]
fn klipper_refuses_a_driver_without_a_wave_table_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for axis in ["tmc2209 stepper_x", "tmc2208 stepper_y", "tmc2660 stepper_z", "tmc2160 stepper_x"] {
        let out = dir.path().join("tmc.cfg");
        let o = stepdamp(&[
            "export",
            "klipper-tmc",
            "--motor",
            "patent-motor",
            "--current",
            "1.9",
            "--axis",
            axis,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{axis}: {}", text(&o));
        assert!(text(&o).contains("tmc2130, tmc2240, tmc5160"), "{}", text(&o));
        assert!(!out.exists(), "{axis}: a file was written");
    }
    let out = dir.path().join("ok.cfg");
    let o = stepdamp(&[
        "export",
        "klipper-tmc",
        "--motor",
        "patent-motor",
        "--current",
        "1.9",
        "--axis",
        "tmc2240 stepper_y",
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let cfg = std::fs::read_to_string(&out).unwrap();
    assert!(cfg.contains("\n[tmc2240 stepper_y]\ndriver_MSLUT0: "), "{cfg}");
    // Values are decimal: Klipper's getint takes nothing else.
    for l in cfg.lines().filter(|l| l.starts_with("driver_")) {
        let v = l.split_once(": ").unwrap().1;
        assert!(v.parse::<u32>().is_ok(), "{l}");
    }
}

#[test]
fn c_headers_of_two_axes_compile_in_one_unit_and_keep_their_values() {
    let Ok(cc) = Command::new("cc").arg("--version").output() else {
        eprintln!("skipped: no cc");
        return;
    };
    assert!(cc.status.success());
    let dir = tempfile::tempdir().unwrap();
    for (file, current) in [("x_axis.h", "1.9"), ("y-axis.h", "1.2")] {
        let out = dir.path().join(file);
        let o = stepdamp(&[
            "export",
            "c-header",
            "--motor",
            "patent-motor",
            "--current",
            current,
            "--out",
            out.to_str().unwrap(),
            "--duration",
            "0",
        ]);
        assert!(o.status.success(), "{}", text(&o));
    }
    let c = dir.path().join("two.c");
    std::fs::write(
        &c,
        "#include \"x_axis.h\"\n#include \"y-axis.h\"\n#include \"x_axis.h\"\n\
         int main(void) {\n\
             return (x_axis_PARAMS.drive.holding_current_a == 1.9f && y_axis_PARAMS.drive.holding_current_a == 1.2f\n\
                     && x_axis_PARAMS.motor.detent == x_axis_DETENT && y_axis_PARAMS.motor.detent == y_axis_DETENT) ? 0 : 1;\n\
         }\n",
    )
    .unwrap();
    let include = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../include");
    let exe = dir.path().join("two");
    let o = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(&include)
        .arg("-I")
        .arg(dir.path())
        .arg(&c)
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let run = Command::new(&exe).output().unwrap();
    assert_eq!(run.status.code(), Some(0), "an axis lost its values");
}

#[test]
fn options_that_do_nothing_for_a_format_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.h");
    let o = out.to_str().unwrap();
    for (fmt, extra) in [
        ("simplefoc", &["--current", "1.0"][..]),
        ("simplefoc", &["--axis", "X"][..]),
        ("simplefoc", &["--name", "m"][..]),
        ("c-header", &["--axis", "X"][..]),
        ("c-header", &["--loop-hz", "5000"][..]),
        ("prusa", &["--loop-hz", "5000"][..]),
        ("klipper-tmc", &["--name", "m"][..]),
    ] {
        let mut args = vec!["export", fmt, "--motor", "patent-motor", "--out", o, "--duration", "0"];
        args.extend_from_slice(extra);
        let r = stepdamp(&args);
        assert!(!r.status.success(), "{fmt} {extra:?}: {}", text(&r));
        assert!(text(&r).contains("does nothing for export"), "{}", text(&r));
        assert!(!out.exists());
    }
}

#[test]
fn an_export_the_simulation_does_not_confirm_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let show = stepdamp(&["motor", "show", "patent-motor"]);
    let toml = String::from_utf8(show.stdout).unwrap();
    // Order 4 almost all cosine: a Trinamic table carries only its sine part (cos 1.5 = 7 %),
    // so the exported table cannot measurably reduce any resonance.
    let cosine = toml.replacen("amplitude_nm = 0.02\nphase_rad = 0.0\n", "amplitude_nm = 0.02\nphase_rad = 1.5\n", 1);
    assert_ne!(cosine, toml);
    let prof = dir.path().join("cosine.toml");
    std::fs::write(&prof, cosine).unwrap();
    let out = dir.path().join("tmc.cfg");
    let args = [
        "export",
        "klipper-tmc",
        "--motor",
        prof.to_str().unwrap(),
        "--current",
        "1.9",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = stepdamp(&args);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("not measurably better") && text(&o).contains("nothing written"), "{}", text(&o));
    let table = text(&o).split("simulated: open loop, table replay").nth(1).unwrap().to_string();
    assert!(!table.split("simulated:").next().unwrap().contains(" dB lower"), "a gain was printed: {}", text(&o));
    assert!(!out.exists());
    let o = stepdamp(&[&args[..], &["--force"]].concat());
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("writing it anyway") && out.exists(), "{}", text(&o));
}

#[test]
fn a_hostile_table_path_is_escaped_in_its_one_line_error() {
    // A table path is the user's text: read errors (`prusa::read::read_capped`, which every
    // table reader goes through) print it escaped, on one line.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    for name in ["esc\u{1b}[2Jx.gcode", "line\nbreak.gcode"] {
        let path = dir.path().join(name);
        let p = path.to_str().unwrap();
        let simulate = ["accel", "simulate", "--motor", "patent-motor", "--current", "0.9", "--gcode"];
        let simulate = [&simulate[..], &["M973 X F2 R2 H4 A0 B0 C0 D0", "--in-use", p, "--out", out]].concat();
        let sweep = ["-q", "sweep", "--mode", "open-loop", "--compensation", "table", "--table", p, "--out", out];
        for args in [&simulate[..], &sweep[..]] {
            let o = stepdamp(args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(!o.status.success(), "{args:?}: {err}");
            terminal_is_clean(&o);
            assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
            assert!(err.contains("cannot read"), "{args:?}: {err}");
        }
    }
}
