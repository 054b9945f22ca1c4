//! Data the recorder left out, counted per reason: lidar packets, GNSS serial frames that
//! failed their checksum or did not frame, and GNSS messages recorded whole whose fields did
//! not decode (their fix or attitude is missing).
//!
//! Both recorders (`--from` and live) keep one [`LidarRejects`] and one [`GnssRejects`]:
//! printed at the end (the lidar's also in the live health lines), written into the
//! recording's `hilrig/end` metadata and read back from it through the same type, so that a
//! recording says itself what it is missing and why. Anything rejected makes `hilrig record`
//! exit 1.

use hilrig_gnss::framer::RejectReason as FrameReject;
use hilrig_velodyne::source::PacketPort;
use hilrig_velodyne::DecodeError;
use std::collections::BTreeMap;
use std::fmt;

/// Why a lidar packet was not recorded: the cause without the packet's details, the key the
/// packets are counted by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RejectReason {
    /// A data-port payload that is not 1206 bytes.
    WrongSize,
    /// A block flag that no Velodyne sensor writes (malformed bytes).
    BadBlockFlag,
    /// A bank flag of another model (the VLS-128's banks on a 32-laser sensor's port).
    ForeignBankFlag,
    /// A block azimuth above 36000.
    AzimuthOutOfRange,
    /// A return-mode byte no decoder reads.
    UnsupportedReturnMode,
    /// Another sensor's packet: the product byte found.
    OtherSensor(u8),
    /// A timestamp whose hour nothing gives: no position packet with a valid RMC, and the
    /// capture's clock before 2000 (unset).
    NoHour,
    /// A position-port datagram that is not a position packet.
    PositionPacket,
    /// Anything else the driver refuses.
    Other,
}

impl RejectReason {
    /// The reason a packet from `port` was refused with `error`.
    pub fn of(port: PacketPort, error: &DecodeError) -> RejectReason {
        if port == PacketPort::Position {
            return RejectReason::PositionPacket;
        }
        match error {
            DecodeError::WrongSize { .. } => RejectReason::WrongSize,
            DecodeError::BadBlockFlag { .. } => RejectReason::BadBlockFlag,
            DecodeError::ForeignBankFlag { .. } => RejectReason::ForeignBankFlag,
            DecodeError::AzimuthOutOfRange { .. } => RejectReason::AzimuthOutOfRange,
            DecodeError::UnsupportedReturnMode(_) => RejectReason::UnsupportedReturnMode,
            DecodeError::OtherSensor { got, .. } => RejectReason::OtherSensor(*got),
            _ => RejectReason::Other,
        }
    }

    /// Whether a data packet refused for this reason may be the rig's own sensor's (damaged,
    /// or its hour unknown) rather than other traffic on its port (another sensor, another
    /// model's banks, a datagram of the wrong size): only those stand for packets of the
    /// stream that came ([`hilrig_velodyne::LossCounter::rejected`]); another sensor's would
    /// hide this one's losses.
    pub fn may_be_own(self) -> bool {
        matches!(
            self,
            RejectReason::BadBlockFlag
                | RejectReason::AzimuthOutOfRange
                | RejectReason::UnsupportedReturnMode
                | RejectReason::NoHour
                | RejectReason::Other
        )
    }

    /// The name in the metadata (`wrong_size`, `other_sensor_0x22`, ...).
    pub fn key(self) -> String {
        match self {
            RejectReason::WrongSize => "wrong_size".into(),
            RejectReason::BadBlockFlag => "bad_block_flag".into(),
            RejectReason::ForeignBankFlag => "foreign_bank_flag".into(),
            RejectReason::AzimuthOutOfRange => "azimuth_out_of_range".into(),
            RejectReason::UnsupportedReturnMode => "unsupported_return_mode".into(),
            RejectReason::OtherSensor(p) => format!("other_sensor_{p:#04x}"),
            RejectReason::NoHour => "no_hour".into(),
            RejectReason::PositionPacket => "position_packet".into(),
            RejectReason::Other => "other".into(),
        }
    }

    /// The reason named by [`RejectReason::key`].
    pub fn from_key(key: &str) -> Option<RejectReason> {
        Some(match key {
            "wrong_size" => RejectReason::WrongSize,
            "bad_block_flag" => RejectReason::BadBlockFlag,
            "foreign_bank_flag" => RejectReason::ForeignBankFlag,
            "azimuth_out_of_range" => RejectReason::AzimuthOutOfRange,
            "unsupported_return_mode" => RejectReason::UnsupportedReturnMode,
            "no_hour" => RejectReason::NoHour,
            "position_packet" => RejectReason::PositionPacket,
            "other" => RejectReason::Other,
            k => {
                let hex = k.strip_prefix("other_sensor_0x")?;
                RejectReason::OtherSensor(u8::from_str_radix(hex, 16).ok()?)
            }
        })
    }

