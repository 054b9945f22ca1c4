//! The JSON files the commands write, as one contract that other programs (and `report`, and the
//! demo) can script against.
//!
//! Every file is an envelope, `{"kind": "check", "schema": 1, ...}`, whose other keys are the
//! fields of one typed struct that implements [`Output`]: [`crate::bag::info::Info`] (`info --json`),
//! [`crate::reference::check::Report`] (`check --json`), [`crate::metrics::report::Comparison`]
//! (`compare --json`), [`crate::stats::repetitions::Validation`] (`validate --json`) and
//! [`crate::gap::report::GapReport`] (`gap.json`). The same struct writes and reads a file, so a
//! field renamed in a producer breaks the build of every reader in this crate instead of
//! leaving `report` to show a blank. The kind says what a file is (before, `report` guessed it
//! from which keys existed); the schema number says which version of the struct wrote it and
//! goes up whenever its fields change (a field renamed, removed, added or changed in meaning),
//! except for a field that is optional and defaults when absent (`#[serde(default)]`).
//!
//! Why serde and not a schema language: the types are the documentation users read (`cargo doc`),
//! and serde writes and reads them in one spelling (snake_case enums) with nothing to keep in
//! step by hand.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// This build of hilrig: its version and the SHA-256 of the source it was built from (the
/// crates' files, manifests, lock file and compiler version; build.rs). The same on every
/// node of a cluster that runs one build, whatever the path or time of its executable: what
/// an output made by a task elsewhere is checked against (campaign stamps, gap trials).
pub const BUILD: &str = concat!(
    "hilrig ",
    env!("CARGO_PKG_VERSION"),
    " source sha256:",
    env!("HILRIG_SOURCE")
);

/// What a JSON file is: the command that wrote it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputKind {
    /// `hilrig info --json`: a recording's channels, counts, metadata.
    Recording,
    /// `hilrig check --json`: the reference data's accuracy and verdict.
    Check,
    /// `hilrig compare --json`: a run against its re-simulation, per scan.
    Compare,
    /// `hilrig validate --json`: repetitions against re-simulations, traffic lights.
    Validate,
    /// `hilrig gap` (`gap.json`): the rounds of the gap workflow.
    Gap,
    /// `hilrig campaign plan --json`: a campaign's task graph.
    CampaignPlan,
    /// A campaign task's stamp: what it read and wrote when it finished.
    CampaignTask,
    /// `hilrig gap trial`: one validation run re-simulated with a round's model and measured,
    /// for the gap workflow that planned it.
    GapTrial,
}

impl OutputKind {
    /// The command that writes it.
    pub fn command(self) -> &'static str {
        match self {
            OutputKind::Recording => "info --json",
            OutputKind::Check => "check",
            OutputKind::Compare => "compare",
            OutputKind::Validate => "validate",
            OutputKind::Gap => "gap",
            OutputKind::CampaignPlan => "campaign plan --json",
            OutputKind::CampaignTask => "campaign",
            OutputKind::GapTrial => "gap",
        }
    }

    /// Whether `report` reads it (the campaign's own files are not results).
    pub fn is_result(self) -> bool {
        !matches!(
            self,
            OutputKind::CampaignPlan | OutputKind::CampaignTask | OutputKind::GapTrial
        )
    }

    /// The spelling in the envelope.
    pub fn name(self) -> &'static str {
        match self {
            OutputKind::Recording => "recording",
            OutputKind::Check => "check",
            OutputKind::Compare => "compare",
            OutputKind::Validate => "validate",
            OutputKind::Gap => "gap",
            OutputKind::CampaignPlan => "campaign_plan",
            OutputKind::CampaignTask => "campaign_task",
            OutputKind::GapTrial => "gap_trial",
        }
    }
}

/// A struct that is written as one kind of JSON file.
pub trait Output: Serialize + DeserializeOwned {
    /// Its kind.
    const KIND: OutputKind;
    /// The version of its fields that this build writes and reads.
    const SCHEMA: u32;
}

