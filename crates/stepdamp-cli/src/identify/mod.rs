//! `stepdamp identify`: detent harmonics and friction from servo-mode run logs
//! (docs/design.md#identification), the experiment plan, simulated runs, refinement, the static route.
//! One file per subcommand; each parses its arguments, calls the library and prints its
//! result types.
//!
//! ```text
//! stepdamp identify --log a.csv --log b.csv --motor base.toml --out identified.toml [--orders 1,2,4] [--report DIR]
//! stepdamp identify --accel CAPTURE... --motor base.toml --axis X|Y --current-rms A --out ripple.toml
//! stepdamp identify plan   --motor FILE [--sensorless] [--format text|json|csv]
//! stepdamp identify run    --motor FILE --out DIR [--refine] [--report] [--sensorless]
//! stepdamp identify static --table curve.csv --motor base.toml --out identified.toml [--sign on-rotor|holding]
//! ```

use crate::Global;
use anyhow::Result;

mod accel_cmd;
mod args;
mod fit_cmd;
mod plan_cmd;
mod report;
mod run_cmd;
mod static_cmd;

/// Arguments of `stepdamp identify`.
#[derive(clap::Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct IdentifyArgs {
    #[command(subcommand)]
    command: Option<IdentifyCommand>,
    #[command(flatten)]
    fit: fit_cmd::FitArgs,
}

/// `stepdamp identify <subcommand>`.
#[derive(clap::Subcommand, Debug)]
enum IdentifyCommand {
    /// Print the runs to record for identification, with the reason for each.
    Plan(plan_cmd::PlanArgs),
    /// Simulate the plan's runs and write their logs (optionally identify and refine).
    Run(run_cmd::RunArgs),
    /// Harmonics from a static torque-versus-angle table (CSV theta_rad, torque_nm) by FFT.
    Static(static_cmd::StaticArgs),
}

/// Runs `stepdamp identify`.
pub fn run(args: IdentifyArgs, global: &Global) -> Result<()> {
    match args.command {
        Some(IdentifyCommand::Plan(a)) => plan_cmd::run_plan_cmd(a),
        Some(IdentifyCommand::Run(a)) => run_cmd::run_run_cmd(a, global),
        Some(IdentifyCommand::Static(a)) => static_cmd::run_static_cmd(a),
        None => fit_cmd::run_fit_cmd(args.fit, global),
    }
}

#[cfg(test)]
mod tests {
    use super::args::{Orders, parse_orders, plan_options};
    use super::run_cmd::SUMMARY_FILE;
    use super::static_cmd::StaticArgs;
    use super::{IdentifyArgs, IdentifyCommand, run};
    use crate::Global;
    use std::fmt::Write as _;
    use std::path::PathBuf;
    use stepdamp_identify::conditions::InertiaMode;
    use stepdamp_identify::fit::{Effort, FitOptions, fit};
    use stepdamp_identify::from_logs::{LogSource, Logs, read_logs};
    use stepdamp_identify::plan::plan;
    use stepdamp_identify::static_curve::TorqueSign;
    use stepdamp_sim::Profile;

    fn try_args(v: &[&str]) -> Result<IdentifyArgs, clap::Error> {
        use clap::Parser;
        #[derive(Parser)]
        struct W {
            #[command(flatten)]
            a: IdentifyArgs,
        }
        let mut all = vec!["identify"];
        all.extend_from_slice(v);
        W::try_parse_from(all).map(|w| w.a)
    }

    fn args(v: &[&str]) -> IdentifyArgs {
        try_args(v).unwrap()
    }

    const Q: Global = Global { quiet: true };

    #[test]
    fn orders_parse_and_reject_nonsense() {
        assert_eq!(parse_orders("1, 2,4").unwrap(), Orders(vec![1, 2, 4]));
        assert!(parse_orders("0").unwrap_err().to_string().contains("1..=32"));
        assert!(parse_orders("4,4").unwrap_err().to_string().contains("twice"));
        assert!(parse_orders("x").unwrap_err().to_string().contains("'x'"));
        assert!(parse_orders("1,,2").unwrap_err().to_string().contains("empty entry"));
    }

    #[test]
    fn choices_take_the_library_names_and_a_wrong_one_names_the_value_and_the_names_allowed() {
        for &e in Effort::ALL {
            assert_eq!(args(&["--effort", e.name()]).fit.effort, e);
        }
        for &m in InertiaMode::ALL {
            assert_eq!(args(&["--inertia", m.name()]).fit.inertia, m);
        }
        for &s in TorqueSign::ALL {
            let a = args(&["static", "--table", "t.csv", "--sign", s.name(), "--motor", "m", "--out", "o.toml"]);
            assert!(matches!(a.command, Some(IdentifyCommand::Static(StaticArgs { sign, .. })) if sign == s));
        }
        assert_eq!(args(&["--orders", "4,1"]).fit.orders, Orders(vec![4, 1]));
        for (v, want) in [
            (&["--effort", "iq"][..], "[possible values: measured, command]"),
            (&["--inertia", "Auto"], "[possible values: fit, base, auto]"),
            (&["static", "--table", "t", "--sign", "up", "--motor", "m", "--out", "o"], "on-rotor, holding"),
            (&["--orders", "1,x"], "'x' is not a whole number"),
        ] {
            let e = try_args(v).map(|_| ()).unwrap_err().to_string();
            let written = v[v.len() - 1 - usize::from(v[0] == "static") * 4];
            assert!(e.contains(&format!("invalid value '{written}'")) && e.contains(want), "{v:?}: {e}");
        }
    }

