//! Attitude reports of the reference system: the heading (and roll, pitch) that an INS or a
//! dual-antenna (moving base) receiver measures itself, with the accuracy the message states.
//!
//! One [`Attitude`] per message, time-tagged like the fixes: a message with its own time
//! (PASHR, PSTI,036, NAV-PVAT) by that time on the date the stream has seen; one without (HDT,
//! THS) by the NMEA epoch in progress; the UBX messages that carry only the GPS time of week
//! (NAV-ATT, HNR-ATT, NAV-RELPOSNED) by the week's offset to UTC that the last NAV-PVT,
//! NAV-PVAT or HNR-PVT showed. A message that its own flags mark invalid (THS mode V, PSTI,036
//! mode N, a NAV-PVAT without a valid angle, a moving-base NAV-RELPOSNED without a valid
//! heading, an empty HDT) is counted and never reported; a malformed one (an angle out of its
//! range, NaN, a bad checksum) fails to decode and is counted with the decode errors.

use crate::nmea::Sentence;
use crate::ubx::{Att, Ubx};
use hilrig_stamp::UtcNanos;

/// The message an attitude report came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AttitudeSource {
    /// NMEA HDT (true heading).
    Hdt,
    /// NMEA THS (true heading with mode).
    Ths,
    /// PASHR (INS attitude with accuracies).
    Pashr,
    /// SkyTraq PSTI,036 (dual-antenna heading, pitch, roll).
    Psti036,
    /// UBX NAV-ATT.
    NavAtt,
    /// UBX NAV-PVAT (F9R).
    NavPvat,
    /// UBX NAV-RELPOSNED of a moving-base rover (the baseline's heading).
    NavRelposned,
    /// UBX HNR-ATT (M8U/M8L high rate).
    HnrAtt,
    /// UBX ESF-ALG: the IMU's mounting angles in the vehicle.
    EsfAlg,
}

impl AttitudeSource {
    /// The message's name as its specification writes it (and hilrig's JSON).
    pub fn name(self) -> &'static str {
        match self {
            AttitudeSource::Hdt => "HDT",
            AttitudeSource::Ths => "THS",
            AttitudeSource::Pashr => "PASHR",
            AttitudeSource::Psti036 => "PSTI,036",
            AttitudeSource::NavAtt => "NAV-ATT",
            AttitudeSource::NavPvat => "NAV-PVAT",
            AttitudeSource::NavRelposned => "NAV-RELPOSNED",
            AttitudeSource::HnrAtt => "HNR-ATT",
            AttitudeSource::EsfAlg => "ESF-ALG",
        }
    }
}

/// How the source says it obtained the attitude.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AttitudeMode {
    /// Measured (autonomous, differential, RTK; every source without a mode field).
    Measured,
    /// Estimated: dead reckoning, held over an outage.
    Estimated,
    /// Entered by hand.
    Manual,
    /// From a simulator.
    Simulator,
}

impl AttitudeMode {
    /// Lower-case name, as in hilrig's JSON.
    pub fn name(self) -> &'static str {
        match self {
            AttitudeMode::Measured => "measured",
            AttitudeMode::Estimated => "estimated",
            AttitudeMode::Manual => "manual",
            AttitudeMode::Simulator => "simulator",
        }
    }

    /// The NMEA mode indicator (THS, PSTI,036): `None` for V and N (not valid) and characters
    /// the specifications do not define.
    fn from_nmea(c: Option<char>) -> Option<AttitudeMode> {
        match c {
            None | Some('A' | 'D' | 'F' | 'R' | 'P') => Some(AttitudeMode::Measured),
            Some('E') => Some(AttitudeMode::Estimated),
            Some('M') => Some(AttitudeMode::Manual),
            Some('S') => Some(AttitudeMode::Simulator),
            Some(_) => None,
        }
    }
}

/// What an attitude report is the attitude of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AttitudeOf {
    /// The vehicle, in the local level frame: what the trajectory's heading is checked against.
    Vehicle,
    /// The receiver's IMU in the vehicle (ESF-ALG: the mounting the receiver estimated; its
    /// yaw is a mounting angle, not a heading).
    SensorMounting,
}