    /// Whether the reason concerns a data packet (not a position packet).
    pub fn is_data(self) -> bool {
        self != RejectReason::PositionPacket
    }
}

impl fmt::Display for RejectReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RejectReason::WrongSize => f.write_str("wrong size"),
            RejectReason::BadBlockFlag => f.write_str("bad block flag"),
            RejectReason::ForeignBankFlag => f.write_str("another model's bank flag"),
            RejectReason::AzimuthOutOfRange => f.write_str("azimuth out of range"),
            RejectReason::UnsupportedReturnMode => f.write_str("unsupported return mode"),
            RejectReason::OtherSensor(p) => write!(f, "another sensor (product byte {p:#04x})"),
            RejectReason::NoHour => f.write_str("no hour for the timestamp"),
            RejectReason::PositionPacket => f.write_str("bad position packet"),
            RejectReason::Other => f.write_str("other"),
        }
    }
}

/// A reason the recorder counts left-out data by.
pub trait Reason: Copy + Ord {
    /// Metadata key of the total (in `hilrig/end`); per reason `TOTAL.KEY`, and its first
    /// occurrence `TOTAL.KEY.first`.
    const TOTAL: &'static str;
    /// The key of this reason in the metadata.
    fn key(self) -> String;
    /// The reason named by [`Reason::key`].
    fn from_key(key: &str) -> Option<Self>;
    /// The reason in words.
    fn describe(self) -> String;
}

impl Reason for RejectReason {
    const TOTAL: &'static str = "lidar_rejected";
    fn key(self) -> String {
        RejectReason::key(self)
    }
    fn from_key(key: &str) -> Option<Self> {
        RejectReason::from_key(key)
    }
    fn describe(self) -> String {
        self.to_string()
    }
}

/// Why the GNSS framer refused a candidate frame: it is then not in the recording (the bytes
/// are skipped and framing goes on).
impl Reason for FrameReject {
    const TOTAL: &'static str = "gnss_rejected";
    fn key(self) -> String {
        match self {
            FrameReject::NmeaChecksum => "nmea_checksum",
            FrameReject::NmeaMalformed => "nmea_malformed",
            FrameReject::UbxChecksum => "ubx_checksum",
            FrameReject::Rtcm3Crc => "rtcm3_crc",
        }
        .into()
    }
    fn from_key(key: &str) -> Option<Self> {
        Some(match key {
            "nmea_checksum" => FrameReject::NmeaChecksum,
            "nmea_malformed" => FrameReject::NmeaMalformed,
            "ubx_checksum" => FrameReject::UbxChecksum,
            "rtcm3_crc" => FrameReject::Rtcm3Crc,
            _ => return None,
        })
    }
    fn describe(self) -> String {
        match self {
            FrameReject::NmeaChecksum => "NMEA sentence with a wrong checksum",
            FrameReject::NmeaMalformed => {
                "NMEA sentence malformed (non-printable bytes, no *hh, too long)"
            }
            FrameReject::UbxChecksum => "UBX frame with a wrong checksum",
            FrameReject::Rtcm3Crc => "RTCM3 frame with a wrong CRC",
        }
        .into()
    }
}

/// Why a GNSS message that framed and passed its checksum did not decode: a sentence or
/// message of a kind the recorder reads (GGA, RMC, GST, HDT, ...; NAV-PVT, NAV-ATT, ...) whose
/// fields do not read. It is in the recording (`/gnss/nmea`, `/gnss/ubx`), but the fix or
/// attitude it carried is not on `/gnss/fix` or `/gnss/attitude`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Undecoded {
    /// An NMEA sentence with a field that does not read, or too few fields.
    NmeaFields,
    /// A UBX message of the wrong length, an unknown version, or an angle out of range.
    UbxPayload,
}

