//! Which way the car travels. Most cars send their speed as a magnitude: the direction is in
//! the gear lever or in a direction signal that a rig file need not map (this project's own
//! DBC has none). A parking manoeuvre backs up, and a leg backed up with its speed taken as
//! forward reads as GNSS positions moving against the speed. The smoother can explain that only
//! as jumps, a wrong lever arm and a heading turned by 180° (a blind check of such a drive
//! raised exactly those faults). So where the run's speed is never negative, each stretch
//! between two stops is given its direction here, before the smoother:
//!
//! - A car does not turn while it stands, so its heading carries across a stop. The yaw rate
//!   carries it along a stretch.
//! - The heading at the start of the drive comes from the rig's heading source where it has
//!   one. Without one the first stretch is taken as forward: a drive that starts by backing up
//!   out of a slot reads, so far, as the same drive forwards with the car turned round. Nothing
//!   in GNSS and a magnitude of speed tells the two apart but the antenna's sideways swing in
//!   turns (`swing.rs`), which then confirms every stretch's direction or turns all of them
//!   round. Where the drive has no turn to tell it, the report says the start was assumed.
//! - A stretch is backed up when its antenna moved against that heading. The sum of each
//!   epoch's displacement along the heading telescopes, so the GNSS noise enters once, not per
//!   epoch. The stretch's end then gives the heading again (its track's direction, turned round
//!   when it backed up), so that the yaw rate's bias does not add up over a long drive.

use super::faults::{iso, secs_ms};
use super::names::FaultName;
use super::report::Warning;
use super::swing::{self, Swing};
use super::travel::{DirectionFrom, LeverSwing, SwingOutcome, Travel, TravelStretch};
use crate::reference::trajectory::{GnssObs, HeadingObs};
use hilrig_stamp::UtcNanos;
use nalgebra::Vector2;

/// A speed below this, m/s, is taken as noise about zero: a signed speed that reads below it
/// carries a sign, and the car moves only above it (a car backing up passes through zero).
const MOVING_MPS: f64 = 0.1;
/// The track's length over which a stretch's direction at its start or end is taken, m.
const ANCHOR_M: f64 = 2.0;
/// A stretch whose antenna moved less than this is too short to say which way it went, m (the
/// GNSS noise is a centimetre or two).
const DECIDABLE_M: f64 = 0.3;
/// The farthest a car is taken to back up in one drive, m, and the fastest, m/s: the antenna's
/// swing may turn a drive round only within these.
const MAX_BACKING_M: f64 = 100.0;
const MAX_BACKING_MPS: f64 = 5.0;
/// What a GNSS step may exceed the CAN speed's distance by (noise, latency), m.
const STEP_SLACK_M: f64 = 0.2;
/// The share of the stretch's path along (or against) the heading that decides it: the
/// antenna, ahead of the rear axle, moves sideways in a turn (by the lever arm over the radius:
/// 0.3 of its speed for 1.5 m on a 5 m radius, 0.7 on a car's tightest 2.2 m), and GNSS noise
/// lengthens the path of a stretch crept at walking pace.
const DECISIVE: f64 = 0.5;

