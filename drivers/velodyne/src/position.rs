//! The 512-byte position (GPS) packet on port 8308 and the NMEA RMC sentence inside it.
//!
//! Layout (VLP-16/32C manuals; HDL-32E the same except that byte 202 is unused): timestamp
//! (µs past the hour) at 198, PPS status at 202, the NMEA sentence (GPRMC or GPGGA) NUL-padded in
//! 72 bytes at 206. Everything else is kept verbatim so that packets re-encode byte-identically.

use crate::error::DecodeError;

/// Size of a position packet's UDP payload.
pub const POSITION_PACKET_SIZE: usize = 512;
const TS_AT: usize = 198;
const PPS_AT: usize = 202;
const NMEA_AT: usize = 206;
const NMEA_LEN: usize = 72;

/// PPS state as the sensor reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PpsStatus {
    /// No PPS signal detected (byte 0 on VLP-16/32C).
    Absent,
    /// PPS detected, sensor synchronising.
    Synchronizing,
    /// PPS locked: timestamps are GPS-disciplined.
    Locked,
    /// PPS error.
    Error,
    /// The model does not report PPS in its position packet (HDL-32E: byte 202 unused).
    NotReported,
    /// A byte value no manual defines.
    Unknown(u8),
}

impl PpsStatus {
    /// Interprets byte 202 for a model (the HDL-32E leaves it unused).
    pub fn from_byte(byte: u8, reports_pps: bool) -> PpsStatus {
        if !reports_pps {
            return PpsStatus::NotReported;
        }
        match byte {
            0 => PpsStatus::Absent,
            1 => PpsStatus::Synchronizing,
            2 => PpsStatus::Locked,
            3 => PpsStatus::Error,
            b => PpsStatus::Unknown(b),
        }
    }
}

/// A decoded position packet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PositionPacket {
    /// Microseconds past the hour of the packet.
    pub timestamp_us: u32,
    /// Raw PPS byte (interpret with [`PpsStatus::from_byte`]).
    pub pps_byte: u8,
    /// The NMEA field, NUL-padded as sent.
    pub nmea_field: [u8; NMEA_LEN],
    raw: Box<[u8; POSITION_PACKET_SIZE]>,
}

impl PositionPacket {
    /// Decodes a UDP payload of 512 bytes.
    pub fn decode(bytes: &[u8]) -> Result<PositionPacket, DecodeError> {
        let raw: [u8; POSITION_PACKET_SIZE] =
            bytes.try_into().map_err(|_| DecodeError::WrongSize {
                expected: POSITION_PACKET_SIZE,
                got: bytes.len(),
            })?;
        let mut nmea_field = [0u8; NMEA_LEN];
        nmea_field.copy_from_slice(&raw[NMEA_AT..NMEA_AT + NMEA_LEN]);
        Ok(PositionPacket {
            timestamp_us: u32::from_le_bytes([
                raw[TS_AT],
                raw[TS_AT + 1],
                raw[TS_AT + 2],
                raw[TS_AT + 3],
            ]),
            pps_byte: raw[PPS_AT],
            nmea_field,
            raw: Box::new(raw),
        })
    }

    /// A packet with the given fields and zeros elsewhere (for synthesis and `--now` replay).
    pub fn new(timestamp_us: u32, pps: PpsStatus, nmea: &str) -> PositionPacket {
        let mut nmea_field = [0u8; NMEA_LEN];
        let n = nmea.len().min(NMEA_LEN);
        nmea_field[..n].copy_from_slice(&nmea.as_bytes()[..n]);
        let pps_byte = match pps {
            PpsStatus::Absent | PpsStatus::NotReported => 0,
            PpsStatus::Synchronizing => 1,
            PpsStatus::Locked => 2,
            PpsStatus::Error => 3,
            PpsStatus::Unknown(b) => b,
        };
        let mut p = PositionPacket {
            timestamp_us,
            pps_byte,
            nmea_field,
            raw: Box::new([0u8; POSITION_PACKET_SIZE]),
        };
        p.raw = Box::new(p.encode());
        p
    }

    /// Encodes to 512 bytes.
    pub fn encode(&self) -> [u8; POSITION_PACKET_SIZE] {
        let mut out = *self.raw;
        out[TS_AT..TS_AT + 4].copy_from_slice(&self.timestamp_us.to_le_bytes());
        out[PPS_AT] = self.pps_byte;
        out[NMEA_AT..NMEA_AT + NMEA_LEN].copy_from_slice(&self.nmea_field);
        out
    }

    /// The NMEA sentence without padding and line end, if it is text.
    pub fn nmea(&self) -> Option<&str> {
        let end = self
            .nmea_field
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(NMEA_LEN);
        let s = std::str::from_utf8(&self.nmea_field[..end]).ok()?;
        let s = s.trim_end_matches(['\r', '\n']);
        (!s.is_empty()).then_some(s)
    }

    /// The RMC sentence, if the packet carries a valid one.
    pub fn rmc(&self) -> Option<Result<Rmc, NmeaError>> {
        let s = self.nmea()?;
        if s.get(3..6) != Some("RMC") {
            return None;
        }
        Some(Rmc::parse(s))
    }
}

// The sentence inside is ordinary NMEA: the GNSS driver's parser reads it (one NMEA parser in
// hilrig, tested against gpsd on real receiver logs).
pub use hilrig_gnss::nmea::{NmeaError, Rmc};

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const MONTEREY_RMC: &str =
        "$GPRMC,220632,A,3707.8324,N,12139.2864,W,000.0,144.7,111212,013.8,E,D*09";

    #[test]
    fn rmc_of_the_monterey_capture() {
        let r = Rmc::parse(MONTEREY_RMC).unwrap();
        // 2012-12-11T22:06:32Z
        assert_eq!(
            r.utc(),
            Some(hilrig_stamp::UtcNanos(1_355_263_592 * 1_000_000_000))
        );
        assert!(r.valid);
        assert!((r.lat.unwrap() - 37.13054).abs() < 1e-5);
        assert!((r.lon.unwrap() + 121.65477).abs() < 1e-5);
        let bad = MONTEREY_RMC.replace("*09", "*0A");
        assert_eq!(
            Rmc::parse(&bad),
            Err(NmeaError::Checksum {
                expected: 0x0A,
                computed: 0x09
            })
        );
    }

    #[test]
    fn position_packet_round_trips_and_reads_fields() {
        let p = PositionPacket::new(
            393_210_381,
            PpsStatus::Locked,
            &format!("{MONTEREY_RMC}\r\n"),
        );
        let back = PositionPacket::decode(&p.encode()).unwrap();
        assert_eq!(back, p);
        assert_eq!(back.nmea(), Some(MONTEREY_RMC));
        assert_eq!(PpsStatus::from_byte(back.pps_byte, true), PpsStatus::Locked);
        assert!(back.rmc().unwrap().is_ok());
    }

    proptest! {
        #[test]
        fn position_decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            if let Ok(p) = PositionPacket::decode(&bytes) {
                let _ = p.rmc();
                prop_assert_eq!(&p.encode()[..], &bytes[..]);
            }
        }

    }
}
