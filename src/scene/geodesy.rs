//! WGS84 geodetic coordinates, ECEF and the local ENU frame of a scene origin.
//!
//! Short closed-form functions rather than a crate: geodetic -> ECEF is one formula, ECEF ->
//! geodetic uses Bowring's method with one refinement (sub-millimetre at the Earth's surface),
//! and ENU is a rotation. They are tested against published values and by round trips.

use crate::scene::file::Wgs84;
use nalgebra::{Matrix3, Vector3};

/// WGS84 semi-major axis, metres.
pub const A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const F: f64 = 1.0 / 298.257_223_563;
const E2: f64 = F * (2.0 - F);
const B: f64 = A * (1.0 - F);
const EP2: f64 = (A * A - B * B) / (B * B);

/// Geodetic to Earth-centred, Earth-fixed.
pub fn to_ecef(p: &Wgs84) -> Vector3<f64> {
    let (lat, lon) = (p.latitude_deg.to_radians(), p.longitude_deg.to_radians());
    let n = A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
    Vector3::new(
        (n + p.height_m) * lat.cos() * lon.cos(),
        (n + p.height_m) * lat.cos() * lon.sin(),
        (n * (1.0 - E2) + p.height_m) * lat.sin(),
    )
}

/// Earth-centred, Earth-fixed to geodetic (Bowring, one refinement step).
pub fn from_ecef(x: &Vector3<f64>) -> Wgs84 {
    let p = x.x.hypot(x.y);
    let lon = x.y.atan2(x.x);
    let theta = (x.z * A).atan2(p * B);
    let mut lat = (x.z + EP2 * B * theta.sin().powi(3)).atan2(p - E2 * A * theta.cos().powi(3));
    for _ in 0..2 {
        let n = A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
        let h = p / lat.cos() - n;
        lat = (x.z / p / (1.0 - E2 * n / (n + h))).atan();
    }
    let n = A / (1.0 - E2 * lat.sin().powi(2)).sqrt();
    let h = if lat.cos().abs() > 1e-9 {
        p / lat.cos() - n
    } else {
        x.z.abs() - B
    };
    Wgs84 {
        latitude_deg: lat.to_degrees(),
        longitude_deg: lon.to_degrees(),
        height_m: h,
    }
}

/// The local East-North-Up frame at an origin.
#[derive(Clone, Debug, PartialEq)]
pub struct Enu {
    origin: Vector3<f64>,
    /// ECEF -> ENU rotation.
    rot: Matrix3<f64>,
}

impl Enu {
    /// The frame at `origin`.
    pub fn new(origin: &Wgs84) -> Enu {
        let (lat, lon) = (
            origin.latitude_deg.to_radians(),
            origin.longitude_deg.to_radians(),
        );
        let (sl, cl) = lat.sin_cos();
        let (so, co) = lon.sin_cos();
        Enu {
            origin: to_ecef(origin),
            rot: Matrix3::new(-so, co, 0.0, -sl * co, -sl * so, cl, cl * co, cl * so, sl),
        }
    }

    /// Geodetic to local ENU metres.
    pub fn from_wgs84(&self, p: &Wgs84) -> Vector3<f64> {
        self.rot * (to_ecef(p) - self.origin)
    }

    /// Local ENU metres to geodetic.
    pub fn to_wgs84(&self, enu: &Vector3<f64>) -> Wgs84 {
        from_ecef(&(self.rot.transpose() * enu + self.origin))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ecef_of_known_points() {
        // Equator, prime meridian: x = a.
        let e = to_ecef(&Wgs84 {
            latitude_deg: 0.0,
            longitude_deg: 0.0,
            height_m: 0.0,
        });
        assert!((e - Vector3::new(A, 0.0, 0.0)).norm() < 1e-6);
        // North pole: z = b.
        let n = to_ecef(&Wgs84 {
            latitude_deg: 90.0,
            longitude_deg: 0.0,
            height_m: 0.0,
        });
        assert!((n.z - B).abs() < 1e-6 && n.x.abs() < 1e-6);
    }

    #[test]
    fn round_trips_to_the_tenth_of_a_millimetre() {
        for &(lat, lon, h) in &[
            (48.78, 11.47, 370.0),
            (-33.9, 151.2, 50.0),
            (0.0, -179.9, -20.0),
            (89.9, 10.0, 1000.0),
        ] {
            let p = Wgs84 {
                latitude_deg: lat,
                longitude_deg: lon,
                height_m: h,
            };
            let q = from_ecef(&to_ecef(&p));
            assert!((q.latitude_deg - lat).abs() < 1e-9, "{lat} {q:?}");
            assert!((q.longitude_deg - lon).abs() < 1e-9);
            assert!((q.height_m - h).abs() < 1e-4, "{h} {q:?}");
            let enu = Enu::new(&p);
            let local = Vector3::new(120.0, -80.0, 3.0);
            let back = enu.from_wgs84(&enu.to_wgs84(&local));
            assert!((back - local).norm() < 1e-4);
        }
    }

    #[test]
    fn east_and_north_point_where_they_should() {
        let o = Wgs84 {
            latitude_deg: 48.0,
            longitude_deg: 11.0,
            height_m: 500.0,
        };
        let enu = Enu::new(&o);
        let north = enu.from_wgs84(&Wgs84 {
            latitude_deg: 48.001,
            ..o
        });
        // One millidegree of latitude at 48° is about 111.2 m.
        assert!(
            north.x.abs() < 1e-3 && (north.y - 111.2).abs() < 0.3,
            "{north}"
        );
        let east = enu.from_wgs84(&Wgs84 {
            longitude_deg: 11.001,
            ..o
        });
        assert!((east.x - 74.6).abs() < 0.3 && east.y.abs() < 0.01, "{east}");
    }
}
