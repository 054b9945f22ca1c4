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
//! rate predict where the antenna goes over each half metre (up to one unknown heading per 10 m
//! piece), and the way whose predictions leave the smaller sideways residuals wins, when it
//! wins by far more than the noise. Without steering (or without a lever arm) the two predict
//! the same track and nothing is decided: the first stretch stays taken as forward, as the
//! report says.
//!
//! What else moves the antenna sideways must not decide it. A GNSS time offset against CAN
//! moves the apparent lever arm by speed x offset and tyre slip by the square of the speed, so
//! only half metres crept at up to 4 m/s count (cars back up slowly). A float epoch or a jump
//! starts the next half metre afresh. A yaw-rate bias turns the integrated heading steadily, so
//! it is taken out where the car stood to measure it, and each 10 m piece has its own heading.
//! And the swing must be about the rig's lever arm, either way: the share of it the track
//! shows is reported, and a share near zero (timing, slip) tells nothing.

use crate::reference::trajectory::GnssObs;
use hilrig_stamp::UtcNanos;
use nalgebra::{Rotation2, Vector2};

/// The length of track over which one direction of the antenna is measured, m: long enough
/// that RTK noise (1-2 cm) is small against its swing, short enough to see a turn's swing.
const SEGMENT_M: f64 = 0.5;
/// Segments per piece of track that gets a heading of its own (10 m): a bias of the yaw rate
/// turns the integrated heading steadily, and over a long stretch that drift would pass for
/// swing.
const SEGMENTS_PER_PIECE: usize = 20;
/// Only segments crept at most this fast count, m/s. Cars back up slowly; faster, what looks
/// like swing also comes from elsewhere: a GNSS time offset against CAN moves the antenna's
/// apparent lever arm by speed x offset (60 ms at 10 m/s is 0.6 m), tyre slip grows with the
/// square of the speed.
const SLOW_MPS: f64 = 4.0;
/// The worst position sigma of an epoch that counts, m (RTK fixed; a float epoch's 0.3 m would
/// decide alone).
const FIXED_SIGMA_M: f64 = 0.05;
/// How far one way must explain the swing better than the other, in squared residual sigmas
/// (a chi-square of one degree of freedom: 25 is five sigma).
const DECISIVE: f64 = 25.0;
/// The least share of the rig's lever arm the track must show, either way: the swing seen is
/// the lever arm the antenna really has, as a share of the rig's (+1 as decided, -1 turned
/// round). A share near zero is no evidence either way, only timing or slip.
const LEVER_SHARE: f64 = 0.5;
/// The least lever arm along the car, m, for the swing to tell anything: an antenna nearer
/// the reference point swings less than timing errors move it.
const LEAST_LEVER_M: f64 = 0.25;
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
    /// The track does not tell (no steering, no lever arm, too little track, or a swing that
    /// fits neither way).
    NotTold,
}

/// The evidence behind a [`Swing`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Evidence {
    /// The lever arm the track shows, as a share of the rig's: +1 as decided, -1 turned round.
    pub lever_share: f64,
    /// How much better the winning way fits, in squared residual sigmas.
    pub margin: f64,
    /// Half-metre segments that counted.
    pub segments: usize,
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
) -> (Swing, Option<Evidence>) {
    if lever.x.abs() < LEAST_LEVER_M || motion.len() < 2 {
        return (Swing::NotTold, None);
    }
    let turned = unbiased(motion, turned);
    let (mut sse_as, mut sse_turned, mut apart, mut n, mut free) = (0.0, 0.0, 0.0, 0usize, 0);
    for &(a, b) in decided {
        let (ta, tb) = (motion[a].0, motion[b].0);
        let track = &obs[obs.partition_point(|o| o.t < ta)..obs.partition_point(|o| o.t <= tb)];
        let window = &motion[a..=b];
        let yaw = &turned[a..=b];
        let ways = [1.0, -1.0].map(|sign| Integral::new(window, yaw, sign, lever));
        for piece in segments(track, window).chunks(SEGMENTS_PER_PIECE) {
            if piece.len() < 3 {
                continue;
            }
            let [r_as, r_turned] = [&ways[0], &ways[1]].map(|way| {
                let pairs: Vec<(Vector2<f64>, Vector2<f64>)> = piece
                    .iter()
                    .map(|&(p, q)| (q.position - p.position, way.between(p.t, q.t)))
                    .collect();
                sideways(&pairs)
            });
            sse_as += r_as.iter().map(|r| r * r).sum::<f64>();
            sse_turned += r_turned.iter().map(|r| r * r).sum::<f64>();
            apart += r_as
                .iter()
                .zip(&r_turned)
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>();
            n += piece.len();
            free += 1;
        }
    }
    if n < free + 3 || apart <= 0.0 {
        return (Swing::NotTold, None);
    }
    let sigma2 = (sse_as.min(sse_turned) / (n - free) as f64).max(SIGMA_FLOOR_M.powi(2));
    let evidence = Evidence {
        lever_share: (sse_turned - sse_as) / apart,
        margin: (sse_turned - sse_as).abs() / sigma2,
        segments: n,
    };
    tracing::debug!(
        segments = n,
        pieces = free,
        sse_as,
        sse_turned,
        apart,
        ?evidence,
        "the antenna's swing"
    );
    let swing = if evidence.margin <= DECISIVE {
        Swing::NotTold
    } else if evidence.lever_share >= LEVER_SHARE {
        Swing::AsDecided
    } else if evidence.lever_share <= -LEVER_SHARE {
        Swing::TurnedRound
    } else {
        Swing::NotTold
    };
    (swing, Some(evidence))
}

