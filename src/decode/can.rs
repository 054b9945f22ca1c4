//! CAN logs to decoded frames: candump logs and the SocketCAN interfaces of pcap/pcapng
//! captures, through a DBC. Used by `hilrig decode --kind can`.

use hilrig_can::candump::{parse_line, CandumpError};
use hilrig_can::{CanFrame, Database};
use hilrig_capture::demux::{Demux, Packet};
use hilrig_capture::{CaptureError, CaptureReader};
use hilrig_stamp::UtcNanos;
use std::io::{BufRead, Read};

/// Counters of a CAN log decode.
#[derive(Clone, Debug, Default)]
pub struct CanSummary {
    /// Frames read.
    pub frames: u64,
    /// Frames decoded with the DBC.
    pub decoded: u64,
    /// Frames whose id is not in the DBC.
    pub unknown_id: u64,
    /// Remote and error frames (not decoded).
    pub remote_or_error: u64,
    /// The error that ended reading early, if any (everything before it was decoded).
    pub error: Option<String>,
}

/// Why a CAN log could not be read at all.
#[derive(Debug, thiserror::Error)]
pub enum CanLogError {
    /// A capture-level error before any frame.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// Reading failed.
    #[error("reading the log failed: {0}")]
    Io(#[from] std::io::Error),
}

/// Decodes every frame of a candump log or capture; `sink` gets (time, frame, decoded values)
/// for each frame the DBC knows.
pub fn decode_can<R: Read + Send + 'static>(
    source: R,
    db: &Database,
    sink: &mut dyn FnMut(UtcNanos, &CanFrame, &hilrig_can::Decoded<'_>) -> std::io::Result<()>,
) -> Result<CanSummary, CanLogError> {
    let (is_capture, source) = hilrig_capture::reader::sniff(source)?;
    let mut summary = CanSummary::default();
    let mut handle = |t: UtcNanos, f: &CanFrame, summary: &mut CanSummary| -> std::io::Result<()> {
        summary.frames += 1;
        if f.rtr || f.error {
            summary.remote_or_error += 1;
            return Ok(());
        }
        match db.decode(f) {
            Some(d) => {
                summary.decoded += 1;
                sink(t, f, &d)
            }
            None => {
                summary.unknown_id += 1;
                Ok(())
            }
        }
    };
    if is_capture {
        let mut demux = Demux::new(CaptureReader::new(source)?);
        while let Some(item) = demux.next_item() {
            match item {
                Ok(i) => {
                    if let Packet::Can(f) = i.packet {
                        handle(i.time, &f, &mut summary)?;
                    }
                }
                Err(e) => {
                    summary.error = Some(e.to_string());
                    break;
                }
            }
        }
        return Ok(summary);
    }
    let reader = std::io::BufReader::new(source);
    for (i, line) in reader.lines().enumerate() {
        let line = line?;
        match parse_line(&line, i + 1) {
            Ok(Some(lf)) => handle(lf.time, &lf.frame, &mut summary)?,
            Ok(None) => {}
            Err(e @ CandumpError { .. }) => {
                summary.error = Some(e.to_string());
                break;
            }
        }
    }
    Ok(summary)
}

/// One decoded frame as hilrig's JSON object (`time` in seconds, `id`, `name`, `signals`).
pub fn frame_json(t: UtcNanos, f: &CanFrame, d: &hilrig_can::Decoded<'_>) -> String {
    let mut signals = serde_json::Map::new();
    for &(i, v) in &d.values {
        signals.insert(d.message.signals[i].name.clone(), serde_json::json!(v));
    }
    format!(
        "{{\"time\":{},\"id\":{},\"name\":{},\"signals\":{}}}",
        t,
        f.id,
        serde_json::Value::String(d.message.name.clone()),
        serde_json::Value::Object(signals)
    )
}
