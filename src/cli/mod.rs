//! One module per command: clap arguments, validation into typed settings, one call into the
//! library, and printing. No engine lives here: decoding is in `hilrig::decode`, recording in
//! `hilrig::record`, replay's pacing, sinks and `--now` in `hilrig::replay`, the check in
//! `hilrig::reference`, synthesis and re-simulation in `hilrig::sim`, the metrics in `hilrig::metrics`.

pub mod campaign;
pub mod check;
pub mod compare;
pub mod coverage;
pub mod decode;
pub mod demo;
pub mod efast;
pub mod gap;
pub mod info;
pub mod record;
pub mod recover;
pub mod replay;
pub mod report;
pub mod resim;
pub mod synth;
pub mod table;
pub mod validate;

use anyhow::{Context, Result};
use std::fs::File;
use std::io::{self, Write};

/// The output file, or standard output.
pub fn open_output(path: Option<&std::path::Path>) -> Result<Box<dyn Write>> {
    Ok(match path {
        Some(p) => {
            Box::new(File::create(p).with_context(|| format!("cannot create {}", p.display()))?)
        }
        None => Box::new(io::stdout().lock()),
    })
}

/// The error and its causes, each said once: library errors already quote their cause in
/// their message, so a cause whose text is already there is not repeated.
pub fn describe(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}
