//! `stepdamp identify --log …`: the arguments, the library's [`identify`], and its report
//! printed (text or JSON), plotted (`--report`) and its profile written.

use super::args::{Orders, check_output_dir, parse_orders};
use super::report::write_report;
use crate::Global;
use crate::common::{Format, choice_parser, load_motor, print_json, write_atomic};
use anyhow::{Result, bail};
use std::path::PathBuf;
use stepdamp_identify::conditions::InertiaMode;
use stepdamp_identify::fit::Effort;
use stepdamp_identify::from_logs::{IdentifyOptions, LogSource, Route, identify};

/// Identification from logs (the default action).
#[derive(clap::Args, Debug)]
pub(super) struct FitArgs {
    /// A run log (CSV, docs/files.md): a file, a FIFO, or - for standard input; each read
    /// once, and no file twice. A servo-mode log needs t_s, theta_fb_rad and i_q_a (or
    /// i_a_a and i_b_a). A log without theta_fb_rad takes the sensorless route (said so in
    /// the output; docs/sensorless.md): it needs t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v,
    /// v_b_v of the runs of `identify plan --sensorless`. Repeat for several runs, all of
    /// one route.
    #[arg(long = "log", value_name = "CSV")]
    pub(super) logs: Vec<PathBuf>,
    /// Base motor profile (preset or TOML): Km, Nr, encoder and servo settings are taken
    /// from it; its detent list, friction and J are replaced by what is identified (J is
    /// fitted; a warning says when it differs from the base's by more than 20 %).
    #[arg(long, value_name = "PRESET|FILE")]
    pub(super) motor: Option<String>,
    /// Where to write the identified profile (TOML).
    #[arg(long, value_name = "FILE")]
    pub(super) out: Option<PathBuf>,
    /// Harmonic orders to identify (comma list).
    #[arg(long, default_value = "1,2,4", value_parser = parse_orders)]
    pub(super) orders: Orders,
    /// Directory for the report: effort-ripple spectrum and residual plots (SVG + PNG).
    #[arg(long, value_name = "DIR")]
    pub(super) report: Option<PathBuf>,
    /// The effort signal: measured (i_q_a) or command (iq_cmd_a).
    #[arg(long, default_value = "measured", value_parser = choice_parser(Effort::ALL, Effort::name))]
    pub(super) effort: Effort,
    /// The logs were recorded with the --motor profile's detent and Fs fed forward: print
    /// the remaining ripple (the patent's refinement criterion). J is then held at the
    /// --motor profile's (fitted otherwise).
    #[arg(long)]
    pub(super) ff_on: bool,
    /// Servo position-loop bandwidth of the logged runs in Hz (default: the profile's
    /// [servo] bandwidth_hz); only used for warnings.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub(super) servo_bandwidth: Option<f64>,
    /// How J is obtained: fit (always fitted), base (the --motor profile's) or auto
    /// (fitted when the logs separate it — two speeds in both directions — and its 95 %
    /// interval is narrow, else the base profile's). The decision is printed.
    #[arg(long, default_value = "auto", value_parser = choice_parser(InertiaMode::ALL, InertiaMode::name))]
    pub(super) inertia: InertiaMode,
    /// text, or json: the fit's report (stepdamp_identify::fit::FitReport, or on the
    /// sensorless route stepdamp_identify::sensorless::report::SensorlessReport) as one line
    /// of JSON on stdout, nothing else (the files are written the same).
    #[arg(long, value_enum, default_value_t)]
    pub(super) format: Format,
    /// Name of the identified profile (default: base name + "-identified").
    #[arg(long)]
    pub(super) name: Option<String>,
    /// Take the sensorless route even when the logs have theta_fb_rad (to compare the two
    /// routes on the same runs; the encoder angle is then not read).
    #[arg(long)]
    pub(super) sensorless: bool,
    /// Instead of run logs: Prusa accelerometer captures (session logs with the echoed
    /// M973/M974 commands, recorded with the correction off): an M974 sweep and an M973 pair
    /// per direction (`identify plan --accel`); or Klipper motion-analysis logs
    /// (data_logger.py's LOG.json.gz, told apart by their gzip header). Identifies the head and the ripple, orders
    /// 1-16 where the sampling rate allows, per direction at the run current, and writes the
    /// TOML of docs/files.md#identified-ripple-toml (docs/accelerometer.md#identifying-the-ripple-from-captures).
    #[arg(long, num_args = 1.., value_name = "CAPTURE")]
    pub(super) accel: Vec<PathBuf>,
    /// With --accel and Klipper motion-analysis logs (LOG.json.gz): the trial the driver's
    /// table carried during LOG, its current-vector angle shift U·sin(H·θe + PHI), U and
    /// PHI in rad (docs/accelerometer.md#klippers-motion-analysis-logs). Repeat per log.
    #[arg(long, value_name = "LOG=H,U,PHI")]
    pub(super) klipper_trial: Vec<String>,
    /// With --accel: the motor the captures moved, X or Y (on CoreXY the A or B motor).
    #[arg(long, value_name = "X|Y")]
    pub(super) axis: Option<String>,
    /// With --accel: the run current the captures were recorded at.
    #[command(flatten)]
    pub(super) current: crate::export::CurrentArgs,
    /// With --accel: belt travel per motor revolution, mm (GT2 belt, 16-tooth pulley: 32);
    /// the pulley's pitch radius is this / 2π.
    #[arg(long, default_value_t = 32.0)]
    pub(super) mm_per_rev: f64,
    /// With --accel and Prusa captures: the printer's kinematics, for the firmware's
    /// projection of the head's acceleration (cartesian: MK4, 1 of the belt's; corexy: XL, iX,
    /// Core One, 1/√2). Klipper logs carry their own.
    #[arg(long, value_enum)]
    pub(super) kinematics: Option<crate::accel::KinematicsArg>,
    /// With --accel: whole electrical periods per lock-in block.
    #[arg(long, default_value_t = 4)]
    pub(super) periods_per_block: u32,
}

