//! Epoch assembly: the sentences and messages of one fix time become one [`Fix`].
//!
//! NMEA and UBX are assembled separately (a receiver that sends both reports each fix twice, and
//! the two differ in resolution: UBX NAV-HPPOSLLH carries 1e-9 degrees, GGA usually 1e-7 of a
//! minute); a [`Fix`] says which protocol it came from.
//!
//! NMEA: an epoch is the run of sentences with the same UTC time of day; GGA gives position,
//! quality, correction age; RMC and ZDA the date; GST the sigmas; HDT, VTG, RMC heading and speed.
//! Sentences without a time (HDT, VTG) join the epoch in progress. The date, once seen, carries
//! over to later epochs (rolling over at midnight), so GGA-only epochs still get a UTC time.
//!
//! UBX: an epoch is the messages with the same GPS time of week; NAV-PVT gives the fix, a
//! following NAV-HPPOSLLH of the same epoch refines position and accuracy.

use crate::attitude::{Attitude, Reading};
use crate::nmea::{self, Sentence};
use crate::ubx::{CarrierSolution, Ubx};
use hilrig_stamp::civil::utc_from_civil;
use hilrig_stamp::UtcNanos;

const DAY_NS: i64 = 86_400 * 1_000_000_000;

/// RTK state of a fix (in hilrig's JSON: `fixed`, `float`, `none`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RtkState {
    /// Carrier-phase ambiguities fixed.
    Fixed,
    /// Carrier-phase float solution.
    Float,
    /// No carrier-phase solution.
    None,
}

impl RtkState {
    /// Lower-case name, as in hilrig's JSON.
    pub fn name(self) -> &'static str {
        match self {
            RtkState::Fixed => "fixed",
            RtkState::Float => "float",
            RtkState::None => "none",
        }
    }
}

/// Which protocol a fix came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FixSource {
    /// NMEA sentences.
    Nmea,
    /// UBX messages.
    Ubx,
}

/// One navigation epoch.
#[derive(Clone, Debug, PartialEq)]
pub struct Fix {
    /// Protocol.
    pub source: FixSource,
    /// UTC of the fix, when the date is known.
    pub time: Option<UtcNanos>,
    /// Nanoseconds of the UTC day (NMEA) even when the date is not known yet.
    pub time_of_day: Option<i64>,
    /// Latitude, degrees.
    pub lat: Option<f64>,
    /// Longitude, degrees.
    pub lon: Option<f64>,
    /// Altitude above mean sea level, metres.
    pub alt_msl: Option<f64>,
    /// Height above the ellipsoid, metres.
    pub alt_ellipsoid: Option<f64>,
    /// GGA fix quality code 0-9 (derived for UBX: 4 fixed, 5 float, 2 differential, 1 GNSS,
    /// 6 dead reckoning, 0 none).
    pub quality: u8,
    /// RTK state.
    pub rtk: RtkState,
    /// 1-sigma latitude error, metres.
    pub sigma_lat_m: Option<f64>,
    /// 1-sigma longitude error, metres.
    pub sigma_lon_m: Option<f64>,
    /// 1-sigma altitude error, metres.
    pub sigma_alt_m: Option<f64>,
    /// Age of differential corrections, seconds.
    pub correction_age_s: Option<f64>,
    /// Reference station id.
    pub station_id: Option<u16>,
    /// Satellites used.
    pub satellites: Option<u8>,
    /// Speed over ground, m/s.
    pub speed_mps: Option<f64>,
    /// Heading (true heading when the receiver reports one, else course over ground), degrees.
    pub heading_deg: Option<f64>,
}

impl Fix {
    fn empty(source: FixSource) -> Fix {
        Fix {
            source,
            time: None,
            time_of_day: None,
            lat: None,
            lon: None,
            alt_msl: None,
            alt_ellipsoid: None,
            quality: 0,
            rtk: RtkState::None,
            sigma_lat_m: None,
            sigma_lon_m: None,
            sigma_alt_m: None,
            correction_age_s: None,
            station_id: None,
            satellites: None,
            speed_mps: None,
            heading_deg: None,
        }
    }
}

const KNOT_MPS: f64 = 1852.0 / 3600.0;

/// Assembles NMEA sentences into fixes.
#[derive(Debug, Default)]
pub struct NmeaEpochs {
    current: Option<Fix>,
    has_true_heading: bool,
    /// Last known date and the time of day it was seen at.
    date: Option<((i64, u32, u32), i64)>,
}

