//! Real signals: a child process (this test binary, re-run in "child" mode) writes outputs
//! slowly, the parent sends SIGINT or SIGTERM at several moments, and afterwards there is
//! no `.tmp-*` file and either the complete output (the child finished) or none of it.

use std::io::Write;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;
use stepdamp_out::{Output, OutputDir, OutputSet, write_file};

const CHILD_ENV: &str = "STEPDAMP_OUT_SIGNAL_CHILD";
const CHUNKS: usize = 40;
const CHUNK: &str = "0.000050,0.1,0.2,0.3\n";

/// What the child writes in `dir`.
fn child(mode: &str, dir: &Path) {
    let slow = || std::thread::sleep(Duration::from_millis(3));
    match mode {
        "single" => {
            let mut out = Output::create(&dir.join("run.csv")).unwrap();
            for _ in 0..CHUNKS {
                out.write_all(CHUNK.as_bytes()).unwrap();
                out.flush().unwrap();
                slow();
            }
            out.commit().unwrap();
        }
        "set" => {
            let mut set = OutputSet::in_dir(&dir.join("sweep")).unwrap();
            for name in ["sweep.csv", "sweep.svg", "sweep.png"] {
                let tmp = set.stage(&dir.join("sweep").join(name)).unwrap();
                let mut f = std::fs::File::create(&tmp).unwrap();
                for _ in 0..CHUNKS / 3 {
                    f.write_all(CHUNK.as_bytes()).unwrap();
                    slow();
                }
            }
            set.commit().unwrap();
        }
        "dir" => {
            let d = OutputDir::prepare(&dir.join("ident")).unwrap();
            for name in ["run-1.csv", "run-2.csv", "plan.txt", "base.toml"] {
                let p = d.path().join(name);
                let mut out = Output::create(&p).unwrap();
                for _ in 0..CHUNKS / 4 {
                    out.write_all(CHUNK.as_bytes()).unwrap();
                    slow();
                }
                out.commit().unwrap();
            }
            d.finish();
        }
        other => panic!("unknown child mode {other}"),
    }
}

/// The child entry point: does nothing unless run by [`run_interrupted`].
#[test]
fn signal_child() {
    if let (Ok(mode), Ok(dir)) = (std::env::var(CHILD_ENV), std::env::var("STEPDAMP_OUT_DIR")) {
        child(&mode, Path::new(&dir));
    }
}

/// Runs the child in `mode` and sends `sig` after `after_ms`; returns whether the child
/// was ended by the signal (false: it finished first).
fn run_interrupted(mode: &str, dir: &Path, sig: &str, after_ms: u64) -> bool {
    let mut c = Command::new(std::env::current_exe().unwrap())
        .args(["--exact", "signal_child", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, mode)
        .env("STEPDAMP_OUT_DIR", dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(after_ms));
    let _ = Command::new("kill").args([&format!("-{sig}"), &c.id().to_string()]).status();
    let status = c.wait().unwrap();
    match status.signal() {
        Some(_) => true,
        None => {
            assert!(status.success(), "{mode}: child failed: {status:?}");
            false
        }
    }
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

fn no_temporaries(dir: &Path, what: &str) {
    let tmp: Vec<_> = tree(dir)
        .into_iter()
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(".tmp-")))
        .collect();
    assert!(tmp.is_empty(), "{what}: temporaries left: {tmp:?}");
}

/// Moments from "while starting up" to "long after the end".
const MOMENTS_MS: [u64; 7] = [0, 5, 15, 40, 80, 130, 400];

