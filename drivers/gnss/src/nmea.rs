//! NMEA 0183 sentences that matter for an RTK reference trajectory.
//!
//! Written here rather than taken from the `nmea` crate: on the real receiver logs in
//! `shared/data/gnss`, `nmea` 0.8 rejects valid GBS sentences and drops the GGA correction age and
//! reference station id, both of which the validator needs (shared/data/README.md). The parser
//! below is a pure function of one checksum-verified sentence; any talker (GP, GN, GL, GA, GB, ...)
//! is accepted, and empty fields are `None`, never zero.

use hilrig_stamp::civil::{parse_hms, utc_from_civil};
use hilrig_stamp::UtcNanos;

/// Why a sentence could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
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
    /// A field is missing or invalid.
    #[error("{sentence} field {field} ({index}) is invalid: '{value}'")]
    Field {
        /// Sentence type, e.g. `GGA`.
        sentence: &'static str,
        /// Field name.
        field: &'static str,
        /// Field index after the address field.
        index: usize,
        /// Its text.
        value: String,
    },
    /// Fewer fields than the sentence type needs.
    #[error("{sentence} has {got} fields, needs at least {needed}")]
    TooShort {
        /// Sentence type.
        sentence: &'static str,
        /// Fields present.
        got: usize,
        /// Fields needed.
        needed: usize,
    },
}

/// Verifies the `*hh` checksum and returns the body between `$` and `*`.
pub fn body(sentence: &str) -> Result<&str, NmeaError> {
    let s = sentence.trim_end_matches(['\r', '\n']);
    let rest = s
        .strip_prefix('$')
        .or_else(|| s.strip_prefix('!'))
        .ok_or_else(|| NmeaError::Framing("does not start with '$'".into()))?;
    let (body, cs) = rest
        .rsplit_once('*')
        .ok_or_else(|| NmeaError::Framing("no '*' before the checksum".into()))?;
    let expected = u8::from_str_radix(cs, 16)
        .ok()
        .filter(|_| cs.len() == 2)
        .ok_or_else(|| NmeaError::Framing(format!("checksum '{cs}' is not two hex digits")))?;
    let computed = body.bytes().fold(0u8, |a, b| a ^ b);
    if computed != expected {
        return Err(NmeaError::Checksum { expected, computed });
    }
    Ok(body)
}

/// GGA: time, position, fix quality, satellites, HDOP, altitude, geoid separation, correction age,
/// reference station.
#[derive(Clone, Debug, PartialEq)]
pub struct Gga {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Latitude, degrees north.
    pub lat: Option<f64>,
    /// Longitude, degrees east.
    pub lon: Option<f64>,
    /// Fix quality: 0 none, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning, ...
    pub quality: u8,
    /// Satellites used.
    pub satellites: Option<u8>,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Altitude above mean sea level, metres.
    pub alt_msl: Option<f64>,
    /// Geoid separation (ellipsoid minus MSL), metres.
    pub geoid_sep: Option<f64>,
    /// Age of differential corrections, seconds.
    pub correction_age_s: Option<f64>,
    /// Reference station id.
    pub station_id: Option<u16>,
}

/// RMC: time, validity, position, speed, course, date, FAA mode.
#[derive(Clone, Debug, PartialEq)]
pub struct Rmc {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Status `A` (valid) rather than `V`.
    pub valid: bool,
    /// Latitude, degrees north.
    pub lat: Option<f64>,
    /// Longitude, degrees east.
    pub lon: Option<f64>,
    /// Speed over ground, knots.
    pub speed_knots: Option<f64>,
    /// Course over ground, degrees true.
    pub course_deg: Option<f64>,
    /// Date (year, month, day).
    pub date: Option<(i64, u32, u32)>,
    /// FAA mode indicator (A autonomous, D differential, R RTK fixed, F RTK float, ...).
    pub mode: Option<char>,
}

impl Rmc {
    /// Parses an RMC sentence (checksum verified).
    pub fn parse(sentence: &str) -> Result<Rmc, NmeaError> {
        match parse(sentence)? {
            Sentence::Rmc(r) => Ok(r),
            _ => Err(NmeaError::Framing(format!(
                "not an RMC sentence: {sentence}"
            ))),
        }
    }

