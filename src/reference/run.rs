//! A recorded run as `check` needs it: GNSS epochs (re-parsed from the raw NMEA/UBX streams, so
//! that RTK state, sigmas and correction age are the receiver's own), ego motion, lidar packet
//! timing, position-packet PPS states, clock-synchronisation metadata and the rig file.

use crate::bag::cdr::CdrReader;
use crate::bag::clock_sync::ClockSync;
use crate::bag::read::{read, read_stream, Event};
use crate::bag::topics;
use hilrig_gnss::{Fix, GnssStream};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{PositionPacket, PpsStatus, DATA_PACKET_SIZE};
use std::collections::BTreeMap;
use std::path::Path;

/// One ego-motion sample (from the DBC mapping, `/ego/twist`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// When the CAN frame arrived: the log time (the logger's clock), on GNSS time where the
    /// run puts its logger times on it ([`Run::logger_clock`]).
    pub t: UtcNanos,
    /// Forward speed, m/s.
    pub speed: f64,
    /// Yaw rate, rad/s (counter-clockwise positive).
    pub yaw_rate: f64,
}

/// One lidar data packet's timing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PacketTime {
    /// The packet's stamp: its sensor time on the logger's clock, as the recorder wrote it
    /// (on GNSS time like [`Motion::t`]).
    pub host: UtcNanos,
    /// The sensor's own stamp, µs past the hour.
    pub sensor_us: u32,
}

/// One lidar scan of a run, without its packets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanIndex {
    /// The scan header's stamp (on GNSS time like [`Motion::t`]).
    pub stamp: UtcNanos,
    /// Its data packets.
    pub packets: u32,
    /// Its first and last packet's receive stamps (as [`crate::bag::scans::Scan::span`]).
    pub span: (UtcNanos, UtcNanos),
}

/// A run, read from an MCAP recording.
#[derive(Clone, Debug, Default)]
pub struct Run {
    /// GNSS epochs with the host time of their last sentence (on GNSS time like
    /// [`Motion::t`]).
    pub fixes: Vec<(UtcNanos, Fix)>,
    /// Ego motion.
    pub motion: Vec<Motion>,
    /// Classic CAN frames: host time (on GNSS time like [`Motion::t`]) and identifier.
    pub can_frames: Vec<(UtcNanos, u32)>,
    /// Lidar data packets.
    pub packets: Vec<PacketTime>,
    /// The lidar scans (`/velodyne_packets` messages) in file order: where each lies and how
    /// many packets it holds, without the packets.
    pub scans: Vec<ScanIndex>,
    /// Position packets: log time (on GNSS time like [`Motion::t`]) and PPS state.
    pub pps: Vec<(UtcNanos, PpsStatus)>,
    /// Metadata records by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// What stopped the reading early (damage), if anything.
    pub damage: Option<String>,
    /// The rig file attached by the recorder, if any.
    pub rig_toml: Option<String>,
    /// Attitude reports of the reference system (INS, dual antenna), decoded from the raw GNSS
    /// topics, with the host time they were received at (on GNSS time like [`Motion::t`]).
    pub attitudes: Vec<(UtcNanos, hilrig_gnss::Attitude)>,
    /// GNSS messages of the raw topics that were not used, counted (the recording keeps them).
    pub gnss_rejected: GnssRejected,
    /// How far the logger's clock ran ahead of GNSS time by the PPS-locked lidar's clock
    /// model, ns (at the lidar's first packet; its transport latency and its own timing error
    /// included).
    pub logger_ahead_of_gnss_ns: Option<i64>,
    /// The model the times on the logger's clock were put on GNSS time with, where they were
    /// (see `Run::logger_times_on_gnss_time`): the logger's clock was off beyond what the
    /// lidar's own timing could be. Files read beside the run (its scans streamed, a
    /// re-simulation's) still carry the logger's clock and go through it too.
    pub logger_clock: LoggerClock,
}

/// The mapping of a run's logger-clock times onto GNSS time: the PPS-locked lidar's clock
/// model where the run put its logger times on GNSS time, else none (the times stay).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoggerClock {
    /// What the run could tell of the logger's clock, and so what it did.
    pub state: LoggerClockState,
    model: Option<ClockSync>,
}

