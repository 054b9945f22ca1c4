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

    /// The worked examples of IOGP Guidance Note 7-2 (Coordinate Conversions and
    /// Transformations, §2.2.1 geographic/geocentric and §2.2.3 geocentric/topocentric, WGS 84):
    /// published to the millimetre, so a spherical Earth, a wrong flattening or a swapped axis
    /// fails by metres.
    #[test]
    fn iogp_worked_examples_to_the_millimetre() {
        let dms = |d: f64, m: f64, s: f64| d + m / 60.0 + s / 3600.0;
        let p = Wgs84 {
            latitude_deg: dms(53.0, 48.0, 33.820),
            longitude_deg: dms(2.0, 7.0, 46.380),
            height_m: 73.0,
        };
        let x = to_ecef(&p);
        let published = Vector3::new(3_771_793.968, 140_253.342, 5_124_304.349);
        assert!((x - published).abs().max() < 0.0005, "{x} vs {published}");
        // And back: the published geocentric coordinates give the geographic ones (1e-8° is
        // 1 mm at the surface).
        let q = from_ecef(&published);
        assert!((q.latitude_deg - p.latitude_deg).abs() < 1e-8, "{q:?}");
        assert!((q.longitude_deg - p.longitude_deg).abs() < 1e-8, "{q:?}");
        assert!((q.height_m - 73.0).abs() < 0.001, "{q:?}");
        // Topocentric: origin 55°N 5°E, 200 m.
        let enu = Enu::new(&Wgs84 {
            latitude_deg: 55.0,
            longitude_deg: 5.0,
            height_m: 200.0,
        });
        let local = enu.from_wgs84(&p);
        let published = Vector3::new(-189_013.869, -128_642.040, -4_220.171);
        assert!(
            (local - published).abs().max() < 0.0005,
            "{local} vs {published}"
        );
    }

    #[test]
    fn east_and_north_point_where_they_should() {
        let o = Wgs84 {
            latitude_deg: 48.0,
            longitude_deg: 11.0,
            height_m: 500.0,
        };
        let enu = Enu::new(&o);
        // Along the meridian: the arc of 0.001° on the ellipse's meridional radius of curvature
        // M = a (1 - e²) / (1 - e² sin²φ)^(3/2) (plus the height), 111.2 m; along the parallel:
        // the chord of the circle of radius (N + h) cos φ, N = a / √(1 - e² sin²φ). Over 100 m
        // both are exact to well under a millimetre.
        let (phi, dang) = (48f64.to_radians(), 0.001f64.to_radians());
        let w = 1.0 - E2 * phi.sin().powi(2);
        let m = A * (1.0 - E2) / w.powf(1.5) + 500.0;
        let n = A / w.sqrt() + 500.0;
        let north = enu.from_wgs84(&Wgs84 {
            latitude_deg: 48.001,
            ..o
        });
        assert!(
            north.x.abs() < 1e-6 && (north.y - m * dang.sin()).abs() < 0.001,
            "{north}"
        );
        let east = enu.from_wgs84(&Wgs84 {
            longitude_deg: 11.001,
            ..o
        });
        assert!(
            (east.x - n * phi.cos() * dang.sin()).abs() < 0.001 && east.y.abs() < 0.001,
            "{east}"
        );
    }
}
