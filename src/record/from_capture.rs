//! `hilrig record --from`: captures into one time-synchronised MCAP, through the same decoders
//! the vehicle recorder uses.
//!
//! Two passes over the inputs. The first estimates a clock model per source that has its own
//! clock (lidar: microseconds past the hour, hour from the position packets' RMC or the capture
//! time; GNSS: the fix's UTC) from its (sensor, host) pairs. The second writes every message
//! with `log_time` = the sensor time mapped onto the host time base by that model (so transport
//! jitter is gone and sources line up), or the host time where a source has no clock (CAN,
//! raw byte streams), and `publish_time` = the host receive time. The models and their residuals
//! go into the file's metadata for `check`.
//!
//! Long file: one `Context` reads four kinds of input (pcap/pcapng with lidar, serial and CAN
//! interfaces; candump logs; raw serial logs) in both passes; its handlers share the pass state
//! and are kept together so that the two passes cannot drift apart.

use crate::bag::msgs;
use crate::bag::topics;
use crate::bag::{BagError, BagWriter};
use crate::record::clock::{ClockEstimator, ClockModel};
use crate::record::gnss_stream::GnssStream;
use crate::record::messages::{cloud_cdr, nav_sat_fix};
use crate::record::rejects::{GnssRejects, GnssUndecoded, LidarRejects, RejectReason, Undecoded};
use crate::rig::Rig;
use hilrig_can::ego::{EgoSample, EgoTracker, Quantity};
use hilrig_can::Database;
use hilrig_capture::demux::{Demux, Packet};
use hilrig_capture::{CaptureError, CaptureReader};
use hilrig_gnss::epoch::{Fix, NmeaEpochs, UbxEpochs};
use hilrig_gnss::framer::{Frame, Framer, Item};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::clock::HourResolver;
use hilrig_velodyne::source::PacketPort;
use hilrig_velodyne::{
    Decoder, Model, PositionPacket, RawDataPacket, ReturnMode, RotationAssembler,
    POSITION_PACKET_SIZE,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why recording from captures failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// An input could not be read.
    #[error("{path}: {source}")]
    Input {
        /// The input.
        path: String,
        /// Cause.
        #[source]
        source: CaptureError,
    },
    /// An input is of a kind `--from` does not read yet.
    #[error("{path}: {what}")]
    Unsupported {
        /// The input.
        path: String,
        /// What.
        what: String,
    },
    /// Writing the MCAP failed; what was written before is in the `.active` file.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// A rig part (DBC, calibration, ego mapping) is unusable.
    #[error("rig: {0}")]
    Rig(String),
    /// Every lidar data packet of the inputs was rejected: the rig's lidar would be missing
    /// from the recording, so none is written.
    #[error(
        "none of the {} lidar data packets in the input could be recorded as the rig's {model}'s, so nothing was written: {}",
        rejects.data_packets(),
        rejects.lines().join("; ")
    )]
    LidarRejected {
        /// The rig's lidar model.
        model: Model,
        /// The packets rejected, per reason.
        rejects: LidarRejects,
    },
}

/// What a `--from` recording did.
#[derive(Clone, Debug, Default)]
pub struct RecordSummary {
    /// Messages per topic.
    pub counts: BTreeMap<String, u64>,
    /// Clock models per source (name, model, residual p50/p95/max in ns, pairs).
    pub clocks: Vec<(String, ClockModel, crate::record::clock::Residuals, u64)>,
    /// Lidar packets lost (sensor timestamp gaps, and outages of more than two seconds told
    /// by the capture's receive times).
    pub lidar_lost: u64,
    /// Of those gaps, outages of more than two seconds.
    pub lidar_outages: u64,
    /// Jumps of the lidar's clock (backwards, or by more than two seconds while its packets
    /// kept coming): not loss, but the sensor re-synchronised or was reset.
    pub lidar_time_jumps: u64,
    /// Pauses of more than two seconds between inputs (captures of separate sessions): not
    /// loss, nothing was capturing.
    pub lidar_input_pauses: u64,
    /// Inputs that ended early (truncated), with the error.
    pub input_errors: Vec<String>,
    /// Lidar packets not recorded, per reason (any makes `record` exit 1).
    pub lidar_rejects: LidarRejects,
    /// GNSS serial frames not recorded (a checksum that fails, a malformed sentence), per
    /// reason (any makes `record` exit 1).
    pub gnss_rejects: GnssRejects,
    /// GNSS messages recorded whole (on /gnss/nmea, /gnss/ubx) whose fields did not decode, so
    /// that their fix or attitude is missing, per reason (any makes `record` exit 1).
    pub gnss_undecoded: GnssUndecoded,
    /// What each GNSS serial stream (a capture's serial interface, a log) held: frames, bytes
    /// outside them, fixes with and without a date.
    pub gnss_streams: Vec<GnssStream>,
    /// UDP datagrams that went to no lidar port of the rig, by destination port.
    pub other_udp_ports: BTreeMap<u16, u64>,
    /// Names of the captures' serial interfaces that carried bytes (read as the GNSS stream,
    /// whatever the rig's `gnss.port` says: that is the live port).
    pub serial_interfaces: std::collections::BTreeSet<String>,
    /// Attitude reports not written to /gnss/attitude because they came before the stream
    /// showed its date (their raw sentences and frames are in /gnss/nmea and /gnss/ubx).
    pub attitude_untimed: u64,
    /// Capture records the reader could not use, per reason.
    pub capture_records: CaptureSkips,
}

