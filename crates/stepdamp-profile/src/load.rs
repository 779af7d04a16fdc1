//! Presets, files, and which of the two a name means.

use crate::data::ProfileData;
use crate::error::ProfileError;
use crate::profile::Profile;
use std::path::Path;

/// Names of the built-in presets; their files are `crates/stepdamp-profile/presets/`.
pub const PRESETS: [&str; 4] = ["patent-motor", "nema17-17hs4401", "nema23-57mm", "nema34-86mm"];

/// Largest profile file read, in bytes: 1 MiB, a thousand times a real profile (a preset is
/// about 1 kB), so that a wrong path (`/dev/zero`, a log) is refused at once.
pub const MAX_PROFILE_BYTES: u64 = 1 << 20;

/// The TOML text of a preset.
pub fn preset_text(name: &str) -> Option<&'static str> {
    Some(match name {
        "patent-motor" => include_str!("../presets/patent-motor.toml"),
        "nema17-17hs4401" => include_str!("../presets/nema17-17hs4401.toml"),
        "nema23-57mm" => include_str!("../presets/nema23-57mm.toml"),
        "nema34-86mm" => include_str!("../presets/nema34-86mm.toml"),
        _ => return None,
    })
}

/// What a motor argument names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotorRef<'a> {
    /// A built-in preset.
    Preset(&'a str),
    /// A profile file.
    File(&'a Path),
}

impl<'a> MotorRef<'a> {
    /// The rule: a name with a `/` (so `./name` too) or ending in `.toml` is a file; a bare
    /// name is a preset. A bare name that is a preset and also a file in the working
    /// directory is an error (which one was meant cannot be told).
    pub fn parse(name: &'a str) -> Result<MotorRef<'a>, ProfileError> {
        let is_path = name.contains('/') || name.contains(std::path::MAIN_SEPARATOR) || name.ends_with(".toml");
        if is_path {
            return Ok(MotorRef::File(Path::new(name)));
        }
        let file_exists = Path::new(name).exists();
        match preset_text(name) {
            Some(_) if file_exists => Err(ProfileError::Ambiguous(name.to_string())),
            Some(_) => Ok(MotorRef::Preset(name)),
            None => Err(ProfileError::Unknown { name: name.to_string(), file_exists }),
        }
    }
}

impl Profile {
    /// A built-in preset by name.
    pub fn preset(name: &str) -> Option<Profile> {
        preset_text(name).map(|t| Profile::from_toml_str(t, name).expect("built-in presets are valid (tested)"))
    }

    /// A preset name or the path of a TOML profile, by the rule of [`MotorRef::parse`].
    pub fn load(name_or_path: &str) -> Result<Profile, ProfileError> {
        match MotorRef::parse(name_or_path)? {
            MotorRef::Preset(name) => Ok(Profile::preset(name).expect("parse found it")),
            MotorRef::File(path) if !path.exists() => Err(ProfileError::NoSuchFile(path.to_path_buf())),
            MotorRef::File(path) => Profile::from_file(path),
        }
    }

    /// Reads and validates a TOML profile of at most [`MAX_PROFILE_BYTES`] (a larger or
    /// endless input, such as `/dev/zero`, is refused after reading that much).
    pub fn from_file(path: &Path) -> Result<Profile, ProfileError> {
        let text = stepdamp_out::input::read_to_string_bounded(path, MAX_PROFILE_BYTES)
            .map_err(|source| ProfileError::Read { path: path.to_path_buf(), source })?;
        Profile::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses and validates TOML text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Profile, ProfileError> {
        ProfileData::from_toml_str(text, origin)?.validate(origin)
    }
}

impl ProfileData {
    /// Parses TOML text without checking the values; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<ProfileData, ProfileError> {
        toml::from_str(text)
            .map_err(|e| ProfileError::Parse { path: origin.to_string(), message: one_line(&e.to_string()) })
    }
}

/// Longest parser message shown, in characters (it quotes the offending line).
const MAX_MESSAGE_CHARS: usize = 400;

/// A parser message on one line with the control characters of the file's text (an ESC
/// sequence in the quoted line) escaped, so that it cannot drive the terminal.
fn one_line(s: &str) -> String {
    stepdamp_out::input::printable(joined(s).as_bytes(), MAX_MESSAGE_CHARS)
}

/// The parser message on one line: toml's "TOML parse error at line L, column C", its
/// source excerpt (`L | text`, caret lines dropped) and the reason become
/// "TOML parse error at line L, column C (`text`): reason".
fn joined(s: &str) -> String {
    let mut head = Vec::new();
    let mut source = Vec::new();
    let mut rest = Vec::new();
    for line in s.lines().map(str::trim).filter(|l| !l.is_empty()) {
        match line.split_once('|') {
            Some((n, text)) if n.trim().chars().all(|c| c.is_ascii_digit()) => {
                let text = text.trim();
                // `|` alone and `| ^^^` carets carry no words.
                if !n.trim().is_empty() && !text.is_empty() {
                    source.push(format!("`{text}`"));
                }
            }
            _ if head.is_empty() && rest.is_empty() && line.starts_with("TOML parse error") => head.push(line),
            _ => rest.push(line),
        }
    }
    let mut out = head.join(" ");
    if !source.is_empty() {
        out += &format!(" ({})", source.join(" "));
    }
    if !rest.is_empty() {
        if !out.is_empty() {
            out += ": ";
        }
        out += &rest.join(" ");
    }
    out
}
