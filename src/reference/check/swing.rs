//! The antenna's sideways swing in turns: what tells a drive that starts by backing up from
//! the same drive forwards with the car turned round, where CAN sends the speed as a magnitude
//! and the rig has no heading source.
//!
//! A position and a magnitude of speed cannot tell the two apart: backed up with the heading
//! turned by 180°, the car's reference point travels the same track at the same yaw rate. The
//! antenna can, because it is not on the reference point. In a turn it moves sideways by the
//! yaw rate times its lever arm, and which side that is depends on which way the car travels:
//! its course runs off the reference point's by atan(curvature x lever arm), to one side
//! forwards and to the other backing up. An antenna 0.6 m ahead of the rear axle on a 5 m
//! radius runs 7° off; taken the wrong way round, 14° off what the model predicts. The heading
//! is unknown here, so an offset that stays the same is no evidence (in a turn of constant
//! curvature the antenna runs on a circle either way, turned about the centre): what tells is
//! the offset changing as the driver steers into or out of a turn. Steering from straight into
//! that turn, the wrong way round puts each later half metre of track 12 cm sideways of the
//! earlier ones, against the centimetre or two of RTK noise.
//!
//! So both ways are tried on the stretches the track decided: with each, the CAN speed and yaw
//! rate predict where the antenna goes over each half metre (up to one unknown heading per
//! stretch), and the way whose predictions leave the smaller sideways residuals wins, when it
//! wins by far more than the noise. Without steering (or without a lever arm) the two predict
//! the same track and nothing is decided: the first stretch stays taken as forward, as the
//! report says.

use crate::reference::trajectory::GnssObs;
use hilrig_stamp::UtcNanos;
use nalgebra::{Rotation2, Vector2};

/// The length of track over which one direction of the antenna is measured, m: long enough
/// that RTK noise (1-2 cm) is small against its swing, short enough to see a turn's swing.
const SEGMENT_M: f64 = 0.5;
/// How far one way must explain the swing better than the other, in squared residual sigmas
/// (a chi-square of one degree of freedom: 25 is five sigma). A turn of a few metres gives
/// hundreds; a straight drive gives none either way.
const DECISIVE: f64 = 25.0;
/// The least sideways residual sigma taken, m: synthesized tracks can be cleaner than any
/// receiver, and the decision must not rest on a sigma of zero.
const SIGMA_FLOOR_M: f64 = 0.005;

/// What the swing says of the stretches as the track decided them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Swing {
    /// They fit the way they were decided.
    AsDecided,
    /// They fit only turned round: each was travelled the other way.
    TurnedRound,
    /// The track does not tell (no turns, no lever arm, too little track).
    NotTold,
}

/// Tests the stretches `decided` (index ranges of `motion`, inclusive) with `motion`'s speeds
/// signed as decided, against all of them turned round. `turned` is the yaw integrated from
/// the first motion sample, at every sample; `lever` the antenna's position on the vehicle
/// (x forward, y left), m.
pub(super) fn test(
    obs: &[GnssObs],
    motion: &[(UtcNanos, f64, f64)],
    turned: &[f64],
    decided: &[(usize, usize)],
    lever: Vector2<f64>,
) -> Swing {
    if lever.norm() < 0.05 {
        return Swing::NotTold;
    }
    let (mut sse_as, mut sse_turned, mut n, mut free) = (0.0, 0.0, 0usize, 0usize);
    for &(a, b) in decided {
        let (ta, tb) = (motion[a].0, motion[b].0);
        let track = &obs[obs.partition_point(|o| o.t < ta)..obs.partition_point(|o| o.t <= tb)];
        let segments = segments(track);
        if segments.len() < 3 {
            continue;
        }
        let window = &motion[a..=b];
        let yaw = &turned[a..=b];
        for (sign, sse) in [(1.0, &mut sse_as), (-1.0, &mut sse_turned)] {
            let pairs: Vec<(Vector2<f64>, Vector2<f64>)> = segments
                .iter()
                .map(|&(p, q)| {
                    let predicted = travelled(window, yaw, p.t, q.t, sign, lever);
                    (q.position - p.position, predicted)
                })
                .collect();
            *sse += sideways_sse(&pairs);
        }
        n += segments.len();
        free += 1;
    }
    if n < free + 3 {
        return Swing::NotTold;
    }
    let sigma2 = (sse_as.min(sse_turned) / (n - free) as f64).max(SIGMA_FLOOR_M.powi(2));
    let margin = (sse_turned - sse_as) / sigma2;
    tracing::debug!(
        segments = n,
        stretches = free,
        sse_as,
        sse_turned,
        margin,
        "the antenna's swing: how much better the stretches fit as decided than turned round"
    );
    if margin > DECISIVE {
        Swing::AsDecided
    } else if margin < -DECISIVE {
        Swing::TurnedRound
    } else {
        Swing::NotTold
    }
}

