//! Any of the outputs `report` reads, by the kind its file says.

use crate::output::{from_slice, header, Envelope, Output, OutputError, OutputKind};
use serde::Serialize;
use std::path::Path;

/// Any output, by its kind: what `report` reads. It serializes as the file it was read from
/// (envelope included).
#[derive(Clone, Debug)]
pub enum Document {
    /// `info --json`.
    Recording(Box<crate::bag::info::Info>),
    /// `check --json`.
    Check(Box<crate::reference::check::Report>),
    /// `compare --json`.
    Compare(Box<crate::metrics::report::Comparison>),
    /// `validate --json`.
    Validate(Box<crate::stats::repetitions::Validation>),
    /// `gap.json`.
    Gap(Box<crate::gap::report::GapReport>),
}

impl Document {
    /// Reads a file of any kind from its bytes (`path` only names it in errors).
    pub fn from_slice(path: &Path, bytes: &[u8]) -> Result<Document, OutputError> {
        Ok(match header(path, bytes)?.0 {
            OutputKind::Recording => Document::Recording(Box::new(from_slice(path, bytes)?)),
            OutputKind::Check => Document::Check(Box::new(from_slice(path, bytes)?)),
            OutputKind::Compare => Document::Compare(Box::new(from_slice(path, bytes)?)),
            OutputKind::Validate => Document::Validate(Box::new(from_slice(path, bytes)?)),
            OutputKind::Gap => Document::Gap(Box::new(from_slice(path, bytes)?)),
            found
            @ (OutputKind::CampaignPlan | OutputKind::CampaignTask | OutputKind::GapTrial) => {
                return Err(OutputError::WrongKind {
                    path: path.to_owned(),
                    found: found.name(),
                    wanted: "check, compare, validate, gap or recording",
                })
            }
        })
    }

    /// Its kind.
    pub fn kind(&self) -> OutputKind {
        match self {
            Document::Recording(_) => OutputKind::Recording,
            Document::Check(_) => OutputKind::Check,
            Document::Compare(_) => OutputKind::Compare,
            Document::Validate(_) => OutputKind::Validate,
            Document::Gap(_) => OutputKind::Gap,
        }
    }
}

impl Serialize for Document {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        fn env<T: Output, S: serde::Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
            Envelope::of(v).serialize(s)
        }
        match self {
            Document::Recording(v) => env(v.as_ref(), s),
            Document::Check(v) => env(v.as_ref(), s),
            Document::Compare(v) => env(v.as_ref(), s),
            Document::Validate(v) => env(v.as_ref(), s),
            Document::Gap(v) => env(v.as_ref(), s),
        }
    }
}
