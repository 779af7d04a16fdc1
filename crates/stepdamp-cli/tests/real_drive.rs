//! `sweep` and `identify run` take a profile with the simulator's real-drive models
//! (smooth or Stribeck friction, current-sensor offset and gain errors, an eccentric
//! encoder disc: `docs/files.md`, "Simulated friction and sensors").

use std::process::{Command, Output};

const PATENT_MOTOR: &str = include_str!("../../stepdamp-profile/presets/patent-motor.toml");

fn stepdamp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_stepdamp")).args(args).output().expect("runs")
}

/// The patent motor with friction law `law` ("smooth" or "stribeck") and every sensor error.
fn real_drive_profile(law: &str) -> String {
    let friction = if law == "smooth" {
        "[motor.friction]\nlaw = \"smooth\"\ncreep_speed_rad_s = 0.002\n".to_string()
    } else {
        "[motor.friction]\nlaw = \"stribeck\"\ncreep_speed_rad_s = 0.002\nstatic_nm = 0.015\nstribeck_speed_rad_s = 0.05\n"
            .to_string()
    };
    PATENT_MOTOR
        .replacen("name = \"patent-motor\"", &format!("name = \"real-{law}\""), 1)
        .replacen(
            "\n[drive]\n",
            &format!("\n{friction}\n[drive]\ncurrent_offset_a = [0.02, -0.01]\ncurrent_gain_error = [0.02, -0.01]\n"),
            1,
        )
        .replacen(
            "counts_per_rev = 4000",
            "counts_per_rev = 4000\neccentricity_rad = 0.002\neccentricity_phase_rad = 0.5",
            1,
        )
}

#[test]
fn sweep_and_identify_run_take_a_profile_with_real_drive_models() {
    let dir = tempfile::tempdir().unwrap();
    for law in ["smooth", "stribeck"] {
        let motor = dir.path().join(format!("{law}.toml"));
        std::fs::write(&motor, real_drive_profile(law)).unwrap();
        let motor = motor.to_str().unwrap();
        let check = stepdamp(&["motor", "check", motor]);
        assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stderr));

        let out = dir.path().join(format!("sweep-{law}"));
        let o = stepdamp(&[
            "--quiet",
            "sweep",
            "--motor",
            motor,
            "--mode",
            "both",
            "--compensation",
            "patent",
            "--from",
            "4",
            "--to",
            "9",
            "--points",
            "2",
            "--duration",
            "0.3",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let table = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
        assert_eq!(table.lines().count(), 1 + 4, "{table}");

        let out = dir.path().join(format!("identify-{law}"));
        let o = stepdamp(&[
            "--quiet",
            "identify",
            "run",
            "--motor",
            motor,
            "--out",
            out.to_str().unwrap(),
            "--periods",
            "6",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // The runs were recorded with the real-drive models, and the base profile says so.
        let base = std::fs::read_to_string(out.join("base.toml")).unwrap();
        assert!(base.contains(&format!("law = \"{law}\"")) && base.contains("eccentricity_rad = 0.002"), "{base}");
    }
}