    /// UTC of the fix, when both date and time are present (and the date exists).
    pub fn utc(&self) -> Option<UtcNanos> {
        let (y, m, d) = self.date?;
        utc_from_civil(y, m, d, self.time_of_day?)
    }
}

/// GST: pseudorange error statistics, the receiver's own 1-sigma accuracy estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct Gst {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// RMS of the range residuals.
    pub rms: Option<f64>,
    /// Error ellipse semi-major axis, metres.
    pub sigma_major_m: Option<f64>,
    /// Error ellipse semi-minor axis, metres.
    pub sigma_minor_m: Option<f64>,
    /// Orientation of the semi-major axis, degrees from true north.
    pub orientation_deg: Option<f64>,
    /// Latitude error, 1 sigma, metres.
    pub sigma_lat_m: Option<f64>,
    /// Longitude error, 1 sigma, metres.
    pub sigma_lon_m: Option<f64>,
    /// Altitude error, 1 sigma, metres.
    pub sigma_alt_m: Option<f64>,
}

/// ZDA: UTC date and time.
#[derive(Clone, Debug, PartialEq)]
pub struct Zda {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Date (year, month, day).
    pub date: Option<(i64, u32, u32)>,
}

/// HDT: true heading.
#[derive(Clone, Debug, PartialEq)]
pub struct Hdt {
    /// Heading, degrees true.
    pub heading_deg: Option<f64>,
}

/// THS: true heading with its mode (NMEA 0183 v4).
#[derive(Clone, Debug, PartialEq)]
pub struct Ths {
    /// Heading, degrees true.
    pub heading_deg: Option<f64>,
    /// Mode indicator: A autonomous, E estimated (dead reckoning), M manual input,
    /// S simulator, V not valid.
    pub mode: Option<char>,
}

/// PASHR in the form INS units write it (OxTS, Applanix, NovAtel SPAN, Trimble): attitude
/// with its accuracies. The older Ashtech forms (`PASHR,ATT`, `PASHR,HPR`, ...), whose first
/// field names the message, are other sentences.
#[derive(Clone, Debug, PartialEq)]
pub struct Pashr {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Heading, degrees true.
    pub heading_deg: Option<f64>,
    /// Roll, degrees.
    pub roll_deg: Option<f64>,
    /// Pitch, degrees.
    pub pitch_deg: Option<f64>,
    /// Heave, metres.
    pub heave_m: Option<f64>,
    /// Roll accuracy, degrees (1 sigma).
    pub sigma_roll_deg: Option<f64>,
    /// Pitch accuracy, degrees (1 sigma).
    pub sigma_pitch_deg: Option<f64>,
    /// Heading accuracy, degrees (1 sigma).
    pub sigma_heading_deg: Option<f64>,
    /// GNSS quality flag (0: no position; the other values differ between makers).
    pub gnss_quality: Option<u8>,
    /// INS aiding or alignment status (0: GNSS only, not aligned; absent before NovAtel
    /// firmware 7.03).
    pub ins_status: Option<u8>,
}

/// SkyTraq PSTI,036: heading, pitch and roll of a dual-antenna receiver's baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct Psti036 {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Date (year, month, day).
    pub date: Option<(i64, u32, u32)>,
    /// Heading, degrees true.
    pub heading_deg: Option<f64>,
    /// Pitch, degrees.
    pub pitch_deg: Option<f64>,
    /// Roll, degrees.
    pub roll_deg: Option<f64>,
    /// Mode: N not valid, A autonomous, D differential, E estimated, M manual, S simulator,
    /// F float RTK, R fixed RTK.
    pub mode: Option<char>,
}

/// VTG: course and speed over ground.
#[derive(Clone, Debug, PartialEq)]
pub struct Vtg {
    /// Course, degrees true.
    pub course_deg: Option<f64>,
    /// Speed, km/h.
    pub speed_kmh: Option<f64>,
    /// Speed, knots.
    pub speed_knots: Option<f64>,
    /// FAA mode.
    pub mode: Option<char>,
}