#[test]
fn an_interrupted_single_file_leaves_the_old_file_or_the_complete_new_one() {
    for sig in ["INT", "TERM"] {
        for ms in MOMENTS_MS {
            let dir = tempfile::tempdir().unwrap();
            std::fs::write(dir.path().join("run.csv"), "old\n").unwrap();
            let killed = run_interrupted("single", dir.path(), sig, ms);
            let what = format!("SIG{sig} after {ms} ms (killed: {killed})");
            no_temporaries(dir.path(), &what);
            let text = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
            assert!(text == "old\n" || text == CHUNK.repeat(CHUNKS), "{what}: {} bytes", text.len());
            if !killed {
                assert_eq!(text, CHUNK.repeat(CHUNKS), "{what}");
            }
        }
    }
}

#[test]
fn a_temporary_left_by_sigkill_is_removed_by_the_next_write_to_that_target() {
    let dir = tempfile::tempdir().unwrap();
    // SIGKILL cannot be caught: the child's temporary stays behind.
    assert!(run_interrupted("single", dir.path(), "KILL", 40), "the child finished before SIGKILL");
    let left = |d: &Path| -> Vec<PathBuf> {
        tree(d).into_iter().filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(".tmp-")).collect()
    };
    assert_eq!(left(dir.path()).len(), 1, "{:?}", tree(dir.path()));
    // Beside it: a live process's temporary for the same target (this test's own parent,
    // alive), and files that only look alike; none of them may go.
    let parent = std::os::unix::process::parent_id();
    let keep = [
        format!(".tmp-{parent}-a1B2c3-run.csv"),
        ".tmp-x1-a1B2c3-run.csv".to_string(),
        ".tmp-999999999-a1B2c3-other.csv".to_string(),
        ".tmp-999999999-a1B2c3-run.csv.bak".to_string(),
        "run.csv.tmp-999999999".to_string(),
    ];
    for k in &keep {
        std::fs::write(dir.path().join(k), "keep").unwrap();
    }
    std::fs::create_dir(dir.path().join(".tmp-999999998-a1B2c3-run.csv")).unwrap();
    write_file(&dir.path().join("run.csv"), b"new\n").unwrap();
    assert_eq!(std::fs::read_to_string(dir.path().join("run.csv")).unwrap(), "new\n");
    let mut names: Vec<String> =
        left(dir.path()).iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    names.sort();
    let mut want: Vec<String> = keep.iter().filter(|k| k.starts_with(".tmp-")).cloned().collect();
    want.push(".tmp-999999998-a1B2c3-run.csv".into());
    want.sort();
    assert_eq!(names, want, "the killed child's temporary is gone, nothing else");
    assert!(dir.path().join("run.csv.tmp-999999999").exists());
}

#[test]
fn an_interrupted_set_appears_complete_or_not_at_all() {
    for ms in MOMENTS_MS {
        let dir = tempfile::tempdir().unwrap();
        let killed = run_interrupted("set", dir.path(), "INT", ms);
        let what = format!("SIGINT after {ms} ms (killed: {killed})");
        no_temporaries(dir.path(), &what);
        let out = dir.path().join("sweep");
        if killed {
            assert!(!out.exists() || tree(&out).len() == 3, "{what}: {:?}", tree(dir.path()));
        } else {
            assert_eq!(tree(&out).len(), 3, "{what}");
        }
    }
}

#[test]
fn an_interrupted_directory_of_outputs_is_removed_or_complete() {
    for existing in [false, true] {
        for ms in MOMENTS_MS {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("ident");
            if existing {
                std::fs::create_dir(&out).unwrap();
                std::fs::write(out.join("notes.txt"), "mine").unwrap();
            }
            let killed = run_interrupted("dir", dir.path(), "INT", ms);
            let what = format!("existing {existing}, SIGINT after {ms} ms (killed: {killed})");
            no_temporaries(dir.path(), &what);
            let mut names: Vec<String> = if out.exists() {
                tree(&out).iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect()
            } else {
                Vec::new()
            };
            names.retain(|n| n != "notes.txt");
            assert!(names.is_empty() || names.len() == 4, "{what}: partial set {names:?}");
            assert!(!killed || names.is_empty() || names.len() == 4);
            if existing {
                assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "mine", "{what}");
            }
            if !killed {
                assert_eq!(names.len(), 4, "{what}");
            }
        }
    }
}

