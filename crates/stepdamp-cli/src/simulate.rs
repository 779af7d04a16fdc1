//! `stepdamp simulate`: one constant-speed run, optionally logged per control period.

use crate::Global;
use crate::common::{ChoiceList, load_motor, parse_compensations, parse_modes, sim_error_with_flag};
use anyhow::{Context, Result, anyhow, bail};
use std::path::{Path, PathBuf};
use stepdamp_core::Mode;
use stepdamp_sim::runlog::{FromRecord, LogRow};
use stepdamp_sim::{
    ClosedLoop, Compensation, ESTIMATED_IS_OPEN_LOOP_ONLY, RunSpec, SimOptions, check_mode_compensation,
    check_same_hardware, run as run_spec,
};

/// Arguments of `stepdamp simulate`.
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Motor: a preset name or a profile TOML file.
    #[arg(long, default_value = "patent-motor")]
    pub motor: String,
    /// The motor the controller believes in (default: the simulated one).
    #[arg(long, value_name = "PRESET|FILE")]
    pub controller_motor: Option<String>,
    /// open-loop or servo.
    #[arg(long, default_value = "open-loop", value_parser = parse_modes)]
    pub mode: ChoiceList<Mode>,
    /// off, patent (alias on), or estimated (the rotor angle estimated from the currents
    /// and voltages; open loop only).
    #[arg(long, default_value = "patent", value_parser = parse_compensations)]
    pub compensation: ChoiceList<Compensation>,
    /// Commanded speed in rad/s (negative runs backwards).
    #[arg(long, allow_negative_numbers = true)]
    pub speed: f64,
    /// Simulated time in s (error measured over the last ≤ 0.5 s, whole electrical periods,
    /// at least 50 ms after the ramp).
    #[arg(long, default_value_t = RunSpec::DURATION_S, allow_negative_numbers = true)]
    pub duration: f64,
    /// Standstill time with the holding current on before the ramp, s.
    #[arg(long, default_value_t = RunSpec::DWELL_S, allow_negative_numbers = true)]
    pub dwell: f64,
    /// Ramp time from rest to the speed in s.
    #[arg(long, default_value_t = RunSpec::RAMP_S, allow_negative_numbers = true)]
    pub ramp: f64,
    /// Constant load torque in N·m opposing the direction of travel.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub load_torque: f64,
    /// Current-sensor noise, standard deviation in A.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub current_noise: f64,
    /// Seed of the noise generator.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub seed: u64,
    /// Write the run log (one row per control period, docs/files.md) to this CSV file; a
    /// device, FIFO or `-` (standard output) is written straight through.
    #[arg(long)]
    pub log: Option<PathBuf>,
}