fn rtk_from_quality(q: u8) -> RtkState {
    match q {
        4 => RtkState::Fixed,
        5 => RtkState::Float,
        _ => RtkState::None,
    }
}

impl NmeaEpochs {
    /// Takes one decoded sentence; returns the previous epoch when this one starts a new one.
    pub fn push(&mut self, s: &Sentence) -> Option<Fix> {
        let tod = match s {
            Sentence::Gga(g) => g.time_of_day,
            Sentence::Rmc(r) => r.time_of_day,
            Sentence::Gst(g) => g.time_of_day,
            Sentence::Zda(z) => z.time_of_day,
            Sentence::Gns(g) => g.time_of_day,
            Sentence::Gbs(g) => g.time_of_day,
            // The attitude sentences do not start epochs: an INS writes them at its own rate.
            Sentence::Hdt(_)
            | Sentence::Vtg(_)
            | Sentence::Ths(_)
            | Sentence::Pashr(_)
            | Sentence::Psti036(_)
            | Sentence::Other { .. } => None,
        };
        let mut done = None;
        if let Some(t) = tod {
            if self
                .current
                .as_ref()
                .is_some_and(|c| c.time_of_day != Some(t))
            {
                done = self.take();
            }
            if self.current.is_none() {
                let mut f = Fix::empty(FixSource::Nmea);
                f.time_of_day = Some(t);
                self.current = Some(f);
                self.has_true_heading = false;
            }
        }
        let Some(f) = self.current.as_mut() else {
            return done;
        };
        match s {
            Sentence::Gga(g) => {
                f.lat = g.lat.or(f.lat);
                f.lon = g.lon.or(f.lon);
                f.alt_msl = g.alt_msl;
                f.alt_ellipsoid = match (g.alt_msl, g.geoid_sep) {
                    (Some(a), Some(n)) => Some(a + n),
                    _ => None,
                };
                f.quality = g.quality;
                f.rtk = rtk_from_quality(g.quality);
                f.correction_age_s = g.correction_age_s;
                f.station_id = g.station_id;
                f.satellites = g.satellites;
            }
            Sentence::Gns(g) => {
                f.lat = f.lat.or(g.lat);
                f.lon = f.lon.or(g.lon);
                f.alt_msl = f.alt_msl.or(g.alt_msl);
                f.correction_age_s = f.correction_age_s.or(g.correction_age_s);
                f.station_id = f.station_id.or(g.station_id);
                f.satellites = f.satellites.or(g.satellites);
            }
            Sentence::Rmc(r) => {
                if let Some(d) = r.date {
                    self.date = Some((d, r.time_of_day.unwrap_or(0)));
                }
                f.lat = f.lat.or(r.lat);
                f.lon = f.lon.or(r.lon);
                f.speed_mps = r.speed_knots.map(|k| k * KNOT_MPS).or(f.speed_mps);
                if !self.has_true_heading {
                    f.heading_deg = r.course_deg.or(f.heading_deg);
                }
                if f.quality == 0 && r.valid {
                    // RMC alone: the FAA mode tells the RTK state.
                    f.rtk = match r.mode {
                        Some('R') => RtkState::Fixed,
                        Some('F') => RtkState::Float,
                        _ => f.rtk,
                    };
                }
            }
            Sentence::Zda(z) => {
                if let Some(d) = z.date {
                    self.date = Some((d, z.time_of_day.unwrap_or(0)));
                }
            }
            Sentence::Gst(g) => {
                f.sigma_lat_m = g.sigma_lat_m;
                f.sigma_lon_m = g.sigma_lon_m;
                f.sigma_alt_m = g.sigma_alt_m;
            }
            Sentence::Hdt(h) => {
                if h.heading_deg.is_some() {
                    f.heading_deg = h.heading_deg;
                    self.has_true_heading = true;
                }
            }
            Sentence::Vtg(v) => {
                f.speed_mps = v.speed_kmh.map(|k| k / 3.6).or(f.speed_mps);
                if !self.has_true_heading {
                    f.heading_deg = v.course_deg.or(f.heading_deg);
                }
            }
            Sentence::Gbs(_)
            | Sentence::Ths(_)
            | Sentence::Pashr(_)
            | Sentence::Psti036(_)
            | Sentence::Other { .. } => {}
        }
        done
    }

