//! `stepdamp accel refine` (docs/accelerometer.md#refining-from-captures). Translation only:
//! the captures are read, grouped and refined by `stepdamp-accel`, the table written by
//! `stepdamp-export`'s Prusa writer.

use crate::common::{load_motor, write_atomic};
use crate::export::CurrentArgs;
use anyhow::{Result, anyhow, bail};
use std::path::PathBuf;
use stepdamp_accel::refine::{RefineOptions, TABLE_ITEMS, Timing, current_ratio};
use stepdamp_accel::ripple::MM_PER_REV_RANGE;
use stepdamp_export::RunCurrent;
use stepdamp_export::prusa::Firmware;
use stepdamp_export::prusa::refine::{Request, Session, prusa_refine};

/// How the time of each capture's first sample is found.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimingArg {
    /// From the capture's two marker moves.
    Markers,
    /// 0: the firmware's own assumption.
    Planned,
}

/// Arguments of `stepdamp accel refine`.
#[derive(clap::Args, Debug)]
pub struct RefineArgs {
    /// A session log holding the captures (a host's log, e.g. OctoPrint's serial.log, or the
    /// plain serial output); repeat for several. Each capture's G-code must be in the log
    /// (the host's echo of the command it sent).
    #[arg(long = "log", required = true, value_name = "FILE")]
    logs: Vec<PathBuf>,
    /// Motor profile (preset or TOML): its pole pairs are the electrical periods per revolution.
    #[arg(long, value_name = "PRESET|FILE")]
    motor: String,
    /// The table in use while the captures were recorded: a file with its M971 lines (what
    /// `export prusa` wrote, or the printer's M972 read-back), or `none`.
    #[arg(long, value_name = "FILE|none")]
    in_use: String,
    /// The motor the captures moved: X or Y (on CoreXY the A or B motor).
    #[arg(long, value_name = "X|Y")]
    axis: String,
    /// Belt travel per motor revolution, mm (GT2 belt, 16-tooth pulley: 32).
    #[arg(long, default_value_t = 32.0)]
    mm_per_rev: f64,
    /// Whole electrical periods per lock-in block.
    #[arg(long, default_value_t = 20)]
    periods_per_block: u32,
    /// How the first sample's time is found: planned (the firmware's own 0; a start latency
    /// that repeats from capture to capture cancels out of the step) or markers (estimated
    /// from each capture's marker moves; it fails where the head filters the markers away).
    #[arg(long, value_enum, default_value_t = TimingArg::Planned)]
    timing: TimingArg,
    /// The run current the captures were recorded at (the table is valid there).
    #[command(flatten)]
    current: CurrentArgs,
    /// An earlier session's log (its baselines and trials; repeat for several): a harmonic
    /// this session recorded without a trial takes that session's influence at the same speed
    /// and direction, times the ratio of the run currents (a raised current, or a second step
    /// with the refined table loaded; docs/accelerometer.md#a-step-without-a-trial).
    #[arg(long = "influence-from", value_name = "FILE")]
    influence_from: Vec<PathBuf>,
    /// The run current of the --influence-from session, as a PEAK of the current vector, A.
    #[arg(long, value_name = "A", conflicts_with = "influence_current_rms")]
    influence_current: Option<f64>,
    /// The run current of the --influence-from session, as the RMS of each phase's current, A.
    #[arg(long, value_name = "A")]
    influence_current_rms: Option<f64>,
    /// Where to write the new table's G-code.
    #[arg(long)]
    out: PathBuf,
}

impl RefineArgs {
    /// The earlier session's run current, when --influence-from is given (then it is needed).
    fn earlier_current(&self) -> Result<Option<RunCurrent>> {
        let named = |name: &str, v: f64, c: Result<RunCurrent, _>| {
            c.map(Some).map_err(|_: stepdamp_export::ExportError| anyhow!("{name} {v:e} A: must be finite and > 0"))
        };
        match (self.influence_from.is_empty(), self.influence_current, self.influence_current_rms) {
            (true, None, None) => Ok(None),
            (true, _, _) => bail!("--influence-current(-rms) without --influence-from: whose current is it?"),
            (false, Some(p), _) => named("--influence-current (peak)", p, RunCurrent::from_peak(p)),
            (false, None, Some(r)) => named("--influence-current-rms", r, RunCurrent::from_rms(r)),
            (false, None, None) => bail!(
                "--influence-from needs the run current that session was recorded at: --influence-current A (peak) \
                 or --influence-current-rms A (RMS per phase)"
            ),
        }
    }
}

/// Runs `stepdamp accel refine`.
pub(super) fn run_refine(a: RefineArgs) -> Result<()> {
    let (axis, letter) = super::parse_axis(&a.axis)?;
    let (lo, hi) = MM_PER_REV_RANGE;
    if !(a.mm_per_rev.is_finite() && (lo..=hi).contains(&a.mm_per_rev)) {
        bail!("--mm-per-rev {:e}: must be in {lo}..={hi} mm (a pulley pitch radius of 1-50 mm)", a.mm_per_rev);
    }
    let run = a.current.run_current()?;
    let earlier_run = a.earlier_current()?;
    let motor = load_motor(&a.motor)?;
    let captures = super::read_captures(&a.logs, axis)?;
    let in_use = super::table_in_use(&a.in_use, letter)?;
    let earlier_captures = match earlier_run {
        Some(then) => {
            // Checked before the earlier logs are read: a wrong current is the likelier mistake.
            current_ratio(run.peak_a(), then.peak_a())?;
            super::read_captures(&a.influence_from, axis)?
        }
        None => Vec::new(),
    };
    let options = RefineOptions {
        periods_per_rev: u32::from(motor.motor.pole_pairs),
        mm_per_rev: a.mm_per_rev,
        periods_per_block: a.periods_per_block,
        scale: Firmware::V6_3_1.scale(),
        timing: match a.timing {
            TimingArg::Markers => Timing::Markers,
            TimingArg::Planned => Timing::Planned,
        },
    };
    outln!(
        "{} captures; first-sample time {}; belt {} mm/rev; {} electrical periods per revolution",
        captures.len(),
        match a.timing {
            TimingArg::Planned => "planned (0, as the firmware assumes)",
            TimingArg::Markers => "from each capture's markers",
        },
        a.mm_per_rev,
        options.periods_per_rev
    );
    let request = Request {
        options,
        in_use,
        now: Session { captures: &captures, run },
        earlier: earlier_run.map(|run| Session { captures: &earlier_captures, run }),
        axis: letter,
        profile_name: &motor.name,
        current_limit_a: motor.drive.current_limit_a,
    };
    let refined = prusa_refine(&request)?;
    out!("{refined}");
    write_atomic(&a.out, refined.gcode(&request)?.as_bytes())?;
    outln!("not simulated: a measured correction, valid at {run}; record the baselines again with it to confirm");
    outln!("wrote {} (M970 {letter}0, M971 {letter} F|B x{TABLE_ITEMS}, M970 {letter}1)", a.out.display());
    Ok(())
}