impl AttitudeOf {
    /// Lower-case name, as in hilrig's JSON.
    pub fn name(self) -> &'static str {
        match self {
            AttitudeOf::Vehicle => "vehicle",
            AttitudeOf::SensorMounting => "sensor_mounting",
        }
    }
}

/// One attitude report.
#[derive(Clone, Debug, PartialEq)]
pub struct Attitude {
    /// What it is the attitude of.
    pub of: AttitudeOf,
    /// UTC, when the stream's date (or the week's offset to UTC) is known.
    pub time: Option<UtcNanos>,
    /// The message.
    pub source: AttitudeSource,
    /// How it was obtained.
    pub mode: AttitudeMode,
    /// Heading, degrees clockwise from true north.
    pub heading_deg: Option<f64>,
    /// Yaw of a mounting, degrees (the sensor's, not a heading).
    pub yaw_deg: Option<f64>,
    /// Pitch, degrees.
    pub pitch_deg: Option<f64>,
    /// Roll, degrees.
    pub roll_deg: Option<f64>,
    /// Heading accuracy (1 sigma), degrees, where the message states one.
    pub sigma_heading_deg: Option<f64>,
    /// Pitch accuracy (1 sigma), degrees.
    pub sigma_pitch_deg: Option<f64>,
    /// Roll accuracy (1 sigma), degrees.
    pub sigma_roll_deg: Option<f64>,
}

/// What a sentence or message says about the attitude.
#[derive(Clone, Debug, PartialEq)]
pub enum Reading {
    /// Not an attitude message.
    None,
    /// An attitude report.
    Attitude(Attitude),
    /// An attitude message its own flags mark invalid.
    Invalid(AttitudeSource),
}

fn report(source: AttitudeSource, mode: AttitudeMode, time: Option<UtcNanos>) -> Attitude {
    Attitude {
        of: AttitudeOf::Vehicle,
        time,
        source,
        mode,
        heading_deg: None,
        yaw_deg: None,
        pitch_deg: None,
        roll_deg: None,
        sigma_heading_deg: None,
        sigma_pitch_deg: None,
        sigma_roll_deg: None,
    }
}

/// The attitude in an NMEA sentence; `time` is its UTC (the sentence's own time, or the
/// epoch's for HDT and THS).
pub fn from_nmea(s: &Sentence, time: Option<UtcNanos>) -> Reading {
    use AttitudeSource as S;
    match s {
        Sentence::Hdt(h) => match h.heading_deg {
            Some(h) => Reading::Attitude(Attitude {
                heading_deg: Some(h),
                ..report(S::Hdt, AttitudeMode::Measured, time)
            }),
            None => Reading::Invalid(S::Hdt),
        },
        Sentence::Ths(t) => match (t.heading_deg, AttitudeMode::from_nmea(t.mode)) {
            (Some(h), Some(mode)) => Reading::Attitude(Attitude {
                heading_deg: Some(h),
                ..report(S::Ths, mode, time)
            }),
            _ => Reading::Invalid(S::Ths),
        },
        Sentence::Pashr(p) => {
            if p.heading_deg.is_none() && p.roll_deg.is_none() && p.pitch_deg.is_none() {
                return Reading::Invalid(S::Pashr);
            }
            Reading::Attitude(Attitude {
                heading_deg: p.heading_deg,
                pitch_deg: p.pitch_deg,
                roll_deg: p.roll_deg,
                sigma_heading_deg: p.sigma_heading_deg,
                sigma_pitch_deg: p.sigma_pitch_deg,
                sigma_roll_deg: p.sigma_roll_deg,
                ..report(S::Pashr, AttitudeMode::Measured, time)
            })
        }
        Sentence::Psti036(p) => match (p.heading_deg, p.mode) {
            (Some(_), Some(c)) => match AttitudeMode::from_nmea(Some(c)) {
                Some(mode) => Reading::Attitude(Attitude {
                    heading_deg: p.heading_deg,
                    pitch_deg: p.pitch_deg,
                    roll_deg: p.roll_deg,
                    ..report(S::Psti036, mode, time)
                }),
                None => Reading::Invalid(S::Psti036),
            },
            _ => Reading::Invalid(S::Psti036),
        },
        _ => Reading::None,
    }
}