/// What a run could tell of its logger's clock against GNSS time (CAN frames carry the
/// logger's clock, fixes GNSS time), and so whether its logger times were put on GNSS time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoggerClockState {
    /// No PPS-locked lidar with a clock model: nothing tells the logger's clock from GNSS time.
    #[default]
    Unknown,
    /// The lidar's clock model puts the logger within [`LOGGER_OFF_NS`] of GNSS time, which
    /// cannot be told from the lidar's own timing being off: the times stay.
    WithinLidarTiming,
    /// Beyond [`LOGGER_OFF_NS`], but the GNSS receiver's clock model does not agree (or the
    /// recording has none): the times stay.
    GnssModelDisagrees,
    /// Beyond [`LOGGER_OFF_NS`], confirmed by the GNSS receiver's clock model: every logger
    /// time of the run was put on GNSS time with the lidar's model.
    PutOnGnssTime,
}

impl LoggerClockState {
    /// What it says, for a report or a fault: `ahead_ms` is the lidar model's logger offset,
    /// `gnss_ahead_ms` the GNSS receiver model's (host minus GNSS time, its output latency
    /// included).
    pub fn describe(self, ahead_ms: Option<f64>, gnss_ahead_ms: Option<f64>) -> String {
        let limit = LOGGER_OFF_NS as f64 * 1e-6;
        // An offset as "N ms ahead of" or "N ms behind" GNSS time, by its sign.
        let off = |ms: f64| {
            format!(
                "{:.1} ms {}",
                ms.abs(),
                if ms < 0.0 { "behind" } else { "ahead of" }
            )
        };
        let by = ahead_ms.map_or(String::new(), |o| {
            format!(
                "the PPS-locked lidar's clock model puts the logger's clock {} GNSS time (its transport latency included)",
                off(o)
            )
        });
        match self {
            LoggerClockState::Unknown => "without a PPS-locked lidar clock model the run cannot tell the logger's clock from GNSS time: a logger off UTC (no NTP or PTP sync) reads as a GNSS time offset".to_owned(),
            LoggerClockState::WithinLidarTiming => format!(
                "{by}; CAN stays on the logger's clock: within {limit:.0} ms a logger off UTC (no NTP or PTP sync) cannot be told from the lidar's own clock being off"
            ),
            LoggerClockState::GnssModelDisagrees => format!(
                "{by}; CAN stays on the logger's clock: {}",
                gnss_ahead_ms.map_or("the recording has no GNSS clock model to confirm it".to_owned(), |g| format!(
                    "the GNSS receiver's clock model puts it {} GNSS time, which is not the lidar's figure plus an output latency of up to 500 ms",
                    off(g)
                ))
            ),
            LoggerClockState::PutOnGnssTime => format!(
                "{by}; every logger time of the run, CAN among them, was put on GNSS time with that model, so a time offset left is the GNSS receiver's or the lidar's own"
            ),
        }
    }
}

impl LoggerClock {
    /// A logger clock that a run's times were put on GNSS time from with `model` (the
    /// PPS-locked lidar's clock model).
    pub fn put_on_gnss_time_with(model: ClockSync) -> LoggerClock {
        LoggerClock {
            state: LoggerClockState::PutOnGnssTime,
            model: Some(model),
        }
    }

    /// Whether the run's logger times were put on GNSS time.
    pub fn on_gnss(&self) -> bool {
        self.model.is_some()
    }

    /// A time of a file on the logger's clock (a scan's stamp, a packet's receive time) as the
    /// run holds it: on GNSS time where the run's times are, else as it is.
    pub fn gnss_time_of(&self, logger: UtcNanos) -> UtcNanos {
        match &self.model {
            Some(clock) => UtcNanos(clock.sensor_of_host(logger.0)),
            None => logger,
        }
    }
}

/// How far off GNSS time the PPS-locked lidar's clock model must put the logger's clock before
/// the run's logger times are put on GNSS time with it: twice the largest lidar time offset
/// the gap workflow's benches hide (50 ms, `benches/gap_hidden.py`: stamps taken at output, a
/// misconfigured clock), which the model cannot tell from a logger's.
pub const LOGGER_OFF_NS: i64 = 100_000_000;

