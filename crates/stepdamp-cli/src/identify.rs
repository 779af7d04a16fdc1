//! `stepdamp identify`: under construction (issue 4).

use crate::Global;

/// Arguments of `stepdamp identify`.
#[derive(clap::Args, Debug)]
pub struct IdentifyArgs {}

/// Runs `stepdamp identify`.
pub fn run(_args: IdentifyArgs, _global: &Global) -> anyhow::Result<()> {
    anyhow::bail!("identify is not built yet")
}
