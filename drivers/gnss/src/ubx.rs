//! u-blox UBX navigation messages: NAV-PVT, NAV-HPPOSLLH, NAV-RELPOSNED, and the attitude
//! messages NAV-ATT, NAV-PVAT (F9R), HNR-ATT (M8U high rate), with HNR-PVT for the UTC of
//! the high-rate stream.
//!
//! Decoded here from the payloads the framer delivers. The `ublox` crate was not used for the
//! stream: its mixed-protocol parser (`consume_ubx_rtcm_nmea`, 0.10) lost frames on the real
//! ZED-F9R log in shared/data/gnss, and hilrig's framer already yields checksum-verified
//! payloads, so three fixed-layout messages are simpler to decode directly (offsets from the u-blox
//! F9 interface description) than to adapt.

use hilrig_stamp::civil::utc_from_civil;
use hilrig_stamp::UtcNanos;

/// UBX class NAV.
pub const CLASS_NAV: u8 = 0x01;
/// NAV-PVT id.
pub const ID_PVT: u8 = 0x07;
/// NAV-HPPOSLLH id.
pub const ID_HPPOSLLH: u8 = 0x14;
/// NAV-RELPOSNED id.
pub const ID_RELPOSNED: u8 = 0x3C;
/// NAV-ATT id.
pub const ID_ATT: u8 = 0x05;
/// NAV-PVAT id.
pub const ID_PVAT: u8 = 0x17;
/// UBX class ESF (external sensor fusion).
pub const CLASS_ESF: u8 = 0x10;
/// ESF-ALG id.
pub const ID_ESF_ALG: u8 = 0x14;
/// UBX class HNR (high navigation rate, M8 ADR/UDR).
pub const CLASS_HNR: u8 = 0x28;
/// HNR-PVT id.
pub const ID_HNR_PVT: u8 = 0x00;
/// HNR-ATT id.
pub const ID_HNR_ATT: u8 = 0x01;

/// A UBX payload that does not fit its message layout.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum UbxError {
    /// Wrong payload length.
    #[error("UBX {name} payload has {got} bytes, expected {expected}")]
    Length {
        /// Message name.
        name: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// An angle outside the range its field can hold (roll and heading ±180° / 0-360°, pitch
    /// ±90°): the payload is not what the layout says.
    #[error("UBX {name} {field} is {value}°, outside {min}..{max}")]
    Angle {
        /// Message name.
        name: &'static str,
        /// Field name.
        field: &'static str,
        /// The value read, degrees.
        value: f64,
        /// Smallest valid value.
        min: f64,
        /// Largest valid value.
        max: f64,
    },
    /// A message version this decoder does not know.
    #[error("UBX {name} version {version} is not supported")]
    Version {
        /// Message name.
        name: &'static str,
        /// Version byte.
        version: u8,
    },
}

/// Carrier-phase solution state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CarrierSolution {
    /// No carrier-phase range solution.
    None,
    /// RTK float.
    Float,
    /// RTK fixed.
    Fixed,
}

fn check(
    name: &'static str,
    p: &[u8],
    expected: usize,
    version: Option<u8>,
) -> Result<(), UbxError> {
    if p.len() != expected {
        return Err(UbxError::Length {
            name,
            expected,
            got: p.len(),
        });
    }
    match version {
        Some(v) if p[0] != v => Err(UbxError::Version {
            name,
            version: p[0],
        }),
        _ => Ok(()),
    }
}

/// [`check`] for the messages whose version byte follows the time of week (offset 4:
/// NAV-ATT, NAV-PVAT, HNR-ATT, ESF-ALG).
fn check_after_itow(
    name: &'static str,
    p: &[u8],
    expected: usize,
    version: u8,
) -> Result<(), UbxError> {
    check(name, p, expected, None)?;
    if p[4] != version {
        return Err(UbxError::Version {
            name,
            version: p[4],
        });
    }
    Ok(())
}

fn carrier(bits: u32) -> CarrierSolution {
    match bits & 0x03 {
        1 => CarrierSolution::Float,
        2 => CarrierSolution::Fixed,
        _ => CarrierSolution::None,
    }
}