    /// Ends the stream: the epoch in progress.
    pub fn finish(&mut self) -> Option<Fix> {
        self.take()
    }

    fn take(&mut self) -> Option<Fix> {
        let mut f = self.current.take()?;
        f.time = f.time_of_day.and_then(|tod| self.utc_of(tod));
        Some(f)
    }

    /// The UTC of a time of day on the date last seen. A time of day well before the one the
    /// date was seen at is the next day; a date that does not exist gives no time, as a
    /// missing one does.
    fn utc_of(&self, tod: i64) -> Option<UtcNanos> {
        let ((y, m, d), seen_tod) = self.date?;
        utc_from_civil(y, m, d, tod).map(|t| {
            if seen_tod.saturating_sub(tod) > DAY_NS / 2 {
                UtcNanos(t.0.saturating_add(DAY_NS))
            } else {
                t
            }
        })
    }

    /// The UTC of an attitude sentence: its own time (and date), or for HDT and THS, which
    /// have none, the epoch's in progress.
    pub fn attitude_time(&self, s: &Sentence) -> Option<UtcNanos> {
        match s {
            Sentence::Pashr(p) => p.time_of_day.and_then(|t| self.utc_of(t)),
            Sentence::Psti036(p) => match (p.date, p.time_of_day) {
                (Some((y, m, d)), Some(t)) => utc_from_civil(y, m, d, t),
                (None, Some(t)) => self.utc_of(t),
                _ => None,
            },
            _ => self
                .current
                .as_ref()
                .and_then(|c| c.time_of_day)
                .and_then(|t| self.utc_of(t)),
        }
    }
}

/// Assembles UBX messages into fixes.
#[derive(Debug, Default)]
pub struct UbxEpochs {
    current: Option<(u32, Fix)>,
    /// The last (time of week, UTC) pair seen: the week and leap seconds of the attitude
    /// messages that carry only a time of week.
    week: Option<(u32, UtcNanos)>,
}

/// The UTC of a UBX epoch: on the receiver's millisecond grid (see NAV-PVT below).
fn on_ms_grid(t: UtcNanos) -> UtcNanos {
    // The nearest millisecond, halves up, without an overflow at either end of the range.
    let ms = t.0.div_euclid(1_000_000) + i64::from(t.0.rem_euclid(1_000_000) >= 500_000);
    UtcNanos(ms.saturating_mul(1_000_000))
}

impl UbxEpochs {
    /// Takes one decoded message; returns the previous epoch when this one starts a new one.
    pub fn push(&mut self, m: &Ubx) -> Option<Fix> {
        match m {
            Ubx::NavPvt(p) => {
                let done = self.current.take().map(|(_, f)| f);
                let mut f = Fix::empty(FixSource::Ubx);
                // The navigation epoch is on the receiver's millisecond grid (iTOW); the UTC
                // fields plus `nano` land a few hundred microseconds off it by the receiver clock
                // bias. The epoch's time is the grid point, as gpsd reports it.
                f.time = p.utc.map(on_ms_grid);
                if let Some(t) = f.time {
                    self.week = Some((p.itow_ms, t));
                }
                f.lat = Some(p.lat_deg);
                f.lon = Some(p.lon_deg);
                f.alt_msl = Some(p.h_msl_m);
                f.alt_ellipsoid = Some(p.height_m);
                f.rtk = match p.carrier {
                    CarrierSolution::Fixed => RtkState::Fixed,
                    CarrierSolution::Float => RtkState::Float,
                    CarrierSolution::None => RtkState::None,
                };
                f.quality = match (p.carrier, p.fix_ok, p.fix_type, p.diff_soln) {
                    (CarrierSolution::Fixed, ..) => 4,
                    (CarrierSolution::Float, ..) => 5,
                    (_, false, ..) => 0,
                    (_, true, 1, _) => 6,
                    (_, true, _, true) => 2,
                    (_, true, 2..=4, false) => 1,
                    _ => 0,
                };
                if f.quality == 0 {
                    f.lat = None;
                    f.lon = None;
                }
                // UBX reports one horizontal accuracy; it stands for both axes.
                f.sigma_lat_m = Some(p.h_acc_m);
                f.sigma_lon_m = Some(p.h_acc_m);
                f.sigma_alt_m = Some(p.v_acc_m);
                f.correction_age_s = p.correction_age_s;
                f.satellites = Some(p.num_sv);
                f.speed_mps = Some(p.ground_speed_mps);
                f.heading_deg = p.head_vehicle_deg.or(Some(p.head_motion_deg));
                self.current = Some((p.itow_ms, f));
                done
            }
            Ubx::NavHpposllh(h) => {
                if let Some((itow, f)) = self.current.as_mut() {
                    if *itow == h.itow_ms && !h.invalid && f.lat.is_some() {
                        f.lat = Some(h.lat_deg);
                        f.lon = Some(h.lon_deg);
                        f.alt_msl = Some(h.h_msl_m);
                        f.alt_ellipsoid = Some(h.height_m);
                        f.sigma_lat_m = Some(h.h_acc_m);
                        f.sigma_lon_m = Some(h.h_acc_m);
                        f.sigma_alt_m = Some(h.v_acc_m);
                    }
                }
                None
            }
            Ubx::NavRelposned(r) => {
                if let Some((itow, f)) = self.current.as_mut() {
                    if *itow == r.itow_ms {
                        f.station_id = Some(r.station_id);
                    }
                }
                None
            }
            Ubx::NavPvat(p) => {
                if let Some(t) = p.utc {
                    self.week = Some((p.itow_ms, on_ms_grid(t)));
                }
                None
            }
            Ubx::HnrPvt(p) => {
                if let Some(t) = p.utc {
                    self.week = Some((p.itow_ms, on_ms_grid(t)));
                }
                None
            }
            Ubx::NavAtt(_) | Ubx::HnrAtt(_) | Ubx::EsfAlg(_) | Ubx::Other { .. } => None,
        }
    }