/// Capture records that reached no topic, per reason (the reason's key, see [`skip_key`]).
/// A damaged record (cut by the capture's snap length, a truncated or inconsistent header, a
/// malformed CAN frame, a fragment whose datagram never completed) may have held the rig's
/// data: any makes `record` exit 1, and a capture whose lidar packets were all damaged says
/// so. Other traffic (not IPv4, not UDP, a link type the reader does not decode) is counted
/// for the record only.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CaptureSkips {
    /// Damaged records.
    pub damaged: BTreeMap<&'static str, u64>,
    /// Other traffic.
    pub other: BTreeMap<&'static str, u64>,
}

impl CaptureSkips {
    /// Adds what a capture's reader skipped.
    pub fn add(&mut self, stats: &hilrig_capture::demux::Stats) {
        for (reason, n) in &stats.skipped {
            let (key, damaged) = skip_key(*reason);
            let to = if damaged {
                &mut self.damaged
            } else {
                &mut self.other
            };
            *to.entry(key).or_insert(0) += n;
        }
        if stats.fragments_dropped > 0 {
            *self.damaged.entry("incomplete_ipv4_fragments").or_insert(0) +=
                stats.fragments_dropped;
        }
    }

    /// Damaged records in all.
    pub fn damaged_total(&self) -> u64 {
        self.damaged.values().sum()
    }

    /// The counts as `hilrig/end` metadata: `capture_damaged_records` (total) and
    /// `capture_damaged_records.KEY`, `capture_other_records.KEY`.
    fn write_metadata(&self, meta: &mut BTreeMap<String, String>) {
        meta.insert(
            "capture_damaged_records".to_owned(),
            self.damaged_total().to_string(),
        );
        for (k, n) in &self.damaged {
            meta.insert(format!("capture_damaged_records.{k}"), n.to_string());
        }
        for (k, n) in &self.other {
            meta.insert(format!("capture_other_records.{k}"), n.to_string());
        }
    }
}

/// A skip reason's key, and whether the record was damaged (it may have been the rig's data)
/// rather than other traffic.
pub fn skip_key(reason: hilrig_capture::SkipReason) -> (&'static str, bool) {
    use hilrig_capture::SkipReason as S;
    match reason {
        S::CutBySnapLength => ("cut_by_snap_length", true),
        S::TruncatedLinkHeader => ("truncated_link_header", true),
        S::TruncatedIpv4 => ("truncated_ipv4", true),
        S::BadIpv4Header => ("bad_ipv4_header", true),
        S::TruncatedUdp => ("truncated_udp", true),
        S::BadUdpLength => ("bad_udp_length", true),
        S::BadCanFrame => ("bad_can_frame", true),
        S::NotIpv4 => ("not_ipv4", false),
        S::NotUdp(_) => ("not_udp", false),
        S::UnsupportedLinkType(_) => ("unsupported_link_type", false),
    }
}

struct Context<'a> {
    rig: &'a Rig,
    /// The rig's lidar model: data packets are checked to be its.
    model: Option<Model>,
    decoder: Option<Decoder>,
    db: Option<Database>,
    ego: Option<EgoTracker>,
}

/// Per-pass state of the sources.
struct Sources {
    hours: HourResolver,
    hour_source: Option<hilrig_velodyne::clock::HourSource>,
    lidar_clock: ClockEstimator,
    gnss_clock: ClockEstimator,
    framers: BTreeMap<u32, SerialState>,
    /// UTC of the first fix of a serial log (from pass 1), stamping what comes before it.
    first_fix: Option<UtcNanos>,
    /// PPS byte of the last position packet.
    pps_byte: Option<u8>,
    /// Lidar data packets that passed the model's check (pass 1: whether any will be recorded).
    lidar_checked: u64,
    /// Lidar packets left out, per reason.
    rejects: LidarRejects,
    /// GNSS frames left out, per reason.
    gnss_rejects: GnssRejects,
    /// GNSS messages recorded whole whose fields did not decode, per reason.
    gnss_undecoded: GnssUndecoded,
}

/// A serial interface's framer and epoch assemblers, with the receive time of the last frame:
/// an epoch is complete when the next one starts, but it was *received* with its own last
/// sentence, and that is its host time.
struct SerialState {
    /// Keeping what it skips: bytes in no frame are recorded too (`/gnss/unframed`).
    framer: Framer,
    nmea: NmeaEpochs,
    ubx: UbxEpochs,
    last_host: Option<UtcNanos>,
    last_fix: Option<UtcNanos>,
    /// When the stream's last bytes were received (of a frame or not).
    last_receive: Option<UtcNanos>,
    /// The stream has no receive times (a raw serial log).
    timeless: bool,
    /// What the stream held (counted in the pass that writes).
    stream: GnssStream,
}

impl Default for SerialState {
    fn default() -> Self {
        SerialState::with(Framer::new())
    }
}

impl SerialState {
    /// A stream read by `framer` (which is made to keep the bytes it skips).
    fn with(framer: Framer) -> SerialState {
        SerialState {
            framer: framer.keeping_unframed(),
            nmea: NmeaEpochs::default(),
            ubx: UbxEpochs::default(),
            last_host: None,
            last_fix: None,
            last_receive: None,
            timeless: false,
            stream: GnssStream::default(),
        }
    }
}

