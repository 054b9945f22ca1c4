//! Lidar captures to points: the capture layer and the Velodyne driver put together.
//!
//! Used by `hilrig decode` and by the benchmarks, so both measure and run the same code. The
//! pipeline is sans-IO apart from the byte source: packets go in with their capture times,
//! points come out through a [`PointSink`] with absolute UTC times where the hour is resolvable.

use crate::record::rejects::RejectReason;
use hilrig_capture::demux::{Demux, Packet};
use hilrig_capture::{CaptureError, CaptureReader, Stats as CaptureStats};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::clock::{HourResolver, HourSource};
use hilrig_velodyne::plausibility::{Mismatch, ModelCheck};
use hilrig_velodyne::rotation::LossCounter;
use hilrig_velodyne::source::PacketPort;
use hilrig_velodyne::{
    Calibration, DataPacket, DecodeError, Decoder, Model, Point, PositionPacket, PpsStatus,
    ProductId, Rmc, DATA_PACKET_SIZE, POSITION_PACKET_SIZE,
};
use std::collections::BTreeMap;
use std::io::Read;

/// How to decode a lidar capture.
#[derive(Clone, Debug)]
pub struct LidarOptions {
    /// Decode as this model whatever the product byte says.
    pub model: Option<Model>,
    /// Geometry overriding the built-in tables (requires `model` or a recognisable product byte).
    pub calibration: Option<Calibration>,
    /// UDP destination port of data packets; `None` accepts any port (by payload size).
    pub data_port: Option<u16>,
    /// UDP destination port of position packets; `None` accepts any port.
    pub position_port: Option<u16>,
}

impl Default for LidarOptions {
    fn default() -> Self {
        LidarOptions {
            model: None,
            calibration: None,
            data_port: Some(hilrig_velodyne::DATA_PORT),
            position_port: Some(hilrig_velodyne::POSITION_PORT),
        }
    }
}

/// The supported models' names and product bytes, for messages.
pub fn supported_models() -> String {
    Model::ALL
        .iter()
        .map(|m| format!("{m} ({:#04x})", m.product().0))
        .collect::<Vec<_>>()
        .join(", ")
}

/// What a product byte is known to be, for messages.
fn known_product(product: u8) -> &'static str {
    match product {
        0x31 => " (Velarray)",
        0x40 => " (VLP-128)",
        _ => "",
    }
}

/// Where a point's time came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointTime {
    /// Absolute UTC.
    Utc(UtcNanos),
    /// Only the time past the (unknown) hour, in nanoseconds.
    PastHour(i64),
}

impl PointTime {
    /// As `seconds.nanoseconds` text (UTC seconds, or seconds past the hour).
    pub fn to_seconds_string(self) -> String {
        match self {
            PointTime::Utc(t) => t.to_string(),
            PointTime::PastHour(ns) => UtcNanos(ns).to_string(),
        }
    }
}

/// Receives decoded points, packet by packet.
pub trait PointSink {
    /// One data packet's points; `packet_time` is the absolute time of the packet stamp.
    fn packet(&mut self, packet_time: PointTime, points: &[Point]) -> std::io::Result<()>;
}

/// A sink that only counts (for summaries and benchmarks).
#[derive(Default, Debug)]
pub struct CountSink {
    /// Points received.
    pub points: u64,
}

impl PointSink for CountSink {
    fn packet(&mut self, _t: PointTime, points: &[Point]) -> std::io::Result<()> {
        self.points += points.len() as u64;
        Ok(())
    }
}

/// A data or position packet that could not be decoded, with where it was in the file.
#[derive(Clone, Debug)]
pub struct PacketProblem {
    /// Byte offset of the capture record.
    pub offset: u64,
    /// What was wrong.
    pub error: DecodeError,
}

/// Everything counted while decoding a capture.
#[derive(Clone, Debug, Default)]
pub struct LidarSummary {
    /// The model decoded as.
    pub model: Option<Model>,
    /// Product byte of the first data packet.
    pub product: Option<ProductId>,
    /// Data packets decoded.
    pub data_packets: u64,
    /// Position packets seen.
    pub position_packets: u64,
    /// Points written.
    pub points: u64,
    /// UDP datagrams on other ports or of other sizes.
    pub other_udp: u64,
    /// CAN or serial records (not lidar).
    pub non_udp: u64,
    /// Data packets rejected, by reason.
    pub rejected: BTreeMap<String, u64>,
    /// The first few rejected packets with their offsets.
    pub first_problems: Vec<PacketProblem>,
    /// Packets lost: sensor timestamp gaps, and outages of more than two seconds told by the
    /// capture times.
    pub lost_packets: u64,
    /// Sensor time jumps.
    pub time_jumps: u64,
    /// Where the hour of the timestamps came from (last packet).
    pub hour_source: Option<HourSource>,
    /// PPS state of the last position packet.
    pub pps: Option<PpsStatus>,
    /// Last RMC decoded from a position packet.
    pub last_rmc: Option<Rmc>,
    /// Position packets whose RMC failed to parse.
    pub rmc_errors: u64,
    /// Geometry warning (product byte versus packet timing).
    pub model_mismatch: Option<Mismatch>,
    /// Capture-level counters.
    pub capture: CaptureStats,
    /// The error that ended reading early, if any (everything before it was decoded).
    pub capture_error: Option<String>,
}

