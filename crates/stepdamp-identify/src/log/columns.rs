//! The reader under every run log: the header checked once (width, duplicates, unknown
//! names), then only the wanted columns, as `f64` vectors, with `t_s` strictly increasing.
//! The rows come from CSV text, streamed and parsed row by row, or from columns already in
//! memory (a DataFrame's arrays, [`LogColumns`]), checked in place, and only the wanted
//! ones copied. Both the servo log ([`super::parse_log`]) and the sensorless log
//! ([`crate::sensorless::log`]) are read through it, so they give the same errors for the
//! same faults.

use super::{CsvFailure, LogError, MAX_COLUMNS, SHOWN_CHARS, bounded_csv, column_list, header_names};
use std::io::Read;
use stepdamp_out::input::{LineLimited, printable};

/// A run log's columns already in memory (e.g. a pandas DataFrame's), read without
/// going through CSV text. Messages number its rows as lines of the CSV it would be
/// written as: the header is line 1, row `i` (from 0) is line `i + 2`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogColumns<'a> {
    /// Columns with their values, in the frame's order (all the same length), borrowed:
    /// only the columns the reader uses are copied.
    pub values: Vec<(String, &'a [f64])>,
    /// Names of further columns whose values are not passed: those the reader does not use
    /// (not in [`super::KNOWN_COLUMNS`]; a known name here is refused). They count in the
    /// header as in a file and are reported as ignored.
    pub unused: Vec<String>,
}

/// Where the rows come from.
enum Body<'a, R: Read> {
    /// CSV text after its header line.
    Csv(csv::Reader<LineLimited<R>>),
    /// One entry per header name: its values, or `None` for an unused column.
    Arrays(Vec<Option<&'a [f64]>>),
}

/// A log whose header has been read and checked.
pub(crate) struct ColumnReader<'a, R: Read> {
    body: Body<'a, R>,
    path: String,
    header: Vec<String>,
    /// Header names not in the known list, in file order.
    pub(crate) ignored: Vec<String>,
}

/// The wanted columns of every data row, in the order they were asked for.
pub(crate) struct Columns {
    /// One vector per wanted column, all the same length.
    pub(crate) values: Vec<Vec<f64>>,
    /// Number of the last line read (1 = the header).
    pub(crate) last_line: u64,
}

fn csv_error(e: csv::Error, path: &str) -> LogError {
    let path = path.to_string();
    match CsvFailure::of(e) {
        CsvFailure::LineTooLong { line, limit } => LogError::LineTooLong { path, line, limit },
        CsvFailure::Io(source) => LogError::Io { path, source },
        CsvFailure::Malformed { line, message } => LogError::Csv { path, line, message },
    }
}

impl<'a, R: Read> ColumnReader<'a, R> {
    /// Reads and checks the header: at most [`MAX_COLUMNS`] names, none twice. Names not in
    /// `known` are kept in [`ColumnReader::ignored`]; `expected` is what an empty file is
    /// told it should have started with.
    pub(crate) fn open(reader: R, path: &str, known: &[&str], expected: &'static str) -> Result<Self, LogError> {
        let path = path.to_string();
        let mut rdr = bounded_csv(reader);
        let mut rec = csv::ByteRecord::new();
        if !rdr.read_byte_record(&mut rec).map_err(|e| csv_error(e, &path))? {
            return Err(LogError::Empty { path, what: expected });
        }
        if rec.len() > MAX_COLUMNS {
            return Err(LogError::TooManyColumns { path, found: rec.len(), max: MAX_COLUMNS });
        }
        let header = header_names(&rec);
        Self::checked(Body::Csv(rdr), path, header, known)
    }

    /// The header's checks, common to both bodies: no name twice; names not in `known`
    /// are kept as ignored.
    fn checked(body: Body<'a, R>, path: String, header: Vec<String>, known: &[&str]) -> Result<Self, LogError> {
        let mut seen = std::collections::HashSet::with_capacity(header.len());
        for h in &header {
            if !seen.insert(h.as_str()) {
                return Err(LogError::DuplicateColumn { path, column: h.clone() });
            }
        }
        let ignored = header.iter().filter(|h| !known.contains(&h.as_str())).cloned().collect();
        Ok(ColumnReader { body, path, header, ignored })
    }

    /// Whether the header has `name`.
    pub(crate) fn has(&self, name: &str) -> bool {
        self.header.iter().any(|h| h == name)
    }

    /// The error for a missing `column`, saying why it is `need`ed and what the header has.
    pub(crate) fn missing(&self, column: &'static str, need: &'static str) -> LogError {
        LogError::MissingColumn { path: self.path.clone(), column, need, found: column_list(&self.header) }
    }

    /// Reads every data row, parsing the `wanted` columns (each must be in the header; the
    /// first must be `t_s`, which must increase strictly). `check` sees each row's wanted
    /// values (in `wanted` order) with its line number and may refuse it. Blank lines are
    /// skipped; a row of another width, a value that is not a finite number, malformed CSV
    /// or a line too long is an error naming the file, line and column.
    pub(crate) fn read(
        self,
        wanted: &[&str],
        check: impl FnMut(u64, &[f64]) -> Result<(), LogError>,
    ) -> Result<Columns, LogError> {
        // (file column, slot in `wanted`), in file order: a row with two bad values names
        // the first one in the file.
        let mut index: Vec<(usize, usize)> = wanted
            .iter()
            .enumerate()
            .filter_map(|(slot, w)| self.header.iter().position(|h| h == w).map(|i| (i, slot)))
            .collect();
        index.sort_unstable();
        debug_assert!(index.len() == wanted.len() && wanted.first() == Some(&"t_s"));
        let mut rows = RowCheck { path: self.path, header: self.header, index, prev_t: f64::NEG_INFINITY, check };
        let values = match self.body {
            Body::Csv(rdr) => rows.csv(rdr)?,
            Body::Arrays(arrays) => rows.arrays(&arrays)?,
        };
        Ok(values)
    }
}