#[test]
fn writes_to_a_fifo_or_device_go_straight_through_and_leave_it_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    write_file(&fifo, b"through\n").unwrap();
    assert_eq!(reader.join().unwrap(), "through\n");
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    write_file(Path::new("/dev/null"), b"x").unwrap();
    assert!(std::fs::symlink_metadata("/dev/null").unwrap().file_type().is_char_device());
    no_temporaries(dir.path(), "fifo");
}

#[test]
fn a_symlinked_output_keeps_its_link_and_replaces_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("real.csv");
    let link = dir.path().join("link.csv");
    std::fs::write(&target, "old").unwrap();
    std::os::unix::fs::symlink("real.csv", &link).unwrap();
    write_file(&link, b"new").unwrap();
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
    // A dangling link: its target is created, the link stays.
    let dangling = dir.path().join("dangling.csv");
    std::os::unix::fs::symlink("later.csv", &dangling).unwrap();
    write_file(&dangling, b"made").unwrap();
    assert!(std::fs::symlink_metadata(&dangling).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(dir.path().join("later.csv")).unwrap(), "made");
    // In a set too.
    let mut set = OutputSet::in_existing_dir(dir.path()).unwrap();
    let tmp = set.stage(&link).unwrap();
    std::fs::write(tmp, "set").unwrap();
    set.commit().unwrap();
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "set");
    no_temporaries(dir.path(), "symlink");
}

#[test]
fn a_replaced_file_keeps_its_permissions_and_errors_name_the_path() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("script.sh");
    std::fs::write(&p, "old").unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o751)).unwrap();
    write_file(&p, b"new").unwrap();
    assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o751);
    let e = write_file(dir.path(), b"x").unwrap_err().to_string();
    assert!(e.contains("is a directory"), "{e}");
    let e = write_file(&dir.path().join("no/such/x.csv"), b"x").unwrap_err().to_string();
    assert!(e.contains("no/such/x.csv") && e.contains("does not exist"), "{e}");
    let e = OutputSet::in_existing_dir(&dir.path().join("nope")).unwrap_err().to_string();
    assert!(e.contains("nope"), "{e}");
}

#[test]
fn a_failed_command_leaves_no_directory_it_created_and_no_temporaries() {
    let dir = tempfile::tempdir().unwrap();
    {
        let mut set = OutputSet::in_dir(&dir.path().join("a/b")).unwrap();
        let tmp = set.stage(&dir.path().join("a/b/x.csv")).unwrap();
        std::fs::write(tmp, "x").unwrap();
    }
    {
        let d = OutputDir::prepare(&dir.path().join("c")).unwrap();
        write_file(&d.path().join("y.csv"), b"y").unwrap();
    }
    assert!(tree(dir.path()).is_empty(), "{:?}", tree(dir.path()));
}

#[test]
fn a_move_that_fails_midway_removes_the_temporaries_not_yet_moved() {
    let dir = tempfile::tempdir().unwrap();
    let mut set = OutputSet::in_existing_dir(dir.path()).unwrap();
    for name in ["a.csv", "b.csv", "c.csv"] {
        let tmp = set.stage(&dir.path().join(name)).unwrap();
        std::fs::write(tmp, name).unwrap();
    }
    // b.csv becomes a non-empty directory after staging: its move fails.
    std::fs::create_dir(dir.path().join("b.csv")).unwrap();
    std::fs::write(dir.path().join("b.csv/keep"), "").unwrap();
    let e = set.commit().unwrap_err().to_string();
    assert!(e.contains("b.csv") && e.contains("cannot write"), "{e}");
    no_temporaries(dir.path(), "failed move");
    assert!(!dir.path().join("c.csv").exists());
    assert_eq!(std::fs::read_to_string(dir.path().join("a.csv")).unwrap(), "a.csv");
}