/// Why a JSON file could not be written or read as the kind expected.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Not JSON, or not an object.
    #[error("{path}: not a JSON object: {source}")]
    NotJson {
        /// The file.
        path: PathBuf,
        /// The parser's complaint.
        #[source]
        source: serde_json::Error,
    },
    /// No `kind` and `schema`: not written by hilrig, or by a version before the envelope.
    #[error(
        "{path}: no \"kind\" and \"schema\" keys: not a file that hilrig's check, compare, \
         validate, gap or info writes (or one written before hilrig 0.2; run the command again)"
    )]
    NoEnvelope {
        /// The file.
        path: PathBuf,
    },
    /// A kind this build does not know.
    #[error("{path}: kind \"{kind}\" is not one of recording, check, compare, validate, gap, campaign_plan, campaign_task, gap_trial")]
    UnknownKind {
        /// The file.
        path: PathBuf,
        /// The kind it says.
        kind: String,
    },
    /// Another kind than the one asked for.
    #[error("{path}: is a {found} file, not a {wanted} file")]
    WrongKind {
        /// The file.
        path: PathBuf,
        /// What it is.
        found: &'static str,
        /// What was asked for.
        wanted: &'static str,
    },
    /// A schema version this build cannot read.
    #[error(
        "{path}: {kind} schema {found}, but this hilrig reads schema {supported}: \
         run `hilrig {command}` of this version again"
    )]
    Schema {
        /// The file.
        path: PathBuf,
        /// Its kind.
        kind: &'static str,
        /// The command that writes it.
        command: &'static str,
        /// The version it says.
        found: u64,
        /// The version this build reads.
        supported: u32,
    },
    /// The envelope is right but a field is missing or of the wrong type.
    #[error("{path}: not a valid {kind} file (schema {schema}): {source}")]
    Body {
        /// The file.
        path: PathBuf,
        /// Its kind.
        kind: &'static str,
        /// Its schema.
        schema: u32,
        /// Which field and why.
        #[source]
        source: serde_json::Error,
    },
}

/// The envelope as written: the kind and schema first, then the struct's fields.
#[derive(Serialize)]
pub struct Envelope<'a, T> {
    kind: OutputKind,
    schema: u32,
    #[serde(flatten)]
    body: &'a T,
}

impl<'a, T: Output> Envelope<'a, T> {
    /// An output in its envelope.
    pub fn of(body: &'a T) -> Self {
        Envelope {
            kind: T::KIND,
            schema: T::SCHEMA,
            body,
        }
    }
}

/// The envelope as read: only its two keys, the body is read after they are checked (so that a
/// file of another version gets the message about its version, not about a field).
#[derive(Deserialize)]
struct Header {
    kind: Option<String>,
    schema: Option<u64>,
}

/// The JSON text of an output (pretty, as the commands write it).
pub fn to_json<T: Output>(value: &T) -> serde_json::Result<String> {
    serde_json::to_string_pretty(&Envelope::of(value))
}

/// Writes an output through a temporary file renamed into place, so that a reader never sees
/// half a file.
pub fn write<T: Output>(path: &Path, value: &T) -> Result<(), OutputError> {
    let io = |source| OutputError::Io {
        path: path.to_owned(),
        source,
    };
    let text = to_json(value).map_err(|e| io(std::io::Error::other(e)))?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, text).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

/// What a file says it is: its kind and schema version, read before anything else so that a
/// file of another version gets the message about its version, not about a field.
pub fn header(path: &Path, bytes: &[u8]) -> Result<(OutputKind, u64), OutputError> {
    let header: Header = serde_json::from_slice(bytes).map_err(|source| OutputError::NotJson {
        path: path.to_owned(),
        source,
    })?;
    let (Some(kind), Some(schema)) = (header.kind, header.schema) else {
        return Err(OutputError::NoEnvelope {
            path: path.to_owned(),
        });
    };
    let found = serde_json::from_value::<OutputKind>(serde_json::Value::String(kind.clone()))
        .map_err(|_| OutputError::UnknownKind {
            path: path.to_owned(),
            kind,
        })?;
    Ok((found, schema))
}