/// Signs `motion`'s speeds (time, speed, yaw rate) in the stretches the car backed up, where
/// the run's speed is a magnitude; says what it found. `heading` holds the rig's heading
/// source's reports (empty without one), in the smoother's frame.
pub(super) fn signed(
    obs: &[GnssObs],
    motion: &mut [(UtcNanos, f64, f64)],
    heading: &[HeadingObs],
    lever: Vector2<f64>,
    start: UtcNanos,
) -> Travel {
    let stretch = |a: UtcNanos, b: UtcNanos| TravelStretch {
        from: iso(a),
        to: iso(b),
        from_s: secs_ms(start, a),
        to_s: secs_ms(start, b),
    };
    if motion.is_empty() {
        return Travel::default();
    }
    let moving = stretches(motion);
    if motion.iter().any(|m| m.1 < -MOVING_MPS) {
        let reversing = moving
            .iter()
            .filter(|&&(a, b)| motion[a..=b].iter().map(|m| m.1).sum::<f64>() < 0.0)
            .map(|&(a, b)| stretch(motion[a].0, motion[b].0))
            .collect();
        return Travel {
            direction_from: DirectionFrom::CanSpeedSign,
            reversing,
            undecided: Vec::new(),
            lever_swing: None,
        };
    }
    // (time, yaw turned since the first sample, speed as sent) per sample: the motion itself is
    // signed as the stretches are decided.
    let turned = yaw_integral(motion);
    let sent: Vec<(UtcNanos, f64, f64)> = motion
        .iter()
        .zip(&turned)
        .map(|(m, &y)| (m.0, y, m.1))
        .collect();
    let at = |t: UtcNanos| sent[sent.partition_point(|x| x.0 < t).min(sent.len() - 1)];
    let turned_at = |t: UtcNanos| at(t).1;
    let speed_at = |t: UtcNanos| at(t).2;
    let mut direction_from = DirectionFrom::NoMotion;
    // The vehicle's heading at one instant: (time, rad from east).
    let mut anchor: Option<(UtcNanos, f64)> = None;
    // Each stretch as the track decided it: backed up or not, `None` where it could not tell;
    // and the antenna's path along it, m.
    let mut decided: Vec<((usize, usize), Option<bool>, f64)> = Vec::new();
    for (a, b) in moving {
        let (ta, tb) = (motion[a].0, motion[b].0);
        let i0 = obs.partition_point(|o| o.t < ta);
        let i1 = obs.partition_point(|o| o.t <= tb);
        let track = &obs[i0..i1];
        let path: f64 = track
            .windows(2)
            .map(|w| (w[1].position - w[0].position).norm())
            .sum();
        if track.len() < 3 || path < DECIDABLE_M {
            decided.push(((a, b), None, path));
            continue;
        }
        let anchor_now = match anchor {
            Some(x) => x,
            None => match heading.iter().find(|h| h.t >= ta && h.t <= tb) {
                Some(h) => {
                    direction_from = DirectionFrom::HeadingSource;
                    (h.t, h.yaw)
                }
                None => {
                    direction_from = DirectionFrom::AssumedForwardAtStart;
                    course(track, false)
                }
            },
        };
        let heading_at = |t: UtcNanos| anchor_now.1 + turned_at(t) - turned_at(anchor_now.0);
        // A step of the antenna that the CAN speed cannot explain (a jump, a float epoch) is
        // left out: it would count its whole length one way.
        let along: f64 = track
            .windows(2)
            .filter(|w| {
                let dt = (w[1].t.0 - w[0].t.0) as f64 * 1e-9;
                let v = speed_at(w[0].t).max(speed_at(w[1].t));
                (w[1].position - w[0].position).norm() <= 1.5 * v * dt + STEP_SLACK_M
            })
            .map(|w| {
                let mid = UtcNanos(w[0].t.0 + (w[1].t.0 - w[0].t.0) / 2);
                let h = heading_at(mid);
                (w[1].position - w[0].position).dot(&Vector2::new(h.cos(), h.sin()))
            })
            .sum();
        if along.abs() <= DECISIVE * path {
            decided.push(((a, b), None, path));
            anchor = Some(anchor_now);
            continue;
        }
        let (t, course_end) = course(track, true);
        let backed = along < 0.0;
        decided.push(((a, b), Some(backed), path));
        anchor = Some((
            t,
            course_end + if backed { std::f64::consts::PI } else { 0.0 },
        ));
    }
    // Without a heading source the first stretch was taken as forward, and every later one
    // follows from it: the antenna's swing in turns says whether all of them are the other way.
    let mut lever_swing = None;
    if direction_from == DirectionFrom::AssumedForwardAtStart {
        let mut trial = motion.to_vec();
        let mut told = Vec::new();
        for &((a, b), backed, _) in &decided {
            if let Some(backed) = backed {
                told.push((a, b));
                if backed {
                    trial[a..=b].iter_mut().for_each(|m| m.1 = -m.1);
                }
            }
        }
        let (swing, evidence) = swing::test(obs, &trial, &turned, &told, lever);
        let outcome = match swing {
            Swing::AsDecided => SwingOutcome::Confirmed,
            Swing::NotTold => SwingOutcome::NotTold,
            Swing::TurnedRound => {
                // Turned round, the stretches taken as forward were backed up: a car backs up
                // slowly and not far. A swing that says a whole drive went backwards at speed
                // says rather that the rig's lever arm has the wrong sign (the lever-arm check
                // then names it).
                let (far, fast) = decided.iter().filter(|d| d.1 == Some(false)).fold(
                    (0.0f64, 0.0f64),
                    |(far, fast), &((a, b), _, path)| {
                        let top = motion[a..=b].iter().map(|m| m.1.abs()).fold(0.0, f64::max);
                        (far + path, fast.max(top))
                    },
                );
                if far > MAX_BACKING_M || fast > MAX_BACKING_MPS {
                    SwingOutcome::Implausible
                } else {
                    for d in &mut decided {
                        d.1 = d.1.map(|backed| !backed);
                    }
                    SwingOutcome::TurnedRound
                }
            }
        };
        if matches!(outcome, SwingOutcome::Confirmed | SwingOutcome::TurnedRound) {
            direction_from = DirectionFrom::LeverArmSwing;
        }
        lever_swing = evidence.map(|e| LeverSwing {
            lever_share: e.lever_share,
            margin: e.margin,
            segments: e.segments,
            outcome,
        });
    }
    let (mut reversing, mut undecided) = (Vec::new(), Vec::new());
    for ((a, b), backed, _) in decided {
        match backed {
            Some(true) => {
                motion[a..=b].iter_mut().for_each(|m| m.1 = -m.1);
                reversing.push(stretch(motion[a].0, motion[b].0));
            }
            Some(false) => {}
            None => undecided.push(stretch(motion[a].0, motion[b].0)),
        }
    }
    Travel {
        direction_from,
        reversing,
        undecided,
        lever_swing,
    }
}