/// GNS: multi-constellation fix with per-system mode characters.
#[derive(Clone, Debug, PartialEq)]
pub struct Gns {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Latitude, degrees north.
    pub lat: Option<f64>,
    /// Longitude, degrees east.
    pub lon: Option<f64>,
    /// Mode characters per constellation (N, A, D, P, R, F, E, M, S).
    pub modes: String,
    /// Satellites used.
    pub satellites: Option<u8>,
    /// Altitude above MSL, metres.
    pub alt_msl: Option<f64>,
    /// Geoid separation, metres.
    pub geoid_sep: Option<f64>,
    /// Age of corrections, seconds.
    pub correction_age_s: Option<f64>,
    /// Reference station id.
    pub station_id: Option<u16>,
}

/// GBS: fault detection, expected errors of the position.
#[derive(Clone, Debug, PartialEq)]
pub struct Gbs {
    /// Nanoseconds of the UTC day.
    pub time_of_day: Option<i64>,
    /// Expected latitude error, metres.
    pub err_lat_m: Option<f64>,
    /// Expected longitude error, metres.
    pub err_lon_m: Option<f64>,
    /// Expected altitude error, metres.
    pub err_alt_m: Option<f64>,
}

/// A decoded sentence.
#[derive(Clone, Debug, PartialEq)]
pub enum Sentence {
    /// GGA.
    Gga(Gga),
    /// RMC.
    Rmc(Rmc),
    /// GST.
    Gst(Gst),
    /// ZDA.
    Zda(Zda),
    /// HDT.
    Hdt(Hdt),
    /// VTG.
    Vtg(Vtg),
    /// GNS.
    Gns(Gns),
    /// GBS.
    Gbs(Gbs),
    /// THS.
    Ths(Ths),
    /// PASHR (INS attitude).
    Pashr(Pashr),
    /// PSTI,036 (SkyTraq attitude).
    Psti036(Psti036),
    /// A valid sentence of a type not decoded here (GSV, GSA, proprietary, ...).
    Other {
        /// The address field, e.g. `GPGSV` or `PSTI`.
        address: String,
    },
}

struct Fields<'a> {
    kind: &'static str,
    f: Vec<&'a str>,
}

impl<'a> Fields<'a> {
    fn need(&self, n: usize) -> Result<(), NmeaError> {
        if self.f.len() < n {
            return Err(NmeaError::TooShort {
                sentence: self.kind,
                got: self.f.len(),
                needed: n,
            });
        }
        Ok(())
    }
    fn get(&self, i: usize) -> &'a str {
        self.f.get(i).copied().unwrap_or("")
    }
    fn err(&self, i: usize, field: &'static str) -> NmeaError {
        NmeaError::Field {
            sentence: self.kind,
            field,
            index: i,
            value: self.get(i).to_owned(),
        }
    }
    fn num<T: std::str::FromStr>(
        &self,
        i: usize,
        field: &'static str,
    ) -> Result<Option<T>, NmeaError> {
        let v = self.get(i);
        if v.is_empty() {
            return Ok(None);
        }
        v.parse().map(Some).map_err(|_| self.err(i, field))
    }
    fn float(&self, i: usize, field: &'static str) -> Result<Option<f64>, NmeaError> {
        let v: Option<f64> = self.num(i, field)?;
        match v {
            Some(x) if !x.is_finite() => Err(self.err(i, field)),
            v => Ok(v),
        }
    }
    /// An angle, degrees, within `min..=max` (a heading 0..360, pitch ±90, roll ±180).
    fn angle(
        &self,
        i: usize,
        field: &'static str,
        min: f64,
        max: f64,
    ) -> Result<Option<f64>, NmeaError> {
        match self.float(i, field)? {
            Some(x) if !(min..=max).contains(&x) => Err(self.err(i, field)),
            v => Ok(v),
        }
    }
    fn time(&self, i: usize) -> Result<Option<i64>, NmeaError> {
        let v = self.get(i);
        if v.is_empty() {
            return Ok(None);
        }
        parse_hms(v).map(Some).ok_or_else(|| self.err(i, "time"))
    }
    fn coord(
        &self,
        i: usize,
        deg_digits: usize,
        field: &'static str,
    ) -> Result<Option<f64>, NmeaError> {
        let (v, hemi) = (self.get(i), self.get(i + 1));
        if v.is_empty() {
            return Ok(None);
        }
        let b = v.as_bytes();
        if b.len() < deg_digits + 2 || !b[..deg_digits].iter().all(u8::is_ascii_digit) {
            return Err(self.err(i, field));
        }
        let deg: f64 = v[..deg_digits].parse().map_err(|_| self.err(i, field))?;
        let min: f64 = v[deg_digits..].parse().map_err(|_| self.err(i, field))?;
        if !(0.0..60.0).contains(&min) {
            return Err(self.err(i, field));
        }
        let x = deg + min / 60.0;
        match hemi {
            "N" | "E" => Ok(Some(x)),
            "S" | "W" => Ok(Some(-x)),
            _ => Err(self.err(i + 1, "hemisphere")),
        }
    }
    fn ch(&self, i: usize) -> Option<char> {
        self.get(i).chars().next()
    }
    fn ddmmyy(&self, i: usize) -> Result<Option<(i64, u32, u32)>, NmeaError> {
        let v = self.get(i);
        if v.is_empty() {
            return Ok(None);
        }
        let b = v.as_bytes();
        if b.len() != 6 || !b.iter().all(u8::is_ascii_digit) {
            return Err(self.err(i, "date"));
        }
        let n = |k: usize| u32::from(b[k] - b'0') * 10 + u32::from(b[k + 1] - b'0');
        let (d, m, y) = (n(0), n(2), i64::from(n(4)));
        if !(1..=31).contains(&d) || !(1..=12).contains(&m) {
            return Err(self.err(i, "date"));
        }
        // Two-digit years: 1980-2079 (NMEA 0183 receivers of this era).
        Ok(Some((if y < 80 { 2000 + y } else { 1900 + y }, m, d)))
    }
}