    #[test]
    fn run_then_identify_writes_a_valid_profile_and_report() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap();
        run(args(&["run", "--motor", "patent-motor", "--out", d, "--periods", "6"]), &Q).unwrap();
        let mut logs: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path().display().to_string())
            .filter(|p| p.ends_with(".csv"))
            .collect();
        logs.sort();
        // The four servo runs and the back-EMF run.
        assert_eq!(logs.len(), 5);
        assert!(logs[4].contains("run-5-emf-"), "{logs:?}");
        // The planned profile, with the servo settings the runs were recorded with.
        let base = dir.path().join("base.toml");
        let planned = Profile::from_file(&base).unwrap();
        let want = plan(&Profile::preset("patent-motor").unwrap(), &plan_options(&[1, 2, 4], 6.0).unwrap()).unwrap();
        assert_eq!(planned.servo, want.profile.servo);
        assert!(planned.servo.bandwidth_hz > 60.0, "{:?}", planned.servo);
        // Identified with it (no --servo-bandwidth): the fit knows the logs' servo, so no
        // "too fast for the servo" warning.
        let fo = FitOptions::for_profile(&planned, &[1, 2, 4]);
        let sources: Vec<LogSource> = logs.iter().map(|l| LogSource::Path(PathBuf::from(l))).collect();
        let Logs::Encoder(parsed) = read_logs(&sources, 50, None).unwrap() else { panic!("encoder logs") };
        let f = fit(&parsed, &fo).unwrap();
        assert!(
            !f.warnings.iter().any(|w| matches!(w, stepdamp_identify::fit::Warning::TooFast { .. })),
            "{:?}",
            f.warnings
        );
        let out = dir.path().join("id.toml");
        let rep = dir.path().join("report");
        let b = base.to_str().unwrap();
        let mut v = vec!["--motor", b, "--out", out.to_str().unwrap(), "--report", rep.to_str().unwrap()];
        for l in &logs {
            v.push("--log");
            v.push(l);
        }
        run(args(&v), &Q).unwrap();
        let p = Profile::from_file(&out).unwrap();
        assert_eq!(p.motor.detent.len(), 3);
        let a4 = p.motor.detent.iter().find(|h| h.order == 4).unwrap().amplitude_nm;
        assert!((a4 - 0.02).abs() < 0.001, "{a4}");
        // J identified and written (the preset's is 4e-5).
        assert!((p.motor.inertia_kg_m2 / 4e-5 - 1.0).abs() < 0.1, "{}", p.motor.inertia_kg_m2);
        for f in ["spectrum.svg", "spectrum.png", "residual.svg", "residual.png"] {
            assert!(std::fs::metadata(rep.join(f)).unwrap().len() > 1000, "{f}");
        }
    }

    #[test]
    fn identify_run_refused_by_its_checks_creates_no_directory() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new").join("runs");
        let o = out.to_str().unwrap();
        // Too many rows for the row limit.
        let e = run(args(&["run", "--motor", "patent-motor", "--out", o, "--periods", "90000"]), &Q)
            .unwrap_err()
            .to_string();
        assert!(e.contains("rows"), "{e}");
        // A plan the planner refuses (a stiffness margin is fine; zero noise is fine; bad
        // periods are caught by the option check, a bad motor by the loader).
        let e =
            run(args(&["run", "--motor", "patent-motor", "--out", o, "--periods", "1"]), &Q).unwrap_err().to_string();
        assert!(e.contains("--periods"), "{e}");
        let e = run(args(&["run", "--motor", "no-such-motor", "--out", o]), &Q).unwrap_err().to_string();
        assert!(e.contains("no-such-motor"), "{e}");
        assert!(!dir.path().join("new").exists(), "nothing is created on an error");
        // A file in the way.
        let file = dir.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        let e = run(args(&["run", "--motor", "patent-motor", "--out", file.to_str().unwrap()]), &Q)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a directory"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn identify_run_with_refine_writes_a_summary_a_script_can_read() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_str().unwrap();
        let a = ["run", "--motor", "patent-motor", "--out", d, "--periods", "6", "--refine", "--iterations", "1"];
        run(args(&a), &Q).unwrap();
        let text = std::fs::read_to_string(dir.path().join(SUMMARY_FILE)).unwrap();
        let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
        assert_eq!(rows[0], ["quantity", "order", "unit", "motor", "identified", "refined"]);
        assert!(rows.iter().all(|r| r.len() == 6), "{text}");
        let get = |q: &str, k: &str| rows.iter().find(|r| r[0] == q && r[1] == k).unwrap_or_else(|| panic!("{q} {k}"));
        let a4 = get("amplitude", "4");
        assert_eq!(a4[3].parse::<f64>().unwrap(), 0.02);
        assert!((a4[5].parse::<f64>().unwrap() - 0.02).abs() < 0.001, "{text}");
        for q in ["phase", "amplitude"] {
            for k in ["1", "2"] {
                get(q, k);
            }
        }
        let fs: f64 = get("coulomb_friction", "")[5].parse().unwrap();
        assert!((fs / 0.01 - 1.0).abs() < 0.1, "{text}");
        let ripple = get("periodic_ripple_rms", "");
        let (before, after): (f64, f64) = (ripple[4].parse().unwrap(), ripple[5].parse().unwrap());
        assert!(before > 10.0 * after, "{text}");
        let ratio: f64 = get("ripple_reduction", "")[5].parse().unwrap();
        assert!((ratio - before / after).abs() < 0.1 * ratio, "{text}");
        assert!(dir.path().join("identified.toml").exists());
    }

    #[test]
    fn a_bad_log_fails_with_file_and_line_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("bad.csv");
        std::fs::write(&log, "t_s,theta_fb_rad,i_q_a\n0.0,0.0,0.1\n0.00005,nan,0.1\n").unwrap();
        let out = dir.path().join("id.toml");
        let e =
            run(args(&["--log", log.to_str().unwrap(), "--motor", "patent-motor", "--out", out.to_str().unwrap()]), &Q)
                .unwrap_err()
                .to_string();
        assert!(e.contains("bad.csv") && e.contains("line 3") && e.contains("theta_fb_rad"), "{e}");
        assert!(!out.exists());
    }

    #[test]
    fn a_directory_given_as_out_is_refused_before_any_report_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("any.csv");
        std::fs::write(&log, "t_s,theta_fb_rad,i_q_a\n0.0,0.0,0.1\n").unwrap();
        let report = dir.path().join("rep");
        let (l, o, r) = (log.to_str().unwrap(), dir.path().to_str().unwrap(), report.to_str().unwrap());
        let e =
            run(args(&["--log", l, "--motor", "patent-motor", "--out", o, "--report", r]), &Q).unwrap_err().to_string();
        assert!(e.contains("is a directory") && e.contains("identified.toml"), "{e}");
        assert!(!report.exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "only the log is there");
    }

    #[test]
    fn missing_arguments_are_one_line_errors() {
        let e = run(args(&["--motor", "patent-motor", "--out", "x.toml"]), &Q).unwrap_err().to_string();
        assert!(e.contains("--log") && !e.contains('\n'), "{e}");
        let e = run(args(&["--log", "a.csv", "--out", "x.toml"]), &Q).unwrap_err().to_string();
        assert!(e.contains("--motor"), "{e}");
    }

    #[test]
    fn static_table_becomes_a_profile() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("curve.csv");
        let mut s = String::from("theta_rad,torque_nm\n");
        for i in 0..400 {
            let th = i as f64 / 400.0 * 2.0 * std::f64::consts::TAU / 50.0;
            // Torque on the rotor: −A sin(4·50·θ + 0.2).
            let _ = writeln!(s, "{th},{}", -0.02 * (200.0 * th + 0.2).sin());
        }
        std::fs::write(&table, s).unwrap();
        let out = dir.path().join("s.toml");
        let t = table.to_str().unwrap();
        let o = out.to_str().unwrap();
        run(
            args(&[
                "static",
                "--table",
                t,
                "--sign",
                "on-rotor",
                "--motor",
                "patent-motor",
                "--out",
                o,
                "--orders",
                "4",
            ]),
            &Q,
        )
        .unwrap();
        let p = Profile::from_file(&out).unwrap();
        assert_eq!(p.motor.detent.len(), 1);
        assert!(
            (p.motor.detent[0].amplitude_nm - 0.02).abs() < 1e-9 && (p.motor.detent[0].phase_rad - 0.2).abs() < 1e-9
        );
    }

    #[test]
    fn a_static_table_too_sparse_for_an_order_names_it_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("sparse.csv");
        // 4 points per electrical period over 2 periods: order 1 resolves, 2 and 4 do not.
        let mut s = String::from("theta_rad,torque_nm\n");
        for i in 0..8 {
            let th = i as f64 / 8.0 * 2.0 * std::f64::consts::TAU / 50.0;
            let _ = writeln!(s, "{th},{}", 0.02 * (200.0 * th).sin());
        }
        std::fs::write(&table, s).unwrap();
        let out = dir.path().join("s.toml");
        let (t, o) = (table.to_str().unwrap(), out.to_str().unwrap());
        let a = ["static", "--table", t, "--sign", "holding", "--motor", "patent-motor", "--out", o];
        let e = run(args(&a), &Q).unwrap_err().to_string();
        assert!(e.contains("sparse.csv") && e.contains("cannot resolve order 2, 4"), "{e}");
        assert!(!out.exists());
    }
}
