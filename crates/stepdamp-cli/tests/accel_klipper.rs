//! The Klipper + Trinamic accelerometer route end to end on the simulated printer: the trial
//! table `accel klipper-trial` writes, logs recorded with Klipper's default table and with it,
//! `accel klipper-refine`, and the table it writes recorded again
//! (docs/accelerometer.md#refining-a-trinamic-table).

use std::path::Path;
use std::process::{Command, Output};
use stepdamp_accel::klipper::table_step::steady_responses;
use stepdamp_accel::klipper::{KlipperOptions, read_file};
use stepdamp_accel::{Axis, Gcode, TrialSweep};
use stepdamp_export::tmc::{self, TmcRegisters};
use stepdamp_printer::{KlipperSetup, SimulatedPrinter};

const MOTOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/profiles/patent-motor-real.toml");

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

/// The printer at 0.9 A with `registers` in its driver records 2 rev/s each way into `path`.
fn record(registers: &TmcRegisters, seed: u64, path: &Path) {
    let profile = stepdamp_sim::Profile::from_file(Path::new(MOTOR)).unwrap();
    let p = SimulatedPrinter { driver_table: Some(tmc::table(registers)), seed, ..SimulatedPrinter::new(profile, 0.9) };
    let trial = TrialSweep { harmonic: 4, pha_start: 0.0, pha_end: 0.0, mag_start: 0.0, mag_end: 0.0 };
    let at = |revs| Gcode::ParamSweep { axis: Axis::X, speed: 2.0, revs, trial };
    let log = p.motan_log(&[at(6.0), at(-6.0)], &KlipperSetup::default()).unwrap();
    std::fs::write(path, log.json_gz).unwrap();
}

/// Order 4's response in each direction of the log at `path` (m/s²).
fn order_4(path: &Path) -> Vec<f64> {
    let log = read_file(path, &KlipperOptions { axis: Axis::X, accelerometer: None, trial: None }).unwrap();
    steady_responses(std::slice::from_ref(&log), 4, 20).iter().map(|r| r.1.value.abs()).collect()
}

fn registers_of(path: &Path) -> TmcRegisters {
    tmc::parse_klipper(&std::fs::read_to_string(path).unwrap(), "block").unwrap()
}

#[test]
fn klipper_refine_writes_the_table_that_takes_order_4_down_on_the_simulated_printer() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let axis = "tmc5160 stepper_x";
    let o = stepdamp(&["accel", "klipper-trial", "--axis", axis, "--out", &p("trial.cfg")]);
    assert!(o.status.success(), "{}", text(&o));
    let arg = text(&o).split("TRIAL_LOG=").nth(1).unwrap().trim().to_string();
    record(&TmcRegisters::KLIPPER_DEFAULT, 1, Path::new(&p("base.json.gz")));
    record(&registers_of(Path::new(&p("trial.cfg"))), 2, Path::new(&p("trial.json.gz")));
    let trial = format!("{}={arg}", p("trial.json.gz"));
    let (base, with_trial, new) = (p("base.json.gz"), p("trial.json.gz"), p("new.cfg"));
    let args = ["accel", "klipper-refine", "--log", &base, "--log", &with_trial, "--klipper-trial", &trial];
    let rest = ["--motor", MOTOR, "--axis", axis, "--in-use", "none", "--out", &new];
    let o = stepdamp(&[&args[..], &rest].concat());
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(
        t.contains("harmonic 4: table in use") && t.contains("forward at +2.000 rev/s") && t.contains("backward"),
        "{t}"
    );
    let block = std::fs::read_to_string(&new).unwrap();
    assert!(block.is_ascii() && block.contains("[tmc5160 stepper_x]\n") && block.contains("# harmonic 4:"), "{block}");
    // Recorded again with the new table: order 4 at least 20 dB down both ways (this motor's
    // order 4 is in sine phase, which a Trinamic table can turn).
    record(&TmcRegisters::KLIPPER_DEFAULT, 3, Path::new(&p("before.json.gz")));
    record(&registers_of(Path::new(&new)), 3, Path::new(&p("after.json.gz")));
    let (before, after) = (order_4(Path::new(&p("before.json.gz"))), order_4(Path::new(&p("after.json.gz"))));
    assert_eq!((before.len(), after.len()), (2, 2));
    for d in 0..2 {
        let db = 20.0 * (before[d] / after[d]).log10();
        println!("direction {d}: {:.3} -> {:.3} m/s², {db:.1} dB", before[d], after[d]);
        assert!(db >= 20.0, "{d}: {before:?} -> {after:?}");
    }
}

#[test]
fn klipper_refine_refuses_what_it_cannot_use_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (base, trial) = (p("base.json.gz"), p("trial.json.gz"));
    record(&TmcRegisters::KLIPPER_DEFAULT, 1, Path::new(&base));
    record(&TmcRegisters::KLIPPER_DEFAULT, 2, Path::new(&trial));
    let x = "tmc5160 stepper_x";
    let cases: [(&[&str], String, &str, &str); 6] = [
        (&[&base, &trial], format!("{trial}=2,0.12,0"), x, "orders 4, 8, 12, 16"),
        (&[&base, &trial], format!("{trial}=4,0.12,1"), x, "sine phase only"),
        (&[&trial], format!("{trial}=4,0.12,0"), x, "every log is a trial log"),
        (&[&base, &trial], format!("{trial}=4,0.12,0"), "tmc5160 extruder", "stepper_x or stepper_y"),
        (&[&base, &trial], "nope".into(), x, "expected LOG=H,U,PHI"),
        (&[&base, &trial], format!("{}=4,0.12,0", p("other.json.gz")), x, "is not one of the --log logs"),
    ];
    for (logs, t, axis, want) in cases {
        let out = p("x.cfg");
        let mut a = vec!["accel", "klipper-refine", "--motor", MOTOR, "--in-use", "none", "--out", &out];
        a.extend(["--klipper-trial", &t, "--axis", axis]);
        for l in logs {
            a.extend(["--log", l]);
        }
        let o = stepdamp(&a);
        assert_eq!(o.status.code(), Some(1), "{want}: {}", text(&o));
        assert!(text(&o).contains(want) && text(&o).trim().lines().count() == 1, "{want}: {}", text(&o));
        assert!(!Path::new(&out).exists());
    }
    let out = p("x.cfg");
    let missing = p("missing.cfg");
    let t = format!("{trial}=4,0.12,0");
    let a = ["accel", "klipper-refine", "--log", &base, "--log", &trial, "--klipper-trial", &t, "--motor", MOTOR];
    let o = stepdamp(&[&a[..], &["--axis", x, "--in-use", &missing, "--out", &out]].concat());
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("missing.cfg") && !Path::new(&out).exists(), "{}", text(&o));
}

#[test]
fn klipper_plan_prints_the_moves_and_refuses_a_travel_too_short_naming_the_least() {
    let a =
        ["accel", "klipper-plan", "--axis", "tmc2240 stepper_y", "--kinematics", "corexy", "--rotation-distance", "32"];
    let o = stepdamp(&a);
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    // B alone: x = −y; 100 mm each is 200 mm of belt at 64 mm/s, the head at 64/√2 mm/s.
    assert!(t.contains("G1 X100 Y-100 F2715.29\nG4 P300\nG1 X-100 Y100 F2715.29\n"), "{t}");
    assert!(t.lines().all(|l| l.is_ascii() || l.starts_with(';')), "{t}");
    let o = stepdamp(&[&a[..], &["--travel-mm", "20"]].concat());
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("at least") && text(&o).trim().lines().count() == 1, "{}", text(&o));
}
