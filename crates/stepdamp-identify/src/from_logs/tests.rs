//! Reading a set of logs: once each, one route, no file twice. Synthetic logs (no
//! simulator needed: these run without the feature `simulate`).

use super::{IdentifyError, IdentifyOptions, LogSource, Logs, Route, identify, read_logs};
use crate::log::{LogColumns, LogError};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use stepdamp_profile::Profile;

/// An encoder log: 1 rad/s for 1 s (8 electrical periods at Nr = 50).
fn encoder_csv() -> String {
    let mut s = String::from("t_s,theta_fb_rad,i_q_a,extra\n");
    for i in 0..1000 {
        let t = i as f64 * 1e-3;
        let _ = writeln!(s, "{t},{t},{},7", 0.1 + 0.05 * (50.0 * t).sin());
    }
    s
}

/// A sensorless log (standstill then turning: only read here, not fitted).
fn sensorless_csv() -> String {
    let mut s = String::from("t_s,theta_cmd_rad,i_a_a,i_b_a,v_a_v,v_b_v\n");
    for i in 0..200 {
        let t = i as f64 * 1e-3;
        let _ = writeln!(s, "{t},{t},1,0,0.9,0");
    }
    s
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn path(p: &Path) -> LogSource<'static> {
    LogSource::Path(p.to_path_buf())
}

#[test]
fn the_route_comes_from_the_headers_and_the_rows_from_the_same_reading() {
    let dir = tempfile::tempdir().unwrap();
    let enc = write(dir.path(), "enc.csv", &encoder_csv());
    let sl = write(dir.path(), "sl.csv", &sensorless_csv());
    let Logs::Encoder(e) = read_logs(&[path(&enc)], 50, None).unwrap() else { panic!("not encoder") };
    assert_eq!((e[0].len(), e[0].ignored_columns.clone()), (1000, vec!["extra".to_string()]));
    let logs = read_logs(&[path(&sl)], 50, None).unwrap();
    assert_eq!(logs.route(), Route::Sensorless);
    assert_eq!(logs.summaries()[0].rows, 200);
    // Forced: an encoder log read for the sensorless route needs the voltages.
    let e = read_logs(&[path(&enc)], 50, Some(Route::Sensorless)).unwrap_err().to_string();
    assert!(e.contains("enc.csv") && e.contains("'theta_cmd_rad'"), "{e}");
}

/// The columns of a CSV text, as a DataFrame would hold them: (name, values), all parsed.
fn columns_of(csv: &str) -> Vec<(String, Vec<f64>)> {
    let mut lines = csv.lines();
    let mut cols: Vec<(String, Vec<f64>)> =
        lines.next().unwrap().split(',').map(|n| (n.to_string(), Vec::new())).collect();
    for l in lines {
        for (c, v) in cols.iter_mut().zip(l.split(',')) {
            c.1.push(v.parse().unwrap());
        }
    }
    cols
}

fn in_memory<'a>(cols: &'a [(String, Vec<f64>)], unused: &[&str]) -> LogSource<'a> {
    LogSource::Columns {
        columns: LogColumns {
            values: cols.iter().map(|(n, v)| (n.clone(), v.as_slice())).collect(),
            unused: unused.iter().map(ToString::to_string).collect(),
        },
        name: "<DataFrame 0>".to_string(),
    }
}

#[test]
fn columns_in_memory_read_as_the_file_does() {
    let dir = tempfile::tempdir().unwrap();
    let enc = write(dir.path(), "enc.csv", &encoder_csv());
    let mut cols = columns_of(&encoder_csv());
    cols.pop(); // `extra`, an unknown column, is passed by name only
    let Logs::Encoder(mut mem) = read_logs(&[in_memory(&cols, &["extra"])], 50, None).unwrap() else {
        panic!("not encoder")
    };
    let Logs::Encoder(file) = read_logs(&[path(&enc)], 50, None).unwrap() else { panic!("not encoder") };
    mem[0].source = file[0].source.clone();
    assert_eq!(mem, file);
    let sl = columns_of(&sensorless_csv());
    assert_eq!(read_logs(&[in_memory(&sl, &[])], 50, None).unwrap().route(), Route::Sensorless);
}

#[test]
fn columns_in_memory_are_checked_as_a_file_is_with_csv_line_numbers() {
    let mut cols = columns_of(&encoder_csv());
    cols[2].1[5] = f64::NAN;
    let e = read_logs(&[in_memory(&cols, &[])], 50, None).unwrap_err().to_string();
    assert!(e.contains("<DataFrame 0>: line 7, column 'i_q_a'") && e.contains("NaN"), "{e}");
    let mut cols = columns_of(&encoder_csv());
    cols[0].1[9] = cols[0].1[8];
    let e = read_logs(&[in_memory(&cols, &[])], 50, None).unwrap_err().to_string();
    assert!(e.contains("line 11, column 't_s'"), "{e}");
    let mut cols = columns_of(&encoder_csv());
    cols[1].1.pop();
    let e = read_logs(&[in_memory(&cols, &[])], 50, None).unwrap_err();
    assert!(matches!(e, IdentifyError::Log(LogError::RaggedColumns { rows: 999, expected: 1000, .. })), "{e}");
    let cols = columns_of(&encoder_csv());
    let e = read_logs(&[in_memory(&cols[..3], &["iq_cmd_a"])], 50, None).unwrap_err().to_string();
    assert!(e.contains("column 'iq_cmd_a' is given without its values"), "{e}");
    let e = read_logs(&[in_memory(&cols, &["extra"])], 50, None).unwrap_err().to_string();
    assert!(e.contains("column 'extra' appears twice"), "{e}");
    let e = read_logs(&[in_memory(&cols[..0], &[])], 50, None).unwrap_err().to_string();
    assert!(e.contains("<DataFrame 0>"), "{e}");
}