/// Whether JSON without the envelope is an output of a hilrig from before it: it has the keys
/// by which `report` used to recognise each kind (so that a folder of such files is refused with
/// the reason, not passed over as another tool's JSON).
pub fn is_pre_envelope_output(bytes: &[u8]) -> bool {
    use serde::de::IgnoredAny;
    #[derive(Deserialize)]
    struct Keys {
        spatial: Option<IgnoredAny>,
        temporal: Option<IgnoredAny>,
        scans: Option<IgnoredAny>,
        calibration: Option<IgnoredAny>,
        cells: Option<IgnoredAny>,
        measurement: Option<IgnoredAny>,
        rounds: Option<IgnoredAny>,
        start_model: Option<IgnoredAny>,
        channels: Option<IgnoredAny>,
        profile: Option<IgnoredAny>,
    }
    serde_json::from_slice::<Keys>(bytes).is_ok_and(|k| {
        (k.spatial.is_some() && k.temporal.is_some())
            || (k.scans.is_some() && k.calibration.is_some())
            || (k.cells.is_some() && k.measurement.is_some())
            || (k.rounds.is_some() && k.start_model.is_some())
            || (k.channels.is_some() && k.profile.is_some())
    })
}

/// Reads an output of kind `T` from its bytes (`path` only names it in errors).
pub fn from_slice<T: Output>(path: &Path, bytes: &[u8]) -> Result<T, OutputError> {
    let (found, schema) = header(path, bytes)?;
    if found != T::KIND {
        return Err(OutputError::WrongKind {
            path: path.to_owned(),
            found: found.name(),
            wanted: T::KIND.name(),
        });
    }
    if schema != u64::from(T::SCHEMA) {
        return Err(OutputError::Schema {
            path: path.to_owned(),
            kind: T::KIND.name(),
            command: T::KIND.command(),
            found: schema,
            supported: T::SCHEMA,
        });
    }
    // The envelope's keys are not fields of `T`: serde passes over keys a struct lacks.
    serde_json::from_slice(bytes).map_err(|source| OutputError::Body {
        path: path.to_owned(),
        kind: T::KIND.name(),
        schema: T::SCHEMA,
        source,
    })
}

/// Reads an output of kind `T` from a file.
pub fn read<T: Output>(path: &Path) -> Result<T, OutputError> {
    let bytes = std::fs::read(path).map_err(|source| OutputError::Io {
        path: path.to_owned(),
        source,
    })?;
    from_slice(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file of another schema names the command that writes its kind (`info --json` for a
    /// recording's summary, which has no command of the kind's name); JSON with the keys of an
    /// output from before the envelope is told from another tool's JSON.
    #[test]
    fn another_version_is_named_with_the_command_to_run_again() {
        let path = Path::new("rec.info.json");
        let e = from_slice::<crate::bag::info::Info>(
            path,
            br#"{"kind": "recording", "schema": 7, "file": "x"}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("rec.info.json")
                && e.contains("recording schema 7")
                && e.contains("`hilrig info --json`"),
            "{e}"
        );
        let e = from_slice::<crate::bag::info::Info>(path, br#"{"kind": "check", "schema": 1}"#)
            .unwrap_err();
        assert!(
            matches!(e, OutputError::WrongKind { found: "check", .. }),
            "{e}"
        );
        assert!(is_pre_envelope_output(
            br#"{"verdict": "pass", "spatial": {}, "temporal": {}}"#
        ));
        assert!(is_pre_envelope_output(
            br#"{"rounds": [], "start_model": "m.toml"}"#
        ));
        assert!(!is_pre_envelope_output(br#"{"spatial": {}}"#));
        assert!(!is_pre_envelope_output(br#"[1, 2]"#));
    }
}