/// The warning a drive turned round by the antenna's swing needs: the turn-round rests on the
/// sign of the rig's lever arm (`lever_x`, m ahead of the reference point), and a drive that
/// starts forwards with the antenna behind the reference point, where the rig says ahead,
/// shows the same track.
pub(super) fn swing_warning(travel: &Travel, lever_x: f64) -> Option<Warning> {
    let s = travel.lever_swing.as_ref()?;
    let detail = match s.outcome {
        SwingOutcome::TurnedRound => format!(
            "the drive was taken to start backing up: the antenna's swing in turns fits the rig's lever arm ({lever_x:.2} m ahead of the reference point) only so; a drive that started forwards with the antenna {lever_x:.2} m behind it would show the same track: if it started forwards, the rig file's antenna is wrong"
        ),
        SwingOutcome::Implausible => format!(
            "the antenna's swing in turns fits a lever arm of {:+.2} times the rig's ({lever_x:.2} m): the rig file's antenna may be on the wrong side of the reference point",
            s.lever_share
        ),
        SwingOutcome::Confirmed | SwingOutcome::NotTold => return None,
    };
    Some(Warning {
        name: FaultName::LeverArm,
        detail,
    })
}

/// The stretches in which the car moves: index ranges of `motion`, inclusive.
fn stretches(motion: &[(UtcNanos, f64, f64)]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut from = None;
    for (k, m) in motion.iter().enumerate() {
        match (m.1.abs() > MOVING_MPS, from) {
            (true, None) => from = Some(k),
            (false, Some(a)) => {
                out.push((a, k - 1));
                from = None;
            }
            _ => {}
        }
    }
    if let Some(a) = from {
        out.push((a, motion.len() - 1));
    }
    out
}

/// The yaw rate integrated from the first sample, at every sample, rad.
fn yaw_integral(motion: &[(UtcNanos, f64, f64)]) -> Vec<f64> {
    let mut out = Vec::with_capacity(motion.len());
    let mut sum = 0.0;
    out.push(0.0);
    for w in motion.windows(2) {
        sum += 0.5 * (w[0].2 + w[1].2) * (w[1].0 .0 - w[0].0 .0) as f64 * 1e-9;
        out.push(sum);
    }
    out
}

/// The direction in which the antenna moved over the first (or, `at_end`, the last)
/// [`ANCHOR_M`] of `track`, with the middle of that time: (time, rad from east).
fn course(track: &[GnssObs], at_end: bool) -> (UtcNanos, f64) {
    let (first, last) = (track[0], track[track.len() - 1]);
    let (p, q) = if at_end {
        let from = track
            .iter()
            .rev()
            .find(|o| (last.position - o.position).norm() >= ANCHOR_M)
            .copied()
            .unwrap_or(first);
        (from, last)
    } else {
        let to = track
            .iter()
            .find(|o| (o.position - first.position).norm() >= ANCHOR_M)
            .copied()
            .unwrap_or(last);
        (first, to)
    };
    let d = q.position - p.position;
    (UtcNanos(p.t.0 + (q.t.0 - p.t.0) / 2), d.y.atan2(d.x))
}

#[cfg(test)]
mod tests {
    use super::*;

    const T0: i64 = 1_000_000_000_000;
    /// The test drives' antenna, 1.5 m ahead of the rear axle.
    const LEVER: Vector2<f64> = Vector2::new(1.5, 0.0);