/// GNSS messages that a run holds but that give nothing: counted, named, never used.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GnssRejected {
    /// Sentences and frames that did not frame (a checksum that fails, a broken frame).
    pub not_framed: u64,
    /// Messages that framed but did not decode (a field out of its range, NaN, too short).
    pub not_decoded: u64,
    /// Attitude messages their own flags mark invalid, by message.
    pub invalid_attitudes: BTreeMap<&'static str, u64>,
}

/// Why a run cannot be read at all.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Unreadable.
    #[error("cannot read {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// Not an MCAP.
    #[error("{0}: not an MCAP recording (a run is what `hilrig record` writes)")]
    NotMcap(String),
    /// The rig file the recorder attached does not read.
    #[error("{path}: the attached rig.toml: {source}")]
    AttachedRig {
        /// The recording.
        path: String,
        /// Why.
        #[source]
        source: crate::rig::RigError,
    },
    /// No rig given and none attached.
    #[error("{0}: no rig.toml attached to the recording: give the rig file (--rig)")]
    NoRig(String),
}

/// The run of a recording and its rig: `rig` when given, else the rig file the recorder
/// attached. What re-simulation and comparison start from; the error says what is wrong and
/// with which file. The recording is read as a stream: its scans are indexed, not kept.
pub fn load_with_rig(
    path: &Path,
    rig: Option<&crate::rig::Rig>,
) -> Result<(Run, crate::rig::Rig), RunError> {
    let run = Run::read(path)?;
    let rig = match (rig, &run.rig_toml) {
        (Some(r), _) => r.clone(),
        (None, Some(text)) => {
            crate::rig::Rig::from_toml(text, "rig.toml attached to the recording").map_err(
                |source| RunError::AttachedRig {
                    path: path.display().to_string(),
                    source,
                },
            )?
        }
        (None, None) => return Err(RunError::NoRig(path.display().to_string())),
    };
    Ok((run, rig))
}

/// Collects a [`Run`] from the events of a recording, in file order.
struct Collector {
    run: Run,
    nmea: GnssStream,
    ubx: GnssStream,
    fixes: Vec<Fix>,
}

impl Default for Collector {
    fn default() -> Collector {
        Collector {
            run: Run::default(),
            nmea: GnssStream::default().with_attitude(),
            ubx: GnssStream::default().with_attitude(),
            fixes: Vec::new(),
        }
    }
}

impl Collector {
    fn event(&mut self, event: Event<'_>) {
        let run = &mut self.run;
        match event {
            Event::Metadata { name, values } => {
                run.metadata.insert(name.to_owned(), values.clone());
            }
            Event::Attachment { name, data } => {
                if name == "rig.toml" {
                    run.rig_toml = String::from_utf8(data.to_vec()).ok();
                }
            }
            Event::Message(m) => {
                let host = UtcNanos(m.publish_time as i64);
                // Every message of the recorder's topics starts with a std_msgs/Header.
                let Some(mut c) = CdrReader::new(m.data) else {
                    return;
                };
                let Some(stamp) = c.header() else {
                    return;
                };
                match m.channel.topic.as_str() {
                    topics::GNSS_NMEA => {
                        if let Some(s) = c.string() {
                            let line = format!("{s}\r\n");
                            self.nmea.push(line.as_bytes(), &mut self.fixes);
                            run.fixes.extend(self.fixes.drain(..).map(|f| (host, f)));
                            run.attitudes
                                .extend(self.nmea.take_attitudes().into_iter().map(|a| (host, a)));
                        }
                    }
                    topics::GNSS_UBX => {
                        if let Some(n) = c.u32() {
                            if let Some(b) = c.bytes(n as usize) {
                                self.ubx.push(b, &mut self.fixes);
                                run.fixes.extend(self.fixes.drain(..).map(|f| (host, f)));
                                run.attitudes.extend(
                                    self.ubx.take_attitudes().into_iter().map(|a| (host, a)),
                                );
                            }
                        }
                    }
                    topics::CAN_FRAMES
                        if m.channel
                            .schema
                            .as_ref()
                            .is_some_and(|s| s.name == "can_msgs/msg/Frame") =>
                    {
                        if let Some(id) = c.u32() {
                            run.can_frames.push((host, id));
                        }
                    }
                    topics::EGO_TWIST => {
                        let v: Option<Vec<f64>> = (0..6).map(|_| c.f64()).collect();
                        if let Some(v) = v {
                            run.motion.push(Motion {
                                t: UtcNanos(m.log_time as i64),
                                speed: v[0],
                                yaw_rate: v[5],
                            });
                        }
                    }
                    topics::VELODYNE_PACKETS => {
                        let n = c.u32().unwrap_or(0);
                        let first = run.packets.len();
                        for _ in 0..n {
                            let (Some(stamp), Some(data)) = (c.time(), c.bytes(DATA_PACKET_SIZE))
                            else {
                                break;
                            };
                            let sensor_us = u32::from_le_bytes([
                                data[1200], data[1201], data[1202], data[1203],
                            ]);
                            run.packets.push(PacketTime {
                                host: stamp,
                                sensor_us,
                            });
                        }
                        let packets = &run.packets[first..];
                        let last = packets.last().map_or(stamp, |p| p.host);
                        run.scans.push(ScanIndex {
                            stamp,
                            packets: packets.len() as u32,
                            span: (stamp.min(last), stamp.max(last)),
                        });
                    }
                    topics::VELODYNE_POSITION => {
                        if let Some(n) = c.u32() {
                            if let Some(Ok(p)) = c.bytes(n as usize).map(PositionPacket::decode) {
                                run.pps.push((
                                    UtcNanos(m.log_time as i64),
                                    PpsStatus::from_byte(p.pps_byte, true),
                                ));
                            }
                        }
                    }
                    _ => {}
                }
            }
        }
    }

