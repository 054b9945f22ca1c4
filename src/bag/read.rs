//! Reading an MCAP robustly: every size a damaged file claims (a chunk's, a record's inside it)
//! is checked against the bytes really there before anything is allocated for it, so a cut-off
//! or bit-flipped recording gives what it holds before the damage and a clear error, never a
//! panic or an abort. Replay and `check` read recordings through this.

use std::collections::BTreeMap;

/// One message with its channel.
pub struct Message<'a> {
    /// The channel (topic, schema).
    pub channel: &'a mcap::Channel<'a>,
    /// Log time (synchronised UTC), ns.
    pub log_time: u64,
    /// Publish time (host receive time), ns.
    pub publish_time: u64,
    /// The serialised message.
    pub data: &'a [u8],
}

/// What the reader hands over.
pub enum Event<'a> {
    /// A message.
    Message(Message<'a>),
    /// A metadata record.
    Metadata {
        /// Its name.
        name: &'a str,
        /// Its key-value pairs.
        values: &'a BTreeMap<String, String>,
    },
    /// An attachment (rig file, DBC, calibration).
    Attachment {
        /// Its name.
        name: &'a str,
        /// Its bytes.
        data: &'a [u8],
    },
}

/// An attachment record's name and data, parsed with every length checked (the `mcap` crate
/// 0.26 slices past the end of an attachment shorter than its CRC).
fn attachment(body: &[u8]) -> Option<(&str, &[u8])> {
    let mut pos = 16usize; // log time, create time
    let mut take = |n: usize| -> Option<&[u8]> {
        let v = body.get(pos..pos.checked_add(n)?)?;
        pos += n;
        Some(v)
    };
    let len = |b: &[u8]| b.iter().rev().fold(0u64, |a, &x| (a << 8) | u64::from(x));
    let n = len(take(4)?) as usize;
    let name = std::str::from_utf8(take(n)?).ok()?;
    let n = len(take(4)?) as usize;
    take(n)?;
    let n = usize::try_from(len(take(8)?)).ok()?;
    let data = take(n)?;
    Some((name, data))
}

/// Why reading stopped before the end of the data section (everything before was handed over).
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be read.
    #[error("reading: {0}")]
    Io(#[source] std::io::Error),
    /// A record the mcap crate's parser refused.
    #[error("{0}")]
    Mcap(#[from] mcap::McapError),
    /// A schema, channel or metadata record whose length fields run past its end.
    #[error("a {record} record of {bytes} bytes whose fields claim more bytes than it has")]
    FieldsOverrun {
        /// `schema`, `channel` or `metadata`.
        record: &'static str,
        /// Its body's length.
        bytes: usize,
    },
    /// A chunk whose compression name runs past its end.
    #[error(
        "a chunk record of {bytes} bytes whose compression name claims more bytes than it has"
    )]
    ChunkNameOverrun {
        /// Its body's length.
        bytes: usize,
    },
    /// A chunk that claims to expand beyond any plausible compression ratio.
    #[error("a chunk of {bytes} bytes claims {claimed} bytes uncompressed")]
    ChunkExpansion {
        /// Its compressed length.
        bytes: usize,
        /// The uncompressed length it claims.
        claimed: u64,
    },
    /// A chunk whose records do not decompress.
    #[error("{compression}: {source}")]
    Decompress {
        /// `zstd` or `lz4`.
        compression: &'static str,
        /// The decompressor's complaint.
        #[source]
        source: std::io::Error,
    },
    /// A compression this reader does not know.
    #[error("a chunk compressed with unknown {0:?}")]
    UnknownCompression(String),
    /// A chunk that holds another size than it claims.
    #[error("a chunk claims {claimed} bytes uncompressed but holds {held}")]
    ChunkSize {
        /// The size it claims.
        claimed: usize,
        /// The size it holds.
        held: usize,
    },
    /// A message on a channel no record defined.
    #[error("a message on channel {0} that was never defined")]
    UndefinedChannel(u16),
    /// A message of one of the contract's topics that does not decode as its type.
    #[error("{topic}: a message does not decode as its type")]
    Undecodable {
        /// Its topic.
        topic: String,
    },
    /// The visitor stopped the reading (its consumer went away): not damage.
    #[error("the reading was stopped")]
    Stopped,
    /// Every record was read, but the summary or footer is cut off.
    #[error("the file ends without MCAP's closing magic: its summary or footer is cut off (every message was read; `hilrig recover` rewrites the file whole)")]
    NoClosingMagic,
    /// Where a record was at fault: the byte of the file it starts at.
    #[error("{source} (in the record at byte {at})")]
    At {
        /// The record's first byte in the file.
        at: usize,
        /// What is wrong with it.
        #[source]
        source: Box<ReadError>,
    },
}

