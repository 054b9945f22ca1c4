//! The 512-byte position (GPS) packet on port 8308 and the NMEA RMC sentence inside it.
//!
//! Layout (VLP-16/32C manuals; HDL-32E the same except that byte 202 is unused): timestamp
//! (µs past the hour) at 198, PPS status at 202, the NMEA sentence (GPRMC or GPGGA) NUL-padded in
//! 72 bytes at 206. Everything else is kept verbatim so that packets re-encode byte-identically.

use crate::error::DecodeError;
use hilrig_stamp::UtcNanos;

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

/// Why an NMEA sentence was rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NmeaError {
    /// Missing `$`, `*` or checksum digits.
    #[error("not an NMEA sentence: {0}")]
    Framing(String),
    /// The checksum does not match.
    #[error("NMEA checksum mismatch: sentence says {expected:02X}, computed {computed:02X}")]
    Checksum {
        /// In the sentence.
        expected: u8,
        /// Computed over the body.
        computed: u8,
    },
    /// A field is missing or not a number.
    #[error("RMC field {field} is invalid: '{value}'")]
    Field {
        /// Field name.
        field: &'static str,
        /// Its text.
        value: String,
    },
}

/// The parts of an RMC sentence the rig needs: UTC date-time, validity, position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rmc {
    /// UTC of the fix.
    pub time: UtcNanos,
    /// Status 'A' (valid) rather than 'V'.
    pub valid: bool,
    /// Latitude, degrees north.
    pub lat_deg: Option<f64>,
    /// Longitude, degrees east.
    pub lon_deg: Option<f64>,
}

/// Verifies the `*hh` checksum and returns the body between `$` and `*`.
pub fn nmea_body(sentence: &str) -> Result<&str, NmeaError> {
    let s = sentence.trim_end_matches(['\r', '\n']);
    let rest = s
        .strip_prefix('$')
        .ok_or_else(|| NmeaError::Framing("does not start with '$'".into()))?;
    let (body, cs) = rest
        .rsplit_once('*')
        .ok_or_else(|| NmeaError::Framing("no '*' before the checksum".into()))?;
    let expected = u8::from_str_radix(cs, 16)
        .map_err(|_| NmeaError::Framing(format!("checksum '{cs}' is not two hex digits")))?;
    let computed = body.bytes().fold(0u8, |a, b| a ^ b);
    if computed != expected {
        return Err(NmeaError::Checksum { expected, computed });
    }
    Ok(body)
}

/// Days since 1970-01-01 of a civil date (proleptic Gregorian; H. Hinnant's algorithm).
pub fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(m);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

fn field_err(field: &'static str, value: &str) -> NmeaError {
    NmeaError::Field {
        field,
        value: value.to_owned(),
    }
}

fn parse_coord(
    value: &str,
    hemi: &str,
    deg_digits: usize,
    field: &'static str,
) -> Result<Option<f64>, NmeaError> {
    if value.is_empty() {
        return Ok(None);
    }
    if value.len() < deg_digits + 2 || !value.is_char_boundary(deg_digits) {
        return Err(field_err(field, value));
    }
    let deg: f64 = value[..deg_digits]
        .parse()
        .map_err(|_| field_err(field, value))?;
    let min: f64 = value[deg_digits..]
        .parse()
        .map_err(|_| field_err(field, value))?;
    let v = deg + min / 60.0;
    match hemi {
        "N" | "E" => Ok(Some(v)),
        "S" | "W" => Ok(Some(-v)),
        _ => Err(field_err(field, hemi)),
    }
}

/// Parses `hhmmss[.fff]` into nanoseconds of the day.
pub fn parse_hms(value: &str) -> Option<i64> {
    if value.len() < 6 || !value.is_char_boundary(6) {
        return None;
    }
    let h: i64 = value.get(0..2)?.parse().ok()?;
    let m: i64 = value.get(2..4)?.parse().ok()?;
    let (sec_int, frac) = value[4..].split_once('.').unwrap_or((&value[4..], ""));
    let s: i64 = sec_int.parse().ok()?;
    if h > 23 || m > 59 || s > 60 || sec_int.len() != 2 {
        return None;
    }
    let mut nanos = 0i64;
    if !frac.is_empty() {
        if frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        nanos = frac.parse::<i64>().ok()? * 10i64.pow(9 - frac.len() as u32);
    }
    Some(((h * 60 + m) * 60 + s) * 1_000_000_000 + nanos)
}

impl Rmc {
    /// Parses `$xxRMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,...*hh`.
    pub fn parse(sentence: &str) -> Result<Rmc, NmeaError> {
        let body = nmea_body(sentence)?;
        let f: Vec<&str> = body.split(',').collect();
        if f.len() < 10 || f[0].get(2..) != Some("RMC") {
            return Err(NmeaError::Framing(format!(
                "not an RMC sentence with 10 fields: {body}"
            )));
        }
        let tod = parse_hms(f[1]).ok_or_else(|| field_err("time", f[1]))?;
        let date = f[9];
        if date.len() != 6 || !date.bytes().all(|b| b.is_ascii_digit()) {
            return Err(field_err("date", date));
        }
        let dd: u32 = date[0..2].parse().map_err(|_| field_err("date", date))?;
        let mm: u32 = date[2..4].parse().map_err(|_| field_err("date", date))?;
        let yy: i64 = date[4..6].parse().map_err(|_| field_err("date", date))?;
        if !(1..=31).contains(&dd) || !(1..=12).contains(&mm) {
            return Err(field_err("date", date));
        }
        // Two-digit years: NMEA 0183 receivers of this era report 1980-2079.
        let year = if yy < 80 { 2000 + yy } else { 1900 + yy };
        let days = days_from_civil(year, mm, dd);
        Ok(Rmc {
            time: UtcNanos(days * 86_400 * 1_000_000_000 + tod),
            valid: f[2] == "A",
            lat_deg: parse_coord(f[3], f[4], 2, "latitude")?,
            lon_deg: parse_coord(f[5], f[6], 3, "longitude")?,
        })
    }
}

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
        assert_eq!(r.time, UtcNanos(1_355_263_592 * 1_000_000_000));
        assert!(r.valid);
        assert!((r.lat_deg.unwrap() - 37.13054).abs() < 1e-5);
        assert!((r.lon_deg.unwrap() + 121.65477).abs() < 1e-5);
    }

    #[test]
    fn checksum_errors_say_both_values() {
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
    fn civil_days_known_values() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        assert_eq!(days_from_civil(2024, 2, 29), 19_782);
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

        #[test]
        fn rmc_parse_never_panics(s in "\\$GPRMC,[0-9.]{0,12},[AV]?,[0-9.]{0,10},[NS]?,[0-9.]{0,11},[EW]?,[0-9.]*,[0-9.]*,[0-9]{0,7},.*") {
            let _ = Rmc::parse(&s);
        }
    }
}
