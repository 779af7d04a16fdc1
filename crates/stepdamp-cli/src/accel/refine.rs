//! `stepdamp accel refine` (docs/accelerometer.md#refining-from-captures). Translation only:
//! the captures are read, grouped and refined by `stepdamp-accel`, the table written by
//! `stepdamp-export`'s Prusa writer.

use crate::common::{load_motor, write_atomic};
use crate::export::CurrentArgs;
use anyhow::{Result, bail};
use std::path::PathBuf;
use stepdamp_accel::refine::{
    Earlier, InUse, InfluenceSource, RefineOptions, Refined, TABLE_ITEMS, Timing, current_ratio, refine, refine_with,
};
use stepdamp_export::prusa::headroom::whole_ma_rms_at_or_above;
use stepdamp_export::prusa::measured::{MeasuredTable, TableVsCurrent};
use stepdamp_export::prusa::{self, Firmware, Fitted, PrusaCorrection, Spectrum, gcode};

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
    fn earlier_current(&self) -> Result<Option<stepdamp_export::RunCurrent>> {
        let given = CurrentArgs { current: self.influence_current, current_rms: self.influence_current_rms };
        match (self.influence_from.is_empty(), given.given()) {
            (true, false) => Ok(None),
            (true, true) => bail!("--influence-current(-rms) without --influence-from: whose current is it?"),
            (false, false) => bail!(
                "--influence-from needs the run current that session was recorded at: --influence-current A (peak) \
                 or --influence-current-rms A (RMS per phase)"
            ),
            (false, true) => Ok(Some(given.run_current()?)),
        }
    }
}

/// Runs `stepdamp accel refine`.
pub(super) fn run_refine(a: RefineArgs) -> Result<()> {
    let (axis, letter) = super::parse_axis(&a.axis)?;
    if !(a.mm_per_rev.is_finite() && (1.0..=1000.0).contains(&a.mm_per_rev)) {
        bail!("--mm-per-rev {:e}: must be in 1..=1000 mm", a.mm_per_rev);
    }
    let run = a.current.run_current()?;
    let earlier_run = a.earlier_current()?;
    let motor = load_motor(&a.motor)?;
    let captures = super::read_captures(&a.logs, axis)?;
    let old = super::table_in_use(&a.in_use, letter)?;
    let o = RefineOptions {
        periods_per_rev: u32::from(motor.motor.pole_pairs),
        mm_per_rev: a.mm_per_rev,
        periods_per_block: a.periods_per_block,
        scale: Firmware::V6_3_1.scale(),
        timing: match a.timing {
            TimingArg::Markers => Timing::Markers,
            TimingArg::Planned => Timing::Planned,
        },
    };
    let spectra = |s: &Spectrum| std::array::from_fn(|n| (f64::from(s.mag[n]), f64::from(s.pha[n])));
    let old_items = InUse { forward: spectra(&old.forward), backward: spectra(&old.backward) };
    outln!(
        "{} captures; first-sample time {}; belt {} mm/rev; {} electrical periods per revolution",
        captures.len(),
        match a.timing {
            TimingArg::Planned => "planned (0, as the firmware assumes)",
            TimingArg::Markers => "from each capture's markers",
        },
        a.mm_per_rev,
        o.periods_per_rev
    );
    let refined = match earlier_run {
        None => refine(&captures, &o, &old_items)?,
        Some(then) => {
            let current_ratio = current_ratio(run.peak_a(), then.peak_a())?;
            let earlier_captures = super::read_captures(&a.influence_from, axis)?;
            // The coefficients do not depend on the table that was in use then.
            let steps = refine(&earlier_captures, &o, &InUse::default())?;
            outln!(
                "earlier session: {} captures at {then}; its influences carried ×{current_ratio:.4} to {run}",
                earlier_captures.len()
            );
            refine_with(&captures, &o, &old_items, Some(&Earlier { steps: &steps, current_ratio }))?
        }
    };
    let mut new = old;
    for r in &refined {
        print_refined(r)?;
        let s = if r.phase_direction > 0.0 { &mut new.forward } else { &mut new.backward };
        let n = r.harmonic as usize;
        s.mag[n] = gcode::quantize(r.item.0, gcode::MAG_DECIMALS);
        s.pha[n] = gcode::quantize(r.item.1, gcode::PHA_DECIMALS);
    }
    let text = write_table(&new, letter, &motor.name, run, motor.drive.current_limit_a)?;
    write_atomic(&a.out, text.as_bytes())?;
    outln!("not simulated: a measured correction, valid at {run}; record the baselines again with it to confirm");
    outln!("wrote {} (M970 {letter}0, M971 {letter} F|B x{TABLE_ITEMS}, M970 {letter}1)", a.out.display());
    Ok(())
}

