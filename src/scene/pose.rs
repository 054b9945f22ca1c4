//! Poses in the scene's local frame and trajectories that give a pose at any instant.
//!
//! The local frame is the scene's ENU frame (x east, y north, z up, metres from the scene's WGS84
//! origin). A vehicle pose places the vehicle frame (ISO 8855: x forward, y left, z up, origin at
//! the rear axle centre on the ground) in it; yaw is measured from east, counter-clockwise.
//!
//! Trajectories are sampled and interpolated linearly (positions) and along the shorter arc
//! (angles). The simulator asks for a pose per laser firing, about 18 000 times per rotation, so
//! [`Trajectory::pose_at`] looks up from a cursor hint rather than searching from scratch.

use hilrig_stamp::UtcNanos;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// One sample of a trajectory: where a body is and how it is oriented at an instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSample {
    /// When.
    pub t: UtcNanos,
    /// Position in the local frame, metres.
    pub position: Vector3<f64>,
    /// Heading from east, counter-clockwise, radians.
    pub yaw: f64,
    /// Pitch, radians (nose down positive, ISO 8855).
    pub pitch: f64,
    /// Roll, radians.
    pub roll: f64,
}

impl PoseSample {
    /// The rigid transform from the body frame to the local frame.
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.position),
            UnitQuaternion::from_euler_angles(self.roll, self.pitch, self.yaw),
        )
    }
}

/// Why a trajectory cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// Fewer than two samples.
    #[error("a trajectory needs at least two samples, got {0}")]
    TooShort(usize),
    /// Times must increase.
    #[error("trajectory sample {index} at {t} ns is not after the previous one")]
    NotIncreasing {
        /// Sample index.
        index: usize,
        /// Its time.
        t: i64,
    },
    /// A value is NaN or infinite.
    #[error("trajectory sample {0} has a value that is not finite")]
    NotFinite(usize),
    /// A CSV row without the five fields.
    #[error("line {line}: expected 5 fields (t, x, y, z, yaw_deg), got {fields}")]
    CsvFields {
        /// 1-based line.
        line: usize,
        /// Fields found.
        fields: usize,
    },
    /// A CSV field that is not a number (the time: not seconds).
    #[error("line {line}: field {field} ('{text}') is not {what}")]
    CsvNumber {
        /// 1-based line.
        line: usize,
        /// 1-based field.
        field: usize,
        /// The field's text.
        text: String,
        /// `seconds` or `a number`.
        what: &'static str,
    },
}

/// A time-ordered list of poses.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    samples: Vec<PoseSample>,
}

fn lerp_angle(a: f64, b: f64, f: f64) -> f64 {
    let d = (b - a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    a + d * f
}

impl Trajectory {
    /// A trajectory from samples with strictly increasing times.
    pub fn new(samples: Vec<PoseSample>) -> Result<Trajectory, TrajectoryError> {
        if samples.len() < 2 {
            return Err(TrajectoryError::TooShort(samples.len()));
        }
        for (i, s) in samples.iter().enumerate() {
            let finite = s.position.iter().all(|v| v.is_finite())
                && s.yaw.is_finite()
                && s.pitch.is_finite()
                && s.roll.is_finite();
            if !finite {
                return Err(TrajectoryError::NotFinite(i));
            }
            if i > 0 && s.t <= samples[i - 1].t {
                return Err(TrajectoryError::NotIncreasing { index: i, t: s.t.0 });
            }
        }
        Ok(Trajectory { samples })
    }

    /// The samples.
    pub fn samples(&self) -> &[PoseSample] {
        &self.samples
    }

    /// First and last sample time.
    pub fn span(&self) -> (UtcNanos, UtcNanos) {
        (self.samples[0].t, self.samples[self.samples.len() - 1].t)
    }

    /// Index `i` with `samples[i].t <= t < samples[i + 1].t`, starting from `hint` (what the
    /// previous call returned); `None` outside the span.
    pub fn segment(&self, t: UtcNanos, hint: &mut usize) -> Option<usize> {
        let s = &self.samples;
        let (first, last) = self.span();
        if t < first || t > last {
            return None;
        }
        let mut i = (*hint).min(s.len() - 2);
        // Short walks cover sequential queries; a jump falls back to binary search.
        for _ in 0..4 {
            if s[i].t > t {
                if i == 0 {
                    break;
                }
                i -= 1;
            } else if s[i + 1].t < t {
                if i + 2 >= s.len() {
                    break;
                }
                i += 1;
            } else {
                *hint = i;
                return Some(i);
            }
        }
        let i = s
            .partition_point(|p| p.t <= t)
            .saturating_sub(1)
            .min(s.len() - 2);
        *hint = i;
        Some(i)
    }

    /// The interpolated pose at `t` (`None` outside the span), looked up from `hint`.
    pub fn sample_at(&self, t: UtcNanos, hint: &mut usize) -> Option<PoseSample> {
        let i = self.segment(t, hint)?;
        let (a, b) = (&self.samples[i], &self.samples[i + 1]);
        let f = (t.0 - a.t.0) as f64 / (b.t.0 - a.t.0) as f64;
        Some(PoseSample {
            t,
            position: a.position + (b.position - a.position) * f,
            yaw: lerp_angle(a.yaw, b.yaw, f),
            pitch: lerp_angle(a.pitch, b.pitch, f),
            roll: lerp_angle(a.roll, b.roll, f),
        })
    }

    /// The body-to-local transform at `t` (`None` outside the span).
    pub fn pose_at(&self, t: UtcNanos, hint: &mut usize) -> Option<Isometry3<f64>> {
        self.sample_at(t, hint).map(|s| s.isometry())
    }

    /// Velocity in the local frame at `t` (metres per second), from the enclosing segment.
    pub fn velocity_at(&self, t: UtcNanos, hint: &mut usize) -> Option<Vector3<f64>> {
        let i = self.segment(t, hint)?;
        let (a, b) = (&self.samples[i], &self.samples[i + 1]);
        Some((b.position - a.position) / ((b.t.0 - a.t.0) as f64 * 1e-9))
    }

    /// Reads `t, x, y, z, yaw_deg` CSV rows (t in seconds since the Unix epoch; a header line and
    /// `#` comments are skipped) as used for actors in scene files.
    pub fn from_csv(text: &str) -> Result<Trajectory, TrajectoryError> {
        let mut samples = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if n == 0 && fields.first().is_some_and(|f| f.parse::<f64>().is_err()) {
                continue;
            }
            if fields.len() != 5 {
                return Err(TrajectoryError::CsvFields {
                    line: n + 1,
                    fields: fields.len(),
                });
            }
            let not = |field: usize, what| TrajectoryError::CsvNumber {
                line: n + 1,
                field: field + 1,
                text: fields[field].to_owned(),
                what,
            };
            let t = parse_seconds(fields[0]).ok_or_else(|| not(0, "seconds"))?;
            let mut v = [0.0f64; 5];
            for (k, f) in fields.iter().enumerate().skip(1) {
                v[k] = f.parse().map_err(|_| not(k, "a number"))?;
            }
            samples.push(PoseSample {
                t,
                position: Vector3::new(v[1], v[2], v[3]),
                yaw: v[4].to_radians(),
                pitch: 0.0,
                roll: 0.0,
            });
        }
        Trajectory::new(samples)
    }

    /// Writes the CSV that [`Trajectory::from_csv`] reads.
    pub fn to_csv(&self) -> String {
        let mut s = String::from("t,x,y,z,yaw_deg\n");
        for p in &self.samples {
            let (secs, nanos) = p.t.secs_nanos();
            // Shortest representations that read back to the same f64: re-simulation from this
            // file must cast exactly the rays the synthesizer cast.
            s.push_str(&format!(
                "{secs}.{nanos:09},{},{},{},{}\n",
                p.position.x,
                p.position.y,
                p.position.z,
                p.yaw.to_degrees()
            ));
        }
        s
    }
}

