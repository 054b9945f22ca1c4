//! What a car can drive: the limits of a passenger car's motion, and a path as driven (its
//! curvature and the speed it is passed at) judged against them.
//!
//! `synth` makes reference data that `check` must find clean. A path that no car can drive (a
//! spline that loops between close waypoints, a hairpin taken at cruise speed) makes a
//! trajectory with yaw rates and accelerations that no vehicle, GNSS receiver or yaw-rate
//! sensor would produce; `check` then finds jumps in a drive that was meant to be clean, and
//! the user looks for a bug in the wrong place. `synth` refuses such a drive before anything
//! is written, with the place and the numbers ([`super::drive::DriveFile::drivable`] says
//! which limits refuse a drive and which are only named).
//!
//! The limits are those of a road-going passenger car at the edge of what it can physically
//! do, not of comfortable driving: a drive between the two is odd but possible, and is kept.

/// Standard gravity, m/s².
pub const G: f64 = 9.806_65;

/// Largest lateral acceleration of a passenger car, m/s² (0.9 g). Cornering force comes from
/// tyre–road friction, so v²κ cannot exceed μ·g; the peak coefficient of road adhesion of dry
/// asphalt or concrete is 0.8–0.9 (Wong, Theory of Ground Vehicles, Table 1.3), less on a wet
/// or loose surface. Series cars on road tyres reach 0.8–0.9 g on a skid pad; above 0.9 g is
/// a racing car, not a validation rig's vehicle.
pub const MAX_LATERAL_ACCELERATION_MPS2: f64 = 0.9 * G;

/// Smallest radius of the rear-axle centre's path, m (the point a drive's waypoints
/// describe). The tightest-turning series car, the Smart fortwo (2014: a 6.95 m kerb-to-kerb
/// turning circle, 1.87 m wheelbase, 1.47 m front track), runs its outer front wheel on
/// 3.475 m and so its rear-axle centre on √(3.475² − 1.87²) − 1.47/2 = 2.2 m; a compact car
/// (VW Golf VII: 10.9 m, 2.64 m, 1.55 m) on 4.0 m. A tighter path needs rear-wheel steering or
/// a vehicle that is not a car.
pub const MIN_TURN_RADIUS_M: f64 = 2.2;

/// Largest yaw rate, rad/s. Not a third independent limit: the yaw rate is speed times
/// curvature, and it is largest where the two limits above meet (v = √(a·R) = 4.4 m/s), at
/// √(a/R) = 2.0 rad/s (115 °/s). It is checked and named in its own right because it is what
/// the CAN yaw-rate signal and `check` see, and what a user looking at the synthesized data
/// notices first.
pub const MAX_YAW_RATE_RPS: f64 = 2.003;

/// Fastest change of curvature as driven, 1/(m·s): how fast the steering can turn. A car's
/// curvature follows its road-wheel angle, κ = tan δ / L, so dκ/dt = δ̇ / (L cos² δ), and at
/// speed v a path may bend in no faster than a clothoid with dκ/ds = this / v. NHTSA's
/// rollover-resistance fishhook manoeuvre steers at 720 °/s at the wheel, chosen as about the
/// most a driver achieves in an emergency; with a quick 13:1 steering ratio that is 55 °/s =
/// 0.97 rad/s at the road wheels, and with the short 1.87 m wheelbase above at a 35° road-wheel
/// angle (cos² = 0.67), dκ/dt = 0.97 / (1.87 · 0.67) = 0.77 1/(m·s); rounded up to 0.8.
pub const MAX_CURVATURE_RATE_PER_M_S: f64 = 0.8;

/// The limits a path as driven is judged against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarLimits {
    /// Lateral acceleration, m/s².
    pub lateral_acceleration_mps2: f64,
    /// Smallest turning radius of the path's reference point, m.
    pub min_turn_radius_m: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_rps: f64,
    /// Change of curvature per second, 1/(m·s).
    pub curvature_rate_per_m_s: f64,
}

/// A passenger car at the edge of its ability (the constants above).
pub const PASSENGER_CAR: CarLimits = CarLimits {
    lateral_acceleration_mps2: MAX_LATERAL_ACCELERATION_MPS2,
    min_turn_radius_m: MIN_TURN_RADIUS_M,
    yaw_rate_rps: MAX_YAW_RATE_RPS,
    curvature_rate_per_m_s: MAX_CURVATURE_RATE_PER_M_S,
};

