//! `stepdamp`: sweeps, simulations, identification and motor profiles.

/// `print!` to standard output that returns (with `?`) an error on failure, and
/// [`common::StdoutClosed`] when the reader has gone (`stepdamp … | head -1`): the command
/// then ends quietly with status 0.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::common::write_out(std::io::stdout().lock(), format_args!($($arg)*))?
    };
}

/// `println!` with the error handling of [`out!`].
macro_rules! outln {
    () => {
        out!("\n")
    };
    ($($arg:tt)*) => {
        $crate::common::write_out(std::io::stdout().lock(), format_args!("{}\n", format_args!($($arg)*)))?
    };
}

mod accel;
mod common;
mod export;
mod identify;
mod motor;
mod plot;
mod simulate;
mod study;
mod sweep;

use clap::{Parser, Subcommand};

/// Model-based active damping of hybrid stepper motors (US 7,733,051 and beyond).
#[derive(Parser, Debug)]
#[command(name = "stepdamp", version, about, propagate_version = true)]
struct Cli {
    /// No progress bars.
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

/// Options every subcommand sees.
#[derive(Debug, Clone, Copy)]
pub struct Global {
    /// No progress bars.
    pub quiet: bool,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Sweep velocity error against speed, with and without compensation (figs. 4–7).
    Sweep(sweep::SweepArgs),
    /// Simulate one constant-speed run; optionally write its run log.
    Simulate(simulate::SimulateArgs),
    /// Print the natural frequency and the resonance speeds of a motor.
    Resonance(motor::ResonanceArgs),
    /// Show, check or list motor profiles.
    #[command(subcommand)]
    Motor(motor::MotorCommand),
    /// Identify detent harmonics and friction from servo-mode logs.
    Identify(identify::IdentifyArgs),
    /// Write a profile's correction for another drive (Prusa, Klipper/Trinamic, SimpleFOC, C).
    Export(export::ExportArgs),
    /// Read another drive's correction into a profile.
    Import(export::ImportArgs),
    /// Tolerance study: draw motor variants, sweep their resonances, report the spread.
    Study(study::StudyArgs),
    /// The accelerometer route on a Prusa printer: simulate a capture, refine the table from recorded ones.
    #[command(subcommand)]
    Accel(accel::AccelCommand),
}

fn main() {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion)
                || e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            {
                e.exit();
            }
            // One line: what is wrong (`stepdamp … --help` shows the usage).
            let text = e.render().to_string();
            let message: Vec<&str> = text
                .lines()
                .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
                .map(str::trim)
                .filter(|l| !l.is_empty())
                .collect();
            eprintln!("{}", message.join(" "));
            std::process::exit(2);
        }
    };
    let global = Global { quiet: cli.quiet };
    let result = match cli.command {
        Command::Sweep(a) => sweep::run(a, &global),
        Command::Simulate(a) => simulate::run(a, &global),
        Command::Resonance(a) => motor::resonance(a, &global),
        Command::Motor(c) => motor::run(c, &global),
        Command::Identify(a) => identify::run(a, &global),
        Command::Export(a) => export::run_export(a, &global),
        Command::Import(a) => export::run_import(a, &global),
        Command::Study(a) => study::run(a, &global),
        Command::Accel(c) => accel::run(c, &global),
    };
    if let Err(e) = result {
        if common::is_stdout_closed(&e) {
            std::process::exit(0);
        }
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
