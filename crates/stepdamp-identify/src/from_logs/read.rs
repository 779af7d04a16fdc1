//! Reading a set of run logs for [`super::identify`]: each source opened once and read in
//! one pass (the header, then the rows, from the same reader), the route taken from the
//! headers, and a log given twice refused before anything is opened
//! (docs/files.md#run-log-csv).

use super::IdentifyError;
use crate::log::columns::ColumnReader;
use crate::log::{EXPECTED_HEADER, KNOWN_COLUMNS, LogColumns, LogError, LogOptions, RunLog, log_from_columns};
use crate::sensorless::log::{
    EXPECTED_HEADER as SENSORLESS_EXPECTED_HEADER, SensorlessLog, sensorless_log_from_columns,
};
use std::io::Read;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Name standard input goes by in messages and reports.
pub const STDIN_NAME: &str = "<stdin>";

/// Where a run log comes from. Each is opened once and read once, front to back, so a
/// FIFO, a pipe (`<(…)`) or standard input work as a file does.
#[derive(Clone, Debug, PartialEq)]
pub enum LogSource<'a> {
    /// A file, FIFO or device, by path.
    Path(PathBuf),
    /// Standard input (`-` on the command line): at most once in a set.
    Stdin,
    /// Columns already in memory (a DataFrame's arrays, borrowed): read without CSV text,
    /// only the wanted columns copied.
    Columns {
        /// The columns.
        columns: LogColumns<'a>,
        /// Its name in messages.
        name: String,
    },
}

impl LogSource<'_> {
    /// A command-line argument: `-` is standard input, anything else a path.
    pub fn from_arg(arg: impl Into<PathBuf>) -> LogSource<'static> {
        let p = arg.into();
        if p.as_os_str() == "-" { LogSource::Stdin } else { LogSource::Path(p) }
    }

    /// The name messages give it: the path as written, [`STDIN_NAME`], or the text's name.
    pub fn name(&self) -> String {
        match self {
            LogSource::Path(p) => p.display().to_string(),
            LogSource::Stdin => STDIN_NAME.to_string(),
            LogSource::Columns { name, .. } => name.clone(),
        }
    }
}

/// The identification route, from the logs' headers (docs/sensorless.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Route {
    /// Encoder logs (they have `theta_fb_rad`): the servo route ([`crate::log`], [`crate::fit`]).
    Encoder,
    /// Logs without `theta_fb_rad`, with the voltages and currents: the sensorless route
    /// ([`crate::sensorless`]).
    Sensorless,
}

impl Route {
    /// Its name, as in the JSON and the Python report: `encoder` or `sensorless`.
    pub fn name(self) -> &'static str {
        match self {
            Route::Encoder => "encoder",
            Route::Sensorless => "sensorless",
        }
    }

    /// What a log of this route has, for the message that refuses a mixed set.
    fn has(self) -> &'static str {
        match self {
            Route::Encoder => "has theta_fb_rad (an encoder log)",
            Route::Sensorless => "has no theta_fb_rad (a sensorless log)",
        }
    }

    /// The route a header calls for: encoder with `theta_fb_rad`, sensorless with a
    /// voltage column instead (a missing current or voltage is then the reader's error);
    /// neither is an error naming what is missing.
    fn of_header<R: Read>(cols: &ColumnReader<'_, R>) -> Result<Route, LogError> {
        if cols.has("theta_fb_rad") {
            Ok(Route::Encoder)
        } else if cols.has("v_a_v") || cols.has("v_b_v") {
            Ok(Route::Sensorless)
        } else {
            Err(cols.missing("theta_fb_rad", "encoder angle in rad; or, for the sensorless route, v_a_v and v_b_v"))
        }
    }
}

/// A set of logs read for one route.
#[derive(Clone, Debug, PartialEq)]
pub enum Logs {
    /// Encoder logs.
    Encoder(Vec<RunLog>),
    /// Sensorless logs.
    Sensorless(Vec<SensorlessLog>),
}