fn att(source: AttitudeSource, a: &Att, time: Option<UtcNanos>) -> Reading {
    Reading::Attitude(Attitude {
        heading_deg: Some(a.heading_deg),
        pitch_deg: Some(a.pitch_deg),
        roll_deg: Some(a.roll_deg),
        sigma_heading_deg: Some(a.heading_acc_deg),
        sigma_pitch_deg: Some(a.pitch_acc_deg),
        sigma_roll_deg: Some(a.roll_acc_deg),
        ..report(source, AttitudeMode::Measured, time)
    })
}

/// The attitude in a UBX message; `time` is the UTC of its time of week.
pub fn from_ubx(m: &Ubx, time: Option<UtcNanos>) -> Reading {
    use AttitudeSource as S;
    match m {
        Ubx::NavAtt(a) => att(S::NavAtt, a, time),
        Ubx::HnrAtt(a) => att(S::HnrAtt, a, time),
        Ubx::NavPvat(p) => {
            if p.heading_deg.is_none() && p.pitch_deg.is_none() && p.roll_deg.is_none() {
                return Reading::Invalid(S::NavPvat);
            }
            Reading::Attitude(Attitude {
                heading_deg: p.heading_deg,
                pitch_deg: p.pitch_deg,
                roll_deg: p.roll_deg,
                sigma_heading_deg: p.heading_deg.map(|_| p.heading_acc_deg),
                sigma_pitch_deg: p.pitch_deg.map(|_| p.pitch_acc_deg),
                sigma_roll_deg: p.roll_deg.map(|_| p.roll_acc_deg),
                ..report(S::NavPvat, AttitudeMode::Measured, p.utc.or(time))
            })
        }
        Ubx::EsfAlg(a) if a.error => Reading::Invalid(S::EsfAlg),
        Ubx::EsfAlg(a) => Reading::Attitude(Attitude {
            of: AttitudeOf::SensorMounting,
            yaw_deg: Some(a.yaw_deg),
            pitch_deg: Some(a.pitch_deg),
            roll_deg: Some(a.roll_deg),
            ..report(
                S::EsfAlg,
                if a.status == 0 {
                    AttitudeMode::Manual
                } else {
                    AttitudeMode::Measured
                },
                time,
            )
        }),
        // Only a moving-base rover's baseline is an attitude; a static base's is a position.
        Ubx::NavRelposned(r) if r.moving_base => match r.heading_deg {
            Some(h) if r.valid => Reading::Attitude(Attitude {
                heading_deg: Some(h),
                sigma_heading_deg: Some(r.heading_acc_deg),
                ..report(S::NavRelposned, AttitudeMode::Measured, time)
            }),
            _ => Reading::Invalid(S::NavRelposned),
        },
        _ => Reading::None,
    }
}