impl Sources {
    fn new() -> Sources {
        Sources {
            hours: HourResolver::default(),
            hour_source: None,
            lidar_clock: ClockEstimator::new(),
            gnss_clock: ClockEstimator::new(),
            framers: BTreeMap::new(),
            first_fix: None,
            pps_byte: None,
            lidar_checked: 0,
            rejects: LidarRejects::default(),
            gnss_rejects: GnssRejects::default(),
            gnss_undecoded: GnssUndecoded::default(),
        }
    }
}

/// The writing side of pass 2.
struct Output<'a> {
    bag: BagWriter,
    lidar: Option<ClockModel>,
    gnss: Option<ClockModel>,
    /// Rotation assembly, started at the first packet (whose return mode sets the packet
    /// period that loss is counted in).
    rotation: Option<RotationAssembler<RawDataPacket>>,
    /// Where rotations are cut (hundredths of a degree), and the lidar's model (None: the rig
    /// has no lidar).
    cut: Option<(u16, Model)>,
    /// Decoder for /points (None: not written).
    points: Option<Decoder>,
    frame_lidar: String,
    frame_gnss: String,
    /// Attitude reports without a time (see [`RecordSummary::attitude_untimed`]).
    attitude_untimed: u64,
    last_speed: Option<f64>,
    last_yaw: Option<f64>,
    rig: &'a Rig,
}

impl Output<'_> {
    /// Adds a data packet to the current rotation; gives the rotation it completed. The first
    /// packet starts the assembler with the period its return mode gives (a dual-return packet
    /// covers a third, or half, of a single-return one's time).
    fn rotate(
        &mut self,
        packet: hilrig_stamp::Stamped<RawDataPacket>,
    ) -> Option<hilrig_velodyne::Rotation<RawDataPacket>> {
        if self.rotation.is_none() {
            let (cut, model) = self.cut?;
            let mode = hilrig_velodyne::packet::ReturnModeByte(packet.value.0[1204])
                .mode()
                .unwrap_or(ReturnMode::Strongest);
            let period = Decoder::new(model).packet_period_us(mode);
            self.rotation = Some(RotationAssembler::new(cut, period));
        }
        self.rotation.as_mut()?.push(packet)
    }
}

/// A data packet received at `host` and rejected for `reason` (counted among the rejects):
/// the loss count leaves it out when it may be the sensor's own.
fn rejected_data(out: Option<&mut Output<'_>>, host: UtcNanos, reason: RejectReason) {
    if let Some(r) = out.and_then(|o| o.rotation.as_mut()) {
        if reason.may_be_own() {
            r.loss_mut().rejected(host);
        }
    }
}

fn sync(model: Option<ClockModel>, sensor: UtcNanos) -> UtcNanos {
    model.map_or(sensor, |m| m.to_host(sensor))
}