impl Reason for Undecoded {
    const TOTAL: &'static str = "gnss_undecoded";
    fn key(self) -> String {
        match self {
            Undecoded::NmeaFields => "nmea_fields",
            Undecoded::UbxPayload => "ubx_payload",
        }
        .into()
    }
    fn from_key(key: &str) -> Option<Self> {
        Some(match key {
            "nmea_fields" => Undecoded::NmeaFields,
            "ubx_payload" => Undecoded::UbxPayload,
            _ => return None,
        })
    }
    fn describe(self) -> String {
        match self {
            Undecoded::NmeaFields => "NMEA sentence whose fields do not read",
            Undecoded::UbxPayload => "UBX message whose payload does not read",
        }
        .into()
    }
}

/// What a recording left out: counts per reason and, per reason, where the first one was and
/// what was wrong with it (for lidar packets the full error: offsets, expected and found
/// values).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rejects<R: Reason> {
    /// Items per reason.
    pub counts: BTreeMap<R, u64>,
    /// The first item of each reason: where (file and byte offset, or receive time) and why.
    pub first: BTreeMap<R, String>,
}

/// The lidar packets a recording left out.
pub type LidarRejects = Rejects<RejectReason>;

/// The GNSS serial frames a recording left out.
pub type GnssRejects = Rejects<FrameReject>;

/// The GNSS messages a recording holds but could not decode.
pub type GnssUndecoded = Rejects<Undecoded>;

impl<R: Reason> Default for Rejects<R> {
    fn default() -> Self {
        Rejects {
            counts: BTreeMap::new(),
            first: BTreeMap::new(),
        }
    }
}

impl LidarRejects {
    /// Data packets rejected.
    pub fn data_packets(&self) -> u64 {
        self.counts
            .iter()
            .filter(|(r, _)| r.is_data())
            .map(|(_, n)| n)
            .sum()
    }
}

impl<R: Reason> Rejects<R> {
    /// Counts one item; `describe` says where it was and why (called for a reason's first
    /// item only, so counting stays cheap).
    pub fn add(&mut self, reason: R, describe: impl FnOnce() -> String) {
        *self.counts.entry(reason).or_default() += 1;
        self.first.entry(reason).or_insert_with(describe);
    }

    /// Items rejected.
    pub fn total(&self) -> u64 {
        self.counts.values().sum()
    }

