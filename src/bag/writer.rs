//! The MCAP writer of the recorder.

use super::msgs::MessageType;
use hilrig_stamp::UtcNanos;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Chunk compression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// zstd (level 1 by default: fast enough for live recording).
    Zstd,
    /// LZ4.
    Lz4,
    /// No compression.
    None,
}

/// How to write.
#[derive(Clone, Debug)]
pub struct BagOptions {
    /// Chunk compression.
    pub compression: Compression,
    /// Compression level (zstd).
    pub level: u32,
    /// Chunk size in bytes (a chunk is also closed after one second of log time).
    pub chunk_size: u64,
}

impl Default for BagOptions {
    fn default() -> Self {
        BagOptions {
            compression: Compression::Zstd,
            level: 1,
            chunk_size: 4 * 1024 * 1024,
        }
    }
}

/// Why writing failed. Everything written before the error stays readable in the `.active` file
/// (complete chunks; `hilrig recover` finishes it).
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The output file cannot be created (missing folder, no permission, read-only disk).
    #[error("cannot create {path}: {source}")]
    Create {
        /// The file.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// Flushing or renaming the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// The mcap writer failed (typically: the disk is full).
    #[error("{path}: writing MCAP failed: {source}")]
    Mcap {
        /// The file.
        path: String,
        /// Cause.
        #[source]
        source: mcap::McapError,
    },
}

/// Writes one MCAP file.
pub struct BagWriter {
    writer: mcap::Writer<BufWriter<File>>,
    active: PathBuf,
    target: PathBuf,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, (u16, u32)>,
    counts: BTreeMap<String, u64>,
    chunk_started: Option<UtcNanos>,
}

const CHUNK_MAX_SPAN_NS: i64 = 1_000_000_000;

impl BagWriter {
    /// Creates `TARGET.active` (e.g. `drive.mcap.active`) for writing; [`BagWriter::finish`]
    /// renames it to `target`.
    pub fn create(target: &Path, options: &BagOptions) -> Result<BagWriter, BagError> {
        let mut active = target.as_os_str().to_owned();
        active.push(".active");
        let active = PathBuf::from(active);
        let file = File::create(&active).map_err(|e| BagError::Create {
            path: active.display().to_string(),
            source: e,
        })?;
        let compression = match options.compression {
            Compression::Zstd => Some(mcap::Compression::Zstd),
            Compression::Lz4 => Some(mcap::Compression::Lz4),
            Compression::None => None,
        };
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("hilrig ", env!("CARGO_PKG_VERSION")))
            .compression(compression)
            .compression_level(options.level)
            .chunk_size(Some(options.chunk_size))
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| BagError::Mcap {
                path: active.display().to_string(),
                source: e,
            })?;
        Ok(BagWriter {
            writer,
            active,
            target: target.to_owned(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            counts: BTreeMap::new(),
            chunk_started: None,
        })
    }

    fn err(&self, e: mcap::McapError) -> BagError {
        BagError::Mcap {
            path: self.active.display().to_string(),
            source: e,
        }
    }

    /// Writes one CDR message on a topic (the channel is created on first use).
    pub fn write(
        &mut self,
        topic: &str,
        ty: &MessageType,
        log_time: UtcNanos,
        publish_time: UtcNanos,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        // Close the chunk once it spans a second of log time, so a cut-off file loses at most
        // that much.
        match self.chunk_started {
            Some(start) if log_time.0 - start.0 >= CHUNK_MAX_SPAN_NS => {
                self.writer.flush().map_err(|e| self.err(e))?;
                self.chunk_started = Some(log_time);
            }
            None => self.chunk_started = Some(log_time),
            _ => {}
        }
        let (channel, seq) = match self.channels.get_mut(topic) {
            Some(c) => {
                c.1 += 1;
                *c
            }
            None => {
                let schema = match self.schemas.get(ty.name) {
                    Some(&s) => s,
                    None => {
                        let s = self
                            .writer
                            .add_schema(ty.name, "ros2msg", ty.schema.as_bytes())
                            .map_err(|e| self.err(e))?;
                        self.schemas.insert(ty.name, s);
                        s
                    }
                };
                let c = self
                    .writer
                    .add_channel(schema, topic, "cdr", &BTreeMap::new())
                    .map_err(|e| self.err(e))?;
                self.channels.insert(topic.to_owned(), (c, 1));
                (c, 1)
            }
        };
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: seq,
            log_time: log_time.0.max(0) as u64,
            publish_time: publish_time.0.max(0) as u64,
        };
        self.writer
            .write_to_known_channel(&header, cdr)
            .map_err(|e| self.err(e))?;
        *self.counts.entry(topic.to_owned()).or_insert(0) += 1;
        Ok(())
    }

    /// Adds a metadata record.
    pub fn metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), BagError> {
        let m = mcap::records::Metadata {
            name: name.to_owned(),
            metadata: entries,
        };
        self.writer.write_metadata(&m).map_err(|e| self.err(e))
    }

    /// Adds an attachment (rig file, DBC, calibration).
    pub fn attach(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
        time: UtcNanos,
    ) -> Result<(), BagError> {
        let a = mcap::Attachment {
            log_time: time.0.max(0) as u64,
            create_time: time.0.max(0) as u64,
            name: name.to_owned(),
            media_type: media_type.to_owned(),
            data: std::borrow::Cow::Borrowed(data),
        };
        self.writer.attach(&a).map_err(|e| self.err(e))
    }

    /// Messages written per topic.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// Writes the summary and renames `.active` to the target name.
    pub fn finish(mut self) -> Result<BTreeMap<String, u64>, BagError> {
        self.writer.finish().map_err(|e| self.err(e))?;
        let mut inner = self.writer.into_inner();
        use std::io::Write;
        inner.flush().map_err(|e| BagError::Io {
            path: self.active.display().to_string(),
            source: e,
        })?;
        inner.get_ref().sync_all().map_err(|e| BagError::Io {
            path: self.active.display().to_string(),
            source: e,
        })?;
        std::fs::rename(&self.active, &self.target).map_err(|e| BagError::Io {
            path: self.target.display().to_string(),
            source: e,
        })?;
        Ok(self.counts)
    }
}
