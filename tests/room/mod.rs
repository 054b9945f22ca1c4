//! The round-room captures in fixtures/ (`vlp16_room.pcapng`, `vlp32c_dual_room.pcapng`): a
//! static sensor 1.8 m above a flat floor, inside a cylindrical wall of radius 8 m, with a
//! doorway (no return) between 90° and 100° azimuth. Ranges are analytic, so the decoded points
//! can be checked against closed-form values.
//!
//! Shared by the test that checks the committed files byte for byte (`tests/fixtures.rs`) and by
//! the command that rewrites them after an intended change of the generator
//! (`cargo run --example bless_room_fixtures`); a test never writes them.

#![allow(dead_code)]

use hilrig::capture::writer::udp_ethernet_frame;
use hilrig::capture::{LinkType, PcapngWriter, UtcNanos};
use hilrig::velodyne::decode::firing_offset_us;
use hilrig::velodyne::{
    Channel, Decoder, Model, PacketEncoder, PositionPacket, PpsStatus, ReturnMode, Sequence,
};
use std::net::{Ipv4Addr, SocketAddrV4};
use std::path::PathBuf;

pub const HEIGHT: f64 = 1.8;
pub const RADIUS: f64 = 8.0;
pub const START: i64 = 1_700_000_000_000_000_000; // 2023-11-14T22:13:20Z
pub const SPIN_HZ: f64 = 10.0;

/// Analytic range of a beam at elevation `omega` and azimuth `az_deg` (None: doorway / no return).
pub fn room_range(omega: f64, az_deg: f64) -> Option<f64> {
    if (90.0..100.0).contains(&az_deg) && omega > -0.1 {
        return None;
    }
    let wall = RADIUS / omega.cos();
    if omega < 0.0 {
        let floor = HEIGHT / (-omega).sin();
        if floor < wall {
            return Some(floor);
        }
    }
    Some(wall)
}

pub fn fixture_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// Makes the room capture for a model and return mode, `packets` data packets long.
pub fn generate(model: Model, mode: ReturnMode, packets: usize) -> Vec<u8> {
    let decoder = Decoder::new(model);
    let cal = decoder.calibration().clone();
    let res = cal.distance_resolution_m;
    let mut w = PcapngWriter::new(Vec::new(), "hilrig tests/fixtures.rs").unwrap();
    let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
    let sensor = |port| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), port);
    let host = |port| SocketAddrV4::new(Ipv4Addr::new(255, 255, 255, 255), port);
    let mut enc = PacketEncoder::new(model, mode);
    let per_block = model.timing().sequences_per_block;
    let seq_us = model.timing().sequence_us;
    let mut seq_index: u64 = 0;
    let mut written = 0;
    let mut next_position_us = 0.0;
    while written < packets {
        let t_us = seq_index as f64 * seq_us;
        let t = UtcNanos(START + (t_us * 1000.0).round() as i64);
        if t_us >= next_position_us {
            // One position packet per second of sensor time, PPS locked, RMC of the last second.
            let secs = t.secs_nanos().0;
            let nmea = rmc_sentence(secs);
            let toh = (t.nanos_past_hour() / 1000) as u32;
            let pos = PositionPacket::new(toh, PpsStatus::Locked, &nmea);
            w.write_packet(
                eth,
                t,
                &udp_ethernet_frame(sensor(8308), host(8308), &pos.encode()),
            )
            .unwrap();
            next_position_us += 1e6;
        }
        let az_centi = ((t_us * 1e-6 * SPIN_HZ * 36_000.0).round() as u64 % 36_000) as u16;
        let col = 0; // firing offsets within a sequence do not depend on the column
        let mut strongest = Vec::new();
        let mut last = Vec::new();
        for (laser, l) in cal.lasers.iter().enumerate() {
            let dt = firing_offset_us(model, col, laser) - firing_offset_us(model, col, 0);
            let az = (f64::from(az_centi) + dt * 1e-6 * SPIN_HZ * 36_000.0) / 100.0;
            let az_beam = (az - l.rot_correction_rad.to_degrees()).rem_euclid(360.0);
            let refl = (20 + laser * 5) as u8;
            match room_range(l.vertical_rad, az_beam) {
                Some(d) => {
                    let raw = (d / res).round() as u16;
                    strongest.push(Channel {
                        distance: raw,
                        reflectivity: refl,
                    });
                    // Dual: a weak early echo (dust) at 1.5 m on every fourth laser.
                    let early = (laser % 4 == 0).then(|| (1.5 / res).round() as u16);
                    last.push(Channel {
                        distance: raw,
                        reflectivity: refl,
                    });
                    if let Some(e) = early {
                        // Strongest is the wall, last is the wall too: report the early echo as
                        // the second strongest, as the manuals describe.
                        *strongest.last_mut().unwrap() = Channel {
                            distance: e,
                            reflectivity: 3,
                        };
                    }
                }
                None => {
                    strongest.push(Channel::default());
                    last.push(Channel::default());
                }
            }
        }
        let seq = Sequence {
            azimuth: az_centi,
            strongest: if mode == ReturnMode::Dual {
                strongest
            } else {
                last.clone()
            },
            last: (mode == ReturnMode::Dual).then_some(last),
        };
        let toh = (t.nanos_past_hour() / 1000) as u32;
        if let Some(pkt) = enc.push(&seq, toh).unwrap() {
            // The packet leaves the sensor after its last firing; stamp it then.
            let n_seq = enc.sequences_per_packet() as f64;
            let first_us = (seq_index as f64 + 1.0 - n_seq) * seq_us;
            let host_t =
                UtcNanos(START + ((first_us + n_seq * seq_us) * 1000.0).round() as i64 + 150_000);
            w.write_packet(
                eth,
                host_t,
                &udp_ethernet_frame(sensor(2368), host(2368), &pkt.encode()),
            )
            .unwrap();
            written += 1;
        }
        seq_index += 1;
        let _ = per_block;
    }
    w.finish().unwrap()
}

pub fn rmc_sentence(secs: i64) -> String {
    let days = secs.div_euclid(86_400);
    let tod = secs.rem_euclid(86_400);
    let (y, m, d) = hilrig::stamp::civil::civil_from_days(days).unwrap();
    let body = format!(
        "GPRMC,{:02}{:02}{:02},A,4807.0380,N,01131.0000,E,000.0,000.0,{:02}{:02}{:02},,,A",
        tod / 3600,
        tod / 60 % 60,
        tod % 60,
        d,
        m,
        y % 100
    );
    hilrig::gnss::framer::nmea_sentence(&body)
}

pub const FIXTURES: [(&str, Model, ReturnMode, usize); 2] = [
    (
        "vlp16_room.pcapng",
        Model::Vlp16,
        ReturnMode::Strongest,
        160,
    ),
    (
        "vlp32c_dual_room.pcapng",
        Model::Vlp32c,
        ReturnMode::Dual,
        320,
    ),
];