fn u16le(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}
fn u32le(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn i32le(b: &[u8], o: usize) -> i32 {
    u32le(b, o) as i32
}

/// UTC from the date and time fields every UBX PVT layout shares (year U2 at `at`, then month,
/// day, hour, minute, second; nanoseconds I4 at `nano`), when `valid` and in range.
fn utc_at(p: &[u8], at: usize, valid: bool, nano: usize) -> Option<UtcNanos> {
    let (mo, d, h, mi, s) = (p[at + 2], p[at + 3], p[at + 4], p[at + 5], p[at + 6]);
    if !(valid && (1..=12).contains(&mo) && (1..=31).contains(&d) && h < 24 && mi < 60 && s < 61) {
        return None;
    }
    let tod = ((i64::from(h) * 60 + i64::from(mi)) * 60 + i64::from(s)) * 1_000_000_000
        + i64::from(i32le(p, nano));
    utc_from_civil(i64::from(u16le(p, at)), u32::from(mo), u32::from(d), tod)
}

/// An angle field, degrees, checked against the range the field can hold.
fn angle(
    name: &'static str,
    field: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<f64, UbxError> {
    if (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(UbxError::Angle {
            name,
            field,
            value,
            min,
            max,
        })
    }
}

/// NAV-PVT: the receiver's navigation solution.
#[derive(Clone, Debug, PartialEq)]
pub struct NavPvt {
    /// GPS time of week of the epoch, ms.
    pub itow_ms: u32,
    /// UTC of the epoch, when date and time are valid.
    pub utc: Option<UtcNanos>,
    /// Time accuracy estimate, ns.
    pub t_acc_ns: u32,
    /// Fix type: 0 none, 1 dead reckoning, 2 2D, 3 3D, 4 GNSS + DR, 5 time only.
    pub fix_type: u8,
    /// gnssFixOK flag.
    pub fix_ok: bool,
    /// Differential corrections applied.
    pub diff_soln: bool,
    /// Carrier-phase solution.
    pub carrier: CarrierSolution,
    /// Satellites used.
    pub num_sv: u8,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Height above ellipsoid, metres.
    pub height_m: f64,
    /// Height above mean sea level, metres.
    pub h_msl_m: f64,
    /// Horizontal accuracy estimate, metres.
    pub h_acc_m: f64,
    /// Vertical accuracy estimate, metres.
    pub v_acc_m: f64,
    /// Ground speed, m/s.
    pub ground_speed_mps: f64,
    /// Heading of motion, degrees.
    pub head_motion_deg: f64,
    /// Vehicle heading, degrees, when the receiver marks it valid.
    pub head_vehicle_deg: Option<f64>,
    /// Age of the last correction, upper bound of the receiver's bucket, seconds.
    pub correction_age_s: Option<f64>,
}

/// Upper bounds of NAV-PVT's lastCorrectionAge buckets (index 1..=12), seconds.
const CORRECTION_AGE_BUCKETS: [f64; 12] = [
    1.0,
    2.0,
    5.0,
    10.0,
    15.0,
    20.0,
    30.0,
    45.0,
    60.0,
    90.0,
    120.0,
    f64::INFINITY,
];

impl NavPvt {
    /// Decodes a 92-byte NAV-PVT payload.
    pub fn decode(p: &[u8]) -> Result<NavPvt, UbxError> {
        check("NAV-PVT", p, 92, None)?;
        let utc = utc_at(p, 4, p[11] & 0x03 == 0x03, 16);
        let flags = p[21];
        let carrier = carrier(u32::from(flags >> 6));
        let flags3 = u16le(p, 78);
        let age_idx = usize::from((flags3 >> 1) & 0x0F);
        Ok(NavPvt {
            itow_ms: u32le(p, 0),
            utc,
            t_acc_ns: u32le(p, 12),
            fix_type: p[20],
            fix_ok: flags & 0x01 != 0,
            diff_soln: flags & 0x02 != 0,
            carrier,
            num_sv: p[23],
            lon_deg: f64::from(i32le(p, 24)) * 1e-7,
            lat_deg: f64::from(i32le(p, 28)) * 1e-7,
            height_m: f64::from(i32le(p, 32)) * 1e-3,
            h_msl_m: f64::from(i32le(p, 36)) * 1e-3,
            h_acc_m: f64::from(u32le(p, 40)) * 1e-3,
            v_acc_m: f64::from(u32le(p, 44)) * 1e-3,
            ground_speed_mps: f64::from(i32le(p, 60)) * 1e-3,
            head_motion_deg: f64::from(i32le(p, 64)) * 1e-5,
            head_vehicle_deg: (flags & 0x20 != 0).then(|| f64::from(i32le(p, 84)) * 1e-5),
            correction_age_s: (1..=12)
                .contains(&age_idx)
                .then(|| CORRECTION_AGE_BUCKETS[age_idx - 1]),
        })
    }
}

/// NAV-HPPOSLLH: high-precision geodetic position.
#[derive(Clone, Debug, PartialEq)]
pub struct NavHpposllh {
    /// GPS time of week, ms.
    pub itow_ms: u32,
    /// The receiver flags the position invalid.
    pub invalid: bool,
    /// Longitude, degrees (with the 1e-9 degree high-precision part).
    pub lon_deg: f64,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Height above ellipsoid, metres (0.1 mm resolution).
    pub height_m: f64,
    /// Height above mean sea level, metres.
    pub h_msl_m: f64,
    /// Horizontal accuracy, metres.
    pub h_acc_m: f64,
    /// Vertical accuracy, metres.
    pub v_acc_m: f64,
}

impl NavHpposllh {
    /// Decodes a 36-byte NAV-HPPOSLLH payload (version 0).
    pub fn decode(p: &[u8]) -> Result<NavHpposllh, UbxError> {
        check("NAV-HPPOSLLH", p, 36, Some(0))?;
        let hp = |o: usize| f64::from(p[o] as i8);
        Ok(NavHpposllh {
            itow_ms: u32le(p, 4),
            invalid: p[3] & 0x01 != 0,
            lon_deg: f64::from(i32le(p, 8)) * 1e-7 + hp(24) * 1e-9,
            lat_deg: f64::from(i32le(p, 12)) * 1e-7 + hp(25) * 1e-9,
            height_m: f64::from(i32le(p, 16)) * 1e-3 + hp(26) * 1e-4,
            h_msl_m: f64::from(i32le(p, 20)) * 1e-3 + hp(27) * 1e-4,
            h_acc_m: f64::from(u32le(p, 28)) * 1e-4,
            v_acc_m: f64::from(u32le(p, 32)) * 1e-4,
        })
    }
}

/// NAV-RELPOSNED: position of the rover relative to the reference station (or moving base).
#[derive(Clone, Debug, PartialEq)]
pub struct NavRelposned {
    /// GPS time of week, ms.
    pub itow_ms: u32,
    /// Reference station id.
    pub station_id: u16,
    /// North, east, down, metres.
    pub rel_ned_m: [f64; 3],
    /// Accuracy of north, east, down, metres.
    pub acc_ned_m: [f64; 3],
    /// Heading of the relative position vector, degrees, when valid.
    pub heading_deg: Option<f64>,
    /// Accuracy of that heading, degrees (1 sigma, as the receiver states it).
    pub heading_acc_deg: f64,
    /// Carrier-phase solution.
    pub carrier: CarrierSolution,
    /// The relative position is valid.
    pub valid: bool,
    /// The reference is a moving base (a dual-antenna heading receiver), not a static station.
    pub moving_base: bool,
}

impl NavRelposned {
    /// Decodes a 64-byte NAV-RELPOSNED payload (version 1, F9 series).
    pub fn decode(p: &[u8]) -> Result<NavRelposned, UbxError> {
        check("NAV-RELPOSNED", p, 64, Some(1))?;
        let flags = u32le(p, 60);
        let rel =
            |o: usize, hp: usize| f64::from(i32le(p, o)) * 1e-2 + f64::from(p[hp] as i8) * 1e-4;
        Ok(NavRelposned {
            itow_ms: u32le(p, 4),
            station_id: u16le(p, 2),
            rel_ned_m: [rel(8, 32), rel(12, 33), rel(16, 34)],
            acc_ned_m: [
                f64::from(u32le(p, 36)) * 1e-4,
                f64::from(u32le(p, 40)) * 1e-4,
                f64::from(u32le(p, 44)) * 1e-4,
            ],
            heading_deg: (flags & 0x100 != 0)
                .then(|| {
                    angle(
                        "NAV-RELPOSNED",
                        "relPosHeading",
                        f64::from(i32le(p, 24)) / 1e5,
                        -180.0,
                        360.0,
                    )
                })
                .transpose()?,
            heading_acc_deg: f64::from(u32le(p, 52)) / 1e5,
            carrier: carrier(flags >> 3),
            valid: flags & 0x04 != 0,
            moving_base: flags & 0x20 != 0,
        })
    }
}

/// NAV-ATT and HNR-ATT (the same layout): roll, pitch and heading of the vehicle from the
/// receiver's sensor fusion, with their accuracies.
#[derive(Clone, Debug, PartialEq)]
pub struct Att {
    /// GPS time of week, ms.
    pub itow_ms: u32,
    /// Roll, degrees.
    pub roll_deg: f64,
    /// Pitch, degrees.
    pub pitch_deg: f64,
    /// Heading, degrees.
    pub heading_deg: f64,
    /// Roll accuracy, degrees.
    pub roll_acc_deg: f64,
    /// Pitch accuracy, degrees.
    pub pitch_acc_deg: f64,
    /// Heading accuracy, degrees.
    pub heading_acc_deg: f64,
}

impl Att {
    /// Decodes a 32-byte NAV-ATT (message version 0) or HNR-ATT (version 1) payload; `name`
    /// says which. The version byte follows the time of week.
    pub fn decode(name: &'static str, version: u8, p: &[u8]) -> Result<Att, UbxError> {
        check_after_itow(name, p, 32, version)?;
        let deg = |o: usize| f64::from(i32le(p, o)) / 1e5;
        let acc = |o: usize| f64::from(u32le(p, o)) / 1e5;
        Ok(Att {
            itow_ms: u32le(p, 0),
            roll_deg: angle(name, "roll", deg(8), -180.0, 180.0)?,
            pitch_deg: angle(name, "pitch", deg(12), -90.0, 90.0)?,
            heading_deg: angle(name, "heading", deg(16), -180.0, 360.0)?,
            roll_acc_deg: acc(20),
            pitch_acc_deg: acc(24),
            heading_acc_deg: acc(28),
        })
    }
}

/// NAV-PVAT (F9R): the navigation solution with the vehicle's attitude; each angle only when
/// the receiver marks it valid.
#[derive(Clone, Debug, PartialEq)]
pub struct NavPvat {
    /// GPS time of week, ms.
    pub itow_ms: u32,
    /// UTC of the epoch, when date and time are valid.
    pub utc: Option<UtcNanos>,
    /// Vehicle roll, degrees, when valid.
    pub roll_deg: Option<f64>,
    /// Vehicle pitch, degrees, when valid.
    pub pitch_deg: Option<f64>,
    /// Vehicle heading, degrees, when valid.
    pub heading_deg: Option<f64>,
    /// Heading of motion, degrees.
    pub motion_heading_deg: f64,
    /// Roll accuracy, degrees.
    pub roll_acc_deg: f64,
    /// Pitch accuracy, degrees.
    pub pitch_acc_deg: f64,
    /// Heading accuracy, degrees.
    pub heading_acc_deg: f64,
}

impl NavPvat {
    /// Decodes a 116-byte NAV-PVAT payload (version 0).
    pub fn decode(p: &[u8]) -> Result<NavPvat, UbxError> {
        const NAME: &str = "NAV-PVAT";
        check_after_itow(NAME, p, 116, 0)?;
        let flags = p[25];
        let deg = |o: usize| f64::from(i32le(p, o)) / 1e5;
        let acc = |o: usize| f64::from(u16le(p, o)) / 1e2;
        let valid = |bit: u8, field: &'static str, o: usize, min: f64, max: f64| {
            if flags & bit != 0 {
                angle(NAME, field, deg(o), min, max).map(Some)
            } else {
                Ok(None)
            }
        };
        Ok(NavPvat {
            itow_ms: u32le(p, 0),
            utc: utc_at(p, 6, p[5] & 0x03 == 0x03, 20),
            roll_deg: valid(0x08, "vehRoll", 72, -180.0, 180.0)?,
            pitch_deg: valid(0x10, "vehPitch", 76, -90.0, 90.0)?,
            heading_deg: valid(0x20, "vehHeading", 80, -180.0, 360.0)?,
            motion_heading_deg: deg(84),
            roll_acc_deg: acc(88),
            pitch_acc_deg: acc(90),
            heading_acc_deg: acc(92),
        })
    }
}

/// ESF-ALG: the angles the receiver's IMU is mounted at in the vehicle (its automatic
/// alignment), not the vehicle's attitude.
#[derive(Clone, Debug, PartialEq)]
pub struct EsfAlg {
    /// GPS time of week, ms.
    pub itow_ms: u32,
    /// Alignment status (0 user-defined angles, 1-2 alignment ongoing, 3 coarse, 4 fine).
    pub status: u8,
    /// An alignment error flag is set (tilt, yaw or angle).
    pub error: bool,
    /// Yaw of the IMU in the vehicle, degrees.
    pub yaw_deg: f64,
    /// Pitch, degrees.
    pub pitch_deg: f64,
    /// Roll, degrees.
    pub roll_deg: f64,
}

impl EsfAlg {
    /// Decodes a 16-byte ESF-ALG payload (version 1).
    pub fn decode(p: &[u8]) -> Result<EsfAlg, UbxError> {
        const NAME: &str = "ESF-ALG";
        check_after_itow(NAME, p, 16, 1)?;
        let i16le = |o: usize| u16le(p, o) as i16;
        Ok(EsfAlg {
            itow_ms: u32le(p, 0),
            status: (p[5] >> 1) & 0x07,
            error: p[6] & 0x07 != 0,
            yaw_deg: angle(NAME, "yaw", f64::from(u32le(p, 8)) / 1e2, 0.0, 360.0)?,
            pitch_deg: angle(NAME, "pitch", f64::from(i16le(12)) / 1e2, -90.0, 90.0)?,
            roll_deg: angle(NAME, "roll", f64::from(i16le(14)) / 1e2, -180.0, 180.0)?,
        })
    }
}

/// HNR-PVT, the part the attitude needs: the UTC of a GPS time of week at the high rate.
#[derive(Clone, Debug, PartialEq)]
pub struct HnrPvt {
    /// GPS time of week, ms.
    pub itow_ms: u32,
    /// UTC, when date and time are valid.
    pub utc: Option<UtcNanos>,
}

impl HnrPvt {
    /// Decodes a 72-byte HNR-PVT payload (its time fields).
    pub fn decode(p: &[u8]) -> Result<HnrPvt, UbxError> {
        check("HNR-PVT", p, 72, None)?;
        Ok(HnrPvt {
            itow_ms: u32le(p, 0),
            utc: utc_at(p, 4, p[11] & 0x03 == 0x03, 12),
        })
    }
}

/// A decoded UBX message.
#[derive(Clone, Debug, PartialEq)]
pub enum Ubx {
    /// NAV-PVT.
    NavPvt(NavPvt),
    /// NAV-HPPOSLLH.
    NavHpposllh(NavHpposllh),
    /// NAV-RELPOSNED.
    NavRelposned(NavRelposned),
    /// NAV-ATT.
    NavAtt(Att),
    /// NAV-PVAT.
    NavPvat(NavPvat),
    /// HNR-ATT.
    HnrAtt(Att),
    /// HNR-PVT (its time).
    HnrPvt(HnrPvt),
    /// ESF-ALG.
    EsfAlg(EsfAlg),
    /// Any other class/id (valid frame, not decoded).
    Other {
        /// Class.
        class: u8,
        /// Id.
        id: u8,
    },
}

/// Decodes a UBX payload by class and id.
pub fn decode(class: u8, id: u8, payload: &[u8]) -> Result<Ubx, UbxError> {
    Ok(match (class, id) {
        (CLASS_NAV, ID_PVT) => Ubx::NavPvt(NavPvt::decode(payload)?),
        (CLASS_NAV, ID_HPPOSLLH) => Ubx::NavHpposllh(NavHpposllh::decode(payload)?),
        (CLASS_NAV, ID_RELPOSNED) => Ubx::NavRelposned(NavRelposned::decode(payload)?),
        (CLASS_NAV, ID_ATT) => Ubx::NavAtt(Att::decode("NAV-ATT", 0, payload)?),
        (CLASS_NAV, ID_PVAT) => Ubx::NavPvat(NavPvat::decode(payload)?),
        (CLASS_HNR, ID_HNR_ATT) => Ubx::HnrAtt(Att::decode("HNR-ATT", 1, payload)?),
        (CLASS_HNR, ID_HNR_PVT) => Ubx::HnrPvt(HnrPvt::decode(payload)?),
        (CLASS_ESF, ID_ESF_ALG) => Ubx::EsfAlg(EsfAlg::decode(payload)?),
        _ => Ubx::Other { class, id },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn pvt_fields() {
        let mut p = [0u8; 92];
        p[4..6].copy_from_slice(&2025u16.to_le_bytes());
        p[6] = 4;
        p[7] = 11;
        p[8] = 23;
        p[9] = 14;
        p[10] = 9;
        p[11] = 0x07;
        p[20] = 3;
        p[21] = 0x01 | 0x02 | (1 << 6);
        p[28..32].copy_from_slice(&450_657_718i32.to_le_bytes());
        p[40..44].copy_from_slice(&14u32.to_le_bytes());
        let v = NavPvt::decode(&p).unwrap();
        assert_eq!(v.carrier, CarrierSolution::Float);
        assert!((v.lat_deg - 45.0657718).abs() < 1e-12);
        assert_eq!(
            hilrig_stamp::civil::iso8601_millis(v.utc.unwrap()),
            "2025-04-11T23:14:09.000Z"
        );
        assert!((v.h_acc_m - 0.014).abs() < 1e-12);
        assert!(NavPvt::decode(&p[..91]).is_err());
    }

    #[test]
    fn relposned_fields() {
        let mut p = [0u8; 64];
        p[0] = 1;
        p[2..4].copy_from_slice(&42u16.to_le_bytes());
        p[8..12].copy_from_slice(&123i32.to_le_bytes()); // 1.23 m north
        p[32] = (-5i8) as u8; // -0.5 mm high-precision part
        p[24..28].copy_from_slice(&9_000_000i32.to_le_bytes()); // 90 degrees
        p[36..40].copy_from_slice(&140u32.to_le_bytes()); // 14 mm
        p[60..64].copy_from_slice(&(0x04u32 | (2 << 3) | 0x100).to_le_bytes());
        let r = NavRelposned::decode(&p).unwrap();
        assert_eq!(r.station_id, 42);
        assert!((r.rel_ned_m[0] - 1.2295).abs() < 1e-12);
        assert!((r.acc_ned_m[0] - 0.014).abs() < 1e-12);
        assert!((r.heading_deg.unwrap() - 90.0).abs() < 1e-9);
        assert_eq!(r.carrier, CarrierSolution::Fixed);
        assert!(r.valid);
        p[0] = 0;
        assert_eq!(
            NavRelposned::decode(&p),
            Err(UbxError::Version {
                name: "NAV-RELPOSNED",
                version: 0
            })
        );
    }

    #[test]
    fn hpposllh_adds_the_high_precision_part() {
        let mut p = [0u8; 36];
        p[12..16].copy_from_slice(&(-458_775_252i32).to_le_bytes());
        p[25] = (-9i8) as u8;
        let h = NavHpposllh::decode(&p).unwrap();
        assert!((h.lat_deg - (-45.877_525_2 - 9e-9)).abs() < 1e-12);
    }

    proptest! {
        #[test]
        fn arbitrary_payloads_never_panic(class in any::<u8>(), id in any::<u8>(), p in proptest::collection::vec(any::<u8>(), 0..100)) {
            let _ = decode(class, id, &p);
            let _ = decode(CLASS_NAV, ID_PVT, &p);
        }
    }
}