/// The callback of [`read`].
pub type Visitor<'a> = dyn FnMut(Event<'_>) -> Result<(), ReadError> + 'a;

/// Walks the data section of an MCAP held in memory and hands every message, metadata record
/// and attachment to `each`, in file order. `Err` says what stopped the reading (damage, or an
/// error `each` returned) and, where a record was at fault, at which byte of the file that
/// record starts; everything before it has been handed over.
pub fn read(bytes: &[u8], each: &mut Visitor<'_>) -> Result<(), ReadError> {
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_skip_end_magic(true)
        .with_emit_chunks(true)
        .with_record_length_limit(bytes.len());
    let mut channels = mcap::read::ChannelAccumulator::<'static>::default();
    // Records follow the magic back to back: opcode (1 byte), length (8), body.
    let mut at = mcap::MAGIC.len();
    records(bytes, options, &mut |op, body| {
        let here = at;
        at += 9 + body.len();
        data_record(op, body, &mut channels, each).map_err(|e| match e {
            ReadError::Stopped => e,
            e => ReadError::At {
                at: here,
                source: Box::new(e),
            },
        })
    })?;
    // Every record of the data section was read; a file cut after it (in its summary or
    // footer) still lost its index, and a reader that trusts the index finds nothing.
    if !bytes.ends_with(mcap::MAGIC) {
        return Err(ReadError::NoClosingMagic);
    }
    Ok(())
}

/// Like [`read`], from a reader of a file of `len` bytes: only one record (a chunk, at most)
/// is held at a time, so memory does not grow with the file. Replay streams recordings so.
pub fn read_stream(
    mut src: impl std::io::Read,
    len: u64,
    each: &mut Visitor<'_>,
) -> Result<(), ReadError> {
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_skip_end_magic(true)
        .with_emit_chunks(true)
        .with_record_length_limit(usize::try_from(len).unwrap_or(usize::MAX));
    let mut channels = mcap::read::ChannelAccumulator::<'static>::default();
    // The last bytes read, for the closing magic.
    let mut tail: Vec<u8> = Vec::with_capacity(16);
    let mut fill = |buf: &mut [u8]| -> Result<usize, ReadError> {
        let mut got = 0;
        while got < buf.len() {
            match src.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(ReadError::Io(e)),
            }
        }
        tail.extend_from_slice(&buf[..got]);
        if tail.len() > 8 {
            tail.drain(..tail.len() - 8);
        }
        Ok(got)
    };
    records_from(&mut fill, options, &mut |op, body| {
        data_record(op, body, &mut channels, each)
    })?;
    // After the data section the summary and footer follow; read them to find the magic.
    let mut rest = [0u8; 1 << 16];
    while fill(&mut rest)? > 0 {}
    if tail != mcap::MAGIC {
        return Err(ReadError::NoClosingMagic);
    }
    Ok(())
}

/// What [`records`] hands each record to: opcode and body in, whether to go on out.
type RecordVisitor<'a> = dyn FnMut(u8, &[u8]) -> Result<bool, ReadError> + 'a;

/// Feeds every record of `bytes` (opcode, body) to `each` until it says stop. The records are
/// handed over raw so that only the ones replay needs are parsed: the mcap crate's parser panics
/// on some damaged records it does not need (an attachment shorter than its CRC, found by
/// fuzzing `replay_schedule`).
fn records(
    mut bytes: &[u8],
    options: mcap::sans_io::LinearReaderOptions,
    each: &mut RecordVisitor<'_>,
) -> Result<(), ReadError> {
    let mut fill = |buf: &mut [u8]| -> Result<usize, ReadError> {
        let n = buf.len().min(bytes.len());
        buf[..n].copy_from_slice(&bytes[..n]);
        bytes = &bytes[n..];
        Ok(n)
    };
    records_from(&mut fill, options, each)
}