/// Runs `stepdamp identify --log …`.
pub(super) fn run_fit_cmd(a: FitArgs, _global: &Global) -> Result<()> {
    if !a.accel.is_empty() {
        return super::accel_cmd::run_accel_cmd(&a);
    }
    if a.axis.is_some() || a.current.given() || a.kinematics.is_some() {
        bail!("--axis, --kinematics and --current/--current-rms go with --accel (run logs carry their own currents)");
    }
    let Some(motor) = &a.motor else { bail!("--motor is needed: the base profile (preset or TOML) with Km, Nr, J") };
    let Some(out) = &a.out else { bail!("--out is needed: where to write the identified profile (TOML)") };
    if a.logs.is_empty() {
        bail!("no --log given: pass the servo-mode run logs (CSV), e.g. --log a.csv --log b.csv");
    }
    let base = load_motor(motor)?;
    check_output_dir(out)?;
    let options = IdentifyOptions {
        route: a.sensorless.then_some(Route::Sensorless),
        effort: a.effort,
        inertia: a.inertia,
        servo_bandwidth_hz: a.servo_bandwidth,
        feed_forward_on: a.ff_on,
        name: a.name.clone(),
        destination: out.display().to_string(),
        ..IdentifyOptions::new(&a.orders.0)
    };
    let sources: Vec<LogSource> = a.logs.iter().map(LogSource::from_arg).collect();
    let report = identify(&sources, &base, &options)?;
    // With --format json stdout is the report's JSON alone (one line); the files are written
    // all the same.
    let text = a.format == Format::Text;
    if text {
        outln!("{report}");
        outln!("{}", report.timing());
    } else {
        print_json(&report.result)?;
    }
    if let Some(dir) = &a.report {
        let fit = report.fit_report();
        for w in write_report(dir, &fit.fit, None, Some(&fit.validation), &report.profile.name)? {
            if text {
                outln!("wrote {}", w.display());
            }
        }
    }
    write_atomic(out, report.profile.to_toml_string().as_bytes())?;
    if text {
        outln!("wrote {}", out.display());
    }
    Ok(())
}
