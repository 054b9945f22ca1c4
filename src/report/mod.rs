//! `hilrig report`: the validation report a validation engineer attaches to a review, built
//! from the JSON that `info`, `check`, `compare`, `validate` and `gap` write.
//!
//! One self-contained HTML file: the plots are SVG drawn in Rust ([`plots`]), the style is
//! inline, nothing is fetched (a Content-Security-Policy forbids it), and a few lines of inline
//! script only record each figure's rendered size in the page (so a headless browser can show
//! that every figure was laid out). Beside it, `report.json` holds every number the report
//! shows: the inputs themselves, each with its SHA-256, so that the report can be rebuilt and
//! its sources identified.
//!
//! Inputs are read through the types that wrote them ([`crate::output`]): each file says its
//! kind and schema, so a file of another version is refused with its version named, and a field
//! renamed in a producer breaks this module's build rather than leaving a blank in the page.

mod document;
pub mod gap_plots;
mod gap_section;
mod glance;
mod html;
mod markup;
pub mod plots;

pub use document::Document;

use crate::output::{header, OutputError, OutputKind};
use sha2::Digest;
use std::path::{Path, PathBuf};

/// One input file.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Input {
    /// Where it was read.
    pub path: PathBuf,
    /// A short name for the report (the path below the directory given).
    pub name: String,
    /// What it is.
    pub kind: OutputKind,
    /// Its bytes' SHA-256, hex.
    pub sha256: String,
    /// Size, bytes.
    pub bytes: u64,
    /// The content, as written (envelope included).
    pub value: Document,
}

/// Why a report cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file or directory could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A path that does not exist.
    #[error("{path}: no such file or directory")]
    Missing {
        /// The path given.
        path: PathBuf,
    },
    /// An input that is not one of the outputs the report reads, or not of this version.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Nothing to report on.
    #[error("{paths}: no JSON of check, compare, validate, gap or info found")]
    Empty {
        /// The paths given, joined.
        paths: String,
    },
}

/// Reads the inputs: files as given, directories searched (sorted, recursively) for `.json`
/// files of a known kind; a JSON file given by name must be of a known kind.
pub fn gather(paths: &[PathBuf]) -> Result<Vec<Input>, ReportError> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut files = Vec::new();
            walk(p, &mut files).map_err(|source| ReportError::Io {
                path: p.clone(),
                source,
            })?;
            files.sort();
            for f in files {
                if let Some(i) = read(&f, p, false)? {
                    out.push(i);
                }
            }
        } else if p.exists() {
            let base = p.parent().unwrap_or(Path::new(""));
            if let Some(i) = read(p, base, true)? {
                out.push(i);
            }
        } else {
            return Err(ReportError::Missing { path: p.clone() });
        }
    }
    if out.is_empty() {
        return Err(ReportError::Empty {
            paths: paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    Ok(out)
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let p = entry?.path();
        if p.is_dir() {
            walk(&p, out)?;
        } else if p.extension().is_some_and(|e| e == "json")
            && p.file_name().is_some_and(|n| n != "report.json")
        {
            out.push(p);
        }
    }
    Ok(())
}

/// Reads one input. In a directory searched (`named` false), JSON that is not an output of
/// hilrig (no envelope, and not the keys of one from before the envelope: another tool's file)
/// is passed over; a hilrig output of another schema, from before the envelope, or with a
/// broken body is an error wherever it is.
fn read(path: &Path, base: &Path, named: bool) -> Result<Option<Input>, ReportError> {
    let bytes = std::fs::read(path).map_err(|source| ReportError::Io {
        path: path.to_owned(),
        source,
    })?;
    // A campaign's own files (its plan, its stamps) sit beside its results: not inputs.
    if !named && header(path, &bytes).is_ok_and(|(k, _)| !k.is_result()) {
        return Ok(None);
    }
    let value = match Document::from_slice(path, &bytes) {
        Ok(v) => v,
        Err(OutputError::NotJson { .. }) if !named => return Ok(None),
        Err(OutputError::NoEnvelope { .. })
            if !named && !crate::output::is_pre_envelope_output(&bytes) =>
        {
            return Ok(None)
        }
        Err(e) => return Err(e.into()),
    };
    let name = path
        .strip_prefix(base)
        .unwrap_or(path)
        .display()
        .to_string();
    Ok(Some(Input {
        path: path.to_owned(),
        name,
        kind: value.kind(),
        sha256: hex(&sha2::Sha256::digest(&bytes)),
        bytes: bytes.len() as u64,
        value,
    }))
}

/// Lowercase hex of bytes: the SHA-256 digests the report and the campaign's stamps quote.
pub(crate) fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// The report: the page and the JSON of every number on it.
pub struct Rendered {
    /// The HTML page.
    pub html: String,
    /// `report.json`.
    pub json: String,
}

/// `report.json`: the version that built the report and its inputs, each with its content.
#[derive(serde::Serialize)]
struct ReportJson<'a> {
    hilrig_version: &'static str,
    inputs: &'a [Input],
}

/// Builds the report from the inputs.
pub fn render(inputs: &[Input]) -> Rendered {
    let html = html::page(inputs);
    let json = serde_json::to_string_pretty(&ReportJson {
        hilrig_version: env!("CARGO_PKG_VERSION"),
        inputs,
    })
    .unwrap_or_default();
    Rendered { html, json }
}

/// Writes `report.html` (at `out`) and `report.json` beside it, each through a temporary file
/// renamed into place, so that a reader never sees half a report.
pub fn write(out: &Path, r: &Rendered) -> std::io::Result<PathBuf> {
    let json_path = out.with_extension("json");
    let put = |p: &Path, bytes: &[u8]| -> std::io::Result<()> {
        let mut tmp = p.as_os_str().to_owned();
        tmp.push(".tmp");
        std::fs::write(&tmp, bytes)?;
        std::fs::rename(&tmp, p)
    };
    put(out, r.html.as_bytes())?;
    put(&json_path, r.json.as_bytes())?;
    Ok(json_path)
}