#[cfg(unix)]
#[test]
fn a_fifo_is_opened_once_and_reads_as_the_file_does() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "enc.csv", &encoder_csv());
    let fifo = dir.path().join("fifo.csv");
    let status = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(status.success());
    // The writer opens the FIFO once and writes the log once: a second open by the reader
    // would wait for a second writer forever (the test would hang), and a header read
    // through another handle would take a data row for the header.
    let writer = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::write(fifo, encoder_csv()).unwrap())
    };
    let from_fifo = read_logs(&[path(&fifo)], 50, None).unwrap();
    writer.join().unwrap();
    let Logs::Encoder(mut f) = from_fifo else { panic!("not encoder") };
    let Logs::Encoder(g) = read_logs(&[path(&file)], 50, None).unwrap() else { panic!("not encoder") };
    f[0].source = g[0].source.clone();
    assert_eq!(f, g);
}

#[test]
fn a_file_given_twice_is_refused_by_name_before_anything_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let enc = write(dir.path(), "enc.csv", &encoder_csv());
    let other = write(dir.path(), "other.csv", &encoder_csv());
    let same_by_another_name = dir.path().join(".").join("enc.csv");
    for again in [enc.clone(), same_by_another_name] {
        let e = read_logs(&[path(&enc), path(&other), path(&again)], 50, None).unwrap_err();
        assert!(matches!(e, IdentifyError::GivenTwice { .. }), "{e}");
        let e = e.to_string();
        assert!(e.starts_with(&format!("{}: given twice (first as {})", again.display(), enc.display())), "{e}");
    }
    #[cfg(unix)]
    {
        let link = dir.path().join("link.csv");
        std::os::unix::fs::symlink(&enc, &link).unwrap();
        let e = read_logs(&[path(&link), path(&enc)], 50, None).unwrap_err().to_string();
        assert!(e.contains("given twice"), "{e}");
    }
    // Two files with the same content are two logs.
    assert!(read_logs(&[path(&enc), path(&other)], 50, None).is_ok());
    let e = read_logs(&[LogSource::Stdin, LogSource::Stdin], 50, None).unwrap_err().to_string();
    assert!(e.contains("standard input (-) is given twice"), "{e}");
}

#[test]
fn a_set_of_encoder_and_sensorless_logs_is_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    // A one-row encoder log: too short to read, but the mixed set is refused first.
    let enc = write(dir.path(), "enc.csv", "t_s,theta_fb_rad,i_q_a\n0,0,0\n");
    let sl = write(dir.path(), "sl.csv", &sensorless_csv());
    let e = read_logs(&[path(&enc), path(&sl)], 50, None).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "{} has no theta_fb_rad (a sensorless log), but {} has theta_fb_rad (an encoder log): give logs of one route",
            sl.display(),
            enc.display()
        )
    );
    // Forced to one route, the set is read for it: an encoder log that also has the
    // voltages and currents goes the sensorless route with the others.
    let both = sensorless_csv().replace("v_b_v\n", "v_b_v,theta_fb_rad\n").replace(",0.9,0\n", ",0.9,0,0\n");
    let both = write(dir.path(), "both.csv", &both);
    let e = read_logs(&[path(&sl), path(&both)], 50, None).unwrap_err().to_string();
    assert!(e.contains("one route"), "{e}");
    let forced = read_logs(&[path(&sl), path(&both)], 50, Some(Route::Sensorless)).unwrap();
    assert_eq!(forced.route(), Route::Sensorless);
}

#[test]
fn the_first_error_in_the_order_given_wins() {
    let dir = tempfile::tempdir().unwrap();
    let good = write(dir.path(), "good.csv", &encoder_csv());
    let bad = write(dir.path(), "bad.csv", "t_s,theta_fb_rad,i_q_a\n0,0,x\n");
    let missing = dir.path().join("missing.csv");
    let e = read_logs(&[path(&good), path(&missing), path(&bad)], 50, None).unwrap_err();
    // One line: the I/O error's text once, not again as a source.
    assert!(std::error::Error::source(&e).is_none(), "{e:?}");
    let e = e.to_string();
    assert!(e.contains("missing.csv") && e.contains("cannot read"), "{e}");
    let e = read_logs(&[path(&bad), path(&missing)], 50, None).unwrap_err().to_string();
    assert!(e.contains("bad.csv") && e.contains("line 2"), "{e}");
    assert!(matches!(read_logs(&[], 50, None), Err(IdentifyError::NoLogs)));
}

#[test]
fn options_of_the_encoder_route_are_refused_on_sensorless_logs() {
    let dir = tempfile::tempdir().unwrap();
    let sl = write(dir.path(), "sl.csv", &sensorless_csv());
    let base = Profile::preset("patent-motor").unwrap();
    let o = IdentifyOptions { feed_forward_on: true, ..IdentifyOptions::new(&[1, 2, 4]) };
    let e = identify(&[path(&sl)], &base, &o).unwrap_err().to_string();
    assert!(e.starts_with("--ff-on: the logs are sensorless"), "{e}");
    let o = IdentifyOptions { servo_bandwidth_hz: Some(-1.0), ..IdentifyOptions::new(&[1, 2, 4]) };
    let e = identify(&[path(&sl)], &base, &o).unwrap_err().to_string();
    assert!(e.contains("-1: must be a positive number of Hz"), "{e}");
}