    /// The UTC of a message's time of week, once a NAV-PVT, NAV-PVAT or HNR-PVT has shown
    /// the week.
    pub fn attitude_time(&self, m: &Ubx) -> Option<UtcNanos> {
        let itow = match m {
            Ubx::NavAtt(a) | Ubx::HnrAtt(a) => a.itow_ms,
            Ubx::NavRelposned(r) => r.itow_ms,
            Ubx::NavPvat(p) => p.itow_ms,
            Ubx::EsfAlg(a) => a.itow_ms,
            _ => return None,
        };
        self.week.map(|w| crate::attitude::utc_of_itow(itow, w))
    }

    /// Ends the stream: the epoch in progress.
    pub fn finish(&mut self) -> Option<Fix> {
        self.current.take().map(|(_, f)| f)
    }
}

/// Counters of a GNSS stream decode.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DecodeStats {
    /// NMEA sentences that framed but did not decode (bad fields).
    pub nmea_errors: u64,
    /// UBX frames that framed but did not decode.
    pub ubx_errors: u64,
    /// Attitude reports (all, whether collected or not).
    pub attitudes: u64,
    /// Attitude messages their own flags mark invalid, by message: counted, never used.
    pub invalid_attitudes: std::collections::BTreeMap<&'static str, u64>,
}

/// The whole sans-IO pipeline: bytes in, fixes out (framer + decoders + both assemblers).
#[derive(Debug, Default)]
pub struct GnssStream {
    /// The framer.
    pub framer: crate::framer::Framer,
    nmea: NmeaEpochs,
    ubx: UbxEpochs,
    /// Decode error counters.
    pub stats: DecodeStats,
    /// Attitude reports not yet taken, when collected.
    attitudes: Option<Vec<Attitude>>,
}

impl GnssStream {
    /// A stream over a gpsd-style log (comment lines skipped).
    pub fn for_gpsd_log() -> GnssStream {
        GnssStream {
            framer: crate::framer::Framer::for_gpsd_log(),
            ..GnssStream::default()
        }
    }

    /// The same stream collecting attitude reports for [`GnssStream::take_attitudes`] (they
    /// are counted either way; a stream whose reader never takes them does not collect them).
    pub fn with_attitude(mut self) -> GnssStream {
        self.attitudes = Some(Vec::new());
        self
    }