/// `track` cut into consecutive pieces of at least [`SEGMENT_M`]: (first, last) epoch.
fn segments(track: &[GnssObs]) -> Vec<(GnssObs, GnssObs)> {
    let mut out = Vec::new();
    let Some(mut from) = track.first().copied() else {
        return out;
    };
    for o in &track[1..] {
        if (o.position - from.position).norm() >= SEGMENT_M {
            out.push((from, *o));
            from = *o;
        }
    }
    out
}

/// Where the antenna goes from `t0` to `t1` by the CAN motion, in the frame of the heading at
/// the first motion sample (`yaw` turned since then at every sample): the integral of the
/// antenna's velocity on the vehicle, (speed - yaw rate * lever y, yaw rate * lever x), turned
/// by the yaw at each instant. `sign` -1 takes every speed the other way.
fn travelled(
    motion: &[(UtcNanos, f64, f64)],
    yaw: &[f64],
    t0: UtcNanos,
    t1: UtcNanos,
    sign: f64,
    lever: Vector2<f64>,
) -> Vector2<f64> {
    let mut sum = Vector2::zeros();
    for (w, y) in motion.windows(2).zip(yaw.windows(2)) {
        let from = w[0].0 .0.max(t0.0);
        let to = w[1].0 .0.min(t1.0);
        if to <= from {
            continue;
        }
        let dt = (to - from) as f64 * 1e-9;
        let speed = sign * 0.5 * (w[0].1 + w[1].1);
        let rate = 0.5 * (w[0].2 + w[1].2);
        let body = Vector2::new(speed - rate * lever.y, rate * lever.x);
        sum += Rotation2::new(0.5 * (y[0] + y[1])) * body * dt;
    }
    sum
}

/// The sum of squared sideways residuals of measured displacements against predicted ones
/// (measured, predicted), after the one rotation that fits them best (the stretch's unknown
/// heading), m².
fn sideways_sse(pairs: &[(Vector2<f64>, Vector2<f64>)]) -> f64 {
    let unit = |v: Vector2<f64>| v.try_normalize(1e-9).unwrap_or_else(Vector2::zeros);
    // The rotation of the predicted directions onto the measured displacements.
    let (c, s) = pairs.iter().fold((0.0, 0.0), |(c, s), (m, p)| {
        let u = unit(*p);
        (c + m.dot(&u), s + u.perp(m))
    });
    let turn = Rotation2::new(s.atan2(c));
    pairs
        .iter()
        .map(|(m, p)| (turn * unit(*p)).perp(m).powi(2))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drive: GNSS epochs, CAN motion (time, speed, yaw rate) and the yaw turned at each.
    type Drive = (Vec<GnssObs>, Vec<(UtcNanos, f64, f64)>, Vec<f64>);

    /// A drive at `speed` (negative: backing up), straight for 2 s and then turning at yaw
    /// rate `rate`, its antenna at `lever`, 20 Hz GNSS without noise (but a centimetre's
    /// wobble) and 50 Hz CAN with the speed as a magnitude.
    fn drive(speed: f64, rate: f64, lever: Vector2<f64>) -> Drive {
        let (mut obs, mut motion, mut turned) = (Vec::new(), Vec::new(), Vec::new());
        let (mut x, mut y, mut psi) = (0.0f64, 0.0f64, 0.3f64);
        for k in 0..=8000 {
            let t = UtcNanos(k as i64 * 1_000_000);
            // Straight for 2 s, then turning: the curvature changes, as a driver steers.
            let rate = if k < 2000 { 0.0 } else { rate };
            if k % 20 == 0 {
                motion.push((t, speed.abs(), rate));
                turned.push(psi - 0.3);
            }
            if k % 50 == 0 {
                let wobble = 0.01 * ((k / 50) as f64 * 2.1).sin();
                let at = Vector2::new(x, y) + Rotation2::new(psi) * lever;
                obs.push(GnssObs {
                    t,
                    position: at + Vector2::new(wobble, -wobble),
                    sigma: Vector2::new(0.01, 0.01),
                });
            }
            x += speed * psi.cos() * 1e-3;
            y += speed * psi.sin() * 1e-3;
            psi += rate * 1e-3;
        }
        (obs, motion, turned)
    }

    /// Backing up into a turn, taken as forward, fits only turned round; forwards fits as
    /// decided; a straight drive or an antenna on the reference point does not tell. (In a
    /// turn of constant curvature the antenna runs on a circle either way, turned about its
    /// centre: only a change of curvature tells.)
    #[test]
    fn the_swing_tells_the_way_in_turns_only() {
        let lever = Vector2::new(0.6, 0.1);
        for (speed, rate, at, want) in [
            (-1.0, 0.25, lever, Swing::TurnedRound),
            (1.5, -0.3, lever, Swing::AsDecided),
            (-1.0, 0.0, lever, Swing::NotTold),
            (-1.0, 0.25, Vector2::zeros(), Swing::NotTold),
        ] {
            let (obs, motion, turned) = drive(speed, rate, at);
            let all = [(0, motion.len() - 1)];
            assert_eq!(
                test(&obs, &motion, &turned, &all, at),
                want,
                "speed {speed}, yaw rate {rate}, lever {at:?}"
            );
        }
    }
}