    fn finish(mut self, result: Result<(), crate::bag::read::ReadError>) -> Run {
        let mut run = self.run;
        self.nmea.finish(&mut self.fixes);
        self.ubx.finish(&mut self.fixes);
        for s in [&self.nmea, &self.ubx] {
            let r = &mut run.gnss_rejected;
            r.not_framed += s.framer.stats.rejected;
            r.not_decoded += s.stats.nmea_errors + s.stats.ubx_errors;
            for (k, n) in &s.stats.invalid_attitudes {
                *r.invalid_attitudes.entry(k).or_default() += n;
            }
        }
        let last = run.fixes.last().map_or(UtcNanos(0), |f| f.0);
        run.fixes.extend(self.fixes.drain(..).map(|f| (last, f)));
        run.damage = result.err().map(|e| e.to_string());
        run.logger_times_on_gnss_time();
        // Sorted once every time is on one clock (a fix without UTC sorts by its host time).
        run.fixes.sort_by_key(|(h, f)| f.time.unwrap_or(*h));
        run.motion.sort_by_key(|m| m.t);
        run.packets.sort_by_key(|p| p.host);
        run
    }
}

impl Run {
    /// CAN frames carry no clock of their own: the recorder stamps them, and the ego motion
    /// decoded from them, with the logger's clock. GNSS fixes carry GNSS time, and so do a
    /// PPS-locked lidar's packets. A logger whose clock is not on UTC (no NTP or PTP on the
    /// vehicle, or not yet settled) sets the motion off the fixes by its offset, and `check`
    /// reads that as GNSS time stamps off the vehicle's motion (a drive of another generator
    /// with the logger 2.5 s ahead raised jumps at every epoch and a lever arm 2 m off).
    ///
    /// The PPS-locked lidar's clock model tells how far the logger's clock is off GNSS time,
    /// to within the lidar's transport latency and its own timing error. That error can be
    /// tens of milliseconds (a stamp taken at output, not at firing: the catalogue's lidar
    /// time offset, which the gap workflow fits against the trajectory and which must not move
    /// the trajectory itself), so the model alone cannot tell a logger 50 ms ahead from a lidar
    /// 50 ms late. Beyond [`LOGGER_OFF_NS`], and where the GNSS clock model agrees (it holds
    /// the receiver's output latency besides, so it may only be later, by up to half a
    /// second), it is the logger's clock: every time of the run on it is put on GNSS time
    /// with the lidar's model. Below, the times stay, and `check` names the logger's clock
    /// beside a GNSS time offset it finds ([`Run::logger_ahead_of_gnss_ns`]).
    fn logger_times_on_gnss_time(&mut self) {
        if !self.lidar_pps_locked() {
            return;
        }
        let Some(lidar) = self.clock_sync("lidar") else {
            return;
        };
        // The model's offset is at its reference, the lidar's first packet.
        self.logger_ahead_of_gnss_ns = Some(lidar.offset_ns);
        let later = self
            .clock_sync("gnss")
            .map(|g| g.offset_ns - lidar.offset_ns);
        self.logger_clock.state = if lidar.offset_ns.abs() < LOGGER_OFF_NS {
            LoggerClockState::WithinLidarTiming
        } else if !later.is_some_and(|l| (-5_000_000..=500_000_000).contains(&l)) {
            LoggerClockState::GnssModelDisagrees
        } else {
            LoggerClockState::PutOnGnssTime
        };
        if self.logger_clock.state != LoggerClockState::PutOnGnssTime {
            return;
        }
        // Every time of the run on the logger's clock, so that all of them stay comparable:
        // the lidar's packet stamps are their GNSS time mapped onto the logger's clock by this
        // very model and come back to it; the receive times of packets, frames and sentences
        // come to GNSS time plus their transport latency.
        let logger = LoggerClock::put_on_gnss_time_with(lidar);
        let on_gnss = |t: &mut UtcNanos| *t = logger.gnss_time_of(*t);
        for m in &mut self.motion {
            on_gnss(&mut m.t);
        }
        for (t, _) in &mut self.can_frames {
            on_gnss(t);
        }
        for (t, _) in &mut self.fixes {
            on_gnss(t);
        }
        for (t, _) in &mut self.attitudes {
            on_gnss(t);
        }
        for p in &mut self.packets {
            on_gnss(&mut p.host);
        }
        for s in &mut self.scans {
            on_gnss(&mut s.stamp);
            on_gnss(&mut s.span.0);
            on_gnss(&mut s.span.1);
        }
        for (t, _) in &mut self.pps {
            on_gnss(t);
        }
        self.logger_clock = logger;
    }