/// Parses one sentence (with or without line end); the checksum must be valid.
pub fn parse(sentence: &str) -> Result<Sentence, NmeaError> {
    let body = body(sentence)?;
    let mut parts = body.split(',');
    let address = parts.next().unwrap_or("");
    let f: Vec<&str> = parts.collect();
    // Standard sentences: two-letter talker + three-letter type; proprietary ones start with P.
    // (Only ASCII addresses: a multi-byte character must not be split; found by cargo-fuzz.)
    let kind = if address.len() == 5 && address.is_ascii() && !address.starts_with('P') {
        &address[2..]
    } else if address == "PASHR"
        && f.first()
            .is_some_and(|t| t.starts_with(|c: char| c.is_ascii_digit()))
    {
        // The INS form begins with a time; the Ashtech forms with a message name.
        "PASHR"
    } else if address == "PSTI" && f.first() == Some(&"036") {
        "PSTI036"
    } else {
        ""
    };
    let mk = |kind: &'static str| Fields { kind, f: f.clone() };
    Ok(match kind {
        "GGA" => {
            let x = mk("GGA");
            x.need(9)?;
            Sentence::Gga(Gga {
                time_of_day: x.time(0)?,
                lat: x.coord(1, 2, "latitude")?,
                lon: x.coord(3, 3, "longitude")?,
                quality: x.num(5, "quality")?.unwrap_or(0),
                satellites: x.num(6, "satellites")?,
                hdop: x.float(7, "hdop")?,
                alt_msl: x.float(8, "altitude")?,
                geoid_sep: x.float(10, "geoid separation")?,
                correction_age_s: x.float(12, "correction age")?,
                station_id: x.num(13, "station id")?,
            })
        }
        "RMC" => {
            let x = mk("RMC");
            x.need(9)?;
            Sentence::Rmc(Rmc {
                time_of_day: x.time(0)?,
                valid: x.get(1) == "A",
                lat: x.coord(2, 2, "latitude")?,
                lon: x.coord(4, 3, "longitude")?,
                speed_knots: x.float(6, "speed")?,
                course_deg: x.float(7, "course")?,
                date: x.ddmmyy(8)?,
                mode: x.ch(11),
            })
        }
        "GST" => {
            let x = mk("GST");
            x.need(8)?;
            Sentence::Gst(Gst {
                time_of_day: x.time(0)?,
                rms: x.float(1, "rms")?,
                sigma_major_m: x.float(2, "semi-major")?,
                sigma_minor_m: x.float(3, "semi-minor")?,
                orientation_deg: x.float(4, "orientation")?,
                sigma_lat_m: x.float(5, "latitude sigma")?,
                sigma_lon_m: x.float(6, "longitude sigma")?,
                sigma_alt_m: x.float(7, "altitude sigma")?,
            })
        }
        "ZDA" => {
            let x = mk("ZDA");
            x.need(4)?;
            let day: Option<u32> = x.num(1, "day")?;
            let month: Option<u32> = x.num(2, "month")?;
            let year: Option<i64> = x.num(3, "year")?;
            let date = match (year, month, day) {
                (Some(y), Some(m), Some(d)) if (1..=12).contains(&m) && (1..=31).contains(&d) => {
                    Some((y, m, d))
                }
                (None, None, None) => None,
                _ => return Err(x.err(1, "date")),
            };
            Sentence::Zda(Zda {
                time_of_day: x.time(0)?,
                date,
            })
        }
        "HDT" => {
            let x = mk("HDT");
            x.need(1)?;
            Sentence::Hdt(Hdt {
                heading_deg: x.angle(0, "heading", 0.0, 360.0)?,
            })
        }
        "VTG" => {
            let x = mk("VTG");
            x.need(7)?;
            Sentence::Vtg(Vtg {
                course_deg: x.float(0, "course")?,
                speed_knots: x.float(4, "speed knots")?,
                speed_kmh: x.float(6, "speed km/h")?,
                mode: x.ch(8),
            })
        }
        "GNS" => {
            let x = mk("GNS");
            x.need(12)?;
            Sentence::Gns(Gns {
                time_of_day: x.time(0)?,
                lat: x.coord(1, 2, "latitude")?,
                lon: x.coord(3, 3, "longitude")?,
                modes: x.get(5).to_owned(),
                satellites: x.num(6, "satellites")?,
                alt_msl: x.float(8, "altitude")?,
                geoid_sep: x.float(9, "geoid separation")?,
                correction_age_s: x.float(10, "correction age")?,
                station_id: x.num(11, "station id")?,
            })
        }
        "GBS" => {
            let x = mk("GBS");
            x.need(4)?;
            Sentence::Gbs(Gbs {
                time_of_day: x.time(0)?,
                err_lat_m: x.float(1, "latitude error")?,
                err_lon_m: x.float(2, "longitude error")?,
                err_alt_m: x.float(3, "altitude error")?,
            })
        }
        "THS" => {
            let x = mk("THS");
            x.need(2)?;
            Sentence::Ths(Ths {
                heading_deg: x.angle(0, "heading", 0.0, 360.0)?,
                mode: x.ch(1),
            })
        }
        "PASHR" => {
            let x = mk("PASHR");
            x.need(10)?;
            if x.get(2) != "T" && !x.get(2).is_empty() {
                return Err(x.err(2, "true heading flag"));
            }
            Sentence::Pashr(Pashr {
                time_of_day: x.time(0)?,
                heading_deg: x.angle(1, "heading", 0.0, 360.0)?,
                roll_deg: x.angle(3, "roll", -180.0, 180.0)?,
                pitch_deg: x.angle(4, "pitch", -90.0, 90.0)?,
                heave_m: x.float(5, "heave")?,
                sigma_roll_deg: x.angle(6, "roll accuracy", 0.0, 180.0)?,
                sigma_pitch_deg: x.angle(7, "pitch accuracy", 0.0, 180.0)?,
                sigma_heading_deg: x.angle(8, "heading accuracy", 0.0, 180.0)?,
                gnss_quality: x.num(9, "GNSS quality")?,
                ins_status: x.num(10, "INS status")?,
            })
        }
        "PSTI036" => {
            let x = mk("PSTI036");
            x.need(7)?;
            Sentence::Psti036(Psti036 {
                time_of_day: x.time(1)?,
                date: x.ddmmyy(2)?,
                heading_deg: x.angle(3, "heading", 0.0, 360.0)?,
                pitch_deg: x.angle(4, "pitch", -90.0, 90.0)?,
                roll_deg: x.angle(5, "roll", -180.0, 180.0)?,
                mode: x.ch(6),
            })
        }
        _ => Sentence::Other {
            address: address.to_owned(),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn gga_keeps_correction_age_and_station() {
        let s = "$GNGGA,132819.60,4134.49795459,N,09345.03431408,W,2,10,0.9,278.161,M,-31.442,M,6.6,0133*6A";
        let Sentence::Gga(g) = parse(s).unwrap() else {
            panic!()
        };
        assert_eq!(g.quality, 2);
        assert_eq!(g.correction_age_s, Some(6.6));
        assert_eq!(g.station_id, Some(133));
        assert!((g.lat.unwrap() - 41.574965910).abs() < 1e-9);
        assert!((g.lon.unwrap() + 93.750571901).abs() < 1e-9);
        assert_eq!(
            g.time_of_day,
            Some((13 * 3600 + 28 * 60 + 19) * 1_000_000_000 + 600_000_000)
        );
    }

    #[test]
    fn real_gbs_and_gst_parse() {
        let Sentence::Gbs(g) = parse("$GNGBS,231408.00,0.0,0.1,0.1,,,,,,*53").unwrap() else {
            panic!()
        };
        assert_eq!(g.err_lon_m, Some(0.1));
        let Sentence::Gst(g) =
            parse("$GNGST,231408.00,32,0.19,0.12,97,0.049,0.078,0.088*43").unwrap()
        else {
            panic!()
        };
        assert_eq!(g.sigma_alt_m, Some(0.088));
    }

    #[test]
    fn rmc_date_and_mode() {
        let r = Rmc::parse("$GNRMC,132819.60,A,4134.49795459,N,09345.03431408,W,0.148,124.888,180320,11.5985,E,D*3F").unwrap();
        assert_eq!(r.date, Some((2020, 3, 18)));
        assert_eq!(r.mode, Some('D'));
        assert_eq!(
            hilrig_stamp::civil::iso8601_millis(r.utc().unwrap()),
            "2020-03-18T13:28:19.600Z"
        );
    }

    /// Found by cargo-fuzz: a non-ASCII address field split a multi-byte character.
    #[test]
    fn non_ascii_address_is_not_a_panic() {
        let s = crate::framer::nmea_sentence("Tո84");
        assert!(matches!(parse(&s), Ok(Sentence::Other { .. })));
    }

    #[test]
    fn errors_name_the_field() {
        let s = crate::framer::nmea_sentence(
            "GPGGA,1200xx,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
        );
        let e = parse(&s).unwrap_err();
        assert!(
            e.to_string()
                .contains("GGA field time (0) is invalid: '1200xx'"),
            "{e}"
        );
    }

    proptest! {
        #[test]
        fn never_panics(body in "[A-Z]{2}(GGA|RMC|GST|ZDA|HDT|VTG|GNS|GBS|THS)(,[0-9A-Z.+-]{0,12}){0,16}") {
            let _ = parse(&crate::framer::nmea_sentence(&body));
        }

        #[test]
        fn attitude_sentences_never_panic(body in "(PASHR|PSTI,036)(,[0-9A-Z.+-]{0,12}){0,14}") {
            let _ = parse(&crate::framer::nmea_sentence(&body));
        }

        /// A PASHR of any in-range attitude reads back to the printed precision; out of
        /// range, it is an error naming the field.
        #[test]
        fn pashr_round_trips(h in 0.0f64..360.0, r in -180.0f64..180.0, p in -90.0f64..90.0, bad in 90.01f64..1e6) {
            let s = crate::framer::nmea_sentence(&format!(
                "PASHR,120000.00,{h:.2},T,{r:+.2},{p:+.2},+0.01,0.030,0.031,0.060,2,1"
            ));
            let Sentence::Pashr(a) = parse(&s).unwrap() else { panic!("{s}") };
            prop_assert!((a.heading_deg.unwrap() - h).abs() <= 0.005 + 1e-9);
            prop_assert!((a.roll_deg.unwrap() - r).abs() <= 0.005 + 1e-9);
            prop_assert!((a.pitch_deg.unwrap() - p).abs() <= 0.005 + 1e-9);
            prop_assert_eq!(a.sigma_heading_deg, Some(0.06));
            let s = crate::framer::nmea_sentence(&format!(
                "PASHR,120000.00,{h:.2},T,{r:+.2},{bad:+.2},+0.01,0.030,0.031,0.060,2,1"
            ));
            let e = parse(&s).unwrap_err().to_string();
            prop_assert!(e.contains("PASHR field pitch (4)"), "{}", e);
        }
    }
}
