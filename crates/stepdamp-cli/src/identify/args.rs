//! What several `identify` subcommands parse and check alike: harmonic orders, the plan's
//! options, the output file, the default profile name.

use anyhow::{Result, anyhow, bail};
use std::path::Path;
use stepdamp_identify::plan::PlanOptions;
use stepdamp_sim::Profile;

/// `--orders`: harmonic orders, distinct, each in 1..=[`stepdamp_core::MAX_HARMONIC_ORDER`]
/// (a typed clap value: clap names the option and the value as written).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Orders(pub(super) Vec<u16>);

/// Parses a comma list of harmonic orders (1..=32, distinct).
pub(super) fn parse_orders(s: &str) -> Result<Orders, String> {
    let mut out: Vec<u16> = Vec::new();
    for part in s.split(',').map(str::trim) {
        if part.is_empty() {
            return Err("an empty entry; give a comma list such as 1,2,4".into());
        }
        let k: u16 = part.parse().map_err(|_| format!("'{part}' is not a whole number"))?;
        if k == 0 || usize::from(k) > stepdamp_core::MAX_HARMONIC_ORDER {
            return Err(format!("{k}: each order must be in 1..={}", stepdamp_core::MAX_HARMONIC_ORDER));
        }
        if out.contains(&k) {
            return Err(format!("{k} is listed twice"));
        }
        out.push(k);
    }
    Ok(Orders(out))
}

/// The plan's options from `--orders` and `--periods` (checked: 2..=100000 periods).
pub(super) fn plan_options(orders: &[u16], periods: f64) -> Result<PlanOptions> {
    if !(periods.is_finite() && (2.0..=100_000.0).contains(&periods)) {
        bail!("--periods {periods}: must be between 2 and 100000 electrical periods");
    }
    Ok(PlanOptions { orders: orders.to_vec(), electrical_periods: periods, ..PlanOptions::default() })
}

/// `<base name>-<suffix>`.
pub(super) fn default_name(base: &Profile, suffix: &str) -> String {
    format!("{}-{suffix}", base.name)
}

/// Refuses an `--out` file that could not be written (its directory missing or not
/// writable, or a directory in its place), before any work or any report file.
pub(super) fn check_output_dir(out: &Path) -> Result<()> {
    let dir = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!("--out {}: directory {} does not exist", out.display(), dir.display());
    }
    if out.is_dir() {
        bail!(
            "--out {}: is a directory; give the profile's file name, e.g. {}",
            out.display(),
            out.join("identified.toml").display()
        );
    }
    // Fail now, before any work or any report file, if the profile could not be written.
    let probe = dir.join(format!(".stepdamp-write-test-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .map_err(|e| anyhow!("--out {}: directory {} is not writable: {e}", out.display(), dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}