/// One point of a path as driven: where it is, how the path bends there, how fast it is
/// passed, and which stretch between two waypoints it belongs to (what the user wrote, and
/// can change).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathPoint {
    /// Arc length from the path's start, m.
    pub s_m: f64,
    /// Position, local frame, m.
    pub position: [f64; 2],
    /// Speed there, m/s (the fastest it is passed at).
    pub speed_mps: f64,
    /// Curvature, 1/m (positive to the left).
    pub curvature_per_m: f64,
    /// Change of curvature along the path, 1/m².
    pub curvature_change_per_m2: f64,
    /// The stretch from waypoint `segment` to waypoint `segment + 1`.
    pub segment: usize,
}

/// A quantity a car's limits bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Quantity {
    /// v²·κ.
    LateralAcceleration,
    /// v·κ.
    YawRate,
    /// |κ| against the smallest turning radius.
    Curvature,
    /// v·dκ/ds: how fast the steering turns.
    CurvatureRate,
}

/// A limit a path exceeds, at the point where it exceeds it most.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exceedance {
    /// What.
    pub quantity: Quantity,
    /// Its value there (absolute).
    pub value: f64,
    /// The limit.
    pub limit: f64,
    /// Where.
    pub at: PathPoint,
}

impl Quantity {
    /// Its value at `p`, absolute, in the unit of its limit.
    fn value(self, p: &PathPoint) -> f64 {
        let (v, k) = (p.speed_mps, p.curvature_per_m);
        match self {
            Quantity::LateralAcceleration => (v * v * k).abs(),
            Quantity::YawRate => (v * k).abs(),
            Quantity::Curvature => k.abs(),
            Quantity::CurvatureRate => (v * p.curvature_change_per_m2).abs(),
        }
    }

    /// Its limit in `limits` (the curvature's is the reciprocal of the smallest radius).
    fn limit(self, limits: &CarLimits) -> f64 {
        match self {
            Quantity::LateralAcceleration => limits.lateral_acceleration_mps2,
            Quantity::YawRate => limits.yaw_rate_rps,
            Quantity::Curvature => 1.0 / limits.min_turn_radius_m,
            Quantity::CurvatureRate => limits.curvature_rate_per_m_s,
        }
    }
}

/// Every limit of `limits` that the path `points` exceeds, each at the point where it exceeds
/// it most, the largest excess (value over limit) first; empty when a car can drive it. A
/// value that is not a number (a path built from non-finite input) exceeds every limit.
pub fn beyond(points: &[PathPoint], limits: &CarLimits) -> Vec<Exceedance> {
    let quantities = [
        Quantity::LateralAcceleration,
        Quantity::YawRate,
        Quantity::Curvature,
        Quantity::CurvatureRate,
    ];
    // Each exceedance with its value as compared: NaN counts as beyond every number.
    let mut out: Vec<(f64, Exceedance)> = Vec::new();
    for q in quantities {
        let limit = q.limit(limits);
        let mut worst: Option<(f64, Exceedance)> = None;
        for p in points {
            let value = q.value(p);
            let key = if value.is_nan() { f64::INFINITY } else { value };
            if key > limit && worst.as_ref().is_none_or(|w| key > w.0) {
                worst = Some((
                    key,
                    Exceedance {
                        quantity: q,
                        value,
                        limit,
                        at: *p,
                    },
                ));
            }
        }
        out.extend(worst);
    }
    out.sort_by(|a, b| (b.0 / b.1.limit).total_cmp(&(a.0 / a.1.limit)));
    out.into_iter().map(|(_, e)| e).collect()
}