impl<'a> ColumnReader<'a, std::io::Empty> {
    /// A log from columns in memory, named `path` in messages; the same header checks as a
    /// file's ([`ColumnReader::open`]), plus: every column the same length, and no known
    /// column among [`LogColumns::unused`].
    pub(crate) fn from_arrays(columns: &LogColumns<'a>, path: &str, known: &[&str]) -> Result<Self, LogError> {
        let path = path.to_string();
        let found = columns.values.len() + columns.unused.len();
        if found > MAX_COLUMNS {
            return Err(LogError::TooManyColumns { path, found, max: MAX_COLUMNS });
        }
        if let Some(name) = columns.unused.iter().find(|u| known.contains(&u.as_str())) {
            return Err(LogError::ColumnWithoutValues { path, column: printable(name.as_bytes(), SHOWN_CHARS) });
        }
        let rows = columns.values.first().map_or(0, |c| c.1.len());
        if let Some((name, v)) = columns.values.iter().find(|c| c.1.len() != rows) {
            let (column, first) = (printable(name.as_bytes(), SHOWN_CHARS), columns.values[0].0.clone());
            return Err(LogError::RaggedColumns { path, column, rows: v.len(), first, expected: rows });
        }
        let mut header = Vec::with_capacity(found);
        let mut body = Vec::with_capacity(found);
        for (name, v) in &columns.values {
            header.push(printable(name.as_bytes(), SHOWN_CHARS));
            body.push(Some(*v));
        }
        for name in &columns.unused {
            header.push(printable(name.as_bytes(), SHOWN_CHARS));
            body.push(None);
        }
        Self::checked(Body::Arrays(body), path, header, known)
    }
}

/// The per-row checks of [`ColumnReader::read`], whatever the body: each wanted value a
/// finite number, `t_s` strictly increasing, then the caller's `check`.
struct RowCheck<F> {
    path: String,
    header: Vec<String>,
    /// (header column, slot in the wanted list), in header order.
    index: Vec<(usize, usize)>,
    prev_t: f64,
    check: F,
}

impl<F: FnMut(u64, &[f64]) -> Result<(), LogError>> RowCheck<F> {
    /// Checks one row's wanted values (in wanted order; `row[0]` is `t_s`).
    fn row(&mut self, line: u64, row: &[f64]) -> Result<(), LogError> {
        if let Some(&tn) = row.first() {
            if tn <= self.prev_t {
                return Err(LogError::NonMonotonicTime { path: self.path.clone(), line, t: tn, prev: self.prev_t });
            }
            self.prev_t = tn;
        }
        (self.check)(line, row)
    }

    /// The error for a value that is not a finite number (`text` as found).
    fn bad(&self, line: u64, column: usize, text: String) -> LogError {
        LogError::BadValue { path: self.path.clone(), line, column: self.header[column].clone(), value: text }
    }

    /// Checks every row of columns in memory and copies the wanted ones.
    fn arrays(&mut self, arrays: &[Option<&[f64]>]) -> Result<Columns, LogError> {
        let mut given: Vec<&[f64]> = vec![&[]; self.index.len()];
        for &(i, slot) in &self.index {
            given[slot] = arrays.get(i).copied().flatten().unwrap_or_default();
        }
        let n = given.first().map_or(0, |c| c.len());
        let mut row = vec![0.0; given.len()];
        for (r, line) in (0..n).zip(2u64..) {
            for &(i, slot) in &self.index {
                let v = given[slot][r];
                if !v.is_finite() {
                    return Err(self.bad(line, i, v.to_string()));
                }
                row[slot] = v;
            }
            self.row(line, &row)?;
        }
        if n == 0 {
            return Err(LogError::Empty { path: self.path.clone(), what: "no data rows (the columns are empty)" });
        }
        Ok(Columns { values: given.into_iter().map(<[f64]>::to_vec).collect(), last_line: n as u64 + 1 })
    }

    /// Parses the wanted columns of every CSV row.
    fn csv<R: Read>(&mut self, mut rdr: csv::Reader<LineLimited<R>>) -> Result<Columns, LogError> {
        let path = self.path.clone();
        let mut values = vec![Vec::new(); self.index.len()];
        let mut row = vec![0.0; self.index.len()];
        let ncol = self.header.len();
        let mut rec = csv::ByteRecord::new();
        let mut line: u64 = 1;
        loop {
            match rdr.read_byte_record(&mut rec) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(csv_error(e, &path)),
            }
            line = rec.position().map_or(line + 1, |p| p.line());
            if rec.len() == 1 && rec.get(0).is_some_and(<[u8]>::is_empty) {
                continue; // blank line
            }
            if rec.len() != ncol {
                return Err(LogError::ShortRow { path, line, found: rec.len(), expected: ncol });
            }
            for &(i, slot) in &self.index {
                let field = &rec[i];
                let v = std::str::from_utf8(field).ok().and_then(|s| s.parse::<f64>().ok()).filter(|v| v.is_finite());
                let Some(v) = v else {
                    return Err(self.bad(line, i, printable(field, SHOWN_CHARS)));
                };
                row[slot] = v;
            }
            self.row(line, &row)?;
            for (col, &v) in values.iter_mut().zip(&row) {
                col.push(v);
            }
        }
        if values.first().is_none_or(Vec::is_empty) {
            return Err(LogError::Empty { path, what: "no data rows after the header" });
        }
        Ok(Columns { values, last_line: line })
    }
}