    /// The clock model a source's clock-sync record holds, if it reads.
    pub fn clock_sync(&self, source: &str) -> Option<ClockSync> {
        self.metadata
            .get(&crate::bag::clock_sync::record_name(source))
            .and_then(|v| ClockSync::from_metadata(source, v).ok())
    }

    /// Whether the lidar's packet stamps are GNSS time: the recorder found its PPS locked and
    /// wrote so into the lidar's clock-sync record ([`ClockSync`]; its PPS state is read alone,
    /// so that another key of the record that does not read cannot unlock it). Without that
    /// record the packets' stamps are the host's.
    pub fn lidar_pps_locked(&self) -> bool {
        self.metadata
            .get(&crate::bag::clock_sync::record_name("lidar"))
            .and_then(ClockSync::pps_of)
            == Some(hilrig_velodyne::PpsStatus::Locked)
    }

    /// Reads a recording, as a stream: memory grows with its GNSS, CAN and packet-timing
    /// records, not with its lidar data.
    pub fn read(path: &Path) -> Result<Run, RunError> {
        let io = |source| RunError::Io {
            path: path.display().to_string(),
            source,
        };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let mut magic = [0u8; 8];
        {
            use std::io::{Read, Seek};
            if file.read_exact(&mut magic).is_err() || magic[..] != mcap::MAGIC[..] {
                return Err(RunError::NotMcap(path.display().to_string()));
            }
            file.rewind().map_err(io)?;
        }
        let mut collector = Collector::default();
        let result = read_stream(
            std::io::BufReader::with_capacity(1 << 20, file),
            len,
            &mut |event| {
                collector.event(event);
                Ok(())
            },
        );
        Ok(collector.finish(result))
    }

    /// Reads a recording held in memory (a damaged one up to the damage).
    pub fn from_bytes(bytes: &[u8]) -> Run {
        let mut collector = Collector::default();
        let result = read(bytes, &mut |event| {
            collector.event(event);
            Ok(())
        });
        collector.finish(result)
    }
}