    /// A car 20 Hz GNSS, 50 Hz CAN: forward east for `fwd` s at 2 m/s, stands 1 s, then backs
    /// up for `back` s at 1 m/s, straight for 1.5 s and then turning left (its heading grows by
    /// `yaw_rate`), the CAN speed a magnitude. The antenna 1.5 m ahead of the rear axle.
    fn drive(fwd: f64, back: f64, yaw_rate: f64) -> (Vec<GnssObs>, Vec<(UtcNanos, f64, f64)>) {
        let mut motion = Vec::new();
        let mut obs = Vec::new();
        let (mut x, mut y, mut psi) = (0.0f64, 0.0f64, 0.0f64);
        let total = fwd + 1.0 + back;
        let steps = (total * 1000.0) as usize;
        for k in 0..=steps {
            let t = k as f64 * 1e-3;
            let (v, w): (f64, f64) = if t < fwd {
                (2.0, 0.0)
            } else if t < fwd + 1.0 {
                (0.0, 0.0)
            } else if t < fwd + 2.5 {
                (-1.0, 0.0)
            } else {
                (-1.0, yaw_rate)
            };
            if k % 20 == 0 {
                motion.push((UtcNanos(T0 + (t * 1e9) as i64), v.abs(), w));
            }
            if k % 50 == 0 {
                obs.push(GnssObs {
                    t: UtcNanos(T0 + (t * 1e9) as i64),
                    position: Vector2::new(x + 1.5 * psi.cos(), y + 1.5 * psi.sin()),
                    sigma: Vector2::new(0.01, 0.01),
                });
            }
            x += v * psi.cos() * 1e-3;
            y += v * psi.sin() * 1e-3;
            psi += w * 1e-3;
        }
        (obs, motion)
    }

    /// Forward, a stop, backing up in a turn: the second stretch is signed negative and named,
    /// the first stays, and the report says the turn's swing confirmed it.
    #[test]
    fn a_leg_backed_up_after_a_stop_is_signed_and_named() {
        let (obs, mut motion) = drive(5.0, 4.0, 0.3);
        let travel = signed(&obs, &mut motion, &[], LEVER, UtcNanos(T0));
        assert_eq!(travel.direction_from, DirectionFrom::LeverArmSwing);
        assert_eq!(travel.reversing.len(), 1, "{travel:?}");
        let r = &travel.reversing[0];
        assert!(
            (r.from_s - 6.0).abs() < 0.05 && (r.to_s - 10.0).abs() < 0.05,
            "{r:?}"
        );
        for m in &motion {
            let t = (m.0 .0 - T0) as f64 * 1e-9;
            if t > 6.05 {
                assert!(m.1 < 0.0, "at {t} s: {}", m.1);
            } else if t < 5.95 {
                assert!(m.1 >= 0.0, "at {t} s: {}", m.1);
            }
        }
    }

    /// A drive that only goes forward is left alone; a signed speed is left alone and its
    /// backing up named from its sign.
    #[test]
    fn forward_only_and_signed_speeds_are_left_alone() {
        let (obs, mut motion) = drive(5.0, 0.0, 0.0);
        let before = motion.clone();
        let travel = signed(&obs, &mut motion, &[], LEVER, UtcNanos(T0));
        assert!(travel.reversing.is_empty(), "{travel:?}");
        assert_eq!(motion, before);

        let (obs, mut motion) = drive(5.0, 4.0, 0.3);
        for m in &mut motion {
            if (m.0 .0 - T0) as f64 * 1e-9 > 6.0 {
                m.1 = -m.1;
            }
        }
        let before = motion.clone();
        let travel = signed(&obs, &mut motion, &[], LEVER, UtcNanos(T0));
        assert_eq!(travel.direction_from, DirectionFrom::CanSpeedSign);
        assert_eq!(travel.reversing.len(), 1, "{travel:?}");
        assert_eq!(motion, before);
    }

    /// A drive that starts backing up straight: with a heading source the first stretch is
    /// known to be backed up; without one it is taken as forward, and the report says it was
    /// assumed. Backing up in a turn, the antenna's swing tells it without a heading source.
    #[test]
    fn a_start_backing_up_is_told_by_the_heading_source_only() {
        let (obs, motion) = drive(0.0, 4.0, 0.0);
        let heading = [HeadingObs {
            t: UtcNanos(T0 + 1_500_000_000),
            yaw: 0.0,
            sigma: 0.001,
        }];
        let mut with = motion.clone();
        let travel = signed(&obs, &mut with, &heading, LEVER, UtcNanos(T0));
        assert_eq!(travel.direction_from, DirectionFrom::HeadingSource);
        assert_eq!(travel.reversing.len(), 1, "{travel:?}");
        let mut without = motion.clone();
        let travel = signed(&obs, &mut without, &[], LEVER, UtcNanos(T0));
        assert_eq!(travel.direction_from, DirectionFrom::AssumedForwardAtStart);
        assert!(travel.reversing.is_empty());
        assert_eq!(without, motion);

        let (obs, mut motion) = drive(0.0, 4.0, 0.3);
        let travel = signed(&obs, &mut motion, &[], LEVER, UtcNanos(T0));
        assert_eq!(travel.direction_from, DirectionFrom::LeverArmSwing);
        assert_eq!(travel.reversing.len(), 1, "{travel:?}");
        assert!(motion.iter().all(|m| m.1 <= 0.0), "{motion:?}");
    }
}