/// Seconds with up to nine decimals, exactly to the nanosecond (an f64 of today's epoch seconds
/// times 1e9 would round to 256 ns).
fn parse_seconds(s: &str) -> Option<UtcNanos> {
    let (neg, s) = s.strip_prefix('-').map_or((false, s), |r| (true, r));
    let (int, frac) = s.split_once('.').unwrap_or((s, ""));
    if frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let secs: i64 = int.parse().ok()?;
    let nanos: i64 = format!("{frac:0<9}").parse().ok()?;
    let v = secs.checked_mul(1_000_000_000)?.checked_add(nanos)?;
    Some(UtcNanos(if neg { -v } else { v }))
}

/// A mounting (rig extrinsics) as a transform from the sensor frame to the vehicle frame.
pub fn mounting_isometry(m: &crate::rig::Mounting) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(m.x, m.y, m.z),
        UnitQuaternion::from_euler_angles(
            m.roll_deg.to_radians(),
            m.pitch_deg.to_radians(),
            m.yaw_deg.to_radians(),
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight() -> Trajectory {
        let s = |t: i64, x: f64, yaw: f64| PoseSample {
            t: UtcNanos(t),
            position: Vector3::new(x, 0.0, 0.0),
            yaw,
            pitch: 0.0,
            roll: 0.0,
        };
        Trajectory::new(vec![
            s(0, 0.0, 3.0),
            s(1_000_000_000, 2.0, -3.0),
            s(2_000_000_000, 4.0, -3.0),
        ])
        .unwrap()
    }

    #[test]
    fn interpolates_position_and_yaw_on_the_short_arc() {
        let tr = straight();
        let mut h = 0;
        let p = tr.sample_at(UtcNanos(500_000_000), &mut h).unwrap();
        assert!((p.position.x - 1.0).abs() < 1e-12);
        // 3 rad -> -3 rad is 0.283 rad across ±π, not 6 rad the long way.
        let expect = 3.0 + (std::f64::consts::TAU - 6.0) / 2.0;
        assert!((p.yaw - expect).abs() < 1e-12, "{}", p.yaw);
        assert!(tr.sample_at(UtcNanos(-1), &mut h).is_none());
        assert!(tr.sample_at(UtcNanos(2_000_000_001), &mut h).is_none());
        // Hints far off still find the right segment.
        let mut h = 1;
        assert_eq!(tr.segment(UtcNanos(10), &mut h), Some(0));
        let v = tr.velocity_at(UtcNanos(1_500_000_000), &mut h).unwrap();
        assert!((v.x - 2.0).abs() < 1e-12);
    }

    #[test]
    fn csv_round_trips_and_errors_name_the_line() {
        let tr = straight();
        let back = Trajectory::from_csv(&tr.to_csv()).unwrap();
        assert_eq!(back.samples().len(), 3);
        assert!((back.samples()[1].yaw - -3.0).abs() < 1e-6);
        let e = Trajectory::from_csv("t,x,y,z,yaw_deg\n0,1,2,3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2"), "{e}");
        assert!(Trajectory::from_csv("1,1,1,1,1\n0,1,1,1,1\n").is_err());
    }
}
