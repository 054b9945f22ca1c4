//! The MCAP writer of the recorder.

use super::msgs::MessageType;
use super::sync::Syncer;
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
    /// Start a new file after this many bytes of messages (None: never).
    pub split_size: Option<u64>,
    /// Start a new file after this much log time, nanoseconds (None: never).
    pub split_duration_ns: Option<i64>,
    /// Force every chunk closed on the one-second timer onto the disk (`fdatasync`), and the
    /// rename of a finished file into its directory: what a live recording on the vehicle
    /// needs, where the power can go at any moment. Without it the kernel may hold half a
    /// minute of the drive in memory; with it a cut loses at most about a second. Recording
    /// from captures leaves it off (the captures are still there).
    pub durable: bool,
}

impl Default for BagOptions {
    fn default() -> Self {
        BagOptions {
            compression: Compression::Zstd,
            level: 1,
            chunk_size: 4 * 1024 * 1024,
            split_size: None,
            split_duration_ns: None,
            durable: false,
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
    /// A message of another type than the topic's (its readers would decode it as the
    /// topic's type): a program error, refused instead of written.
    #[error("{path}: a {ty} message on {topic}, whose messages are {was}")]
    MixedTypes {
        /// The file.
        path: String,
        /// The topic.
        topic: String,
        /// The message's type.
        ty: &'static str,
        /// The topic's type.
        was: &'static str,
    },
}

/// Writes one MCAP file.
struct OneFile {
    writer: mcap::Writer<BufWriter<File>>,
    active: PathBuf,
    target: PathBuf,
    schemas: HashMap<&'static str, u16>,
    /// Per topic: its channel, the last sequence number, its message type.
    channels: HashMap<String, (u16, u32, &'static str)>,
    counts: BTreeMap<String, u64>,
    chunk_started: Option<UtcNanos>,
    /// With [`BagOptions::durable`]: the thread that syncs what the writer has handed the
    /// kernel (through a second handle: the `mcap` writer owns the first).
    sync: Option<Syncer>,
}

const CHUNK_MAX_SPAN_NS: i64 = 1_000_000_000;

/// Syncs the directory of `file`, so that its name (created or renamed) survives a power cut.
/// A file system that cannot sync a directory (EINVAL) has nothing to sync.
fn sync_directory(file: &Path) -> Result<(), BagError> {
    let dir = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    match File::open(dir).and_then(|d| d.sync_all()) {
        Err(e) if e.raw_os_error() != Some(22) => Err(BagError::Io {
            path: dir.display().to_string(),
            source: e,
        }),
        _ => Ok(()),
    }
}

impl OneFile {
    /// Creates `TARGET.active` (e.g. `drive.mcap.active`) for writing; [`BagWriter::finish`]
    /// renames it to `target`.
    fn create(target: &Path, options: &BagOptions) -> Result<OneFile, BagError> {
        let mut active = target.as_os_str().to_owned();
        active.push(".active");
        let active = PathBuf::from(active);
        let file = File::create(&active).map_err(|e| BagError::Create {
            path: active.display().to_string(),
            source: e,
        })?;
        let sync = if options.durable {
            let handle = file.try_clone().map_err(|e| BagError::Create {
                path: active.display().to_string(),
                source: e,
            })?;
            // The new name reaches the disk with its directory.
            sync_directory(&active)?;
            let syncer = Syncer::start(Box::new(move || handle.sync_data()));
            Some(syncer.map_err(|e| BagError::Create {
                path: active.display().to_string(),
                source: e,
            })?)
        } else {
            None
        };
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
        Ok(OneFile {
            writer,
            active,
            target: target.to_owned(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            counts: BTreeMap::new(),
            chunk_started: None,
            sync,
        })
    }

    /// Chunks closed for the disk so far ([`BagOptions::durable`]).
    fn syncs(&self) -> u64 {
        self.sync.as_ref().map_or(0, |s| s.asked)
    }

    fn sync_error(&self, source: std::io::Error) -> BagError {
        BagError::Io {
            path: self.active.display().to_string(),
            source,
        }
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
        if let Some(e) = self.sync.as_ref().and_then(Syncer::failure) {
            return Err(self.sync_error(e));
        }
        // Close the chunk once it spans a second of log time, so a cut-off file loses at most
        // that much.
        // Durable, a second of the clock closes the chunk too: one message stamped in the
        // future must not hold the drive back in memory until log time catches up.
        let wall_due = self
            .sync
            .as_ref()
            .is_some_and(|s| s.last.elapsed().as_nanos() >= CHUNK_MAX_SPAN_NS as u128);
        match self.chunk_started {
            Some(start) if log_time.0 - start.0 >= CHUNK_MAX_SPAN_NS || wall_due => {
                self.writer.flush().map_err(|e| self.err(e))?;
                if let Some(s) = self.sync.as_mut() {
                    s.request();
                }
                self.chunk_started = Some(log_time);
            }
            None => self.chunk_started = Some(log_time),
            _ => {}
        }
        let (channel, seq) = match self.channels.get_mut(topic) {
            Some(c) if c.2 != ty.name => {
                return Err(BagError::MixedTypes {
                    path: self.active.display().to_string(),
                    topic: topic.to_owned(),
                    ty: ty.name,
                    was: c.2,
                })
            }
            Some(c) => {
                c.1 += 1;
                (c.0, c.1)
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
                self.channels.insert(topic.to_owned(), (c, 1, ty.name));
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

    /// Writes the summary and renames `.active` to the target name.
    pub fn finish(mut self) -> Result<BTreeMap<String, u64>, BagError> {
        let durable = self.sync.is_some();
        if let Some(mut s) = self.sync.take() {
            // A sync that failed is the disk's error, reported as such (the sync_all below
            // might pass where the card lost what the failed one held).
            s.finish().map_err(|e| self.sync_error(e))?;
        }
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
        if durable {
            // The rename reaches the disk with its directory.
            sync_directory(&self.target)?;
        }
        Ok(self.counts)
    }
}

/// A static item repeated at the start of every split file.
#[derive(Clone)]
enum Static {
    Metadata(String, BTreeMap<String, String>),
    Attachment(String, String, Vec<u8>, UtcNanos),
    Message(String, MessageType, UtcNanos, Vec<u8>),
}

/// Writes a recording: one MCAP file, or a series when splitting by size or duration. Static
/// data (metadata, attachments, `/tf_static`) is written again at the start of every file, so
/// each file stands on its own in Foxglove, `ros2 bag` and `hilrig check`.
pub struct BagWriter {
    current: Option<OneFile>,
    options: BagOptions,
    target: PathBuf,
    index: u32,
    statics: Vec<Static>,
    file_start: Option<UtcNanos>,
    bytes: u64,
    counts: BTreeMap<String, u64>,
    files: Vec<PathBuf>,
    /// Syncs of the files finished before the current one.
    syncs_before: u64,
}

impl BagWriter {
    /// Starts a recording at `target` (with splitting: `STEM_0000.mcap`, `STEM_0001.mcap`, ...).
    /// Each file is written as `NAME.active` and renamed when it is complete.
    pub fn create(target: &Path, options: &BagOptions) -> Result<BagWriter, BagError> {
        let mut w = BagWriter {
            current: None,
            options: options.clone(),
            target: target.to_owned(),
            index: 0,
            statics: Vec::new(),
            file_start: None,
            bytes: 0,
            counts: BTreeMap::new(),
            files: Vec::new(),
            syncs_before: 0,
        };
        let first = w.file_name(0);
        w.current = Some(OneFile::create(&first, options)?);
        w.files.push(first);
        Ok(w)
    }

    fn splitting(&self) -> bool {
        self.options.split_size.is_some() || self.options.split_duration_ns.is_some()
    }

    fn file_name(&self, index: u32) -> PathBuf {
        if !self.splitting() {
            return self.target.clone();
        }
        let stem = self
            .target
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let ext = self
            .target
            .extension()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "mcap".into());
        self.target
            .with_file_name(format!("{stem}_{index:04}.{ext}"))
    }

    fn file(&mut self) -> &mut OneFile {
        self.current
            .as_mut()
            .expect("a file is open between create and finish")
    }

    fn rotate(&mut self) -> Result<(), BagError> {
        if let Some(done) = self.current.take() {
            self.syncs_before += done.syncs();
            done.finish()?;
        }
        self.index += 1;
        let name = self.file_name(self.index);
        let mut next = OneFile::create(&name, &self.options)?;
        for s in &self.statics {
            match s {
                Static::Metadata(n, m) => next.metadata(n, m.clone())?,
                Static::Attachment(n, t, d, at) => next.attach(n, t, d, *at)?,
                Static::Message(topic, ty, t, cdr) => next.write(topic, ty, *t, *t, cdr)?,
            }
        }
        self.current = Some(next);
        self.files.push(name);
        self.file_start = None;
        self.bytes = 0;
        Ok(())
    }

    /// Writes one CDR message.
    pub fn write(
        &mut self,
        topic: &str,
        ty: &MessageType,
        log_time: UtcNanos,
        publish_time: UtcNanos,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let start = *self.file_start.get_or_insert(log_time);
        let over_size = self.options.split_size.is_some_and(|s| self.bytes >= s);
        let over_time = self
            .options
            .split_duration_ns
            .is_some_and(|d| log_time.0 - start.0 >= d);
        if over_size || over_time {
            self.rotate()?;
            self.file_start = Some(log_time);
        }
        self.bytes += cdr.len() as u64;
        *self.counts.entry(topic.to_owned()).or_insert(0) += 1;
        self.file().write(topic, ty, log_time, publish_time, cdr)
    }

    /// Writes a message that every split file repeats (e.g. `/tf_static`).
    pub fn write_static(
        &mut self,
        topic: &str,
        ty: &MessageType,
        time: UtcNanos,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        self.statics.push(Static::Message(
            topic.to_owned(),
            ty.clone(),
            time,
            cdr.to_vec(),
        ));
        *self.counts.entry(topic.to_owned()).or_insert(0) += 1;
        self.file().write(topic, ty, time, time, cdr)
    }

    /// Adds a metadata record (repeated in every split file written after this call).
    pub fn metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), BagError> {
        self.statics
            .push(Static::Metadata(name.to_owned(), entries.clone()));
        self.file().metadata(name, entries)
    }

    /// Adds an attachment (repeated in every split file written after this call).
    pub fn attach(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
        time: UtcNanos,
    ) -> Result<(), BagError> {
        self.statics.push(Static::Attachment(
            name.to_owned(),
            media_type.to_owned(),
            data.to_vec(),
            time,
        ));
        self.file().attach(name, media_type, data, time)
    }

    /// Messages written per topic, over all files.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// The files of this recording so far.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// Chunks closed for the disk so far ([`BagOptions::durable`]): each is on the disk once
    /// the sync thread's next `fdatasync` has ended.
    pub fn syncs(&self) -> u64 {
        self.syncs_before + self.current.as_ref().map_or(0, OneFile::syncs)
    }

    /// Finishes the last file.
    pub fn finish(mut self) -> Result<BTreeMap<String, u64>, BagError> {
        if let Some(f) = self.current.take() {
            f.finish()?;
        }
        Ok(self.counts)
    }
}

#[cfg(test)]
mod tests {
    use super::{BagOptions, BagWriter};
    use crate::bag::msgs;
    use hilrig_stamp::UtcNanos;

    /// A durable recording forces each chunk closed on the one-second timer onto the disk,
    /// across split files too; a recording from captures does not sync until it finishes.
    #[test]
    fn a_durable_recording_syncs_every_second_of_log_time() {
        let dir = tempfile::tempdir().unwrap();
        let ty = msgs::raw_packet_type();
        for (durable, split, want) in [
            (true, None, 4),
            (true, Some(2_500_000_000), 4),
            (false, None, 0),
        ] {
            let path = dir.path().join(format!("{durable}-{split:?}.mcap"));
            let options = BagOptions {
                durable,
                split_duration_ns: split,
                ..BagOptions::default()
            };
            let mut bag = BagWriter::create(&path, &options).unwrap();
            // 4.5 s of messages, ten a second.
            for i in 0..46i64 {
                let t = UtcNanos(1_700_000_000_000_000_000 + i * 100_000_000);
                bag.write("/x", &ty, t, t, &msgs::raw_packet(t, "x", &[1, 2, 3]))
                    .unwrap();
            }
            assert_eq!(bag.syncs(), want, "durable {durable}, split {split:?}");
            bag.finish().unwrap();
        }
    }

    /// A durable bag whose syncs run `sync` instead of `fdatasync`.
    fn with_sync(path: &std::path::Path, sync: super::super::sync::SyncFn) -> BagWriter {
        let options = BagOptions {
            durable: true,
            ..BagOptions::default()
        };
        let mut bag = BagWriter::create(path, &options).unwrap();
        bag.current.as_mut().unwrap().sync = Some(super::Syncer::start(sync).unwrap());
        bag
    }

    /// Writes `seconds` of messages, ten a second.
    fn write_seconds(bag: &mut BagWriter, seconds: i64) -> Result<(), super::BagError> {
        let ty = msgs::raw_packet_type();
        for i in 0..seconds * 10 {
            let t = UtcNanos(1_700_000_000_000_000_000 + i * 100_000_000);
            bag.write("/x", &ty, t, t, &msgs::raw_packet(t, "x", &[1, 2, 3]))?;
        }
        Ok(())
    }

    /// A disk whose sync hangs does not hold the writer: every message of ten seconds is
    /// written while the first sync has not returned, the syncs asked meanwhile wait as one,
    /// and the file is whole once the disk answers.
    #[test]
    fn a_sync_that_hangs_does_not_hold_the_writer() {
        let dir = tempfile::tempdir().unwrap();
        let (gate, wait) = std::sync::mpsc::channel::<()>();
        let calls = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
        let c = calls.clone();
        let path = dir.path().join("slow.mcap");
        let mut bag = with_sync(
            &path,
            Box::new(move || {
                c.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                wait.recv().map_err(std::io::Error::other)
            }),
        );
        write_seconds(&mut bag, 10).unwrap();
        assert_eq!(bag.syncs(), 9);
        // One sync has begun and not returned (its gate is shut); the rest wait as one.
        while calls.load(std::sync::atomic::Ordering::SeqCst) == 0 {
            std::thread::yield_now();
        }
        assert_eq!(calls.load(std::sync::atomic::Ordering::SeqCst), 1);
        // The disk answers: the sync under way, then the one that waited for it.
        for _ in 0..2 {
            gate.send(()).unwrap();
        }
        let counts = bag.finish().unwrap();
        assert_eq!(counts["/x"], 100);
        // Two when the thread took the first request before the next came, else one.
        let calls = calls.load(std::sync::atomic::Ordering::SeqCst);
        assert!((1..=2).contains(&calls), "{calls} syncs for 9 requests");
        let bytes = std::fs::read(&path).unwrap();
        let n = mcap::MessageStream::new(&bytes).unwrap().count();
        assert_eq!(n, 100);
    }

    /// A sync that fails is the disk's error: a later write reports it with the file's name,
    /// and so does finishing, which does not rename the file as if it were whole.
    #[test]
    fn a_sync_that_fails_is_reported_by_a_later_write_and_by_finish() {
        let dir = tempfile::tempdir().unwrap();
        for finish in [false, true] {
            let path = dir.path().join(format!("failing-{finish}.mcap"));
            // Finishing: the sync fails once the writes are done.
            let (gate, wait) = std::sync::mpsc::channel::<()>();
            if !finish {
                gate.send(()).unwrap();
            }
            let mut bag = with_sync(
                &path,
                Box::new(move || {
                    let _ = wait.recv();
                    Err(std::io::Error::other("the card was removed"))
                }),
            );
            let e = if finish {
                write_seconds(&mut bag, 2).unwrap();
                gate.send(()).unwrap();
                bag.finish().unwrap_err()
            } else {
                // Past the first second a sync is asked for; its failure reaches a write after,
                // and every write after that, and finishing.
                let e = loop {
                    if let Err(e) = write_seconds(&mut bag, 2) {
                        break e;
                    }
                };
                let again = write_seconds(&mut bag, 1).unwrap_err().to_string();
                assert!(again.contains("the card was removed"), "{again}");
                let last = bag.finish().unwrap_err().to_string();
                assert!(last.contains("the card was removed"), "{last}");
                e
            };
            let text = e.to_string();
            assert!(text.contains("the card was removed"), "{text}");
            assert!(text.contains("failing-"), "{text}");
            assert!(!path.exists(), "{text}");
        }
    }
}