    /// Nothing rejected.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// The counts in one line (`bad block flag 3, wrong size 1`), for health lines.
    pub fn brief(&self) -> String {
        self.counts
            .iter()
            .map(|(r, n)| format!("{} {n}", r.describe()))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// One line per reason with its count and first item, for the end of a recording.
    pub fn lines(&self) -> Vec<String> {
        self.counts
            .iter()
            .map(|(r, n)| match self.first.get(r) {
                Some(first) => format!("{}: {n} (first: {first})", r.describe()),
                None => format!("{}: {n}", r.describe()),
            })
            .collect()
    }

    /// Writes the counts into `meta` (the `hilrig/end` metadata); the total always, so that a
    /// recording without rejects says so.
    pub fn write_metadata(&self, meta: &mut BTreeMap<String, String>) {
        meta.insert(R::TOTAL.to_owned(), self.total().to_string());
        for (r, n) in &self.counts {
            meta.insert(format!("{}.{}", R::TOTAL, r.key()), n.to_string());
        }
        for (r, first) in &self.first {
            meta.insert(format!("{}.{}.first", R::TOTAL, r.key()), first.clone());
        }
    }

    /// Reads what [`Rejects::write_metadata`] wrote; `None` when the metadata has no reject
    /// counts (a recording by an older hilrig), an error naming the entry that does not read.
    pub fn from_metadata(meta: &BTreeMap<String, String>) -> Result<Option<Self>, MetadataError> {
        let total_key = R::TOTAL;
        let Some(total) = meta.get(total_key) else {
            return Ok(None);
        };
        let mut out = Self::default();
        let prefix = format!("{total_key}.");
        for (k, v) in meta {
            let Some(rest) = k.strip_prefix(&prefix) else {
                continue;
            };
            let (key, first) = match rest.strip_suffix(".first") {
                Some(key) => (key, true),
                None => (rest, false),
            };
            let reason = R::from_key(key).ok_or_else(|| MetadataError::UnknownReason {
                key: k.clone(),
                reason: key.to_owned(),
            })?;
            if first {
                out.first.insert(reason, v.clone());
            } else {
                let n = v.parse().map_err(|_| MetadataError::NotACount {
                    key: k.clone(),
                    value: v.clone(),
                })?;
                out.counts.insert(reason, n);
            }
        }
        let total: u64 = total.parse().map_err(|_| MetadataError::NotACount {
            key: total_key.to_owned(),
            value: total.clone(),
        })?;
        if total != out.total() {
            return Err(MetadataError::Total {
                key: total_key.to_owned(),
                total,
                sum: out.total(),
            });
        }
        Ok(Some(out))
    }
}

/// Why the reject counts of a recording's metadata do not read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MetadataError {
    /// An entry naming no reject reason.
    #[error("metadata {key}: no reject reason is called {reason}")]
    UnknownReason {
        /// The metadata key.
        key: String,
        /// The reason it names.
        reason: String,
    },
    /// A count that is not a number.
    #[error("metadata {key}: {value:?} is not a count")]
    NotACount {
        /// The metadata key.
        key: String,
        /// Its value.
        value: String,
    },
    /// A total that the reasons do not add up to.
    #[error("metadata {key} is {total} but the reasons add up to {sum}")]
    Total {
        /// The metadata key.
        key: String,
        /// The total written.
        total: u64,
        /// The sum of the reasons.
        sum: u64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use hilrig_velodyne::Model;

    #[test]
    fn reasons_round_trip_through_the_metadata() {
        let mut r = LidarRejects::default();
        let other = DecodeError::OtherSensor {
            got: 0x22,
            expected: Model::Vls128,
        };
        for i in 0..3 {
            r.add(RejectReason::of(PacketPort::Data, &other), || {
                format!("a.pcap byte {}: {other}", 24 + 1250 * i)
            });
        }
        r.add(RejectReason::NoHour, || "b".into());
        r.add(
            RejectReason::of(
                PacketPort::Position,
                &DecodeError::WrongSize {
                    expected: 512,
                    got: 3,
                },
            ),
            || "c".into(),
        );
        assert_eq!(r.total(), 5);
        assert_eq!(r.data_packets(), 4);
        // The first packet of a reason is kept, not the latest.
        assert_eq!(
            r.first[&RejectReason::OtherSensor(0x22)],
            format!("a.pcap byte 24: {other}")
        );
        let mut meta = BTreeMap::new();
        r.write_metadata(&mut meta);
        assert_eq!(meta["lidar_rejected.other_sensor_0x22"], "3");
        assert_eq!(LidarRejects::from_metadata(&meta), Ok(Some(r.clone())));
        assert!(r.brief().contains("another sensor (product byte 0x22) 3"));
        meta.insert("lidar_rejected".into(), "6".into());
        assert!(LidarRejects::from_metadata(&meta).is_err());
        assert_eq!(LidarRejects::from_metadata(&BTreeMap::new()), Ok(None));
        for reason in [
            RejectReason::WrongSize,
            RejectReason::BadBlockFlag,
            RejectReason::ForeignBankFlag,
            RejectReason::AzimuthOutOfRange,
            RejectReason::UnsupportedReturnMode,
            RejectReason::OtherSensor(0xA1),
            RejectReason::NoHour,
            RejectReason::PositionPacket,
            RejectReason::Other,
        ] {
            assert_eq!(RejectReason::from_key(&reason.key()), Some(reason));
        }
    }

    #[test]
    fn gnss_frame_rejects_round_trip_through_the_metadata() {
        let mut r = GnssRejects::default();
        r.add(FrameReject::NmeaChecksum, || "serial 0 byte 77".into());
        r.add(FrameReject::NmeaChecksum, || "serial 0 byte 901".into());
        r.add(FrameReject::UbxChecksum, || "serial 1 byte 12".into());
        assert_eq!(r.total(), 3);
        assert_eq!(r.first[&FrameReject::NmeaChecksum], "serial 0 byte 77");
        let mut meta = BTreeMap::new();
        r.write_metadata(&mut meta);
        assert_eq!(meta["gnss_rejected"], "3");
        assert_eq!(meta["gnss_rejected.nmea_checksum"], "2");
        assert_eq!(GnssRejects::from_metadata(&meta), Ok(Some(r.clone())));
        // The lidar's counts live beside them under their own keys.
        assert_eq!(LidarRejects::from_metadata(&meta), Ok(None));
        assert!(r.lines()[0]
            .starts_with("NMEA sentence with a wrong checksum: 2 (first: serial 0 byte 77)"));
        for reason in [
            FrameReject::NmeaChecksum,
            FrameReject::NmeaMalformed,
            FrameReject::UbxChecksum,
            FrameReject::Rtcm3Crc,
        ] {
            assert_eq!(
                <FrameReject as Reason>::from_key(&Reason::key(reason)),
                Some(reason)
            );
        }
    }
}
