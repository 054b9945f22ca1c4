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
pub mod fleet;
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
    gather_from(paths, None)
}

/// [`gather`], where a file named that does not exist is not an error but listed in the
/// second vector: a campaign's report over the outputs of tasks of which some did not run
/// (a drive that failed its check is not re-simulated, so it has no comparison).
pub fn gather_allowing_absent(
    paths: &[PathBuf],
) -> Result<(Vec<Input>, Vec<PathBuf>), ReportError> {
    let mut absent = Vec::new();
    let inputs = gather_from(paths, Some(&mut absent))?;
    Ok((inputs, absent))
}

fn gather_from(
    paths: &[PathBuf],
    mut absent: Option<&mut Vec<PathBuf>>,
) -> Result<Vec<Input>, ReportError> {
    let named: Vec<&Path> = paths
        .iter()
        .filter(|p| !p.is_dir())
        .map(PathBuf::as_path)
        .collect();
    let named_base = common_dir(&named);
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
            if let Some(i) = read(p, &named_base, true)? {
                out.push(i);
            }
        } else if let Some(a) = absent.as_deref_mut() {
            a.push(p.clone());
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

/// The deepest folder that holds all of `files`: files named one by one are called by their
/// path below it, so that a campaign's `compare/idealized/rep-01.json` and
/// `compare/truth/rep-01.json` keep their model in their names (a single file is called by its
/// file name).
fn common_dir(files: &[&Path]) -> PathBuf {
    let mut dirs = files.iter().map(|f| f.parent().unwrap_or(Path::new("")));
    let Some(first) = dirs.next() else {
        return PathBuf::new();
    };
    let mut base: Vec<_> = first.components().collect();
    for d in dirs {
        let same = base
            .iter()
            .zip(d.components())
            .take_while(|(a, b)| *a == b)
            .count();
        base.truncate(same);
    }
    base.iter().collect()
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
    /// Files named as inputs that did not exist ([`gather_allowing_absent`]).
    absent: &'a [PathBuf],
    /// OCR^K over distance, pooled over all comparisons ([`fleet::bins`]).
    fleet: &'a [fleet::FleetBin],
}

/// Builds the report from the inputs; `absent` are files named as inputs that did not exist,
/// listed on the page and in report.json.
pub fn render(inputs: &[Input], absent: &[PathBuf]) -> Rendered {
    let cmps: Vec<(&str, &crate::metrics::report::Comparison)> = inputs
        .iter()
        .filter_map(|i| match &i.value {
            Document::Compare(c) => Some((i.name.as_str(), c.as_ref())),
            _ => None,
        })
        .collect();
    let fleet = fleet::bins(&cmps);
    let html = html::page(inputs, absent, &fleet);
    let json = serde_json::to_string_pretty(&ReportJson {
        hilrig_version: env!("CARGO_PKG_VERSION"),
        inputs,
        absent,
        fleet: &fleet,
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

#[cfg(test)]
mod tests {
    use super::common_dir;
    use std::path::{Path, PathBuf};

    #[test]
    fn files_named_one_by_one_are_called_by_their_path_below_their_common_folder() {
        let files = [
            Path::new("/out/compare/idealized/rep-01.json"),
            Path::new("/out/compare/truth/rep-01.json"),
            Path::new("/out/check/rep-01.json"),
        ];
        assert_eq!(common_dir(&files), PathBuf::from("/out"));
        assert_eq!(
            common_dir(&files[..2]),
            PathBuf::from("/out/compare"),
            "two models' comparisons keep the model"
        );
        assert_eq!(
            common_dir(&files[..1]),
            PathBuf::from("/out/compare/idealized")
        );
        assert_eq!(common_dir(&[]), PathBuf::new());
        assert_eq!(
            common_dir(&[Path::new("a.json"), Path::new("b/c.json")]),
            PathBuf::new()
        );
    }
}