impl Context<'_> {
    /// One capture input through both passes' logic; `out` is `None` in pass 1.
    fn run_capture(
        &self,
        path: &Path,
        src: &mut Sources,
        mut out: Option<&mut Output<'_>>,
        summary: &mut RecordSummary,
    ) -> Result<(), RecordError> {
        let file = std::fs::File::open(path).map_err(|e| RecordError::Input {
            path: path.display().to_string(),
            source: CaptureError::Io {
                offset: 0,
                source: e,
            },
        })?;
        let reader =
            CaptureReader::new(std::io::BufReader::with_capacity(1 << 20, file)).map_err(|e| {
                RecordError::Input {
                    path: path.display().to_string(),
                    source: e,
                }
            })?;
        let mut demux = Demux::new(reader);
        let lidar = self.rig.lidar.as_ref();
        let mut serial_seen = std::collections::BTreeSet::new();
        loop {
            let item = match demux.next_item() {
                None => break,
                Some(Err(e)) => {
                    if out.is_some() {
                        summary
                            .input_errors
                            .push(format!("{}: {e}", path.display()));
                    }
                    break;
                }
                Some(Ok(i)) => i,
            };
            let host = item.time;
            match item.packet {
                Packet::Udp { dst, payload, .. } => {
                    let (Some(l), Some(model)) = (lidar, self.model) else {
                        continue;
                    };
                    let port = dst.port();
                    let at = || format!("{} byte {}", path.display(), item.offset);
                    // A 512-byte datagram to a shared port is a position packet.
                    if port == l.position_port
                        && (payload.len() == POSITION_PACKET_SIZE || port != l.data_port)
                    {
                        let p = match PositionPacket::decode(payload) {
                            Ok(p) => p,
                            Err(e) => {
                                src.rejects
                                    .add(RejectReason::of(PacketPort::Position, &e), || {
                                        format!("{}: {e}", at())
                                    });
                                continue;
                            }
                        };
                        src.hours.handle_position(&p, host);
                        src.pps_byte = Some(p.pps_byte);
                        if let Some(o) = out.as_deref_mut() {
                            o.bag.write(
                                topics::VELODYNE_POSITION,
                                &msgs::raw_packet_type(),
                                host,
                                host,
                                &msgs::raw_packet(host, &o.frame_lidar, payload),
                            )?;
                        }
                    } else if port == l.data_port {
                        // Validated but not decoded: the recorder writes the bytes as received.
                        let raw = match RawDataPacket::check(payload, model) {
                            Ok(raw) => raw,
                            Err(e) => {
                                let reason = RejectReason::of(PacketPort::Data, &e);
                                src.rejects.add(reason, || format!("{}: {e}", at()));
                                rejected_data(out.as_deref_mut(), host, reason);
                                continue;
                            }
                        };
                        src.lidar_checked += 1;
                        let toh = RawDataPacket::timestamp_of(raw);
                        let Some((sensor, hour_source)) = src.hours.resolve(toh, host) else {
                            src.rejects.add(RejectReason::NoHour, || {
                                format!(
                                    "{}: timestamp {toh} µs past an unknown hour: no position packet with a valid RMC, and the capture's clock reads {} (before 2000: unset)",
                                    at(),
                                    hilrig_stamp::civil::iso8601_millis(host)
                                )
                            });
                            rejected_data(out.as_deref_mut(), host, RejectReason::NoHour);
                            continue;
                        };
                        // The hour moving from the host clock to the RMC can shift sensor times
                        // by hours: pairs from before belong to another line.
                        if src
                            .hour_source
                            .replace(hour_source)
                            .is_some_and(|prev| prev != hour_source)
                        {
                            src.lidar_clock = ClockEstimator::new();
                        }
                        match out.as_deref_mut() {
                            None => src.lidar_clock.handle(sensor, host),
                            Some(o) => {
                                let t = sync(o.lidar, sensor);
                                let packet = hilrig_stamp::Stamped {
                                    host,
                                    sensor: Some(t),
                                    value: RawDataPacket(Box::new(*raw)),
                                };
                                if let Some(done) = o.rotate(packet) {
                                    write_scan(o, &done.packets)?;
                                }
                            }
                        }
                    } else if out.is_none() {
                        // Counted once (in the first pass), to say where the traffic went when
                        // the rig's ports match nothing.
                        *summary.other_udp_ports.entry(port).or_default() += 1;
                    }
                }
                Packet::Serial(bytes) => {
                    serial_seen.insert(item.interface);
                    self.serial(src, out.as_deref_mut(), item.interface, bytes, Some(host))?;
                }
                Packet::Can(frame) => {
                    if let Some(o) = out.as_deref_mut() {
                        self.can(o, &frame, host)?;
                    }
                }
            }
        }
        if out.is_some() {
            // Counted once, in the pass that writes.
            summary.capture_records.add(demux.stats());
        } else {
            for i in serial_seen {
                let name = demux
                    .interfaces()
                    .get(i as usize)
                    .and_then(|f| f.name.clone())
                    .unwrap_or_else(|| format!("interface {i}"));
                if let Some(s) = src.framers.get_mut(&i) {
                    if s.stream.name.is_empty() {
                        s.stream.name = format!("{} ({name})", path.display());
                    }
                }
                summary.serial_interfaces.insert(name);
            }
        }
        self.finish_serial(src, out)
    }

    /// Closes the serial epochs still open at the end of an input.
    fn finish_serial(
        &self,
        src: &mut Sources,
        mut out: Option<&mut Output<'_>>,
    ) -> Result<(), RecordError> {
        // Epochs still open at the end of the input, received with the interface's last frame.
        // Not while the framer holds bytes of a frame not yet complete: they may belong to the
        // epoch (a frame cut by the capture's end continues in the next input; a bogus length
        // may have swallowed the rest of the epoch, found when the stream ends).
        let mut open: Vec<(Fix, UtcNanos)> = Vec::new();
        for s in src.framers.values_mut() {
            let Some(h) = s.last_host else { continue };
            if s.framer.pending() > 0 {
                continue;
            }
            let timeless = s.timeless;
            for f in s.nmea.finish().into_iter().chain(s.ubx.finish()) {
                // A log without receive times: the fix's own UTC is its host time.
                let h = if timeless { f.time.unwrap_or(h) } else { h };
                if out.is_some() {
                    s.stream.count(&f);
                }
                open.push((f, h));
            }
        }
        for (f, h) in open {
            self.fix(src, out.as_deref_mut(), &f, h)?;
        }
        Ok(())
    }

    /// Bytes of a serial stream; `host` is the receive time, or `None` for logs without one
    /// (then frames carry the UTC of the latest fix, and fixes their own UTC).
    fn serial(
        &self,
        src: &mut Sources,
        mut out: Option<&mut Output<'_>>,
        interface: u32,
        bytes: &[u8],
        host: Option<UtcNanos>,
    ) -> Result<(), RecordError> {
        let first_fix = src.first_fix;
        let entry = src.framers.entry(interface).or_default();
        entry.timeless = host.is_none();
        entry.last_receive = host.or(entry.last_receive);
        entry.framer.push(bytes);
        let mut fixes = Vec::new();
        let mut attitudes = Vec::new();
        let time_of = |entry: &SerialState| {
            host.or(entry.last_fix)
                .or(first_fix)
                .unwrap_or(UtcNanos::EPOCH)
        };
        loop {
            let item = entry.framer.next_frame();
            // The bytes in no frame before the item (or at the end of what came), as they came.
            while let Some(run) = entry.framer.take_unframed() {
                if let Some(o) = out.as_deref_mut() {
                    let t = time_of(entry);
                    o.bag.write(
                        topics::GNSS_UNFRAMED,
                        &msgs::raw_packet_type(),
                        t,
                        t,
                        &msgs::raw_packet(t, &o.frame_gnss, &run.bytes),
                    )?;
                }
            }
            let Some(it) = item else { break };
            let (frame, offset) = match it {
                Item::Frame { frame, offset } => (frame, offset),
                Item::Rejected { offset, reason } => {
                    src.gnss_rejects.add(reason, || {
                        format!(
                            "serial interface {interface}, stream byte {offset}{}",
                            host.map_or(String::new(), |h| format!(", received {h}"))
                        )
                    });
                    continue;
                }
            };
            let t = time_of(entry);
            // A fix completed by this frame was received with the previous one.
            let epoch_host = entry.last_host.unwrap_or(t);
            entry.last_host = Some(t);
            match frame {
                Frame::Nmea(s) => {
                    if let Some(o) = out.as_deref_mut() {
                        o.bag.write(
                            topics::GNSS_NMEA,
                            &msgs::nmea_sentence_type(),
                            t,
                            t,
                            &msgs::nmea_sentence(t, &o.frame_gnss, &s),
                        )?;
                    }
                    match hilrig_gnss::nmea::parse(&s) {
                        Ok(sentence) => {
                            let time = entry.nmea.attitude_time(&sentence);
                            attitudes.push((hilrig_gnss::attitude::from_nmea(&sentence, time), t));
                            fixes.extend(entry.nmea.push(&sentence).map(|f| (f, epoch_host)));
                        }
                        Err(e) => src.gnss_undecoded.add(Undecoded::NmeaFields, || {
                            format!("serial interface {interface}, stream byte {offset}: {e}")
                        }),
                    }
                }
                Frame::Ubx { class, id, payload } => {
                    if let Some(o) = out.as_deref_mut() {
                        let raw = hilrig_gnss::framer::ubx_frame(class, id, &payload);
                        o.bag.write(
                            topics::GNSS_UBX,
                            &msgs::raw_packet_type(),
                            t,
                            t,
                            &msgs::raw_packet(t, &o.frame_gnss, &raw),
                        )?;
                    }
                    match hilrig_gnss::ubx::decode(class, id, &payload) {
                        Ok(m) => {
                            fixes.extend(entry.ubx.push(&m).map(|f| (f, epoch_host)));
                            let time = entry.ubx.attitude_time(&m);
                            attitudes.push((hilrig_gnss::attitude::from_ubx(&m, time), t));
                        }
                        Err(e) => src.gnss_undecoded.add(Undecoded::UbxPayload, || {
                            format!("serial interface {interface}, stream byte {offset}: {e}")
                        }),
                    }
                }
                Frame::Rtcm3 { bytes, .. } => {
                    if let Some(o) = out.as_deref_mut() {
                        o.bag.write(
                            topics::GNSS_RTCM,
                            &msgs::raw_packet_type(),
                            t,
                            t,
                            &msgs::raw_packet(t, &o.frame_gnss, &bytes),
                        )?;
                    }
                }
            }
            for (f, _) in &fixes {
                if let Some(ft) = f.time {
                    entry.last_fix = Some(ft);
                }
            }
        }
        if out.is_some() {
            for (f, _) in &fixes {
                entry.stream.count(f);
            }
        }
        if let Some(o) = out.as_deref_mut() {
            for (r, host) in attitudes {
                let hilrig_gnss::attitude::Reading::Attitude(a) = r else {
                    continue;
                };
                let Some(at) = a.time else {
                    o.attitude_untimed += 1;
                    continue;
                };
                // Without receive times the report's own time is its host time.
                let host = if entry.timeless { at } else { host };
                o.bag.write(
                    topics::GNSS_ATTITUDE,
                    &msgs::attitude_type(),
                    sync(o.gnss, at),
                    host,
                    &msgs::attitude(at, &o.frame_gnss, &a),
                )?;
            }
        }
        for (f, h) in fixes {
            if let Some(ft) = f.time {
                src.first_fix.get_or_insert(ft);
            }
            // Without receive times the fix's own time is its host time.
            let h = if host.is_some() {
                h
            } else {
                f.time.unwrap_or(h)
            };
            self.fix(src, out.as_deref_mut(), &f, h)?;
        }
        Ok(())
    }

    fn fix(
        &self,
        src: &mut Sources,
        out: Option<&mut Output<'_>>,
        f: &Fix,
        host: UtcNanos,
    ) -> Result<(), RecordError> {
        let Some(t) = f.time else { return Ok(()) };
        match out {
            None => src.gnss_clock.handle(t, host),
            Some(o) => {
                if let Some(nav) = nav_sat_fix(f) {
                    let log = sync(o.gnss, t);
                    o.bag.write(
                        topics::GNSS_FIX,
                        &msgs::nav_sat_fix_type(),
                        log,
                        host,
                        &msgs::nav_sat_fix(t, &o.frame_gnss, &nav),
                    )?;
                }
            }
        }
        Ok(())
    }

    fn can(
        &self,
        o: &mut Output<'_>,
        frame: &hilrig_capture::CanFrame,
        host: UtcNanos,
    ) -> Result<(), RecordError> {
        let iface = o
            .rig
            .can
            .as_ref()
            .map_or("can0", |c| c.interface.as_str())
            .to_owned();
        if frame.fd {
            o.bag.write(
                topics::CAN_FD_FRAMES,
                &msgs::raw_packet_type(),
                host,
                host,
                &msgs::raw_packet(host, &iface, &frame.encode_socketcan()),
            )?;
        } else {
            o.bag.write(
                topics::CAN_FRAMES,
                &msgs::can_frame_type(),
                host,
                host,
                &msgs::can_frame(host, &iface, frame),
            )?;
        }
        let (Some(db), Some(ego)) = (&self.db, &self.ego) else {
            return Ok(());
        };
        let Some(d) = db.decode(frame) else {
            return Ok(());
        };
        let mut samples: Vec<EgoSample> = Vec::new();
        ego.handle(host, &d, &mut samples);
        let mut changed = false;
        for s in &samples {
            match s.quantity {
                Quantity::Speed => {
                    o.last_speed = Some(s.value);
                    changed = true;
                }
                Quantity::YawRate => {
                    o.last_yaw = Some(s.value);
                    changed = true;
                }
                _ => {}
            }
        }
        if changed {
            if let (Some(v), Some(w)) = (o.last_speed, o.last_yaw) {
                o.bag.write(
                    topics::EGO_TWIST,
                    &msgs::twist_stamped_type(),
                    host,
                    host,
                    &msgs::twist_stamped(host, "base_link", [v, 0.0, 0.0], [0.0, 0.0, w]),
                )?;
            }
        }
        Ok(())
    }
}