/// The UTC of a GPS time of week, from one known pair (time of week, UTC) within half a week
/// of it: the offset between GPS time and UTC (leap seconds) and the week are the pair's.
pub fn utc_of_itow(itow_ms: u32, known: (u32, UtcNanos)) -> UtcNanos {
    const WEEK_MS: i64 = 604_800_000;
    let mut d = i64::from(itow_ms) - i64::from(known.0);
    if d > WEEK_MS / 2 {
        d -= WEEK_MS;
    } else if d < -WEEK_MS / 2 {
        d += WEEK_MS;
    }
    UtcNanos(known.1 .0.saturating_add(d * 1_000_000))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nmea::parse;

    fn sentence(body: &str) -> Sentence {
        parse(&crate::framer::nmea_sentence(body)).unwrap()
    }

    #[test]
    fn ths_modes_and_the_invalid_one() {
        let t = Some(UtcNanos(5));
        let Reading::Attitude(a) = from_nmea(&sentence("GNTHS,244.28,A"), t) else {
            panic!()
        };
        assert_eq!(
            (a.heading_deg, a.mode, a.time),
            (Some(244.28), AttitudeMode::Measured, t)
        );
        let Reading::Attitude(a) = from_nmea(&sentence("GNTHS,10.5,E"), t) else {
            panic!()
        };
        assert_eq!(a.mode, AttitudeMode::Estimated);
        assert_eq!(
            from_nmea(&sentence("GNTHS,10.5,V"), t),
            Reading::Invalid(AttitudeSource::Ths)
        );
        assert_eq!(
            from_nmea(&sentence("GNTHS,,A"), t),
            Reading::Invalid(AttitudeSource::Ths)
        );
        // Out of range and NaN fail to decode: a malformed sentence, not an attitude.
        assert!(parse(&crate::framer::nmea_sentence("GNTHS,361.0,A")).is_err());
        // Found by cargo-fuzz: an HDT of 828° was taken as a heading.
        assert!(parse(&crate::framer::nmea_sentence("GPHDT,828,T")).is_err());
        assert!(parse(&crate::framer::nmea_sentence("GNTHS,NaN,A")).is_err());
    }

    #[test]
    fn pashr_of_a_span_unit() {
        // NovAtel's example (OEM7 firmware 7.03 and later: with the INS status).
        let s = sentence("PASHR,163029.000,158.09,T,-0.30,+0.31,+0.01,0.029,0.029,0.059,1,1");
        let Sentence::Pashr(p) = &s else { panic!() };
        assert_eq!(
            p.time_of_day,
            Some(((16 * 60 + 30) * 60 + 29) * 1_000_000_000)
        );
        let Reading::Attitude(a) = from_nmea(&s, None) else {
            panic!()
        };
        assert_eq!(a.heading_deg, Some(158.09));
        assert_eq!(a.roll_deg, Some(-0.30));
        assert_eq!(a.pitch_deg, Some(0.31));
        assert_eq!(a.sigma_heading_deg, Some(0.059));
        assert_eq!(a.sigma_roll_deg, Some(0.029));
        assert_eq!(a.source.name(), "PASHR");
        // The older firmware's form without the INS status reads too.
        assert!(matches!(
            sentence("PASHR,163029.000,158.09,T,-0.30,+0.31,+0.01,0.029,0.029,0.059,1"),
            Sentence::Pashr(_)
        ));
        // Ashtech's named forms are other sentences.
        assert!(matches!(
            sentence("PASHR,ATT,88536.0000,345.9640,0.0390,-0.9052,0.0024,0.0144,0"),
            Sentence::Other { .. }
        ));
    }

    #[test]
    fn psti_036_with_its_mode() {
        let s = sentence("PSTI,036,003832.000,290322,244.28,2.77,0.00,R");
        let Sentence::Psti036(p) = &s else { panic!() };
        assert_eq!(p.date, Some((2022, 3, 29)));
        let Reading::Attitude(a) = from_nmea(&s, None) else {
            panic!()
        };
        assert_eq!(
            (a.heading_deg, a.pitch_deg, a.roll_deg),
            (Some(244.28), Some(2.77), Some(0.0))
        );
        assert_eq!(
            from_nmea(
                &sentence("PSTI,036,003832.000,290322,244.28,2.77,0.00,N"),
                None
            ),
            Reading::Invalid(AttitudeSource::Psti036)
        );
    }

    /// A moving-base rover's baseline heading is an attitude; a static base's baseline is
    /// not; a moving base without a valid heading is counted invalid.
    #[test]
    fn relposned_heading_only_from_a_moving_base() {
        let frame = |flags: u32| {
            let mut p = [0u8; 64];
            p[0] = 1;
            p[4..8].copy_from_slice(&1000u32.to_le_bytes());
            p[24..28].copy_from_slice(&(-9_012_345i32).to_le_bytes());
            p[52..56].copy_from_slice(&25_000u32.to_le_bytes());
            p[60..64].copy_from_slice(&flags.to_le_bytes());
            crate::ubx::decode(0x01, 0x3C, &p).unwrap()
        };
        let (valid, moving, heading) = (0x04, 0x20, 0x100);
        let Reading::Attitude(a) = from_ubx(&frame(valid | moving | heading), None) else {
            panic!()
        };
        assert_eq!(a.heading_deg, Some(-90.12345));
        assert_eq!(a.sigma_heading_deg, Some(0.25));
        assert_eq!(a.source.name(), "NAV-RELPOSNED");
        assert_eq!(from_ubx(&frame(valid | heading), None), Reading::None);
        assert_eq!(
            from_ubx(&frame(valid | moving), None),
            Reading::Invalid(AttitudeSource::NavRelposned)
        );
        // Found by cargo-fuzz: a heading flagged valid at -7717.5° was reported. Malformed.
        let mut p = [0u8; 64];
        p[0] = 1;
        p[24..28].copy_from_slice(&(-771_751_936i32).to_le_bytes());
        p[60..64].copy_from_slice(&(valid | moving | heading).to_le_bytes());
        assert!(crate::ubx::decode(0x01, 0x3C, &p).is_err());
    }

    /// NAV-PVAT: each angle only with its valid flag, accuracies in 0.01°; ESF-ALG: the IMU's
    /// mounting, not the vehicle's attitude; an alignment error is invalid.
    #[test]
    fn pvat_angles_by_their_flags_and_alg_as_a_mounting() {
        let mut p = [0u8; 116];
        p[25] = 0x08 | 0x10; // roll and pitch valid, heading not
        p[72..76].copy_from_slice(&150_000i32.to_le_bytes());
        p[76..80].copy_from_slice(&(-250_000i32).to_le_bytes());
        p[80..84].copy_from_slice(&9_000_000i32.to_le_bytes());
        p[88..90].copy_from_slice(&7u16.to_le_bytes());
        p[90..92].copy_from_slice(&8u16.to_le_bytes());
        let Reading::Attitude(a) = from_ubx(&crate::ubx::decode(0x01, 0x17, &p).unwrap(), None)
        else {
            panic!()
        };
        assert_eq!(
            (a.roll_deg, a.pitch_deg, a.heading_deg),
            (Some(1.5), Some(-2.5), None)
        );
        assert_eq!(
            (a.sigma_roll_deg, a.sigma_pitch_deg),
            (Some(0.07), Some(0.08))
        );
        // Pitch beyond 90°: malformed.
        p[76..80].copy_from_slice(&9_100_000i32.to_le_bytes());
        assert!(crate::ubx::decode(0x01, 0x17, &p).is_err());

        let mut q = [0u8; 16];
        q[4] = 1;
        q[5] = 4 << 1; // fine alignment
        q[8..12].copy_from_slice(&35_990u32.to_le_bytes());
        q[12..14].copy_from_slice(&(-120i16).to_le_bytes());
        let Reading::Attitude(a) = from_ubx(&crate::ubx::decode(0x10, 0x14, &q).unwrap(), None)
        else {
            panic!()
        };
        assert_eq!(a.of, AttitudeOf::SensorMounting);
        assert_eq!(
            (a.yaw_deg, a.pitch_deg, a.heading_deg),
            (Some(359.9), Some(-1.2), None)
        );
        q[6] = 0x02; // yaw alignment error
        assert_eq!(
            from_ubx(&crate::ubx::decode(0x10, 0x14, &q).unwrap(), None),
            Reading::Invalid(AttitudeSource::EsfAlg)
        );
    }

    #[test]
    fn the_time_of_week_carries_over_the_week_end() {
        let known = (604_799_000, UtcNanos(1_000_000_000_000));
        // One second later is the next week's second 0.
        assert_eq!(
            utc_of_itow(0, known),
            UtcNanos(1_000_000_000_000 + 1_000_000_000)
        );
        assert_eq!(
            utc_of_itow(604_798_900, known),
            UtcNanos(1_000_000_000_000 - 100_000_000)
        );
    }
}