/// [`records`] from a source that fills a buffer and says how much it filled (0 at the end).
fn records_from(
    fill: &mut dyn FnMut(&mut [u8]) -> Result<usize, ReadError>,
    options: mcap::sans_io::LinearReaderOptions,
    each: &mut RecordVisitor<'_>,
) -> Result<(), ReadError> {
    use mcap::sans_io::LinearReadEvent;
    let mut reader = mcap::sans_io::LinearReader::new_with_options(options);
    while let Some(event) = reader.next_event() {
        match event? {
            LinearReadEvent::ReadRequest(need) => {
                let n = fill(reader.insert(need))?;
                reader.notify_read(n);
            }
            LinearReadEvent::Record { data, opcode } => {
                if !each(opcode, data)? {
                    break;
                }
            }
        }
    }
    Ok(())
}

/// How much larger than its compressed bytes a chunk may claim to be. The `mcap` crate (0.26)
/// reserves a chunk's claimed uncompressed size, and the claimed length of each record inside
/// it, before reading, so one flipped bit in a damaged recording could ask for exabytes (a panic)
/// or gigabytes (an abort where memory is limited); fuzzing `replay_schedule` found both. Sensor
/// data compress by well under 100x.
const MAX_CHUNK_EXPANSION: u64 = 1000;

/// Whether every length-prefixed field of a schema, channel, metadata or chunk record lies
/// within its body (`None` where one does not). The `mcap` crate (0.26) reserves a string's or a byte
/// field's claimed length before reading it, so a damaged length asks for gigabytes: fuzzing
/// `check_run` found a 33-byte file whose schema name claimed 4 GB, then a chunk whose
/// compression name claimed 3 GB. A message's data has no
/// prefix (it is the rest of the record).
fn fields_fit(op: u8, body: &[u8]) -> Option<()> {
    use mcap::records::op;
    // The field at `at` (a u32 length, then that many bytes) ending by `end`; `at` moves past it.
    fn field(body: &[u8], at: &mut usize, end: usize) -> Option<(usize, usize)> {
        let len = u32::from_le_bytes(body.get(*at..*at + 4)?.try_into().ok()?) as usize;
        let start = *at + 4;
        let stop = start.checked_add(len).filter(|&e| e <= end)?;
        *at = stop;
        Some((start, stop))
    }
    // A map: its byte length, then key and value strings, each within the map.
    fn map(body: &[u8], at: &mut usize, end: usize) -> Option<()> {
        let (mut k, stop) = field(body, at, end)?;
        while k < stop {
            field(body, &mut k, stop)?;
            field(body, &mut k, stop)?;
        }
        Some(())
    }
    let end = body.len();
    match op {
        op::SCHEMA => {
            let mut at = 2;
            field(body, &mut at, end)?;
            field(body, &mut at, end)?;
            field(body, &mut at, end).map(|_| ())
        }
        op::CHANNEL => {
            let mut at = 4;
            field(body, &mut at, end)?;
            field(body, &mut at, end)?;
            map(body, &mut at, end)
        }
        op::METADATA => {
            let mut at = 0;
            field(body, &mut at, end)?;
            map(body, &mut at, end)
        }
        // Start and end time, uncompressed size and CRC, then the compression's name.
        op::CHUNK => {
            let mut at = 28;
            field(body, &mut at, end).map(|_| ())
        }
        _ => Some(()),
    }
}