fn write_scan(
    o: &mut Output<'_>,
    packets: &[hilrig_stamp::Stamped<RawDataPacket>],
) -> Result<(), RecordError> {
    let Some(first) = packets.first() else {
        return Ok(());
    };
    let list: Vec<(UtcNanos, &[u8; 1206])> = packets
        .iter()
        .map(|p| (p.sensor.unwrap_or(p.host), &*p.value.0))
        .collect();
    let stamp = first.sensor.unwrap_or(first.host);
    let publish = packets.last().map_or(first.host, |p| p.host);
    let cdr = msgs::velodyne_scan(stamp, &o.frame_lidar, &list);
    o.bag.write(
        topics::VELODYNE_PACKETS,
        &msgs::velodyne_scan_type(),
        stamp,
        publish,
        &cdr,
    )?;
    if let Some(d) = &o.points {
        let cdr = cloud_cdr(d, stamp, &o.frame_lidar, &list);
        o.bag.write(
            topics::POINTS,
            &msgs::point_cloud2_type(),
            stamp,
            publish,
            &cdr,
        )?;
    }
    Ok(())
}

/// What an input file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum InputKind {
    /// pcap or pcapng.
    Capture,
    /// A candump log (`(time) iface id#data` lines).
    Candump,
    /// A raw serial byte log (gpsd logs included), without receive times.
    Serial,
}