/// Runs `stepdamp simulate`.
pub fn run(a: SimulateArgs, _g: &Global) -> Result<()> {
    let motor = load_motor(&a.motor)?;
    let controller = match &a.controller_motor {
        Some(c) => {
            let p = load_motor(c).context("--controller-motor")?;
            check_same_hardware(&motor, &a.motor, &p, c)?;
            p
        }
        None => motor.clone(),
    };
    let (mode, comp) = checked_choice(&a)?;
    check_times(&a)?;
    let spec = RunSpec { dwell_s: a.dwell, ramp_s: a.ramp, ..RunSpec::for_duration(a.speed, a.duration) };
    let pwm = motor.drive.pwm_hz;
    let nr = motor.motor.pole_pairs;
    // Name the flag: the run's duration, speed, dwell and ramp are the options'.
    let flag_error = |e| {
        sim_error_with_flag(
            e,
            &[("duration", "--duration"), ("speed", "--speed"), ("dwell", "--dwell"), ("ramp", "--ramp")],
        )
    };
    spec.check(pwm, nr).map_err(flag_error)?;
    let opts = SimOptions {
        current_noise_a: a.current_noise,
        seed: a.seed,
        load_torque_nm: a.load_torque,
        ..SimOptions::default()
    };
    let mut lp = ClosedLoop::new(&motor, &controller, mode, comp, &opts).map_err(flag_error)?;
    // The log is streamed to a temporary file next to its target and moved into place
    // when complete (a device, FIFO or `-` is written straight through), so an error or
    // an interruption leaves nothing half-written.
    let mut log = match &a.log {
        Some(path) => {
            let out = stepdamp_out::Output::create(path).with_context(|| "--log".to_string())?;
            Some(csv::Writer::from_writer(out))
        }
        None => None,
    };
    let mut rows = 0usize;
    let mut write_error: Option<csv::Error> = None;
    let m = run_spec(&mut lp, &spec, pwm, |k, rec| {
        if let (Some(w), None) = (&mut log, &write_error) {
            match w.serialize(LogRow::from_record(k, pwm, nr, rec)) {
                Ok(()) => rows += 1,
                Err(e) => write_error = Some(e),
            }
        }
    })?;
    let written = match (log, &a.log) {
        (Some(w), Some(path)) => {
            finish_log(w, write_error, path)?;
            Some(path)
        }
        _ => None,
    };
    outln!(
        "{} {} compensation {} at {} rad/s: velocity error rms {:.4} rad/s, pp {:.4} rad/s, max load angle {:.3} electrical rad{}",
        motor.name,
        mode.name(),
        comp.name(),
        a.speed,
        m.vel_err_rms_rad_s,
        m.vel_err_pp_rad_s,
        m.max_load_angle_e_rad,
        if m.lost_sync { ", LOST SYNC" } else { "" }
    );
    if let Some(path) = written {
        outln!("wrote {} ({rows} rows)", path.display());
    }
    Ok(())
}

/// The one mode and compensation asked for, checked to go together (and not `table`).
fn checked_choice(a: &SimulateArgs) -> Result<(Mode, Compensation)> {
    let (&[mode], &[comp]) = (a.mode.items.as_slice(), a.compensation.items.as_slice()) else {
        bail!("simulate runs one mode and one compensation (got --mode {} --compensation {})", a.mode, a.compensation);
    };
    check_mode_compensation(mode, comp).map_err(|e| match comp {
        stepdamp_sim::Compensation::Estimated => {
            anyhow!("--mode servo --compensation estimated: {ESTIMATED_IS_OPEN_LOOP_ONLY}")
        }
        _ => anyhow!("--mode {} --compensation {}: {e}", a.mode, a.compensation),
    })?;
    if comp == stepdamp_sim::Compensation::Table {
        bail!("--compensation table replays a table file: use `stepdamp sweep --compensation table --table FILE`");
    }
    Ok((mode, comp))
}

/// Checks `--duration`, `--dwell` and `--ramp` (s): a duration in (0, 1000] s, dwell and ramp
/// ≥ 0 and together shorter than it.
fn check_times(a: &SimulateArgs) -> Result<()> {
    if !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= 1000.0) {
        bail!("--duration {}: must be in (0, 1000] s", a.duration);
    }
    if !(a.ramp.is_finite() && a.ramp >= 0.0 && a.dwell.is_finite() && a.dwell >= 0.0 && a.dwell + a.ramp < a.duration)
    {
        bail!("--dwell {} + --ramp {}: must be ≥ 0 and shorter than --duration {}", a.dwell, a.ramp, a.duration);
    }
    Ok(())
}

/// Completes the log written to `path`: its first write error, if any, else the flush and
/// the move into place of the temporary file.
fn finish_log(w: csv::Writer<stepdamp_out::Output>, write_error: Option<csv::Error>, path: &Path) -> Result<()> {
    let out = match write_error.map(csv::Error::into_kind) {
        Some(csv::ErrorKind::Io(e)) => Err(e),
        Some(other) => Err(std::io::Error::other(format!("{other:?}"))),
        None => w.into_inner().map_err(|e| e.into_error()),
    };
    let out = out.map_err(|e| match e.kind() {
        std::io::ErrorKind::BrokenPipe => anyhow::Error::new(crate::common::StdoutClosed),
        _ => anyhow!("{}: cannot write: {e}", path.display()),
    })?;
    out.commit()?;
    Ok(())
}