impl Logs {
    /// The route these logs take.
    pub fn route(&self) -> Route {
        match self {
            Logs::Encoder(_) => Route::Encoder,
            Logs::Sensorless(_) => Route::Sensorless,
        }
    }

    /// Per log, in the order given: its name, rows and the header columns it ignored.
    pub fn summaries(&self) -> Vec<LogSummary> {
        match self {
            Logs::Encoder(l) => l.iter().map(|l| LogSummary::new(&l.source, l.len(), &l.ignored_columns)).collect(),
            Logs::Sensorless(l) => l.iter().map(|l| LogSummary::new(&l.source, l.len(), &l.ignored_columns)).collect(),
        }
    }
}

/// What was read from one log.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LogSummary {
    /// Its name (the path as given, or [`STDIN_NAME`]).
    pub source: String,
    /// Data rows read.
    pub rows: usize,
    /// Header columns not used (unknown names), in file order.
    pub ignored_columns: Vec<String>,
}

impl LogSummary {
    fn new(source: &str, rows: usize, ignored: &[String]) -> Self {
        LogSummary { source: source.to_string(), rows, ignored_columns: ignored.to_vec() }
    }
}

/// One log read for the route its header (or `forced`) calls for.
enum OneLog {
    Encoder(RunLog),
    Sensorless(SensorlessLog),
}

/// What reading one log gave: the route its header called for (`None` when the header
/// could not be read), then the log or the error.
type Outcome = (Option<Route>, Result<OneLog, LogError>);

/// Reads every log once, in parallel (at most one thread per core; the first error in the
/// order given wins), each for the route its header calls for, or `forced`. Refuses an
/// empty set, a file given twice (compared by device and inode, so `a.csv`, `./a.csv`, a
/// link to it and `-` redirected from it are one file), standard input twice, and a set
/// whose headers call for two routes (that refusal wins over any error in the rows).
pub fn read_logs(inputs: &[LogSource<'_>], pole_pairs: u16, forced: Option<Route>) -> Result<Logs, IdentifyError> {
    if inputs.is_empty() {
        return Err(IdentifyError::NoLogs);
    }
    refuse_duplicates(inputs)?;
    let opts = LogOptions::new(pole_pairs);
    let outcomes = in_parallel(inputs, |s| read_source(s, &opts, forced));
    if let Some(first) = outcomes.iter().position(|o| o.0.is_some()) {
        let route = outcomes[first].0;
        if let Some(odd) = outcomes.iter().position(|o| o.0.is_some() && o.0 != route) {
            let (a, b) = (route.unwrap_or(Route::Encoder), outcomes[odd].0.unwrap_or(Route::Encoder));
            return Err(IdentifyError::MixedRoutes {
                log: inputs[odd].name(),
                has: b.has(),
                first: inputs[first].name(),
                first_has: a.has(),
            });
        }
    }
    let mut encoder = Vec::new();
    let mut sensorless = Vec::new();
    for (_, r) in outcomes {
        match r? {
            OneLog::Encoder(l) => encoder.push(l),
            OneLog::Sensorless(l) => sensorless.push(l),
        }
    }
    Ok(if sensorless.is_empty() { Logs::Encoder(encoder) } else { Logs::Sensorless(sensorless) })
}

/// Opens `source` once and reads it: the header, the route, then the rows of that route
/// from the same reader.
fn read_source(source: &LogSource<'_>, opts: &LogOptions, forced: Option<Route>) -> Outcome {
    let name = source.name();
    match source {
        LogSource::Path(p) => match std::fs::File::open(p) {
            Ok(f) => read_reader(f, &name, opts, forced),
            Err(e) => (None, Err(LogError::Io { path: name, source: e })),
        },
        LogSource::Stdin => read_reader(std::io::stdin().lock(), &name, opts, forced),
        LogSource::Columns { columns, .. } => match ColumnReader::from_arrays(columns, &name, &KNOWN_COLUMNS) {
            Ok(cols) => read_opened(cols, &name, opts, forced),
            Err(e) => (None, Err(e)),
        },
    }
}

fn read_reader<R: Read>(reader: R, name: &str, opts: &LogOptions, forced: Option<Route>) -> Outcome {
    let expected = if forced == Some(Route::Sensorless) { SENSORLESS_EXPECTED_HEADER } else { EXPECTED_HEADER };
    match ColumnReader::open(reader, name, &KNOWN_COLUMNS, expected) {
        Ok(cols) => read_opened(cols, name, opts, forced),
        Err(e) => (None, Err(e)),
    }
}

/// The route, then the rows of that route, of a log whose header is read.
fn read_opened<R: Read>(cols: ColumnReader<'_, R>, name: &str, opts: &LogOptions, forced: Option<Route>) -> Outcome {
    let route = match forced.map_or_else(|| Route::of_header(&cols), Ok) {
        Ok(r) => r,
        Err(e) => return (None, Err(e)),
    };
    let log = match route {
        Route::Encoder => log_from_columns(cols, name, opts).map(OneLog::Encoder),
        Route::Sensorless => sensorless_log_from_columns(cols, name).map(OneLog::Sensorless),
    };
    (Some(route), log)
}

/// `work` on every input, on at most one thread per core, results in the inputs' order.
fn in_parallel<T: Send>(inputs: &[LogSource<'_>], work: impl Fn(&LogSource<'_>) -> T + Sync) -> Vec<T> {
    let threads = std::thread::available_parallelism().map_or(1, usize::from).min(inputs.len());
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, T)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(input) = inputs.get(i) else { return mine };
                        mine.push((i, work(input)));
                    }
                })
            })
            .collect();
        // A worker only panics if `work` does; pass that panic on unchanged.
        workers.into_iter().flat_map(|w| w.join().unwrap_or_else(|p| std::panic::resume_unwind(p))).collect()
    });
    done.sort_by_key(|d| d.0);
    done.into_iter().map(|d| d.1).collect()
}

