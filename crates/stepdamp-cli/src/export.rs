//! `stepdamp export` and `stepdamp import`: a profile in the correction formats of other
//! drives (crate `stepdamp-export`), with the library's prediction printed.

use crate::Global;
use crate::common::{load_motor, write_atomic};
use anyhow::{Result, bail};
use std::path::{Path, PathBuf};
use stepdamp_core::{Compensation, Mode};
use stepdamp_export::{Correction, RunCurrent, c_header, escape, predict, prusa, simplefoc, tmc};

/// Target format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Prusa-Firmware-Buddy phase stepping (XL, iX, Core One, MK4): M970/M971 G-code for
    /// firmware >= 6.3.1 (M973 with --firmware 6.2) in FILE, and the binary correction files
    /// FILE.fwd.bin and FILE.bck.bin.
    Prusa,
    /// A Klipper [tmc2130|tmc2240|tmc5160 …] block with a Trinamic microstep table.
    KlipperTmc,
    /// A C++ header for SimpleFOC (>= 2.4.0) feed_forward_current.q.
    Simplefoc,
    /// An sd_params initializer for stepdamp's C library (stepdamp.h).
    CHeader,
}

impl Format {
    /// The subcommand's name as typed.
    fn name(self) -> &'static str {
        match self {
            Format::Prusa => "prusa",
            Format::KlipperTmc => "klipper-tmc",
            Format::Simplefoc => "simplefoc",
            Format::CHeader => "c-header",
        }
    }
}

/// Source format of `stepdamp import`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImportFormat {
    /// Prusa-Firmware-Buddy phase stepping: the `M971 X F` / `M971 X B` read-back of firmware
    /// 6.3.1 and later (a terminal log with OctoPrint's `Recv: ` is fine), the 6.2 M972
    /// print, M973 lines or a 168-byte correction file.
    Prusa,
}

/// Prusa firmware generation of `--firmware`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrusaFirmware {
    /// 6.3.1 and later (v6.3.1, v6.3.2): M970/M971 per item, the fixed-point scale.
    #[value(name = "6.3.1", alias = "6.3")]
    V6_3_1,
    /// 6.2.x: one M973 line per direction, the float scale (4x the 6.3.1 magnitudes).
    #[value(name = "6.2")]
    V6_2,
}

impl From<PrusaFirmware> for prusa::Firmware {
    fn from(f: PrusaFirmware) -> Self {
        match f {
            PrusaFirmware::V6_3_1 => prusa::Firmware::V6_3_1,
            PrusaFirmware::V6_2 => prusa::Firmware::V6_2,
        }
    }
}

/// The run current, peak or RMS: at most one of the two (clap's group); the formats that
/// use a current require one ([`CurrentArgs::run_current`]), `export simplefoc` refuses both.
#[derive(clap::Args, Debug)]
#[group(required = false, multiple = false)]
pub struct CurrentArgs {
    /// Run current as the PEAK of the current vector, A: the amplitude of each phase's sine
    /// wave, the unit of the profile's holding_current_a. For a drive's RMS setting (Klipper
    /// run_current, Prusa's motor current) use --current-rms.
    #[arg(long)]
    pub current: Option<f64>,
    /// Run current as the RMS of each phase's current, A (peak = sqrt(2) x RMS): Klipper's
    /// run_current, Prusa's motor current settings.
    #[arg(long)]
    pub current_rms: Option<f64>,
}

impl CurrentArgs {
    /// Whether either option was given.
    pub fn given(&self) -> bool {
        self.current.is_some() || self.current_rms.is_some()
    }

    /// The run current given; an error when neither option is.
    pub fn run_current(&self) -> Result<RunCurrent> {
        Ok(match (self.current, self.current_rms) {
            (Some(p), None) => RunCurrent::from_peak(p)?,
            (None, Some(r)) => RunCurrent::from_rms(r)?,
            _ => bail!(
                "the run current is needed: --current A (peak, the current vector) or --current-rms A (RMS per phase)"
            ),
        })
    }
}

