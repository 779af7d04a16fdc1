//! `identify --log` reads each log once: a FIFO and standard input (`-`) give the profile the
//! file gives; a file given twice and a set of two routes are refused with one line naming
//! them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs the binary with `stdin`, killed (and the test failed) after two minutes: reading a
/// log twice used to wait forever on a FIFO.
fn stepdamp_with(args: &[&str], stdin: Stdio) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(args)
        .stdin(stdin)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > Duration::from_secs(120) {
            child.kill().unwrap();
            panic!("{args:?}: still running after 120 s (waiting on a log it opened twice?)");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn stepdamp(args: &[&str]) -> Output {
    stepdamp_with(args, Stdio::null())
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout.clone()).unwrap()
}

/// The one-line error of a failed run.
fn error(o: &Output) -> String {
    assert!(!o.status.success(), "succeeded: {}", String::from_utf8_lossy(&o.stdout));
    let e = String::from_utf8(o.stderr.clone()).unwrap();
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    e
}

/// Simulated logs of patent-motor's plan (short runs) and the profile they were recorded with.
fn logs(dir: &Path) -> (Vec<PathBuf>, PathBuf) {
    let out = dir.join("runs");
    ok(&stepdamp(&[
        "--quiet",
        "identify",
        "run",
        "--motor",
        "patent-motor",
        "--periods",
        "5",
        "--out",
        out.to_str().unwrap(),
    ]));
    let mut csv: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    csv.sort();
    (csv, out.join("base.toml"))
}

/// `identify` of `first` (as given) and the other logs, the profile it wrote.
fn identified(first: &str, rest: &[PathBuf], base: &Path, out: &Path, stdin: Stdio) -> String {
    let mut args = vec!["identify", "--log", first];
    for l in rest {
        args.extend(["--log", l.to_str().unwrap()]);
    }
    args.extend(["--motor", base.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    ok(&stepdamp_with(&args, stdin));
    std::fs::read_to_string(out).unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn a_fifo_and_standard_input_give_the_profile_the_file_gives() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (csv, base) = logs(d);
    let from_file = identified(csv[0].to_str().unwrap(), &csv[1..], &base, &d.join("file.toml"), Stdio::null());

    let fifo = d.join("log.fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let writer = {
        let (fifo, src) = (fifo.clone(), csv[0].clone());
        // Opens the FIFO once and writes the log once; an error (the reader gone) ends it.
        std::thread::spawn(move || {
            let _ = std::fs::write(&fifo, std::fs::read(src).unwrap());
        })
    };
    let from_fifo = identified(fifo.to_str().unwrap(), &csv[1..], &base, &d.join("fifo.toml"), Stdio::null());
    if !writer.is_finished() {
        // A writer still waiting for a reader: release it (O_NONBLOCK, 0o4000 on Linux).
        use std::os::unix::fs::OpenOptionsExt;
        let _ = std::fs::OpenOptions::new().read(true).custom_flags(0o4000).open(&fifo);
    }
    writer.join().unwrap();
    assert_eq!(from_fifo, from_file);

    let stdin = Stdio::from(std::fs::File::open(&csv[0]).unwrap());
    let from_stdin = identified("-", &csv[1..], &base, &d.join("stdin.toml"), stdin);
    assert_eq!(from_stdin, from_file);
}

#[test]
fn a_log_given_twice_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("a.csv");
    std::fs::write(&log, "t_s,theta_fb_rad,i_q_a\n0,0,0\n").unwrap();
    let out = d.join("id.toml");
    let run = |logs: &[&str], stdin: Stdio| {
        let mut a = vec!["identify", "--motor", "patent-motor", "--out", out.to_str().unwrap()];
        for l in logs {
            a.extend(["--log", l]);
        }
        stepdamp_with(&a, stdin)
    };
    let l = log.to_str().unwrap();
    let again = d.join(".").join("a.csv");
    for second in [l, again.to_str().unwrap()] {
        let e = error(&run(&[l, second], Stdio::null()));
        assert!(e.contains(&format!("{second}: given twice (first as {l})")), "{e}");
    }
    let e = error(&run(&["-", "-"], Stdio::null()));
    assert!(e.contains("standard input (-) is given twice"), "{e}");
    #[cfg(unix)]
    {
        // Standard input redirected from a file given by name too.
        let e = error(&run(&[l, "-"], Stdio::from(std::fs::File::open(&log).unwrap())));
        assert!(e.contains("<stdin>: given twice") && e.contains(l), "{e}");
    }
    assert!(!out.exists());
}

#[test]
fn a_set_of_encoder_and_sensorless_logs_is_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let enc = d.join("enc.csv");
    let sl = d.join("sl.csv");
    std::fs::write(&enc, "t_s,theta_fb_rad,i_q_a\n0,0,0\n").unwrap();
    std::fs::write(&sl, "t_s,theta_cmd_rad,i_a_a,i_b_a,v_a_v,v_b_v\n0,0,1,0,0.9,0\n").unwrap();
    let out = d.join("id.toml");
    let (e_, s_, o_) = (enc.to_str().unwrap(), sl.to_str().unwrap(), out.to_str().unwrap());
    let e = error(&stepdamp(&["identify", "--log", s_, "--log", e_, "--motor", "patent-motor", "--out", o_]));
    assert!(e.contains(&format!("{e_} has theta_fb_rad (an encoder log), but {s_} has no theta_fb_rad")), "{e}");
    assert!(e.contains("give logs of one route"), "{e}");
    assert!(!out.exists());
}
