//! Reports how long the fit of the plan's logs takes (the release test
//! `ten_seconds_of_20_khz_logs_parse_and_identify_quickly` times reading and fitting once;
//! this repeats the fit alone, for profiling and before/after comparisons):
//!
//! ```text
//! cargo run --release -p stepdamp-identify --example fit_timing [REPEATS]
//! ```
//!
//! Simulates the plan of `patent-motor` (4 runs of 2.5 s at 20 kHz, 200 000 rows), reads
//! the logs, fits them `REPEATS` times (default 15) and prints the median and least wall
//! time and CPU time of this thread (Linux; the wall time on a shared machine includes
//! waiting), and a hash of the whole `Fit` (`Debug`), which a change meant to be only
//! faster must leave as it was.

use stepdamp_identify::fit::{FitOptions, fit};
use stepdamp_identify::log::{LogOptions, RunLog, read_log};
use stepdamp_identify::plan::{PlanOptions, run_plan};
use stepdamp_sim::Profile;

/// CPU time of this thread in s (`/proc/thread-self/schedstat`), `None` where unavailable.
fn thread_cpu_s() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    Some(s.split_whitespace().next()?.parse::<f64>().ok()? * 1e-9)
}

fn median_and_min(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0])
}

fn main() {
    let reps: usize = std::env::args().nth(1).map_or(15, |s| s.parse().expect("REPEATS: a whole number"));
    let reps = reps.max(1);
    let m = Profile::preset("patent-motor").expect("preset");
    let dir = tempfile::tempdir().expect("temporary directory");
    let o = PlanOptions { electrical_periods: 2.0, min_steady_s: 2.3, ..PlanOptions::default() };
    let done = run_plan(&m, &m, dir.path(), &o, &|| {}).expect("simulated plan");
    let logs: Vec<RunLog> = done
        .files
        .iter()
        .map(|f| {
            let mut l = read_log(f, &LogOptions::new(50)).expect("log");
            // The file name alone: the temporary directory's name would change the hash.
            l.source = f.file_name().expect("a file").to_string_lossy().into_owned();
            l
        })
        .collect();
    let rows: usize = logs.iter().map(RunLog::len).sum();
    let fo = FitOptions::for_profile(&done.plan.profile, &[1, 2, 4]);
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    let mut last = None;
    for _ in 0..reps {
        let (t0, c0) = (std::time::Instant::now(), thread_cpu_s());
        let f = fit(&logs, &fo).expect("fit");
        if let (Some(c0), Some(c1)) = (c0, thread_cpu_s()) {
            cpu.push(c1 - c0);
        }
        wall.push(t0.elapsed().as_secs_f64());
        last = Some(f);
    }
    let (w_med, w_min) = median_and_min(wall);
    println!("fit of {rows} rows, {reps} times: wall median {w_med:.4} s, least {w_min:.4} s");
    if !cpu.is_empty() {
        let (c_med, c_min) = median_and_min(cpu);
        println!("CPU time of the fit: median {c_med:.4} s, least {c_min:.4} s");
    }
    let dbg = format!("{:?}", last.expect("at least one fit"));
    let h = dbg.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    println!("the Fit (Debug, {} bytes): FNV-1a {h:016x}", dbg.len());
}
