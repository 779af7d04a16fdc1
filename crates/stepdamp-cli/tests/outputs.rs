//! How the `stepdamp` binary writes its outputs: straight through to pipes and devices,
//! through symlinks, and never leaving a temporary file or a partial set of outputs when
//! interrupted by a real SIGINT at any moment.

use std::io::{BufRead, BufReader};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stepdamp"))
}

fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            v.extend(tree(&p));
        }
        v.push(p);
    }
    v.sort();
    v
}

fn names(dir: &Path) -> Vec<String> {
    if !dir.exists() {
        return Vec::new();
    }
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

fn no_temporaries(dir: &Path, what: &str) {
    let tmp: Vec<_> = tree(dir)
        .into_iter()
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(".tmp-")))
        .collect();
    assert!(tmp.is_empty(), "{what}: temporaries left: {tmp:?}");
}

#[test]
fn a_log_to_dev_stdout_read_by_head_ends_quietly() {
    let mut c = bin()
        .args(["simulate", "--speed", "2", "--duration", "3", "--log", "/dev/stdout"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(c.stdout.take().unwrap()).lines();
    let head: Vec<String> = (0..3).map(|_| lines.next().unwrap().unwrap()).collect();
    drop(lines); // `head -3` exits
    let o = c.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(head[0].starts_with("t_s,theta_cmd_rad,"), "{head:?}");
    assert!(o.status.success() && err.is_empty(), "{:?}: {err}", o.status);
}

#[test]
fn a_symlinked_log_keeps_its_link_and_a_device_stays_a_device() {
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("real.csv");
    let link = dir.path().join("run.csv");
    std::fs::write(&real, "old").unwrap();
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let o = bin().args(["simulate", "--speed", "2", "--duration", "0.3", "--log"]).arg(&link).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert!(std::fs::read_to_string(&real).unwrap().starts_with("t_s,"));
    let o = bin().args(["simulate", "--speed", "2", "--duration", "0.3", "--log", "/dev/null"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    no_temporaries(dir.path(), "symlink");
}

/// Runs `args` in `dir`, sends SIGINT after `ms`; true when the signal ended it.
fn interrupt(args: &[&str], dir: &Path, ms: u64) -> bool {
    let mut c = bin().args(args).current_dir(dir).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    std::thread::sleep(Duration::from_millis(ms));
    let _ = Command::new("kill").args(["-INT", &c.id().to_string()]).status();
    let s = c.wait().unwrap();
    match s.signal() {
        Some(sig) => {
            assert_eq!(sig, 2, "{args:?}: ended by signal {sig}");
            true
        }
        None => {
            assert!(s.success(), "{args:?} after {ms} ms: {s:?}");
            false
        }
    }
}

const MOMENTS_MS: [u64; 6] = [20, 80, 250, 600, 1200, 2500];

#[test]
fn an_interrupted_simulate_leaves_the_old_log_or_the_whole_new_one() {
    for ms in MOMENTS_MS {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("run.csv"), "old\n").unwrap();
        let killed = interrupt(&["simulate", "--speed", "2", "--duration", "2", "--log", "run.csv"], dir.path(), ms);
        let what = format!("SIGINT after {ms} ms (killed: {killed})");
        no_temporaries(dir.path(), &what);
        let text = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
        let complete = text.lines().count() == 40_001;
        assert!(text == "old\n" || complete, "{what}: {} lines", text.lines().count());
        assert!(killed || complete, "{what}");
    }
}

#[test]
fn an_interrupted_sweep_leaves_all_three_outputs_or_none() {
    for ms in MOMENTS_MS {
        let dir = tempfile::tempdir().unwrap();
        let args = ["--quiet", "sweep", "--mode", "open-loop", "--compensation", "off", "--from", "4"];
        let args = [&args[..], &["--to", "9", "--points", "4", "--duration", "0.4", "--out", "out"]].concat();
        let killed = interrupt(&args, dir.path(), ms);
        let what = format!("SIGINT after {ms} ms (killed: {killed})");
        no_temporaries(dir.path(), &what);
        let got = names(&dir.path().join("out"));
        let all = ["sweep.csv", "sweep.png", "sweep.svg"];
        assert!(got.is_empty() && killed || got == all, "{what}: {got:?}");
        assert!(got.is_empty() || dir.path().join("out").is_dir());
    }
}

#[test]
fn an_interrupted_identify_run_leaves_the_whole_set_or_nothing() {
    for ms in MOMENTS_MS {
        for existing in [false, true] {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("runs");
            if existing {
                std::fs::create_dir(&out).unwrap();
                std::fs::write(out.join("notes.txt"), "mine").unwrap();
            }
            let args = ["--quiet", "identify", "run", "--motor", "patent-motor", "--periods", "3", "--out", "runs"];
            let killed = interrupt(&args, dir.path(), ms);
            let what = format!("existing {existing}, SIGINT after {ms} ms (killed: {killed})");
            no_temporaries(dir.path(), &what);
            let mut got = names(&out);
            got.retain(|n| n != "notes.txt");
            let complete = got.contains(&"plan.txt".to_string())
                && got.contains(&"base.toml".to_string())
                && got.iter().filter(|n| n.ends_with(".csv")).count() >= 2;
            assert!(got.is_empty() && killed || complete, "{what}: partial set {got:?}");
            assert_eq!(out.exists(), existing || complete, "{what}");
            if existing {
                assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "mine", "{what}");
            }
        }
    }
}
