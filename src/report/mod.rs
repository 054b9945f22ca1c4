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
//! Inputs are recognised by content, not by name: a check report has `spatial` and `temporal`,
//! a comparison `scans` and `calibration`, a validation `cells` and `measurement`, a gap study
//! `rounds` and `start_model`, a recording's summary `channels` and `profile`.

pub mod gap_plots;
mod glance;
mod html;
pub mod plots;

use serde_json::Value;
use sha2::Digest;
use std::path::{Path, PathBuf};

/// What a JSON input is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// `hilrig info --json`.
    Recording,
    /// `hilrig check --json`.
    Check,
    /// `hilrig compare --json`.
    Compare,
    /// `hilrig validate --json`.
    Validate,
    /// `hilrig gap` (`gap.json`).
    Gap,
}

/// Recognises an input by its keys.
pub fn classify(v: &Value) -> Option<Kind> {
    let has = |k: &str| v.get(k).is_some();
    if has("spatial") && has("temporal") {
        Some(Kind::Check)
    } else if has("scans") && has("calibration") {
        Some(Kind::Compare)
    } else if has("cells") && has("measurement") {
        Some(Kind::Validate)
    } else if has("rounds") && has("start_model") {
        Some(Kind::Gap)
    } else if has("channels") && has("profile") {
        Some(Kind::Recording)
    } else {
        None
    }
}

/// One input file.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Input {
    /// Where it was read.
    pub path: PathBuf,
    /// A short name for the report (the path below the directory given).
    pub name: String,
    /// What it is.
    pub kind: Kind,
    /// Its bytes' SHA-256, hex.
    pub sha256: String,
    /// Size, bytes.
    pub bytes: u64,
    /// The content.
    pub value: Value,
}

/// Why a report cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// An input could not be read or is not one of the JSON kinds.
    #[error("{path}: {what}")]
    Input {
        /// The file or directory.
        path: String,
        /// What is wrong.
        what: String,
    },
}

/// Reads the inputs: files as given, directories searched (sorted, recursively) for `.json`
/// files of a known kind; a JSON file given by name must be of a known kind.
pub fn gather(paths: &[PathBuf]) -> Result<Vec<Input>, ReportError> {
    let mut out = Vec::new();
    for p in paths {
        let err = |what: String| ReportError::Input {
            path: p.display().to_string(),
            what,
        };
        if p.is_dir() {
            let mut files = Vec::new();
            walk(p, &mut files).map_err(|e| err(e.to_string()))?;
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
            return Err(err("no such file or directory".into()));
        }
    }
    if out.is_empty() {
        return Err(ReportError::Input {
            path: paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            what: "no JSON of check, compare, validate, gap or info found".into(),
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

fn read(path: &Path, base: &Path, named: bool) -> Result<Option<Input>, ReportError> {
    let err = |what: String| ReportError::Input {
        path: path.display().to_string(),
        what,
    };
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    let value: Value = match serde_json::from_slice(&bytes) {
        Ok(v) => v,
        Err(e) if named => return Err(err(format!("not JSON: {e}"))),
        Err(_) => return Ok(None),
    };
    let Some(kind) = classify(&value) else {
        return if named {
            Err(err(
                "not a JSON that check, compare, validate, gap or info writes".into(),
            ))
        } else {
            Ok(None)
        };
    };
    let name = path
        .strip_prefix(base)
        .unwrap_or(path)
        .display()
        .to_string();
    Ok(Some(Input {
        path: path.to_owned(),
        name,
        kind,
        sha256: hex(&sha2::Sha256::digest(&bytes)),
        bytes: bytes.len() as u64,
        value,
    }))
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// The report: the page and the JSON of every number on it.
pub struct Rendered {
    /// The HTML page.
    pub html: String,
    /// `report.json`.
    pub json: Value,
}

/// Builds the report from the inputs.
pub fn render(inputs: &[Input]) -> Rendered {
    let html = html::page(inputs);
    let json = serde_json::json!({
        "hilrig_version": env!("CARGO_PKG_VERSION"),
        "inputs": inputs,
    });
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
    put(
        &json_path,
        serde_json::to_string_pretty(&r.json)
            .unwrap_or_default()
            .as_bytes(),
    )?;
    Ok(json_path)
}