/// Whether a serial log is one of gpsd's: it begins with a comment line (`#` then a space or
/// the line's end), as gpsd's test logs do (`# Name: ...`). A receiver's own ASCII log whose
/// lines begin with `#` (NovAtel's `#BESTPOSA,...`) does not.
fn looks_like_gpsd_log(bytes: &[u8]) -> bool {
    matches!(bytes, [b'#', b' ' | b'\r' | b'\n', ..])
}

fn input_kind(p: &Path) -> Result<InputKind, RecordError> {
    let err = |e| RecordError::Input {
        path: p.display().to_string(),
        source: CaptureError::Io {
            offset: 0,
            source: e,
        },
    };
    let f = std::fs::File::open(p).map_err(err)?;
    let (is_capture, mut head) = hilrig_capture::reader::sniff(f).map_err(err)?;
    if is_capture {
        return Ok(InputKind::Capture);
    }
    let mut first = Vec::new();
    std::io::Read::read_to_end(&mut std::io::Read::take(&mut head, 4096), &mut first)
        .map_err(err)?;
    let text = String::from_utf8_lossy(&first);
    let line = text
        .lines()
        .find(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .unwrap_or("");
    if line.starts_with('(') && hilrig_can::candump::parse_line(line, 1).is_ok() {
        return Ok(InputKind::Candump);
    }
    Ok(InputKind::Serial)
}

/// Serial logs get interface numbers above any capture's, one per file.
const SERIAL_LOG_INTERFACE: u32 = 1 << 20;

impl Context<'_> {
    fn run_input(
        &self,
        path: &Path,
        kind: InputKind,
        src: &mut Sources,
        mut out: Option<&mut Output<'_>>,
        summary: &mut RecordSummary,
    ) -> Result<(), RecordError> {
        let err = |e| RecordError::Input {
            path: path.display().to_string(),
            source: CaptureError::Io {
                offset: 0,
                source: e,
            },
        };
        match kind {
            InputKind::Capture => self.run_capture(path, src, out, summary),
            InputKind::Candump => {
                let Some(o) = out.as_deref_mut() else {
                    return Ok(());
                };
                let text = std::fs::read_to_string(path).map_err(err)?;
                for (i, line) in text.lines().enumerate() {
                    match hilrig_can::candump::parse_line(line, i + 1) {
                        Ok(Some(lf)) => self.can(o, &lf.frame, lf.time)?,
                        Ok(None) => {}
                        Err(e) => {
                            summary
                                .input_errors
                                .push(format!("{}: {e}", path.display()));
                            break;
                        }
                    }
                }
                Ok(())
            }
            InputKind::Serial => {
                let iface = SERIAL_LOG_INTERFACE + src.framers.len() as u32;
                let bytes = std::fs::read(path).map_err(err)?;
                // A gpsd log's `#` lines are the log's comments, not the receiver's bytes; in
                // other logs they may be the receiver's (NovAtel ASCII logs begin with `#`).
                src.framers.entry(iface).or_insert_with(|| SerialState {
                    stream: GnssStream::named(path.display().to_string()),
                    ..SerialState::with(if looks_like_gpsd_log(&bytes) {
                        Framer::for_gpsd_log()
                    } else {
                        Framer::new()
                    })
                });
                for chunk in bytes.chunks(4096) {
                    self.serial(src, out.as_deref_mut(), iface, chunk, None)?;
                }
                self.finish_serial(src, out)
            }
        }
    }
}