/// `turned` without the yaw rate's bias, where the car stood long enough to measure it (the
/// mean yaw rate over a second or more of standing): a bias would turn the integrated heading
/// steadily.
fn unbiased(motion: &[(UtcNanos, f64, f64)], turned: &[f64]) -> Vec<f64> {
    let standing: Vec<f64> = motion
        .iter()
        .filter(|m| m.1.abs() < 0.01)
        .map(|m| m.2)
        .collect();
    let span_s = (motion[motion.len() - 1].0 .0 - motion[0].0 .0) as f64 * 1e-9;
    let standing_s = standing.len() as f64 * span_s / (motion.len() - 1) as f64;
    let bias = if standing_s >= 1.0 {
        standing.iter().sum::<f64>() / standing.len() as f64
    } else {
        0.0
    };
    motion
        .iter()
        .zip(turned)
        .map(|(m, y)| y - bias * (m.0 .0 - motion[0].0 .0) as f64 * 1e-9)
        .collect()
}

/// `track` cut into consecutive pieces of at least [`SEGMENT_M`]: (first, last) epoch. A piece
/// starts afresh after an epoch that is not RTK fixed or a step that the CAN speed cannot
/// explain (a jump); pieces crept faster than [`SLOW_MPS`] are left out.
fn segments(track: &[GnssObs], motion: &[(UtcNanos, f64, f64)]) -> Vec<(GnssObs, GnssObs)> {
    let speed_at = |t: UtcNanos| {
        let k = motion.partition_point(|m| m.0 < t).min(motion.len() - 1);
        motion[k].1.abs()
    };
    let fixed = |o: &GnssObs| o.sigma.x.max(o.sigma.y) <= FIXED_SIGMA_M;
    let mut out = Vec::new();
    let mut from: Option<GnssObs> = None;
    let mut last: Option<GnssObs> = None;
    for o in track {
        let explained = last.is_none_or(|l| {
            let dt = (o.t.0 - l.t.0) as f64 * 1e-9;
            let v = speed_at(l.t).max(speed_at(o.t));
            (o.position - l.position).norm() <= 1.5 * v * dt + 0.2
        });
        last = Some(*o);
        if !fixed(o) || !explained {
            from = fixed(o).then_some(*o);
            continue;
        }
        let Some(f) = from else {
            from = Some(*o);
            continue;
        };
        if (o.position - f.position).norm() >= SEGMENT_M {
            let dt = (o.t.0 - f.t.0) as f64 * 1e-9;
            if (o.position - f.position).norm() <= SLOW_MPS * dt {
                out.push((f, *o));
            }
            from = Some(*o);
        }
    }
    out
}

/// Where the antenna goes by the CAN motion, in the frame of the heading at the first motion
/// sample (`yaw` turned since then at every sample): the integral of the antenna's velocity on
/// the vehicle, (speed - yaw rate * lever y, yaw rate * lever x), turned by the yaw at each
/// instant, summed once so that any span of it is a difference. `sign` -1 takes every speed
/// the other way.
struct Integral {
    t: Vec<i64>,
    sum: Vec<Vector2<f64>>,
}

