//! The conversion of what the drivers deliver into the messages of the MCAP contract
//! (DESIGN.md): NavSatFix from a GNSS fix, PointCloud2 from a rotation's packets.
//! Shared by the recorder from captures and the live recorder, so both write the same bytes.

use crate::bag::msgs::{self, NavSatFix};
use hilrig_gnss::epoch::Fix;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::Decoder;

/// The NavSatFix of a fix (covariance from the sigmas; altitude above the ellipsoid).
pub fn nav_sat_fix(f: &Fix) -> Option<NavSatFix> {
    let (lat, lon) = (f.lat?, f.lon?);
    let status = match f.quality {
        0 => -1,
        2 | 9 => 1,
        4 | 5 => 2,
        _ => 0,
    };
    let (covariance, covariance_type) = match (f.sigma_lon_m, f.sigma_lat_m, f.sigma_alt_m) {
        (Some(e), Some(n), Some(u)) => ([e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, u * u], 2),
        _ => ([0.0; 9], 0),
    };
    Some(NavSatFix {
        status,
        service: 1,
        latitude: lat,
        longitude: lon,
        // NavSatFix wants height above the ellipsoid; MSL only when the geoid separation is unknown.
        altitude: f.alt_ellipsoid.or(f.alt_msl).unwrap_or(f64::NAN),
        covariance,
        covariance_type,
    })
}

/// The decoded points of one rotation as a PointCloud2 (for viewing in Foxglove / RViz).
pub fn cloud_cdr(
    decoder: &Decoder,
    stamp: UtcNanos,
    frame: &str,
    packets: &[(UtcNanos, &[u8; 1206])],
) -> Vec<u8> {
    let mut cloud = msgs::PointCloudWriter::new(stamp, frame, packets.len() * 384);
    let mut buf = Vec::with_capacity(800);
    // The packet before (a dual-return VLS-128 packet takes its rotation rate from it).
    let mut previous: Option<hilrig_velodyne::DataPacket> = None;
    for (t, bytes) in packets {
        let Ok(p) = hilrig_velodyne::DataPacket::decode(&bytes[..]) else {
            continue;
        };
        buf.clear();
        let decoded = decoder.decode_into_after(&p, previous.as_ref(), &mut buf);
        previous = Some(p);
        if decoded.is_err() {
            continue;
        }
        let base = (t.0 - stamp.0) as f64 * 1e-9;
        for q in &buf {
            cloud.push(
                q.x,
                q.y,
                q.z,
                f32::from(q.intensity),
                u16::from(q.ring),
                (base + f64::from(q.time_offset_ns) * 1e-9) as f32,
            );
        }
    }
    cloud.finish()
}
