//! A table of scalar columns written as one Parquet file (one row group, Snappy), for DuckDB,
//! Polars or Spark to query a whole campaign at once.
//!
//! Every column is optional (a value a scan or cell does not have is null, not NaN or 0), and
//! typed: text (UTF-8 strings), integers (INT64), reals (DOUBLE), flags (BOOLEAN). Written
//! through the parquet crate's column writers: the rows are a handful of scalars, which is what
//! those writers take directly.

use parquet::basic::{LogicalType, Repetition, Type as Physical};
use parquet::data_type::{BoolType, ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use std::path::Path;
use std::sync::Arc;

/// One column's values, row by row.
#[derive(Clone, Debug, PartialEq)]
pub enum Column {
    /// UTF-8 text.
    Text(Vec<Option<String>>),
    /// 64-bit integers.
    Int(Vec<Option<i64>>),
    /// 64-bit reals.
    Real(Vec<Option<f64>>),
    /// Booleans.
    Flag(Vec<Option<bool>>),
}

impl Column {
    fn len(&self) -> usize {
        match self {
            Column::Text(v) => v.len(),
            Column::Int(v) => v.len(),
            Column::Real(v) => v.len(),
            Column::Flag(v) => v.len(),
        }
    }
}

/// Named columns of equal length.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    /// (name, values), in the file's order.
    pub columns: Vec<(String, Column)>,
}

/// Why a table could not be written.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The columns differ in length (a bug in the caller).
    #[error("column {name} has {len} rows, the first column {first}")]
    Ragged {
        /// The column.
        name: String,
        /// Its rows.
        len: usize,
        /// The first column's rows.
        first: usize,
    },
    /// The file could not be created.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The parquet writer refused.
    #[error("{path}: {source}")]
    Parquet {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        #[source]
        source: parquet::errors::ParquetError,
    },
}

/// Values and definition levels (1: present, 0: null) of an optional column.
fn split<T: Clone, U>(v: &[Option<T>], f: impl Fn(&T) -> U) -> (Vec<U>, Vec<i16>) {
    let values = v.iter().flatten().map(f).collect();
    let levels = v.iter().map(|x| i16::from(x.is_some())).collect();
    (values, levels)
}

impl Table {
    /// Adds a column.
    pub fn push(&mut self, name: &str, column: Column) {
        self.columns.push((name.to_owned(), column));
    }

    /// Rows (of the first column).
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, |c| c.1.len())
    }

    /// Writes the table to `path` (through a temporary file renamed into place).
    pub fn write(&self, path: &Path) -> Result<(), TableError> {
        let pq = |source| TableError::Parquet {
            path: path.to_owned(),
            source,
        };
        let first = self.rows();
        for (name, c) in &self.columns {
            if c.len() != first {
                return Err(TableError::Ragged {
                    name: name.clone(),
                    len: c.len(),
                    first,
                });
            }
        }
        let fields = self
            .columns
            .iter()
            .map(|(name, c)| {
                let (physical, logical) = match c {
                    Column::Text(_) => (Physical::BYTE_ARRAY, Some(LogicalType::String)),
                    Column::Int(_) => (Physical::INT64, None),
                    Column::Real(_) => (Physical::DOUBLE, None),
                    Column::Flag(_) => (Physical::BOOLEAN, None),
                };
                Type::primitive_type_builder(name, physical)
                    .with_repetition(Repetition::OPTIONAL)
                    .with_logical_type(logical)
                    .build()
                    .map(Arc::new)
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(pq)?;
        let schema = Arc::new(
            Type::group_type_builder("hilrig")
                .with_fields(fields)
                .build()
                .map_err(pq)?,
        );
        let props = Arc::new(
            WriterProperties::builder()
                .set_compression(parquet::basic::Compression::SNAPPY)
                .set_created_by(format!("hilrig {}", env!("CARGO_PKG_VERSION")))
                .build(),
        );
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".tmp");
        let tmp = std::path::PathBuf::from(tmp);
        let file = std::fs::File::create(&tmp).map_err(|source| TableError::Io {
            path: tmp.clone(),
            source,
        })?;
        let mut writer = SerializedFileWriter::new(file, schema, props).map_err(pq)?;
        let mut group = writer.next_row_group().map_err(pq)?;
        for (_, c) in &self.columns {
            let mut w = group
                .next_column()
                .map_err(pq)?
                .expect("one writer per column of the schema");
            match c {
                Column::Text(v) => {
                    let (values, levels) = split(v, |s| ByteArray::from(s.as_str()));
                    w.typed::<ByteArrayType>()
                        .write_batch(&values, Some(&levels), None)
                }
                Column::Int(v) => {
                    let (values, levels) = split(v, |x| *x);
                    w.typed::<Int64Type>()
                        .write_batch(&values, Some(&levels), None)
                }
                Column::Real(v) => {
                    let (values, levels) = split(v, |x| *x);
                    w.typed::<DoubleType>()
                        .write_batch(&values, Some(&levels), None)
                }
                Column::Flag(v) => {
                    let (values, levels) = split(v, |x| *x);
                    w.typed::<BoolType>()
                        .write_batch(&values, Some(&levels), None)
                }
            }
            .map_err(pq)?;
            w.close().map_err(pq)?;
        }
        group.close().map_err(pq)?;
        writer.close().map_err(pq)?;
        std::fs::rename(&tmp, path).map_err(|source| TableError::Io {
            path: path.to_owned(),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parquet::file::reader::{FileReader, SerializedFileReader};

    #[test]
    fn nulls_and_values_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.parquet");
        let mut t = Table::default();
        t.push(
            "name",
            Column::Text(vec![Some("a".into()), None, Some("c".into())]),
        );
        t.push("n", Column::Int(vec![None, Some(2), Some(3)]));
        t.push("x", Column::Real(vec![Some(0.5), Some(1.0e300), None]));
        t.push("ok", Column::Flag(vec![Some(true), None, Some(false)]));
        t.write(&p).unwrap();
        let r = SerializedFileReader::new(std::fs::File::open(&p).unwrap()).unwrap();
        assert_eq!(r.metadata().file_metadata().num_rows(), 3);
        let rows: Vec<String> = r
            .get_row_iter(None)
            .unwrap()
            .map(|row| row.unwrap().to_string())
            .collect();
        assert_eq!(
            rows,
            [
                "{name: \"a\", n: null, x: 0.5, ok: true}",
                "{name: null, n: 2, x: 1E300, ok: null}",
                "{name: \"c\", n: 3, x: null, ok: false}",
            ]
        );
        let mut bad = t.clone();
        bad.push("short", Column::Int(vec![Some(1)]));
        assert!(matches!(bad.write(&p), Err(TableError::Ragged { .. })));
    }
}