/// Arguments of `stepdamp export`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// Format to write.
    #[arg(value_enum)]
    pub format: Format,
    /// Motor profile (identified TOML) or preset.
    #[arg(long)]
    pub motor: String,
    /// The run current the correction is computed for (prusa, klipper-tmc, c-header).
    #[command(flatten)]
    pub current: CurrentArgs,
    /// Prusa firmware the G-code is for (prusa only; default 6.3.1, which covers 6.3.x).
    #[arg(long, value_enum)]
    pub firmware: Option<PrusaFirmware>,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// Prusa axis (X or Y) / Klipper section: tmc2130, tmc2240 or tmc5160 and the stepper
    /// (e.g. "tmc5160 stepper_x"; the other drivers have no wave table).
    #[arg(long)]
    pub axis: Option<String>,
    /// Simulated time per prediction run, s (0 skips the prediction and its check: nothing
    /// is claimed).
    #[arg(long, default_value_t = 1.0)]
    pub duration: f64,
    /// Write the files even when the prediction shows the correction makes the simulated
    /// motor worse, or not measurably better (by 1 dB at some resonance).
    #[arg(long)]
    pub force: bool,
    /// c-header: the stem of the C names (`<NAME>_PARAMS`, guard `STEPDAMP_<NAME>_H`);
    /// default: the --out file name up to its first dot.
    #[arg(long)]
    pub name: Option<String>,
    /// simplefoc: the loopFOC rate in Hz the prediction models (default 10000).
    #[arg(long)]
    pub loop_hz: Option<f64>,
}

/// Arguments of `stepdamp import prusa`.
#[derive(clap::Args, Debug)]
pub struct ImportArgs {
    /// Source format (only `prusa`).
    #[arg(value_enum)]
    pub format: ImportFormat,
    /// The printer's output (M971 read-back, 6.2 M972 print, M973 lines) or a 168-byte
    /// correction file; at most 1 MiB.
    #[arg(long, visible_alias = "m972")]
    pub readback: PathBuf,
    /// The motor's base profile (everything but the detent model).
    #[arg(long)]
    pub motor: String,
    /// The run current the printer used.
    #[command(flatten)]
    pub current: CurrentArgs,
    /// Firmware scale of a 168-byte correction file (the text forms say their own).
    #[arg(long, value_enum, default_value = "6.3.1")]
    pub firmware: PrusaFirmware,
    /// Axis to read when the file holds several (X or Y).
    #[arg(long)]
    pub axis: Option<char>,
    /// Profile TOML to write.
    #[arg(long)]
    pub out: PathBuf,
}