/// Records captures into one MCAP at `output` (written as `output.active`, renamed at the end).
#[allow(
    clippy::too_many_lines,
    reason = "the two passes over all inputs, the clock models estimated between them and the metadata written after them read as one sequence; the per-input work is in Context::run_input"
)]
pub fn record_from(
    rig: &Rig,
    rig_text: &str,
    inputs: &[PathBuf],
    output: &Path,
) -> Result<RecordSummary, RecordError> {
    let mut kinds = Vec::new();
    for p in inputs {
        kinds.push(input_kind(p)?);
    }
    let model = match &rig.lidar {
        Some(l) => Some(l.model.parse::<Model>().map_err(RecordError::Rig)?),
        None => None,
    };
    let calibration = match (&rig.lidar, model) {
        (Some(l), Some(m)) => match &l.calibration {
            Some(c) => Some(
                hilrig_velodyne::Calibration::from_file(&rig.resolve(c), m)
                    .map_err(|e| RecordError::Rig(e.to_string()))?,
            ),
            None => None,
        },
        _ => None,
    };
    let (db, ego, dbc_bytes) = match &rig.can {
        Some(c) => {
            let path = rig.resolve(&c.dbc);
            let db = Database::from_file(&path).map_err(|e| RecordError::Rig(e.to_string()))?;
            let ego = EgoTracker::new(&c.ego, &db).map_err(|e| RecordError::Rig(e.to_string()))?;
            let bytes = std::fs::read(&path).unwrap_or_default();
            (Some(db), Some(ego), Some((path, bytes)))
        }
        None => (None, None, None),
    };
    let ctx = Context {
        rig,
        model,
        decoder: model.map(|m| match &calibration {
            Some(c) => Decoder::with_calibration(m, c.clone()),
            None => Decoder::new(m),
        }),
        db,
        ego,
    };
    let mut summary = RecordSummary::default();

    // Pass 1: clock models.
    let mut src = Sources::new();
    for (p, k) in inputs.iter().zip(&kinds) {
        ctx.run_input(p, *k, &mut src, None, &mut summary)?;
    }
    let src_hours = src.hours.clone();
    let first_fix = src.first_fix;
    let pass1_pps = src.pps_byte;
    let pass1_hour_source = src.hour_source;
    // Pass 1 has seen every lidar packet: when none will be recorded, say why before writing
    // anything. Pass 2 resolves hours with the RMC pass 1 found (if any) from the start, so
    // pass 1's "no hour" rejects stand only when there was none.
    if let Some(m) = model {
        let mut rejects = std::mem::take(&mut src.rejects);
        if src.hours.has_rmc() {
            rejects.counts.remove(&RejectReason::NoHour);
            rejects.first.remove(&RejectReason::NoHour);
        }
        let no_hour = rejects.counts.get(&RejectReason::NoHour).copied();
        let recordable = src.lidar_checked - no_hour.unwrap_or(0);
        if recordable == 0 && rejects.data_packets() > 0 {
            return Err(RecordError::LidarRejected { model: m, rejects });
        }
    }
    let lidar_model = src.lidar_clock.model();
    let gnss_model = src.gnss_clock.model();
    for (name, est) in [("lidar", &src.lidar_clock), ("gnss", &src.gnss_clock)] {
        if let Some(m) = est.model() {
            let r = est.residuals();
            summary.clocks.push((name.to_owned(), m, r, est.pairs()));
        }
    }

    // Pass 2: write.
    let rec = &rig.recording;
    let options = rec.bag_options();
    let bag = BagWriter::create(output, &options)?;
    let mut out = Output {
        bag,
        lidar: lidar_model,
        gnss: gnss_model,
        rotation: None,
        cut: rig
            .lidar
            .as_ref()
            .zip(model)
            .map(|(l, m)| ((l.cut_azimuth_deg * 100.0).round() as u16, m)),
        points: ctx.decoder.clone().filter(|_| rig.recording.points),
        frame_lidar: rig
            .lidar
            .as_ref()
            .map_or("velodyne".into(), |l| l.frame_id.clone()),
        frame_gnss: rig
            .gnss
            .as_ref()
            .map_or("gnss".into(), |g| g.frame_id.clone()),
        attitude_untimed: 0,
        last_speed: None,
        last_yaw: None,
        rig,
    };
    let start = UtcNanos::EPOCH;
    out.bag
        .attach("rig.toml", "application/toml", rig_text.as_bytes(), start)?;
    if let Some((path, bytes)) = &dbc_bytes {
        let name = path
            .file_name()
            .map_or("can.dbc".into(), |n| n.to_string_lossy().into_owned());
        out.bag.attach(&name, "text/plain", bytes, start)?;
    }
    if let Some(c) = rig.lidar.as_ref().and_then(|l| l.calibration.as_ref()) {
        let path = rig.resolve(c);
        let bytes = std::fs::read(&path)
            .map_err(|e| RecordError::Rig(format!("calibration {}: {e}", path.display())))?;
        out.bag
            .attach("lidar-calibration.yaml", "application/yaml", &bytes, start)?;
    }
    // Metadata first: a recording cut off later still says what it is and how it was synced.
    let mut meta = BTreeMap::new();
    meta.insert("rig".to_owned(), rig.name.clone());
    meta.insert(
        "hilrig_version".to_owned(),
        env!("CARGO_PKG_VERSION").to_owned(),
    );
    meta.insert(
        "inputs".to_owned(),
        inputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(";"),
    );
    out.bag.metadata("hilrig", meta)?;
    for (name, m, r, pairs) in &summary.clocks {
        let mut sync = crate::record::clock::metadata(m, r, *pairs);
        if name == "lidar" {
            sync.hour_source = pass1_hour_source.map(|s| format!("{s:?}"));
            let reports = model != Some(Model::Hdl32e);
            sync.pps = pass1_pps.map(|b| hilrig_velodyne::PpsStatus::from_byte(b, reports));
        }
        out.bag.metadata(
            &crate::bag::clock_sync::record_name(name),
            sync.to_metadata(),
        )?;
    }
    // Pass 1 has seen the position packets: resolve hours with their RMC from the first packet.
    let pass1_hours = src_hours.clone();
    // The rig's extrinsics, stamped at the start of the data.
    let first = summary
        .clocks
        .iter()
        .map(|(_, m, _, _)| m.to_host(m.reference))
        .min()
        .unwrap_or(UtcNanos::EPOCH);
    out.bag.write_static(
        topics::TF_STATIC,
        &msgs::tf_message_type(),
        first,
        &msgs::tf_message(first, &rig.transforms()),
    )?;
    let mut src = Sources::new();
    src.hours = pass1_hours;
    src.first_fix = first_fix;
    for (p, k) in inputs.iter().zip(&kinds) {
        if let Some(r) = out.rotation.as_mut() {
            r.loss_mut().next_input();
        }
        ctx.run_input(p, *k, &mut src, Some(&mut out), &mut summary)?;
    }
    if let Some(mut rot) = out.rotation.take() {
        if let Some(done) = rot.finish() {
            write_scan(&mut out, &done.packets)?;
        }
        let loss = rot.loss();
        summary.lidar_lost = loss.lost;
        summary.lidar_outages = loss.outages;
        summary.lidar_time_jumps = loss.time_jumps;
        summary.lidar_input_pauses = loss.input_pauses;
    }
    // The serial streams' ends: a frame cut off there is bytes in no frame, recorded as they
    // came (and a valid frame its bogus length had swallowed is found).
    let ends: Vec<(u32, Option<UtcNanos>)> = src
        .framers
        .iter_mut()
        .map(|(i, s)| {
            s.framer.finish();
            (*i, if s.timeless { None } else { s.last_receive })
        })
        .collect();
    for (iface, host) in ends {
        ctx.serial(&mut src, Some(&mut out), iface, &[], host)?;
    }
    // The frames found there may open an epoch: it ends with the stream.
    ctx.finish_serial(&mut src, Some(&mut out))?;
    summary.lidar_rejects = std::mem::take(&mut src.rejects);
    summary.gnss_rejects = std::mem::take(&mut src.gnss_rejects);
    summary.gnss_undecoded = std::mem::take(&mut src.gnss_undecoded);
    summary.gnss_streams = src
        .framers
        .values_mut()
        .map(|s| {
            s.stream.framed_by(&s.framer);
            std::mem::take(&mut s.stream)
        })
        .collect();
    summary.attitude_untimed = out.attitude_untimed;
    let mut meta = BTreeMap::new();
    meta.insert(
        "gnss_attitude_untimed".to_owned(),
        summary.attitude_untimed.to_string(),
    );
    meta.insert(
        "lidar_lost_packets".to_owned(),
        summary.lidar_lost.to_string(),
    );
    meta.insert(
        "lidar_outages".to_owned(),
        summary.lidar_outages.to_string(),
    );
    meta.insert(
        "lidar_time_jumps".to_owned(),
        summary.lidar_time_jumps.to_string(),
    );
    meta.insert(
        "lidar_input_pauses".to_owned(),
        summary.lidar_input_pauses.to_string(),
    );
    meta.insert("input_errors".to_owned(), summary.input_errors.join("; "));
    if model.is_some() {
        summary.lidar_rejects.write_metadata(&mut meta);
    }
    summary.gnss_rejects.write_metadata(&mut meta);
    summary.gnss_undecoded.write_metadata(&mut meta);
    GnssStream::write_metadata(&summary.gnss_streams, &mut meta);
    summary.capture_records.write_metadata(&mut meta);
    out.bag.metadata("hilrig/end", meta)?;
    summary.counts = out.bag.finish()?;
    Ok(summary)
}
