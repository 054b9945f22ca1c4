//! Any bytes as an attitude message, NMEA (HDT, THS, PASHR, PSTI,036, checksum added) or UBX
//! (NAV-ATT, NAV-PVAT, NAV-RELPOSNED, HNR-ATT, HNR-PVT, ESF-ALG, framed), through the whole
//! stream: never a panic, and every attitude reported holds finite angles within their range
//! and non-negative accuracies.
#![no_main]
use hilrig_gnss::framer::{nmea_sentence, ubx_frame};
use hilrig_gnss::GnssStream;
use libfuzzer_sys::fuzz_target;

const UBX: [(u8, u8); 6] = [
    (0x01, 0x05),
    (0x01, 0x17),
    (0x01, 0x3C),
    (0x28, 0x01),
    (0x28, 0x00),
    (0x10, 0x14),
];

fuzz_target!(|data: &[u8]| {
    let Some((&select, rest)) = data.split_first() else {
        return;
    };
    let bytes: Vec<u8> = match select % 10 {
        k @ 0..=3 => {
            let Ok(text) = std::str::from_utf8(rest) else {
                return;
            };
            let head = ["GPHDT,", "GNTHS,", "PASHR,", "PSTI,036,"][usize::from(k)];
            // A date and an epoch first, so that the time tagging is reached too.
            let mut s = nmea_sentence("GPRMC,120000.00,A,4807.038,N,01131.000,E,0.0,0.0,251126,,,R");
            s.push_str(&nmea_sentence(&format!("{head}{text}")));
            s.into_bytes()
        }
        k => {
            let (class, id) = UBX[usize::from(k - 4) % UBX.len()];
            ubx_frame(class, id, rest)
        }
    };
    let mut stream = GnssStream::for_gpsd_log().with_attitude();
    let mut fixes = Vec::new();
    stream.push(&bytes, &mut fixes);
    stream.finish(&mut fixes);
    for a in stream.take_attitudes() {
        let within = |v: Option<f64>, lo: f64, hi: f64| v.is_none_or(|x| x.is_finite() && (lo..=hi).contains(&x));
        assert!(within(a.heading_deg, -180.0, 360.0), "{a:?}");
        assert!(within(a.yaw_deg, -180.0, 360.0), "{a:?}");
        assert!(within(a.pitch_deg, -90.0, 90.0), "{a:?}");
        assert!(within(a.roll_deg, -180.0, 180.0), "{a:?}");
        for s in [a.sigma_heading_deg, a.sigma_pitch_deg, a.sigma_roll_deg] {
            assert!(s.is_none_or(|x| x.is_finite() && x >= 0.0), "{a:?}");
        }
    }
});
