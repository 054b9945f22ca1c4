//! `hilrig info`: what an MCAP holds, from its summary section (channels, types, counts, rates,
//! time span) and metadata (rig, clock synchronisation), without reading the messages.

use std::collections::BTreeMap;
use std::path::Path;

/// One channel's summary.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChannelInfo {
    /// Topic.
    pub topic: String,
    /// Message type (schema name).
    pub message_type: String,
    /// Message encoding.
    pub encoding: String,
    /// Messages.
    pub count: u64,
}

/// The first and last message's log time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct LogSpan {
    /// The first, ns since the Unix epoch.
    pub first_ns: u64,
    /// The last, ns since the Unix epoch.
    pub last_ns: u64,
}

/// One attachment.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AttachmentInfo {
    /// Name.
    pub name: String,
    /// Media type.
    pub media_type: String,
    /// Size, bytes.
    pub bytes: u64,
}

/// A file's summary (and the JSON of `info --json`).
#[derive(Clone, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Info {
    /// The file, as given.
    pub file: String,
    /// MCAP profile.
    pub profile: String,
    /// Channels by topic.
    pub channels: Vec<ChannelInfo>,
    /// First and last message log time (none without messages).
    pub span: Option<LogSpan>,
    /// Chunks.
    pub chunks: usize,
    /// Metadata records by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Attachments.
    pub attachments: Vec<AttachmentInfo>,
}

impl crate::output::Output for Info {
    const KIND: crate::output::OutputKind = crate::output::OutputKind::Recording;
    const SCHEMA: u32 = 1;
}

/// Why a file could not be summarised.
#[derive(Debug, thiserror::Error)]
pub enum InfoError {
    /// Reading failed.
    #[error("cannot read {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// No summary section: the file was cut off.
    #[error(
        "{path} has no summary section (the recording was cut off): run `hilrig recover {path}`"
    )]
    NoSummary {
        /// Path.
        path: String,
    },
    /// Not a valid MCAP.
    #[error("{path}: {what}")]
    Invalid {
        /// Path.
        path: String,
        /// Details.
        what: String,
    },
}

/// Reads a file's summary.
pub fn info(path: &Path) -> Result<Info, InfoError> {
    let p = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|e| InfoError::Io {
        path: p.clone(),
        source: e,
    })?;
    // Safety of the map: read-only, and the file is a finished recording (an `.active` file is
    // refused below for having no summary).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| InfoError::Io {
        path: p.clone(),
        source: e,
    })?;
    let header_profile = mcap::read::LinearReader::new_with_options(
        &map,
        mcap::read::Options::IgnoreEndMagic.into(),
    )
    .ok()
    .and_then(|mut r| r.next())
    .and_then(|r| r.ok())
    .and_then(|r| match r {
        mcap::records::Record::Header(h) => Some(h.profile),
        _ => None,
    })
    .unwrap_or_default();
    if map.len() < 8 || &map[..8] != mcap::MAGIC {
        return Err(InfoError::Invalid {
            path: p,
            what: "not an MCAP file (no magic at the start)".into(),
        });
    }
    // A good start and no readable summary: the recording did not finish.
    let summary = mcap::Summary::read(&map)
        .ok()
        .flatten()
        .ok_or_else(|| InfoError::NoSummary { path: p.clone() })?;
    let mut info = Info {
        file: p.clone(),
        profile: header_profile,
        chunks: summary.chunk_indexes.len(),
        ..Info::default()
    };
    let counts = summary
        .stats
        .as_ref()
        .map(|s| s.channel_message_counts.clone())
        .unwrap_or_default();
    if let Some(s) = &summary.stats {
        if s.message_count > 0 {
            info.span = Some(LogSpan {
                first_ns: s.message_start_time,
                last_ns: s.message_end_time,
            });
        }
    }
    let mut channels: Vec<ChannelInfo> = summary
        .channels
        .values()
        .map(|c| ChannelInfo {
            topic: c.topic.clone(),
            message_type: c
                .schema
                .as_ref()
                .map(|s| s.name.clone())
                .unwrap_or_default(),
            encoding: c.message_encoding.clone(),
            count: counts.get(&c.id).copied().unwrap_or(0),
        })
        .collect();
    channels.sort_by(|a, b| a.topic.cmp(&b.topic));
    info.channels = channels;
    for idx in &summary.metadata_indexes {
        if let Ok(m) = mcap::read::metadata(&map, idx) {
            info.metadata.insert(m.name, m.metadata);
        }
    }
    for a in &summary.attachment_indexes {
        info.attachments.push(AttachmentInfo {
            name: a.name.clone(),
            media_type: a.media_type.clone(),
            bytes: a.data_size,
        });
    }
    Ok(info)
}