impl std::fmt::Display for Exceedance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (v, l) = (self.value, self.limit);
        match self.quantity {
            Quantity::LateralAcceleration => write!(
                f,
                "lateral acceleration {v:.1} m/s² ({:.2} g) above the {l:.1} m/s² ({:.1} g) a car's tyres can hold",
                v / G,
                l / G
            ),
            Quantity::YawRate => write!(
                f,
                "yaw rate {v:.2} rad/s ({:.0} °/s) above the {l:.2} rad/s ({:.0} °/s) a car reaches",
                v.to_degrees(),
                l.to_degrees()
            ),
            Quantity::Curvature => write!(
                f,
                "turning radius {:.2} m below the {:.1} m a car's rear axle can turn on",
                1.0 / v,
                1.0 / l
            ),
            Quantity::CurvatureRate => write!(
                f,
                "curvature changing by {v:.2} 1/(m·s) above the {l:.1} 1/(m·s) a car's steering can turn"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A circle of `radius` passed at `speed`, entered from a straight through a clothoid of
    /// `ramp_m` (so the curvature rate is speed × (1/radius) / ramp).
    fn bend(radius: f64, speed: f64, ramp_m: f64) -> Vec<PathPoint> {
        let k_max = 1.0 / radius;
        (0..=400)
            .map(|i| {
                let s = i as f64 * 0.05;
                let (k, dk) = if s < 5.0 {
                    (0.0, 0.0)
                } else if s < 5.0 + ramp_m {
                    ((s - 5.0) / ramp_m * k_max, k_max / ramp_m)
                } else {
                    (k_max, 0.0)
                };
                PathPoint {
                    s_m: s,
                    position: [s, 0.0],
                    speed_mps: speed,
                    curvature_per_m: k,
                    curvature_change_per_m2: dk,
                    segment: usize::from(s >= 5.0),
                }
            })
            .collect()
    }

    #[test]
    fn what_a_car_does_is_within_the_limits() {
        // A 20 m bend at 8 m/s (3.2 m/s², 0.33 g; 0.4 rad/s), entered over 10 m.
        assert_eq!(beyond(&bend(20.0, 8.0, 10.0), &PASSENGER_CAR), vec![]);
        // Parking at 2 m/s on 4 m (1 m/s², 0.5 rad/s), steered in over 2 m.
        assert_eq!(beyond(&bend(4.0, 2.0, 2.0), &PASSENGER_CAR), vec![]);
        // A motorway curve: 500 m at 36 m/s (2.6 m/s²), over a 150 m clothoid.
        assert_eq!(beyond(&bend(500.0, 36.0, 150.0), &PASSENGER_CAR), vec![]);
        // Creeping round the tightest circle.
        assert_eq!(beyond(&bend(2.3, 0.5, 1.0), &PASSENGER_CAR), vec![]);
        // The yaw-rate limit is where the lateral-acceleration and radius limits meet.
        let meet = MAX_LATERAL_ACCELERATION_MPS2 / MIN_TURN_RADIUS_M;
        assert!((MAX_YAW_RATE_RPS - meet.sqrt()).abs() < 1e-3);
    }

    #[test]
    fn each_limit_is_named_where_it_is_exceeded_most() {
        // The reported loop: a 1.1 m radius at 8.8 m/s, entered over a metre. Excess over the
        // limit: curvature rate 8.0 / 0.8, lateral acceleration 70.4 / 8.83, yaw rate
        // 8.0 / 2.0, curvature 0.91 / 0.45.
        let e = beyond(&bend(1.1, 8.8, 1.0), &PASSENGER_CAR);
        let q: Vec<Quantity> = e.iter().map(|x| x.quantity).collect();
        assert_eq!(
            q,
            [
                Quantity::CurvatureRate,
                Quantity::LateralAcceleration,
                Quantity::YawRate,
                Quantity::Curvature
            ]
        );
        let lateral = e[1];
        assert!((lateral.value - 8.8 * 8.8 / 1.1).abs() < 1e-9, "{lateral}");
        assert_eq!(lateral.at.segment, 1);
        assert!(lateral.to_string().contains("7.18 g"), "{lateral}");
        assert!((e[2].value - 8.0).abs() < 1e-9);
        assert!(e[3].to_string().contains("radius 1.10 m"), "{}", e[3]);
        // 0.95 g on a wide bend: only the lateral acceleration.
        let v = (0.95 * G * 50.0).sqrt();
        let e = beyond(&bend(50.0, v, 10.0), &PASSENGER_CAR);
        assert_eq!(e.len(), 1, "{e:?}");
        assert_eq!(e[0].quantity, Quantity::LateralAcceleration);
        assert_eq!(e[0].limit, MAX_LATERAL_ACCELERATION_MPS2);
        // A 2 m radius at walking pace: only the radius.
        let e = beyond(&bend(2.0, 1.0, 3.0), &PASSENGER_CAR);
        assert_eq!(e.len(), 1, "{e:?}");
        assert_eq!(e[0].quantity, Quantity::Curvature);
        assert!(e[0].to_string().contains("2.00 m"), "{}", e[0]);
        // Straight into a 10 m bend within 20 cm at 6 m/s: only the steering.
        let e = beyond(&bend(10.0, 6.0, 0.2), &PASSENGER_CAR);
        assert_eq!(e.len(), 1, "{e:?}");
        assert_eq!(e[0].quantity, Quantity::CurvatureRate);
        assert!((e[0].value - 6.0 * 0.1 / 0.2).abs() < 1e-9);
        // The worst point of the ramp is reported, not the first one over.
        assert!(e[0].at.s_m >= 5.0 && e[0].at.s_m < 5.2);
    }

    #[test]
    fn a_value_that_is_not_a_number_exceeds_every_limit() {
        let mut p = bend(20.0, 5.0, 10.0);
        p[100].curvature_per_m = f64::NAN;
        let e = beyond(&p, &PASSENGER_CAR);
        assert!(e.iter().any(|x| x.value.is_nan() && x.at.s_m == p[100].s_m));
        p[100].curvature_per_m = 0.0;
        p[50].speed_mps = f64::INFINITY;
        assert!(!beyond(&p, &PASSENGER_CAR).is_empty());
    }
}