    /// The attitude reports decoded since the last call, in stream order.
    pub fn take_attitudes(&mut self) -> Vec<Attitude> {
        self.attitudes
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    fn attitude(&mut self, r: Reading) {
        match r {
            Reading::None => {}
            Reading::Attitude(a) => {
                self.stats.attitudes += 1;
                if let Some(v) = self.attitudes.as_mut() {
                    v.push(a);
                }
            }
            Reading::Invalid(s) => *self.stats.invalid_attitudes.entry(s.name()).or_default() += 1,
        }
    }

    /// Feeds bytes and appends finished fixes to `out`.
    pub fn push(&mut self, bytes: &[u8], out: &mut Vec<Fix>) {
        self.framer.push(bytes);
        self.drain(out);
    }

    /// Ends the stream and appends the remaining fixes.
    pub fn finish(&mut self, out: &mut Vec<Fix>) {
        self.framer.finish();
        self.drain(out);
        out.extend(self.nmea.finish());
        out.extend(self.ubx.finish());
    }

    fn drain(&mut self, out: &mut Vec<Fix>) {
        use crate::framer::{Frame, Item};
        while let Some(item) = self.framer.next_frame() {
            match item {
                Item::Frame {
                    frame: Frame::Nmea(s),
                    ..
                } => match nmea::parse(&s) {
                    Ok(sentence) => {
                        let t = self.nmea.attitude_time(&sentence);
                        self.attitude(crate::attitude::from_nmea(&sentence, t));
                        out.extend(self.nmea.push(&sentence));
                    }
                    Err(_) => self.stats.nmea_errors += 1,
                },
                Item::Frame {
                    frame: Frame::Ubx { class, id, payload },
                    ..
                } => match crate::ubx::decode(class, id, &payload) {
                    Ok(m) => {
                        out.extend(self.ubx.push(&m));
                        let t = self.ubx.attitude_time(&m);
                        self.attitude(crate::attitude::from_ubx(&m, t));
                    }
                    Err(_) => self.stats.ubx_errors += 1,
                },
                Item::Frame {
                    frame: Frame::Rtcm3 { .. },
                    ..
                }
                | Item::Rejected { .. } => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::framer::ubx_frame;

    /// The fixes `stream` makes of `bytes`, to the end of the stream.
    fn fixes(mut stream: GnssStream, bytes: &[u8]) -> Vec<Fix> {
        let mut out = Vec::new();
        stream.push(bytes, &mut out);
        stream.finish(&mut out);
        out
    }

    /// Found by cargo-fuzz: a NAV-PVT dated in the year 65535 overflowed the rounding to the
    /// millisecond grid. Such a date is beyond what a time can hold: the fix comes out
    /// without one (it used to carry the range's end, 2262).
    #[test]
    fn pvt_at_the_end_of_time_does_not_overflow() {
        let mut p = [0u8; 92];
        p[4..6].copy_from_slice(&u16::MAX.to_le_bytes());
        p[6] = 12;
        p[7] = 31;
        p[8] = 23;
        p[9] = 59;
        p[10] = 59;
        p[11] = 0x03;
        p[16..20].copy_from_slice(&999_999_999i32.to_le_bytes());
        p[20] = 3;
        p[21] = 1;
        let out = fixes(GnssStream::default(), &ubx_frame(1, 7, &p));
        assert_eq!(out.len(), 1);
        assert!(out[0].time.is_none());
        // A date within the range keeps its time, on the millisecond grid.
        p[4..6].copy_from_slice(&2026u16.to_le_bytes());
        let out = fixes(GnssStream::default(), &ubx_frame(1, 7, &p));
        let t = out[0].time.expect("a time");
        assert_eq!(t.0.rem_euclid(1_000_000), 0);
    }

    /// Found by cargo-fuzz (the attitude target, 2026-12-08): a NAV-PVAT dated in the year 0
    /// saturated to the start of the range, and the rounding to the millisecond grid then
    /// overflowed. The fuzzer's input, as its target frames it.
    #[test]
    fn pvat_at_the_start_of_time_does_not_overflow() {
        let mut payload = vec![255u8, 255, 0, 0, 0, 255, 15, 0, 4, 6];
        payload.extend([0u8; 52]);
        payload.push(41);
        payload.extend([0u8; 11]);
        payload.extend([26u8, 61, 33, 58, 33, 26, 126, 47, 255, 15]);
        payload.extend([0u8; 6]);
        payload.extend([61u8, 61, 33, 33, 126, 61, 33, 126, 61, 33, 33, 126]);
        payload.extend([0u8; 7]);
        payload.extend([107u8, 58, 33, 26, 39, 36, 10]);
        let out = fixes(
            GnssStream::for_gpsd_log().with_attitude(),
            &ubx_frame(0x01, 0x17, &payload),
        );
        assert!(out.iter().all(|f| f.time.is_none()), "{out:?}");
    }
}