/// One record of the data section (opcode, body); false at its end. Chunks are opened here rather
/// than by the mcap crate, so that every size a damaged file claims (a chunk's, a record's inside
/// it) is checked against the bytes really there before anything is allocated for it.
fn data_record(
    op: u8,
    body: &[u8],
    channels: &mut mcap::read::ChannelAccumulator<'static>,
    out: &mut Visitor<'_>,
) -> Result<bool, ReadError> {
    use mcap::records::op;
    match op {
        op::SCHEMA | op::CHANNEL | op::MESSAGE | op::METADATA => {
            if fields_fit(op, body).is_none() {
                return Err(ReadError::FieldsOverrun {
                    record: match op {
                        op::SCHEMA => "schema",
                        op::CHANNEL => "channel",
                        _ => "metadata",
                    },
                    bytes: body.len(),
                });
            }
            let record = mcap::parse_record(op, body)?;
            record_into(record, channels, out)?;
        }
        op::CHUNK => {
            if fields_fit(op, body).is_none() {
                return Err(ReadError::ChunkNameOverrun { bytes: body.len() });
            }
            // A chunk's opcode parses as a chunk (anything else is the parser's error).
            let mcap::records::Record::Chunk { header, data } = mcap::parse_record(op, body)?
            else {
                return Ok(true);
            };
            let limit = (data.len() as u64)
                .saturating_mul(MAX_CHUNK_EXPANSION)
                .saturating_add(1 << 20);
            if header.uncompressed_size > limit {
                return Err(ReadError::ChunkExpansion {
                    bytes: data.len(),
                    claimed: header.uncompressed_size,
                });
            }
            let inner = decompress(&header, &data)?;
            let options = mcap::sans_io::LinearReaderOptions::default()
                .with_skip_start_magic(true)
                .with_skip_end_magic(true)
                .with_record_length_limit(inner.len());
            // A chunk holds no chunks and no data end; anything else goes the same way.
            records(&inner, options, &mut |op, body| match op {
                op::CHUNK | op::DATA_END => Ok(true),
                _ => data_record(op, body, channels, out),
            })?;
        }
        op::ATTACHMENT => {
            if let Some((name, data)) = attachment(body) {
                out(Event::Attachment { name, data })?;
            }
        }
        op::DATA_END => return Ok(false),
        _ => {}
    }
    Ok(true)
}

/// A chunk's records, uncompressed, checked against the size its header claims (which has been
/// checked for plausibility already, so it bounds the allocation).
fn decompress(header: &mcap::records::ChunkHeader, data: &[u8]) -> Result<Vec<u8>, ReadError> {
    use std::io::Read;
    let claimed = header.uncompressed_size as usize;
    let failed = |compression| {
        move |source| ReadError::Decompress {
            compression,
            source,
        }
    };
    let body = match header.compression.as_str() {
        "" => data.to_vec(),
        "zstd" => zstd::bulk::decompress(data, claimed).map_err(failed("zstd"))?,
        "lz4" => {
            let mut out = Vec::with_capacity(claimed);
            lz4::Decoder::new(data)
                .map_err(failed("lz4"))?
                .take(claimed as u64 + 1)
                .read_to_end(&mut out)
                .map_err(failed("lz4"))?;
            out
        }
        other => return Err(ReadError::UnknownCompression(other.to_owned())),
    };
    if body.len() != claimed {
        return Err(ReadError::ChunkSize {
            claimed,
            held: body.len(),
        });
    }
    Ok(body)
}

