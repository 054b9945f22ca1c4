//! Salvaging a recording that was cut off (power loss, `kill -9`, a full disk).
//!
//! A cut-off MCAP has no summary and ends inside a chunk. Its records are read in file order
//! with mcap's linear reader (chunks decompressed) until the first error, which is where the
//! file was cut: everything before is complete and CRC-checked, and is written to a new, valid
//! MCAP (schemas, channels, messages, metadata, attachments). Reading stops at the first error
//! rather than skipping ahead, because mcap 0.26 repeats the same error forever after a bad
//! chunk, and because data after a cut are not trustworthy anyway.

use super::writer::{BagError, BagOptions};
use mcap::records::Record;
use std::collections::BTreeMap;
use std::path::Path;

/// What recovery kept.
#[derive(Clone, Debug, Default)]
pub struct Recovered {
    /// Messages kept.
    pub messages: u64,
    /// Messages per topic.
    pub counts: BTreeMap<String, u64>,
    /// Log time of the last message kept (ns), if any.
    pub last_log_time: Option<u64>,
    /// Why reading stopped (None: the file was complete).
    pub stopped_by: Option<String>,
}

/// Why recovery failed.
#[derive(Debug, thiserror::Error)]
pub enum RecoverError {
    /// The input could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// Not an MCAP (no magic).
    #[error("{path} is not an MCAP file: {what}")]
    NotMcap {
        /// Path.
        path: String,
        /// Details.
        what: String,
    },
    /// Writing the recovered file failed.
    #[error(transparent)]
    Write(#[from] BagError),
}

/// Copies every complete record of `input` into a new MCAP at `output`.
pub fn recover(
    input: &Path,
    output: &Path,
    options: &BagOptions,
) -> Result<Recovered, RecoverError> {
    let io = |e| RecoverError::Io {
        path: input.display().to_string(),
        source: e,
    };
    let file = std::fs::File::open(input).map_err(io)?;
    // Safety of the map: the file is not written while we read it (a recorder that was cut off
    // is gone; the caller must not recover a file that is still being recorded).
    let map = unsafe { memmap2::Mmap::map(&file) }.map_err(io)?;
    if map.len() < 8 || &map[..8] != mcap::MAGIC {
        return Err(RecoverError::NotMcap {
            path: input.display().to_string(),
            what: "no MCAP magic at the start".into(),
        });
    }
    let reader = mcap::read::ChunkFlattener::new_with_options(
        &map,
        mcap::read::Options::IgnoreEndMagic.into(),
    )
    .map_err(|e| RecoverError::NotMcap {
        path: input.display().to_string(),
        what: e.to_string(),
    })?;
    let out_err = |e: mcap::McapError| {
        RecoverError::Write(BagError::Mcap {
            path: output.display().to_string(),
            source: e,
        })
    };
    let file = std::fs::File::create(output).map_err(|e| {
        RecoverError::Write(BagError::Io {
            path: output.display().to_string(),
            source: e,
        })
    })?;
    let compression = match options.compression {
        super::Compression::Zstd => Some(mcap::Compression::Zstd),
        super::Compression::Lz4 => Some(mcap::Compression::Lz4),
        super::Compression::None => None,
    };
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .library(concat!("hilrig recover ", env!("CARGO_PKG_VERSION")))
        .compression(compression)
        .chunk_size(Some(options.chunk_size))
        .create(std::io::BufWriter::new(file))
        .map_err(out_err)?;
    let mut schemas: BTreeMap<u16, u16> = BTreeMap::new();
    let mut channels: BTreeMap<u16, (u16, String)> = BTreeMap::new();
    let mut result = Recovered::default();
    for record in reader {
        let record = match record {
            Ok(r) => r,
            Err(e) => {
                result.stopped_by = Some(e.to_string());
                break;
            }
        };
        match record {
            Record::Schema { header, data } => {
                let id = w
                    .add_schema(&header.name, &header.encoding, &data)
                    .map_err(out_err)?;
                schemas.insert(header.id, id);
            }
            Record::Channel(c) => {
                let schema = if c.schema_id == 0 {
                    0
                } else {
                    schemas.get(&c.schema_id).copied().unwrap_or(0)
                };
                let id = w
                    .add_channel(schema, &c.topic, &c.message_encoding, &c.metadata)
                    .map_err(out_err)?;
                channels.insert(c.id, (id, c.topic.clone()));
            }
            Record::Message { header, data } => {
                let Some((id, topic)) = channels.get(&header.channel_id) else {
                    continue;
                };
                let h = mcap::records::MessageHeader {
                    channel_id: *id,
                    ..header
                };
                w.write_to_known_channel(&h, &data).map_err(out_err)?;
                result.messages += 1;
                *result.counts.entry(topic.clone()).or_insert(0) += 1;
                result.last_log_time = Some(
                    result
                        .last_log_time
                        .map_or(header.log_time, |t| t.max(header.log_time)),
                );
            }
            Record::Metadata(m) => w.write_metadata(&m).map_err(out_err)?,
            Record::Attachment { header, data, .. } => {
                let a = mcap::Attachment {
                    log_time: header.log_time,
                    create_time: header.create_time,
                    name: header.name,
                    media_type: header.media_type,
                    data,
                };
                w.attach(&a).map_err(out_err)?;
            }
            Record::DataEnd(_) => break,
            _ => {}
        }
    }
    w.finish().map_err(out_err)?;
    Ok(result)
}
