//! HDL-64E S2/S3 packets (upper and lower bank blocks, dual return told by repeated azimuths)
//! decoded with a calibration the input also chooses: angles, offsets, far and near-point
//! distance corrections (the two-point path). Errors are fine; panics are not, and every point
//! a plausible calibration gives is finite.
#![no_main]
use hilrig_velodyne::calibration::TwoPointCorrection;
use hilrig_velodyne::{Calibration, DataPacket, Decoder, Model};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 8 {
        return;
    }
    let (head, body) = data.split_at(8);
    let mut buf = body.to_vec();
    buf.resize(hilrig_velodyne::DATA_PACKET_SIZE, 0);
    let dual = head[0] & 1 == 1;
    for i in 0..12 {
        buf[i * 100] = 0xFF;
        // Upper and lower banks in pairs, or as the input says.
        buf[i * 100 + 1] = if head[0] & 2 == 0 {
            if i % 2 == 0 { 0xEE } else { 0xDD }
        } else if body.get(i).is_some_and(|b| b & 1 == 1) {
            0xEE
        } else {
            0xDD
        };
        if dual && i % 4 >= 2 {
            // A dual packet repeats each pair's azimuths.
            let (a, b) = (buf[(i - 2) * 100 + 2], buf[(i - 2) * 100 + 3]);
            buf[i * 100 + 2] = a;
            buf[i * 100 + 3] = b;
        }
    }
    let Ok(pkt) = DataPacket::decode(&buf) else {
        return;
    };
    let scale = |b: u8, s: f64| (f64::from(b) - 128.0) * s;
    for model in [Model::Hdl64eS2, Model::Hdl64eS3] {
        let mut cal = Calibration::builtin(model);
        for (k, l) in cal.lasers.iter_mut().enumerate() {
            let b = |j: usize| head[(k + j) % 8] ^ (k as u8).wrapping_mul(37);
            l.rot_correction_rad = scale(b(1), 0.001);
            l.vertical_offset_m = scale(b(2), 0.002);
            l.horizontal_offset_m = scale(b(3), 0.0005);
            l.distance_correction_m = scale(b(4), 0.01);
        }
        if head[5] & 1 == 1 {
            cal.two_point = cal
                .lasers
                .iter()
                .enumerate()
                .map(|(k, l)| {
                    let b = |j: usize| head[(k + j) % 8] ^ (k as u8).wrapping_mul(37);
                    Some(TwoPointCorrection {
                        x_m: l.distance_correction_m + scale(b(6), 0.001),
                        y_m: l.distance_correction_m + scale(b(7), 0.001),
                    })
                })
                .collect();
        }
        // Through the file reader, as a user's calibration comes in.
        let Ok(cal) = Calibration::from_text(&cal.to_yaml(), model) else {
            continue;
        };
        let d = Decoder::with_calibration(model, cal);
        let mut out = Vec::new();
        if d.decode_into(&pkt, &mut out).is_ok() {
            for p in &out {
                assert!(p.x.is_finite() && p.y.is_finite() && p.z.is_finite());
            }
        }
        let _ = d.decode_into_after(&pkt, Some(&pkt), &mut out);
    }
});