/// Refuses standard input twice and a file given twice (by device and inode on Unix, by
/// canonical path elsewhere), before anything is opened (a FIFO given twice would wait for
/// a second writer forever). A path that cannot be inspected is left to the reader's error.
fn refuse_duplicates(inputs: &[LogSource<'_>]) -> Result<(), IdentifyError> {
    let mut seen: Vec<(FileId, String)> = Vec::new();
    let mut stdin_seen = false;
    for s in inputs {
        let id = match s {
            LogSource::Path(p) => FileId::of_path(p),
            LogSource::Stdin if stdin_seen => return Err(IdentifyError::StdinTwice),
            LogSource::Stdin => {
                stdin_seen = true;
                FileId::of_stdin()
            }
            LogSource::Columns { .. } => None,
        };
        let Some(id) = id else { continue };
        if let Some((_, first)) = seen.iter().find(|(k, _)| *k == id) {
            return Err(IdentifyError::GivenTwice { first: first.clone(), again: s.name() });
        }
        seen.push((id, s.name()));
    }
    Ok(())
}

/// What makes two names one file.
#[derive(Debug, PartialEq, Eq)]
enum FileId {
    /// Device and inode.
    #[cfg(unix)]
    Inode(u64, u64),
    /// The canonical path.
    #[cfg(not(unix))]
    Canonical(PathBuf),
}

impl FileId {
    #[cfg(unix)]
    fn of_path(p: &std::path::Path) -> Option<FileId> {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(p).ok().map(|m| FileId::Inode(m.dev(), m.ino()))
    }

    #[cfg(not(unix))]
    fn of_path(p: &std::path::Path) -> Option<FileId> {
        std::fs::canonicalize(p).ok().map(FileId::Canonical)
    }

    /// The file standard input reads (a file redirected with `<`, a pipe, a terminal).
    #[cfg(unix)]
    fn of_stdin() -> Option<FileId> {
        use std::os::fd::AsFd;
        use std::os::unix::fs::MetadataExt;
        let fd = std::io::stdin().as_fd().try_clone_to_owned().ok()?;
        std::fs::File::from(fd).metadata().ok().map(|m| FileId::Inode(m.dev(), m.ino()))
    }

    #[cfg(not(unix))]
    fn of_stdin() -> Option<FileId> {
        None
    }
}