/// One record of the data section: schemas and channels are remembered, messages and metadata
/// handed on.
fn record_into(
    record: mcap::records::Record<'_>,
    channels: &mut mcap::read::ChannelAccumulator<'static>,
    out: &mut Visitor<'_>,
) -> Result<(), ReadError> {
    match record {
        mcap::records::Record::Schema { header, data } => {
            Ok(channels.add_schema(header, std::borrow::Cow::Owned(data.into_owned()))?)
        }
        mcap::records::Record::Channel(c) => Ok(channels.add_channel(c)?),
        mcap::records::Record::Message { header, data } => {
            let channel = channels
                .get(header.channel_id)
                .ok_or(ReadError::UndefinedChannel(header.channel_id))?;
            out(Event::Message(Message {
                channel: &channel,
                log_time: header.log_time,
                publish_time: header.publish_time,
                data: &data,
            }))
        }
        mcap::records::Record::Metadata(m) => out(Event::Metadata {
            name: &m.name,
            values: &m.metadata,
        }),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 33-byte file (found by fuzzing `check_run`) whose schema record's name claims 4 GB:
    /// refused before the mcap crate reserves the claimed length, naming the record and where
    /// it starts. Well-formed records of each kind still fit.
    #[test]
    fn a_record_whose_fields_claim_more_than_it_has_is_refused_before_allocating() {
        let damaged: [u8; 33] = [
            0x27, 0x03, 0x11, 0, 0, 0, 0, 0, 0, 0, 0x11, 0x27, 0x02, 0, 0xf6, 0xf5, 0xff, 0xf5,
            0x23, 0x11, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x80, 0x80, 0x0a, 0x29,
        ];
        let mut bytes = mcap::MAGIC.to_vec();
        bytes.extend_from_slice(&damaged[1..]);
        let err = read(&bytes, &mut |_| Ok(())).unwrap_err().to_string();
        assert!(
            err.contains("schema record") && err.contains("claim more bytes than it has"),
            "{err}"
        );
        use mcap::records::op;
        let s = |t: &str| [&(t.len() as u32).to_le_bytes()[..], t.as_bytes()].concat();
        let schema = [&[1u8, 0][..], &s("a"), &s("ros2msg"), &s("int32 x")].concat();
        let pair = [s("k"), s("v")].concat();
        let map = [&(pair.len() as u32).to_le_bytes()[..], &pair].concat();
        let channel = [&[1u8, 0, 1, 0][..], &s("/t"), &s("cdr"), &map].concat();
        let metadata = [s("m"), map.clone()].concat();
        let chunk = [&[0u8; 28][..], &s("zstd"), &[0u8; 8]].concat();
        for (op, body) in [
            (op::SCHEMA, &schema),
            (op::CHANNEL, &channel),
            (op::METADATA, &metadata),
        ] {
            assert_eq!(fields_fit(op, body), Some(()), "op {op}");
            assert_eq!(fields_fit(op, &body[..body.len() - 1]), None, "op {op} cut");
        }
        // A chunk's compression name within it, and one claiming more than there is.
        assert_eq!(fields_fit(op::CHUNK, &chunk), Some(()));
        let claims = [&[0u8; 28][..], &100u32.to_le_bytes(), b"zstd", &[0u8; 8]].concat();
        assert_eq!(fields_fit(op::CHUNK, &claims), None);
    }

    /// A recording cut after its data section (in the summary or footer) has every message, yet
    /// is damaged: reading hands over all messages and then says so.
    #[test]
    fn a_file_cut_in_its_footer_gives_every_message_and_reports_the_damage() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.mcap");
        let mut bag =
            crate::bag::BagWriter::create(&path, &crate::bag::BagOptions::default()).unwrap();
        for k in 0..5i64 {
            let t = hilrig_stamp::UtcNanos(1_000_000_000 + k);
            bag.write("/x", &crate::bag::msgs::can_frame_type(), t, t, &[0u8; 16])
                .unwrap();
        }
        bag.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let count = |b: &[u8]| {
            let mut n = 0;
            let r = read(b, &mut |e| {
                if let Event::Message(_) = e {
                    n += 1;
                }
                Ok(())
            });
            (n, r.map_err(|e| e.to_string()))
        };
        assert_eq!(count(&bytes), (5, Ok(())));
        let (n, r) = count(&bytes[..bytes.len() - 3]);
        assert_eq!(n, 5);
        assert!(r.unwrap_err().contains("closing magic"));
    }

    /// Damage inside a record is located: a chunk whose header claims one byte more than it
    /// holds is named with the byte its record starts at (the chunk index's offset).
    #[test]
    fn a_damaged_chunk_is_named_with_its_byte_offset() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.mcap");
        let mut bag =
            crate::bag::BagWriter::create(&path, &crate::bag::BagOptions::default()).unwrap();
        let t = hilrig_stamp::UtcNanos(1_000_000_000);
        bag.write("/x", &crate::bag::msgs::can_frame_type(), t, t, &[7u8; 16])
            .unwrap();
        bag.finish().unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let chunk = summary.chunk_indexes[0].chunk_start_offset as usize;
        // opcode, record length, start and end time, then the uncompressed size.
        bytes[chunk + 1 + 8 + 16] += 1;
        let err = read(&bytes, &mut |_| Ok(())).unwrap_err().to_string();
        assert!(err.contains("bytes uncompressed but holds"), "{err}");
        assert!(
            err.ends_with(&format!("(in the record at byte {chunk})")),
            "{err}"
        );
    }
}
