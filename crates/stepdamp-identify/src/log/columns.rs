//! The streaming reader under every run log: the header checked once (width, duplicates,
//! unknown names), then only the wanted columns parsed into `f64` vectors, row by row,
//! with `t_s` strictly increasing. Both the servo log ([`super::parse_log`]) and the
//! sensorless log ([`crate::sensorless::log`]) are read through it, so they give the same
//! errors for the same faults.

use super::{CsvFailure, LogError, MAX_COLUMNS, SHOWN_CHARS, bounded_csv, column_list, header_names};
use std::io::Read;
use stepdamp_out::input::{LineLimited, printable};

/// A log whose header has been read and checked.
pub(crate) struct ColumnReader<R: Read> {
    rdr: csv::Reader<LineLimited<R>>,
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

impl<R: Read> ColumnReader<R> {
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
        let mut seen = std::collections::HashSet::with_capacity(header.len());
        for h in &header {
            if !seen.insert(h.as_str()) {
                return Err(LogError::DuplicateColumn { path, column: h.clone() });
            }
        }
        let ignored = header.iter().filter(|h| !known.contains(&h.as_str())).cloned().collect();
        Ok(ColumnReader { rdr, path, header, ignored })
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
        mut self,
        wanted: &[&str],
        mut check: impl FnMut(u64, &[f64]) -> Result<(), LogError>,
    ) -> Result<Columns, LogError> {
        let path = self.path;
        // (file column, slot in `wanted`), in file order: a row with two bad values names
        // the first one in the file.
        let mut index: Vec<(usize, usize)> = wanted
            .iter()
            .enumerate()
            .filter_map(|(slot, w)| self.header.iter().position(|h| h == w).map(|i| (i, slot)))
            .collect();
        index.sort_unstable();
        debug_assert!(index.len() == wanted.len() && wanted.first() == Some(&"t_s"));
        let mut values = vec![Vec::new(); index.len()];
        let mut row = vec![0.0; index.len()];
        let ncol = self.header.len();
        let mut rec = csv::ByteRecord::new();
        let mut line: u64 = 1;
        let mut prev_t = f64::NEG_INFINITY;
        loop {
            match self.rdr.read_byte_record(&mut rec) {
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
            for &(i, slot) in &index {
                let field = &rec[i];
                let v = std::str::from_utf8(field).ok().and_then(|s| s.parse::<f64>().ok()).filter(|v| v.is_finite());
                let Some(v) = v else {
                    return Err(LogError::BadValue {
                        path,
                        line,
                        column: self.header[i].clone(),
                        value: printable(field, SHOWN_CHARS),
                    });
                };
                row[slot] = v;
            }
            if let Some(&tn) = row.first() {
                if tn <= prev_t {
                    return Err(LogError::NonMonotonicTime { path, line, t: tn, prev: prev_t });
                }
                prev_t = tn;
            }
            check(line, &row)?;
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