/// Decoding failed before any point could be produced.
#[derive(Debug, thiserror::Error)]
pub enum LidarError {
    /// The capture could not be opened or read.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// The product byte is unknown and no model was given.
    #[error("data packet at byte {offset}: product byte {product:#04x}{} is not a model hilrig decodes; it decodes {} (force one with --model if the firmware writes a wrong byte)", known_product(*product), supported_models())]
    UnknownModel {
        /// Record offset.
        offset: u64,
        /// Product byte.
        product: u8,
    },
    /// The product byte names two models and no model was given.
    #[error("data packet at byte {offset}: product byte {product:#04x} is written by both the {} and the {}, which differ in geometry; say which with --model ({} or {}) or in the rig's [lidar] model", models[0], models[1], models[0], models[1])]
    AmbiguousModel {
        /// Record offset.
        offset: u64,
        /// Product byte.
        product: u8,
        /// The models it may stand for.
        models: &'static [Model],
    },
    /// The model's data need the unit's calibration file and none was given.
    #[error("the {model} needs its unit's own calibration ({}): give it with --calibration FILE (a ros-drivers YAML or VeloView XML file)", model.calibration_file_reason().unwrap_or_default())]
    NeedsCalibration {
        /// The model.
        model: Model,
    },
    /// Writing to the sink failed.
    #[error("writing points failed: {0}")]
    Output(#[from] std::io::Error),
}

/// Keep at most this many individual problems for the report.
const MAX_PROBLEMS: usize = 20;

/// Decodes every lidar packet of a capture into `sink`.
///
/// Reading stops at a capture-level error (truncated file, corrupt block); what was read before
/// is delivered and the error is reported in the summary rather than returned, so that a
/// cut-off recording still yields its points.
pub fn decode_capture<R: Read + Send + 'static>(
    source: R,
    options: &LidarOptions,
    sink: &mut dyn PointSink,
) -> Result<LidarSummary, LidarError> {
    let mut demux = Demux::new(CaptureReader::new(source)?);
    let mut summary = LidarSummary::default();
    let mut decoder: Option<Decoder> = None;
    let mut hours = HourResolver::default();
    let mut loss: Option<LossCounter> = None;
    let mut previous: Option<hilrig_velodyne::DataPacket> = None;
    let mut check = ModelCheck::default();
    let mut points: Vec<Point> = Vec::with_capacity(800);
    let mut last_pps_byte = None;
    loop {
        let item = match demux.next_item() {
            None => break,
            Some(Err(e)) => {
                summary.capture_error = Some(e.to_string());
                break;
            }
            Some(Ok(item)) => item,
        };
        let (dst_port, payload) = match item.packet {
            Packet::Udp { dst, payload, .. } => (dst.port(), payload),
            _ => {
                summary.non_udp += 1;
                continue;
            }
        };
        let is_data =
            payload.len() == DATA_PACKET_SIZE && options.data_port.is_none_or(|p| p == dst_port);
        let is_position = payload.len() == POSITION_PACKET_SIZE
            && options.position_port.is_none_or(|p| p == dst_port);
        let on_data_port = options.data_port == Some(dst_port);
        let on_position_port = options.position_port == Some(dst_port);
        if !is_data && !is_position && (on_data_port || on_position_port) {
            // Something of the wrong size arrived on a lidar port: a real problem, not traffic
            // that merely shares the network.
            let expected = if on_data_port {
                DATA_PACKET_SIZE
            } else {
                POSITION_PACKET_SIZE
            };
            let got = payload.len();
            note_problem(
                &mut summary,
                item.offset,
                DecodeError::WrongSize { expected, got },
            );
            continue;
        }
        if is_position {
            summary.position_packets += 1;
            match PositionPacket::decode(payload) {
                Ok(pos) => {
                    if let Some(rmc) = hours.handle_position(&pos, item.time) {
                        summary.last_rmc = Some(rmc);
                    }
                    last_pps_byte = Some(pos.pps_byte);
                }
                Err(e) => note_problem(&mut summary, item.offset, e),
            }
            continue;
        }
        if !is_data {
            summary.other_udp += 1;
            continue;
        }
        let pkt = match DataPacket::decode(payload) {
            Ok(p) => p,
            Err(e) => {
                // Counted as a problem, not lost as well (when it may be the sensor's own:
                // another sensor's packets would hide this one's losses), by the recorder's rule.
                if RejectReason::of(PacketPort::Data, &e).may_be_own() {
                    if let Some(l) = loss.as_mut() {
                        l.rejected(item.time);
                    }
                }
                note_problem(&mut summary, item.offset, e);
                continue;
            }
        };
        if decoder.is_none() {
            summary.product = Some(pkt.product);
            let model = match options.model.or_else(|| Model::from_product(pkt.product)) {
                Some(m) => m,
                None => {
                    let models = Model::ambiguous_product(pkt.product);
                    return Err(if models.len() >= 2 {
                        LidarError::AmbiguousModel {
                            offset: item.offset,
                            product: pkt.product.0,
                            models,
                        }
                    } else {
                        LidarError::UnknownModel {
                            offset: item.offset,
                            product: pkt.product.0,
                        }
                    });
                }
            };
            summary.model = Some(model);
            if model.needs_calibration_file() && options.calibration.is_none() {
                return Err(LidarError::NeedsCalibration { model });
            }
            let d = match &options.calibration {
                Some(c) => Decoder::with_calibration(model, c.clone()),
                None => Decoder::new(model),
            };
            let mode = pkt
                .return_mode
                .mode()
                .unwrap_or(hilrig_velodyne::ReturnMode::Strongest);
            loss = Some(LossCounter::new(d.packet_period_us(mode)));
            decoder = Some(d);
        }
        let Some(dec) = decoder.as_ref() else {
            continue;
        };
        check.observe(&pkt);
        if let Some(l) = loss.as_mut() {
            l.observe(pkt.timestamp_us, item.time);
        }
        points.clear();
        if let Err(e) = dec.decode_into_after(&pkt, previous.as_ref(), &mut points) {
            note_problem(&mut summary, item.offset, e);
            continue;
        }
        if dec.model() == hilrig_velodyne::Model::Vls128 {
            // A dual-return VLS-128 packet takes its rotation rate from the one before.
            previous = Some(pkt.clone());
        }
        summary.data_packets += 1;
        summary.points += points.len() as u64;
        let time = match hours.resolve(pkt.timestamp_us, item.time) {
            Some((t, src)) => {
                summary.hour_source = Some(src);
                PointTime::Utc(t)
            }
            None => PointTime::PastHour(i64::from(pkt.timestamp_us) * 1_000),
        };
        sink.packet(time, &points)?;
    }
    if let (Some(model), None) = (summary.model, options.model) {
        summary.model_mismatch = check.verdict(model);
    }
    if let Some(l) = loss {
        summary.lost_packets = l.lost;
        summary.time_jumps = l.time_jumps;
    }
    summary.rmc_errors = hours.rmc_errors;
    // The HDL-32E leaves the PPS byte unused; only other models report it.
    summary.pps =
        last_pps_byte.map(|b| PpsStatus::from_byte(b, summary.model != Some(Model::Hdl32e)));
    summary.capture = demux.stats().clone();
    Ok(summary)
}

fn note_problem(summary: &mut LidarSummary, offset: u64, error: DecodeError) {
    let key = match &error {
        DecodeError::WrongSize { .. } => "wrong payload size",
        DecodeError::BadBlockFlag { .. }
        | DecodeError::ForeignBankFlag { .. }
        | DecodeError::BankPairMismatch { .. } => "bad block flag",
        DecodeError::AzimuthOutOfRange { .. } => "azimuth above 36000",
        DecodeError::UnsupportedProduct(_) => "unsupported product",
        DecodeError::UnsupportedReturnMode(_) => "unsupported return mode",
        _ => "other",
    };
    *summary.rejected.entry(key.to_owned()).or_insert(0) += 1;
    if summary.first_problems.len() < MAX_PROBLEMS {
        summary.first_problems.push(PacketProblem { offset, error });
    }
}

/// Absolute time of a point: packet time plus its firing offset.
pub fn point_time(packet: PointTime, p: &Point) -> PointTime {
    match packet {
        PointTime::Utc(t) => {
            PointTime::Utc(UtcNanos(t.0.saturating_add(i64::from(p.time_offset_ns))))
        }
        PointTime::PastHour(ns) => PointTime::PastHour(ns + i64::from(p.time_offset_ns)),
    }
}