fn sibling(out: &Path, suffix: &str) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Runs `stepdamp export`: builds the files, predicts what the correction does (unless
/// `--duration 0`), refuses a correction the simulation shows worse or not measurably
/// better (unless `--force`), then writes the files.
pub fn run_export(a: ExportArgs, _g: &Global) -> Result<()> {
    let p = load_motor(&a.motor)?;
    if !(a.duration.is_finite() && (a.duration == 0.0 || (0.5..=100.0).contains(&a.duration))) {
        bail!("--duration {}: 0 (no prediction) or 0.5..=100 s", a.duration);
    }
    refuse_unused_options(&a)?;
    // SimpleFOC's feed-forward does not depend on the run current (refused above).
    let current = if a.format == Format::Simplefoc { None } else { Some(a.current.run_current()?) };
    if let Some(i) = current {
        outln!("run current {i}");
    }
    let c = Correction::from_profile(&p, current.map(|i| i.peak_a()))?;
    // The simulation runs at the exported current.
    let scaled = p.edited(&a.motor, |d| d.drive.holding_current_a = c.holding_current_a)?;
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut wrote = String::new();
    let (comp, table) = match a.format {
        Format::Prusa => {
            let axis = match a.axis.as_deref() {
                None | Some("X") | Some("x") => 'X',
                Some("Y") | Some("y") => 'Y',
                Some(o) => bail!("--axis {}: Prusa phase stepping has axes X and Y", escape::line(o)),
            };
            let Some(run) = current else { bail!("export prusa needs the run current") };
            let (mut f, table, how) = prusa_files(&a, &p, &c, run, axis)?;
            files.append(&mut f);
            wrote = how;
            (Compensation::Table, Some(table))
        }
        Format::KlipperTmc => {
            let e = tmc::export(&c)?;
            let section = a.axis.clone().unwrap_or_else(|| "tmc5160 stepper_x".to_string());
            let Some(run) = current else { bail!("export klipper-tmc needs the run current") };
            files.push((a.out.clone(), tmc::klipper_block(&e, &section, &p.name, run)?.into_bytes()));
            out!("{e}");
            wrote = format!("([{section}])");
            (Compensation::Table, Some(tmc::table(&e.registers)))
        }
        Format::Simplefoc => {
            files.push((a.out.clone(), simplefoc::header(&c, "stepdamp_q_current")?.into_bytes()));
            (Compensation::Patent, None)
        }
        Format::CHeader => {
            let ident = c_header::ident_for(&a.out, a.name.as_deref())?;
            files.push((a.out.clone(), c_header::header(&scaled, &p.name, &a.motor, &ident)?.into_bytes()));
            wrote = format!("(sd_params {ident}_PARAMS)");
            (Compensation::Patent, None)
        }
    };
    if a.duration > 0.0 {
        let verdict = predict_export(&a, &scaled, comp, table.as_ref())?;
        if verdict != predict::Verdict::Better {
            if !a.force {
                bail!("{verdict}; nothing written (--force writes it anyway)");
            }
            outln!("{verdict}; writing it anyway (--force)");
        }
    }
    for (path, bytes) in &files {
        write_atomic(path, bytes)?;
    }
    outln!("wrote {}{}", a.out.display(), if wrote.is_empty() { String::new() } else { format!(" {wrote}") });
    Ok(())
}

/// Options that would do nothing for the chosen format are refused, never ignored.
fn refuse_unused_options(a: &ExportArgs) -> Result<()> {
    let unused =
        |opt: &str, why: &str| -> Result<()> { bail!("{opt} does nothing for export {}: {why}", a.format.name()) };
    match a.format {
        Format::Simplefoc => {
            if a.current.given() {
                unused("--current", "the q-current feed-forward A_k/Km does not depend on the run current")?;
            }
            if a.axis.is_some() {
                unused("--axis", "the header is for the motor object you call it with")?;
            }
        }
        Format::CHeader if a.axis.is_some() => unused("--axis", "the header's names come from --out or --name")?,
        _ => {}
    }
    if a.name.is_some() && a.format != Format::CHeader {
        unused("--name", "it names the C header's identifiers (export c-header)")?;
    }
    if a.firmware.is_some() && a.format != Format::Prusa {
        unused("--firmware", "it is the Prusa firmware the G-code is for (export prusa)")?;
    }
    if a.loop_hz.is_some() && a.format != Format::Simplefoc {
        unused("--loop-hz", "it is SimpleFOC's loopFOC rate (export simplefoc)")?;
    }
    Ok(())
}

/// A file to write: its path and bytes.
type OutFile = (PathBuf, Vec<u8>);

/// The Prusa G-code and files, what the "wrote" line says about them, and the table the
/// written G-code makes (read back from the text itself) for the prediction.
fn prusa_files(
    a: &ExportArgs,
    p: &stepdamp_sim::Profile,
    c: &Correction,
    current: RunCurrent,
    axis: char,
) -> Result<(Vec<OutFile>, stepdamp_core::CorrectionTable, String)> {
    let fw: prusa::Firmware = a.firmware.unwrap_or(PrusaFirmware::V6_3_1).into();
    let fitted = prusa::fit(c, fw)?;
    let text = prusa::gcode::write(&fitted, axis, &prusa::gcode::Header { profile: &p.name, current })?;
    let (written, _) = prusa::parse_text(&text, Some(axis), "the exported G-code")?;
    if written != fitted.correction {
        bail!("internal: the exported G-code reads back to another correction");
    }
    out!("{fitted}");
    if fitted.kept < 1.0 {
        // Advice, not the export: a profile the scan cannot evaluate still gets its G-code.
        match prusa::headroom::headroom(p, c, fw) {
            Ok(h) => out!("{h}"),
            Err(e) => eprintln!("warning: no advice on the run current at which the correction fits: {e}"),
        }
    }
    let (f, b) = (sibling(&a.out, ".fwd.bin"), sibling(&a.out, ".bck.bin"));
    let how = match fw {
        prusa::Firmware::V6_3_1 => format!("M970 {axis}0, M971 {axis} F|B x17, M970 {axis}1"),
        prusa::Firmware::V6_2 => format!("M973 {axis}F/{axis}B"),
    };
    let wrote = format!("({how}, firmware {}), {} and {}", fw.label(), f.display(), b.display());
    let files = vec![
        (a.out.clone(), text.into_bytes()),
        (f, prusa::encode_file(&written.forward).to_vec()),
        (b, prusa::encode_file(&written.backward).to_vec()),
    ];
    Ok((files, written.table(), wrote))
}

/// Prints the prediction of the exported correction and returns the verdict on the first
/// (the one that models what is exported).
fn predict_export(
    a: &ExportArgs,
    scaled: &stepdamp_sim::Profile,
    comp: Compensation,
    table: Option<&stepdamp_core::CorrectionTable>,
) -> Result<predict::Verdict> {
    // SimpleFOC runs on its sensor: servo mode; the others microstep in open loop.
    let mode = if a.format == Format::Simplefoc { Mode::Servo } else { Mode::OpenLoop };
    let off = predict::config_in(scaled, mode, Compensation::Off, None)?;
    let mut comps: Vec<(String, predict::ConfigAt<'_>)> = Vec::new();
    match (a.format, comp) {
        (Format::Simplefoc, _) => {
            let timing = simplefoc::LoopTiming {
                loop_hz: a.loop_hz.unwrap_or(DEFAULT_LOOP_HZ),
                order: simplefoc::CallOrder::Documented,
            };
            timing.check()?;
            let name = format!(
                "servo, SimpleFOC loop at {} Hz with the header's call order, q-current feed-forward",
                timing.loop_hz
            );
            comps.push((
                name,
                Box::new(move |speed| {
                    predict::config_in(&timing.as_applied(scaled, speed)?, Mode::Servo, Compensation::Patent, None)
                }),
            ));
        }
        (_, Compensation::Table) => {
            let cfg = predict::config_in(scaled, mode, comp, table)?;
            comps.push(("open loop, table replay".into(), Box::new(move |_| Ok(cfg))));
        }
        _ => {
            let cfg = predict::config_in(scaled, mode, comp, table)?;
            comps.push(("open loop, patent q-current feed-forward".into(), Box::new(move |_| Ok(cfg))));
        }
    }
    if a.format == Format::KlipperTmc {
        // What the coverage report predicts: the continuous angle law carrying exactly
        // the part of the model the table can hold (the table's rounding aside).
        let covered = predict::config(&tmc::covered_profile(scaled)?, Compensation::Angle, None)?;
        comps.push(("open loop, angle law on the covered part only".to_string(), Box::new(move |_| Ok(covered))));
    }
    // A motor with flux harmonics is not symmetric in the direction of travel (the ripple
    // that grows with the current follows the load angle's sign): simulated both ways.
    let directions =
        if scaled.motor.flux.is_default() { predict::Directions::Forward } else { predict::Directions::Both };
    let pr = predict::predict_in(scaled, off, &comps, a.duration, directions)?;
    for p in &pr {
        out!("{p}");
    }
    Ok(pr[0].verdict())
}

/// SimpleFOC loop rate the prediction assumes without `--loop-hz`, Hz.
const DEFAULT_LOOP_HZ: f64 = 10_000.0;

/// Runs `stepdamp import prusa`.
pub fn run_import(a: ImportArgs, _g: &Global) -> Result<()> {
    let base = load_motor(&a.motor)?;
    let current = a.current.run_current()?;
    let bytes = prusa::read::read_capped(&a.readback)?;
    let what = a.readback.display().to_string();
    let axis = match a.axis {
        None => None,
        Some('X' | 'x') => Some('X'),
        Some('Y' | 'y') => Some('Y'),
        Some(o) => bail!("--axis {o:?}: Prusa phase stepping has axes X and Y"),
    };
    let (pc, kind) = prusa::parse_bytes(&bytes, axis, &what, a.firmware.into())?;
    outln!("read {kind}; run current {current}");
    let (p, spread) = prusa::import_profile(&base, &pc, current.peak_a())?;
    write_atomic(&a.out, p.to_toml_string().as_bytes())?;
    for h in &p.motor.detent {
        outln!("order {:>2}: A = {:.5} N·m, φ = {:+.4} rad", h.order, h.amplitude_nm, h.phase_rad);
    }
    outln!("forward and backward corrections differ by up to {spread:.5} rad (averaged)");
    outln!("wrote {}", a.out.display());
    Ok(())
}