impl Integral {
    fn new(motion: &[(UtcNanos, f64, f64)], yaw: &[f64], sign: f64, lever: Vector2<f64>) -> Self {
        let mut sum = Vec::with_capacity(motion.len());
        let mut acc = Vector2::zeros();
        sum.push(acc);
        for (w, y) in motion.windows(2).zip(yaw.windows(2)) {
            let dt = (w[1].0 .0 - w[0].0 .0) as f64 * 1e-9;
            let speed = sign * 0.5 * (w[0].1 + w[1].1);
            let rate = 0.5 * (w[0].2 + w[1].2);
            let body = Vector2::new(speed - rate * lever.y, rate * lever.x);
            acc += Rotation2::new(0.5 * (y[0] + y[1])) * body * dt;
            sum.push(acc);
        }
        Integral {
            t: motion.iter().map(|m| m.0 .0).collect(),
            sum,
        }
    }

    /// The integral at `t`, linear within a sample interval, held beyond the ends.
    fn at(&self, t: UtcNanos) -> Vector2<f64> {
        let k = self.t.partition_point(|&x| x < t.0);
        if k == 0 {
            return self.sum[0];
        }
        if k == self.t.len() {
            return self.sum[k - 1];
        }
        let w = (t.0 - self.t[k - 1]) as f64 / (self.t[k] - self.t[k - 1]).max(1) as f64;
        self.sum[k - 1] + (self.sum[k] - self.sum[k - 1]) * w
    }

    /// Where the antenna goes from `t0` to `t1`.
    fn between(&self, t0: UtcNanos, t1: UtcNanos) -> Vector2<f64> {
        self.at(t1) - self.at(t0)
    }
}

/// The sideways residual (m) of each measured displacement against its predicted direction
/// (pairs of measured, predicted), after the one rotation that fits them best (the piece's
/// unknown heading).
fn sideways(pairs: &[(Vector2<f64>, Vector2<f64>)]) -> Vec<f64> {
    let unit = |v: Vector2<f64>| v.try_normalize(1e-9).unwrap_or_else(Vector2::zeros);
    // The rotation of the predicted directions onto the measured displacements.
    let (c, s) = pairs.iter().fold((0.0, 0.0), |(c, s), (m, p)| {
        let u = unit(*p);
        (c + m.dot(&u), s + u.perp(m))
    });
    let turn = Rotation2::new(s.atan2(c));
    pairs
        .iter()
        .map(|(m, p)| (turn * unit(*p)).perp(m))
        .collect()
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
    /// decided. Nothing is told by a straight drive, an antenna near the reference point, a
    /// rig whose lever arm the antenna does not have (the swing fits neither way), or a drive
    /// too fast for the swing to be told from timing. (In a turn of constant curvature the
    /// antenna runs on a circle either way, turned about its centre: only a change of
    /// curvature tells.)
    #[test]
    fn the_swing_tells_the_way_in_turns_only() {
        let lever = Vector2::new(0.6, 0.1);
        let none = Vector2::zeros();
        for (speed, rate, truth, rig, want) in [
            (-1.0, 0.25, lever, lever, Swing::TurnedRound),
            (1.5, -0.3, lever, lever, Swing::AsDecided),
            (-1.0, 0.0, lever, lever, Swing::NotTold),
            (-1.0, 0.25, none, none, Swing::NotTold),
            (
                -1.0,
                0.25,
                Vector2::new(0.1, 0.0),
                Vector2::new(0.1, 0.0),
                Swing::NotTold,
            ),
            (-1.0, 0.25, none, lever, Swing::NotTold),
            (8.0, 0.25, lever, lever, Swing::NotTold),
        ] {
            let (obs, motion, turned) = drive(speed, rate, truth);
            let all = [(0, motion.len() - 1)];
            let (got, evidence) = test(&obs, &motion, &turned, &all, rig);
            assert_eq!(
                got, want,
                "speed {speed}, yaw rate {rate}, lever {truth:?}, rig {rig:?}: {evidence:?}"
            );
            if want != Swing::NotTold {
                let share = evidence.unwrap().lever_share;
                assert!((share.abs() - 1.0).abs() < 0.2, "{evidence:?}");
            }
        }
    }
}