/// The G-code of `c`, refused when its table would not fit the firmware's int8 shifts, with
/// the run current at which it would (`stepdamp_export::prusa::measured`, from this one
/// table: exact for a detent, an estimate where the ripple grows with the current) up to
/// `limit_a`.
fn write_table(
    c: &PrusaCorrection,
    axis: char,
    name: &str,
    run: stepdamp_export::RunCurrent,
    limit_a: f64,
) -> Result<String> {
    let peaks = [c.forward, c.backward].map(|s| s.peak_shift(c.firmware));
    let peak = peaks.iter().try_fold(0, |m, p| p.map(|p| p.max(m)));
    let Some(peak) = peak.filter(|&p| p <= prusa::SHIFT_LIMIT) else {
        let needs = match peak {
            Some(p) => format!("needs a shift of {p} of 4096"),
            None => "overflows the firmware's 32-bit sum".to_string(),
        };
        let measured = MeasuredTable { peak_a: run.peak_a(), table: *c };
        let up_to = limit_a.max(run.peak_a());
        let limit = "the profile's drive.current_limit_a, or the run current where that is higher";
        let advice = match TableVsCurrent::fit(&[measured])?.lowest_fitting_current_a(up_to)? {
            Some(from) => match whole_ma_rms_at_or_above(from, up_to)? {
                Some(at) => format!(
                    "with a shift that falls as 1/I (a detent's: exact for one; the part of the ripple that grows with \
                     the current moves it either way) the table would fit from {at} (`M906 {axis}{:.0}`, in mA RMS): \
                     record the plan again at that current (whether the motor may run that hot is yours to check) and \
                     refine from those captures",
                    1e3 * at.rms_a()
                ),
                None => format!(
                    "with a shift that falls as 1/I it would fit from {from:.4} A peak, but no whole mA of RMS from \
                     there is within {up_to:.3} A peak ({limit})"
                ),
            },
            None => {
                format!("no run current up to {up_to:.3} A peak ({limit}) makes it fit with a shift that falls as 1/I")
            }
        };
        bail!(
            "the refined table {needs} at {run}, past Prusa's int8 shifts (±{} of 4096, ±0.195 rad): the ripple is \
             too large for the table at this run current; {advice} (docs/accelerometer.md#when-the-table-is-too-small)",
            prusa::SHIFT_LIMIT
        );
    };
    let fitted = Fitted { correction: *c, kept: 1.0, peak_shift: peak, wanted_peak_shift: peak as f64 };
    let text = gcode::write(&fitted, axis, &gcode::Header { profile: name, current: run })?;
    let (back, _) = prusa::parse_text(&text, Some(axis), "the refined G-code")?;
    if back != *c {
        bail!("internal: the refined G-code reads back to another table");
    }
    Ok(text)
}

fn print_refined(r: &Refined) -> Result<()> {
    let dir = if r.phase_direction > 0.0 { "forward" } else { "backward" };
    let (b, i) = (&r.baseline, &r.influence);
    let how = match r.source {
        InfluenceSource::Trial(t) => format!("with the trial {:.4} ± {:.4} m/s²", t.value.abs(), t.radius95),
        InfluenceSource::Carried { current_ratio } => {
            format!("no trial: the earlier session's influence ×{current_ratio:.4}")
        }
    };
    outln!(
        "harmonic {:>2} {dir:<8} at {:+.2} rev/s: baseline {:.4} ± {:.4} m/s², {how}",
        r.harmonic,
        r.speed_rev_s,
        b.value.abs(),
        b.radius95,
    );
    outln!(
        "  influence {:.3e} ± {:.1e} m/s² per rad; item ({:.5}, {:+.4}) -> ({:.5} ± {:.5}, {:+.4}); expected residual within {:.4} m/s²",
        i.coefficient.abs(),
        i.coefficient_radius95,
        r.in_use.0,
        r.in_use.1,
        r.item.0,
        r.item_radius95,
        r.item.1,
        r.expected_residual95
    );
    Ok(())
}
