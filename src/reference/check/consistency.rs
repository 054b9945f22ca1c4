//! GNSS against CAN: what the antenna's track says about the other reference sources.
//!
//! - CAN speed scale: GNSS speed regressed on CAN speed (and acceleration, so that a time offset
//!   does not bend the scale) on straight driving;
//! - GNSS time offset and the antenna's forward lever arm, as constant states of the smoother: a
//!   time offset misfits along track whenever the speed changes (v·δ: 11 cm for 50 ms at
//!   8 km/h), a lever-arm error sideways in turns, which CAN (no side slip) cannot explain;
//! - jumps: epochs the smoothed trajectory cannot explain once those errors are taken out;
//! - yaw rate against the GNSS course rate over a second, speed residuals, travelled distance.

use super::faults::{secs, FaultLog};
use super::names::FaultName;
use super::report::{Spatial, Stats, Warning};
use crate::reference::noise::{correlation_factor, integrated_autocorrelation};
use crate::reference::run::{Motion, Run};
use crate::reference::trajectory::{EgoTrajectory, GnssNoise, GnssObs, Settings};
use crate::rig::Thresholds;
use hilrig_stamp::UtcNanos;
use nalgebra::Vector2;

/// What the GNSS-against-CAN measurements read.
pub(super) struct Inputs<'a> {
    /// The run (CAN motion).
    pub run: &'a Run,
    /// The rig's limits.
    pub th: &'a Thresholds,
    /// Antenna positions in the local frame.
    pub obs: &'a [GnssObs],
    /// Per epoch: RTK fixed.
    pub fixed: &'a [bool],
    /// Per epoch: fixed and within the sigma limits (good enough to differentiate).
    pub good: &'a [bool],
    /// CAN motion as (time, speed, yaw rate).
    pub motion: &'a [(UtcNanos, f64, f64)],
    /// The CAN yaw-rate noise the smoother assumes, rad/s.
    pub yaw_rate_sigma: f64,
    /// The yaw jerk noise the drive's CAN yaw rate shows, rad/s³ per √s (see
    /// [`crate::reference::trajectory::fit_yaw_jerk_noise`]).
    pub yaw_jerk_noise: f64,
    /// The GNSS error model the drive supports best (see
    /// [`crate::reference::trajectory::fit_gnss_noise`]); the time offset and lever arm are
    /// fitted under it, so that their uncertainties account for the wander of the errors.
    pub gnss_noise: GnssNoise,
    /// The rig's antenna position (x forward, y left), m.
    pub lever: Vector2<f64>,
    /// The GNSS epoch period, ns.
    pub gnss_period: i64,
    /// The run's start and end.
    pub span: (UtcNanos, UtcNanos),
}

/// An antenna velocity from a central difference of fixed epochs.
struct Vel {
    t: UtcNanos,
    speed: f64,
    course: f64,
}

/// How an estimate compares with its limit, given its standard uncertainty: beyond it with
/// confidence (|e| - 2σ > limit: a fault), within it with confidence (|e| + 2σ ≤ limit), or
/// undecided (the 2σ interval straddles the limit: a warning, not a fault).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Decision {
    Beyond,
    Within,
    Undecided,
}

fn decide(error: f64, sigma: f64, limit: f64) -> Decision {
    if error.abs() - 2.0 * sigma > limit {
        Decision::Beyond
    } else if error.abs() + 2.0 * sigma <= limit {
        Decision::Within
    } else {
        Decision::Undecided
    }
}

/// Speed scale, time offset, lever arm, jumps, yaw-rate and speed residuals and distances into
/// `sp`, with their faults, and warnings for what this drive cannot decide. Returns the GNSS
/// time offset in seconds (0 when not determinable), which the accuracy budget needs.
pub(super) fn gnss_against_can(
    inp: &Inputs<'_>,
    traj: &EgoTrajectory,
    sp: &mut Spatial,
    log: &mut FaultLog,
    warnings: &mut Vec<Warning>,
) -> f64 {
    let vels = antenna_velocities(inp);
    let moving_span = speed_scale(inp, &vels, sp, log, warnings);
    let fit = offset_and_lever(inp, sp.can_speed_scale.unwrap_or(1.0));
    sp.gnss_noise_correlation = fit.correlation;
    let traj_fit = fit.trajectory.as_ref().unwrap_or(traj);
    jumps(inp, traj_fit, sp, log);

    let (start, end) = inp.span;
    let offset_s = fit.delta.map_or(0.0, |d| d.0);
    sp.gnss_time_offset_ms = fit.delta.map(|d| d.0 * 1e3);
    sp.gnss_time_offset_sigma_ms = fit.delta.map(|d| d.1 * 1e3);
    let limit = inp.th.max_time_offset_ms;
    let span = moving_span.unwrap_or((start, end));
    match fit.delta {
        None => warnings.push(Warning {
            name: FaultName::GnssTimeOffset,
            detail: "not determinable on this drive: it needs at least a second of driving \
                     with speed changes (starting, braking) on RTK-fixed epochs"
                .into(),
        }),
        Some((d, sd)) => match decide(d * 1e3, sd * 1e3, limit) {
            Decision::Beyond => log.fault(
                FaultName::GnssTimeOffset,
                span.0,
                span.1,
                format!(
                    "GNSS time stamps are {:.1} ± {:.1} ms (1 sigma) {} the instants they describe, fitted against CAN motion (limit {limit:.0} ms, exceeded by more than 2 sigma){}",
                    d.abs() * 1e3,
                    sd * 1e3,
                    if d > 0.0 { "later than" } else { "earlier than" },
                    logger_clock(inp.run),
                ),
            ),
            Decision::Undecided => warnings.push(Warning {
                name: FaultName::GnssTimeOffset,
                detail: format!(
                    "{:+.1} ± {:.1} ms (1 sigma): not determinable against the {limit:.0} ms limit on this drive; more speed changes (starting, braking) on RTK-fixed epochs would decide it",
                    d * 1e3,
                    sd * 1e3
                ),
            }),
            Decision::Within => {}
        },
    }
    let scale = sp.can_speed_scale.unwrap_or(1.0);
    let delay = (offset_s * 1e9) as i64;
    // Residuals, distances, yaw rate and lever arm with the measured scale and offset applied.
    let yaw_res = yaw_rate_residuals(inp, &vels, delay);
    let (speed_res, n_turn, turn_span) = speed_residuals_and_turns(inp, &vels, delay, scale);
    sp.lever_arm_turning_epochs = n_turn;
    let limit = inp.th.max_lever_arm_error_m;
    match (fit.lever, n_turn >= 10) {
        (Some((x, sx)), true) => {
            sp.lever_arm_x_measured_m = Some(x);
            sp.lever_arm_x_sigma_m = Some(sx);
            match decide(x - sp.lever_arm_x_rig_m, sx, limit) {
                Decision::Beyond => {
                    let span = turn_span.unwrap_or((start, end));
                    log.fault(
                        FaultName::LeverArm,
                        span.0,
                        span.1,
                        format!(
                            "GNSS against CAN in turns puts the antenna {x:.2} ± {sx:.2} m (1 sigma) ahead of the rear axle; the rig file says {:.2} m ({n_turn} turning epochs; limit {limit:.2} m, exceeded by more than 2 sigma)",
                            sp.lever_arm_x_rig_m
                        ),
                    );
                }
                Decision::Undecided => warnings.push(Warning {
                    name: FaultName::LeverArm,
                    detail: format!(
                        "antenna x {x:.2} ± {sx:.2} m (1 sigma) against {:.2} m in the rig file: not determinable against the {limit:.2} m limit from {n_turn} turning epochs; longer turns at speed (yaw rate above 0.1 rad/s) would decide it",
                        sp.lever_arm_x_rig_m
                    ),
                }),
                Decision::Within => {}
            }
        }
        _ => warnings.push(Warning {
            name: FaultName::LeverArm,
            detail: format!(
                "not determinable on this drive ({n_turn} RTK-fixed epochs in turns): it needs turns at speed (yaw rate above 0.1 rad/s, above 0.5 m/s) for at least a second"
            ),
        }),
    }
    sp.speed_residual_mps = Stats::of(speed_res);
    sp.yaw_rate_residual_rps = Stats::of(yaw_res);
    // The path's length, as the GNSS distance below is: a car that reverses has a signed
    // speed, and summed with its sign a drive out and back again read 1.5 m by CAN against
    // 25.8 m by GNSS.
    sp.distance_can_m = inp
        .run
        .motion
        .windows(2)
        .map(|w| 0.5 * (w[0].speed.abs() + w[1].speed.abs()) * secs(w[0].t, w[1].t))
        .sum();
    sp.distance_gnss_m = inp
        .obs
        .windows(2)
        .zip(inp.good.windows(2))
        .filter(|(_, f)| f[0] && f[1])
        .map(|(o, _)| (o[1].position - o[0].position).norm())
        .sum();
    offset_s
}

/// What a GNSS time offset fault says of the logger's clock: CAN frames carry it, so a logger
/// off UTC reads as GNSS time stamps off the motion; where the run put its logger times on
/// GNSS time with the lidar's clock model, an offset left is the receiver's or the lidar's.
fn logger_clock(run: &crate::reference::run::Run) -> String {
    format!(
        "; CAN frames carry the logger's clock: {}",
        run.logger_clock.state.describe(
            run.logger_ahead_of_gnss_ns.map(|n| n as f64 * 1e-6),
            run.clock_sync("gnss").map(|g| g.offset_ns as f64 * 1e-6)
        )
    )
}

/// Antenna velocities on good epochs, central differences.
fn antenna_velocities(inp: &Inputs<'_>) -> Vec<Vel> {
    let (obs, good) = (inp.obs, inp.good);
    let mut vels = Vec::new();
    for k in 1..obs.len().saturating_sub(1) {
        if !(good[k - 1] && good[k] && good[k + 1]) {
            continue;
        }
        let dt = secs(obs[k - 1].t, obs[k + 1].t);
        if dt <= 0.0 || dt > 3.0 * inp.gnss_period as f64 * 1e-9 {
            continue;
        }
        let d = (obs[k + 1].position - obs[k - 1].position) / dt;
        vels.push(Vel {
            t: obs[k].t,
            speed: d.norm(),
            course: d.y.atan2(d.x),
        });
    }
    vels
}

/// The CAN speed scale from straight driving into `sp`, with its uncertainty and its fault (or
/// a warning when this drive cannot decide it); returns the span in which the ego moves.
fn speed_scale(
    inp: &Inputs<'_>,
    vels: &[Vel],
    sp: &mut Spatial,
    log: &mut FaultLog,
    warnings: &mut Vec<Warning>,
) -> Option<(UtcNanos, UtcNanos)> {
    let motion = &inp.run.motion;
    let accel_at = |t: UtcNanos| -> Option<f64> {
        let h = 100_000_000;
        let (a, _) = motion_at(motion, UtcNanos(t.0 - h))?;
        let (b, _) = motion_at(motion, UtcNanos(t.0 + h))?;
        Some((b - a) / 0.2)
    };
    // Straight driving: v_gnss = b1 v_can + b2 a_can (scale 1/b1, time offset -b2/b1).
    let (mut s11, mut s12, mut s22, mut r1, mut r2, mut n_straight) = (0.0, 0.0, 0.0, 0.0, 0.0, 0);
    let mut moving_span: Option<(UtcNanos, UtcNanos)> = None;
    let mut samples = Vec::new();
    for v in vels {
        let (Some((vc, w)), Some(a)) = (motion_at(motion, v.t), accel_at(v.t)) else {
            continue;
        };
        if vc > 0.3 {
            moving_span = Some(moving_span.map_or((v.t, v.t), |(s, _)| (s, v.t)));
        }
        if vc > 0.3 && w.abs() < 0.05 {
            s11 += vc * vc;
            s12 += vc * a;
            s22 += a * a;
            r1 += vc * v.speed;
            r2 += a * v.speed;
            n_straight += 1;
            samples.push((vc, a, v.speed));
        }
    }
    let det = s11 * s22 - s12 * s12;
    if n_straight >= 20 && s11 > 0.0 {
        let (b1, b2) = if s22 > 5.0 && det.abs() > 1e-9 {
            ((r1 * s22 - r2 * s12) / det, (s11 * r2 - s12 * r1) / det)
        } else {
            (r1 / s11, 0.0)
        };
        if b1 > 0.0 {
            let scale = 1.0 / b1;
            sp.can_speed_scale = Some(scale);
            // b2 (= -δ/scale) is not used: the smoother fits the time offset far better than a
            // regression on the few accelerating epochs; it is in the model so that a time
            // offset does not bend the scale.
            // The slope's variance from the residuals (σ² (XᵀX)⁻¹), inflated by their
            // correlation in time; the scale's by the derivative of 1/b1.
            let two = s22 > 5.0 && det.abs() > 1e-9;
            let res: Vec<f64> = samples
                .iter()
                .map(|&(vc, a, vg)| vg - b1 * vc - if two { b2 * a } else { 0.0 })
                .collect();
            let dof = (res.len() as f64 - if two { 2.0 } else { 1.0 }).max(1.0);
            let var_res = res.iter().map(|r| r * r).sum::<f64>() / dof;
            let var_b1 = var_res * if two { s22 / det } else { 1.0 / s11 };
            let series: Vec<Option<Vector2<f64>>> =
                res.iter().map(|&r| Some(Vector2::new(r, 0.0))).collect();
            let sigma = (var_b1 * integrated_autocorrelation(&series)).sqrt() / (b1 * b1);
            sp.can_speed_scale_sigma = Some(sigma);
            let span = moving_span.unwrap_or(inp.span);
            let limit = inp.th.max_speed_scale_error;
            match decide(scale - 1.0, sigma, limit) {
                Decision::Beyond => log.fault(
                    FaultName::CanSpeedScale,
                    span.0,
                    span.1,
                    format!(
                        "CAN speed is {:.2} ± {:.2} % (1 sigma) {} than GNSS speed ({n_straight} straight-driving epochs; limit {:.1} %, exceeded by more than 2 sigma)",
                        (scale - 1.0).abs() * 100.0,
                        sigma * 100.0,
                        if scale > 1.0 { "higher" } else { "lower" },
                        limit * 100.0
                    ),
                ),
                Decision::Undecided => warnings.push(Warning {
                    name: FaultName::CanSpeedScale,
                    detail: format!(
                        "{scale:.4} ± {sigma:.4} (1 sigma) from {n_straight} straight-driving epochs: not determinable against the {:.1} % limit; longer straight driving at a steady speed would decide it",
                        limit * 100.0
                    ),
                }),
                Decision::Within => {}
            }
        }
    } else {
        warnings.push(Warning {
            name: FaultName::CanSpeedScale,
            detail: format!(
                "not determinable on this drive ({n_straight} straight-driving epochs, 20 needed): it needs a few seconds of straight driving above 0.3 m/s on RTK-fixed epochs"
            ),
        });
    }
    moving_span
}

/// What the smoother with the time offset and lever arm as states found.
struct Fit {
    /// The fitted trajectory.
    trajectory: Option<EgoTrajectory>,
    /// Time offset and its standard uncertainty, s (when the drive makes it determinable).
    delta: Option<(f64, f64)>,
    /// Antenna x and its standard uncertainty, m (when the drive turns).
    lever: Option<(f64, f64)>,
    /// The GNSS residuals' correlation factor (the uncertainties include it when the GNSS
    /// noise model is white).
    correlation: f64,
}

/// The smoother with the time offset and the forward lever arm as constant states, on CAN speed
/// corrected by `speed_scale` (so that a scale error is not taken for a time offset) and on
/// RTK-fixed epochs only (a float epoch's error need not match the sigma it reports), under the
/// drive's GNSS noise model. Their uncertainties are the smoother's: where the model has the
/// errors wander, its covariance carries their correlation; where it is white, they are inflated
/// by the correlation the residuals show all the same (see [`correlation_factor`]). That
/// inflation alone is right only for an estimate that averages the errors over their correlation
/// time; a time offset shows only while the speed changes, for a few seconds at a time: fitted
/// under white noise and inflated, the parking drive's offset sigma was 2.8 times the scatter of
/// the estimates over 12 seeds, under the wandering model 1.0 (tests/check.rs). The offset is
/// reported when the ego moves, the lever arm when it turns.
fn offset_and_lever(inp: &Inputs<'_>, speed_scale: f64) -> Fit {
    let motion_fit: Vec<(UtcNanos, f64, f64)> = inp
        .motion
        .iter()
        .map(|&(t, v, w)| (t, v / speed_scale, w))
        .collect();
    let fixed_only: Vec<GnssObs> = inp
        .obs
        .iter()
        .zip(inp.fixed)
        .map(|(o, &f)| GnssObs {
            sigma: if f { o.sigma } else { o.sigma * 1e3 },
            ..*o
        })
        .collect();
    // Fitted twice: the second fit starts from the first one's lever arm, so that the rig
    // file's value (which only seeds the linearisation) leaves no trace in the estimate.
    let fit_under = |noise: GnssNoise| {
        let fit = |lever: Vector2<f64>| {
            EgoTrajectory::smooth(
                &fixed_only,
                &motion_fit,
                &Settings {
                    lever,
                    estimate_offset_and_lever: true,
                    yaw_rate_sigma: inp.yaw_rate_sigma,
                    yaw_jerk_noise: inp.yaw_jerk_noise,
                    gnss_noise: noise,
                    ..Settings::default()
                },
            )
            .ok()
        };
        fit(inp.lever).and_then(|first| {
            let (_, _, x, _) = first.offset_and_lever();
            fit(Vector2::new(x, inp.lever.y)).or(Some(first))
        })
    };
    let fitted = fit_under(inp.gnss_noise);
    // How much the estimates hang on the wander's correlation time, which the drive tells only
    // to within the candidates' factor of two: under a time longer than the receiver's, the
    // filter takes the wander's swings over a second or two for changes of speed and turns,
    // and the time offset and lever arm take them up (20 Hz fixes wandering over 2 s, fitted
    // as 4 s, on a slow loop: -30 ms against a sigma of 3.6 ms, where 2 s and 8 s gave -11
    // and -57 ms). The spread of the estimates under half and twice the fitted time joins
    // their uncertainty.
    let spread = if inp.gnss_noise.wanders() {
        fitted.as_ref().map_or((0.0, 0.0), |f| {
            let (d, _, x, _) = f.offset_and_lever();
            [0.5, 2.0]
                .iter()
                .filter_map(|k| {
                    fit_under(GnssNoise {
                        correlation_s: inp.gnss_noise.correlation_s * k,
                        ..inp.gnss_noise
                    })
                })
                .map(|g| {
                    let (dg, _, xg, _) = g.offset_and_lever();
                    ((dg - d).abs(), (xg - x).abs())
                })
                .fold((0.0, 0.0), |a: (f64, f64), b| (a.0.max(b.0), a.1.max(b.1)))
        })
    } else {
        (0.0, 0.0)
    };
    let motion = &inp.run.motion;
    let moving = motion.iter().filter(|m| m.speed > 0.5).count() >= 50;
    let turning = motion
        .iter()
        .filter(|m| m.yaw_rate.abs() > 0.1 && m.speed > 0.5)
        .count()
        >= 50;
    let sigmas: Vec<Vector2<f64>> = inp.obs.iter().map(|o| o.sigma).collect();
    let correlation = fitted.as_ref().map_or(1.0, |f| {
        let errors: Vec<Vector2<f64>> = f.residuals.iter().map(|r| r.error).collect();
        correlation_factor(&errors, &sigmas, inp.fixed)
    });
    let (delta, lever) = match &fitted {
        Some(f) => {
            let (d, sd, x, sx) = f.offset_and_lever();
            let k = if inp.gnss_noise.wanders() {
                1.0
            } else {
                correlation.sqrt()
            };
            (
                moving.then_some((d, (sd * k).hypot(spread.0))),
                turning.then_some((x, (sx * k).hypot(spread.1))),
            )
        }
        None => (None, None),
    };
    Fit {
        trajectory: fitted,
        delta,
        lever,
        correlation,
    }
}

/// Fixed epochs more than the jump limit off `traj` (normalised innovation), with their
/// faults, and the residual statistics of fixed epochs.
fn jumps(inp: &Inputs<'_>, traj: &EgoTrajectory, sp: &mut Spatial, log: &mut FaultLog) {
    sp.residual_m = Stats::of(
        traj.residuals
            .iter()
            .zip(inp.fixed)
            .filter(|(_, &f)| f)
            .flat_map(|(r, _)| [r.error.x, r.error.y])
            .map(f64::abs)
            .collect(),
    );
    let jump_limit = inp.th.max_jump_sigma.powi(2);
    let jumps: Vec<(UtcNanos, f64)> = traj
        .residuals
        .iter()
        .zip(inp.fixed)
        .filter(|(r, &f)| f && r.nis > jump_limit)
        .map(|(r, _)| (r.t, r.error.norm()))
        .collect();
    sp.jumps = jumps.len();
    log.runs(FaultName::Jump, &jumps, inp.gnss_period, |n, worst| {
        format!(
            "{n} fixed epochs more than {:.0} sigma off the trajectory that CAN speed and yaw rate allow (worst {worst:.3} m)",
            inp.th.max_jump_sigma
        )
    });
}

/// The GNSS course change over about a second against integrated CAN yaw rate (over one epoch
/// the course noise of a few cm/s at walking pace would swamp it), CAN shifted by `delay` ns.
fn yaw_rate_residuals(inp: &Inputs<'_>, vels: &[Vel], delay: i64) -> Vec<f64> {
    let motion = &inp.run.motion;
    let gnss_period = inp.gnss_period;
    let mut yaw_res = Vec::new();
    let span_epochs = (1_000_000_000 / gnss_period.max(1)).max(1) as usize;
    for k in 0..vels.len().saturating_sub(span_epochs) {
        let (a, b) = (&vels[k], &vels[k + span_epochs]);
        let dt = secs(a.t, b.t);
        if dt <= 0.0
            || dt > 1.5 * span_epochs as f64 * gnss_period as f64 * 1e-9
            || a.speed < 1.0
            || b.speed < 1.0
        {
            continue;
        }
        let (ta, tb) = (UtcNanos(a.t.0 - delay), UtcNanos(b.t.0 - delay));
        let k0 = motion.partition_point(|m| m.t < ta);
        let k1 = motion.partition_point(|m| m.t <= tb);
        if k1 <= k0 + 1 {
            continue;
        }
        let turned: f64 = motion[k0..k1]
            .windows(2)
            .map(|w| 0.5 * (w[0].yaw_rate + w[1].yaw_rate) * secs(w[0].t, w[1].t))
            .sum();
        let covered = secs(motion[k0].t, motion[k1 - 1].t).max(1e-9);
        yaw_res.push(wrap(b.course - a.course) / dt - turned / covered);
    }
    yaw_res
}

/// Speed residuals (GNSS minus scale-corrected CAN), and where the drive turns (where a
/// lever-arm error shows): the number of turning epochs and their span.
fn speed_residuals_and_turns(
    inp: &Inputs<'_>,
    vels: &[Vel],
    delay: i64,
    scale: f64,
) -> (Vec<f64>, usize, Option<(UtcNanos, UtcNanos)>) {
    let mut speed_res = Vec::new();
    let mut n_turn = 0;
    let mut turn_span: Option<(UtcNanos, UtcNanos)> = None;
    for v in vels {
        let tc = UtcNanos(v.t.0 - delay);
        if let Some((vc, w)) = motion_at(&inp.run.motion, tc) {
            if vc > 0.5 {
                speed_res.push(v.speed - vc / scale);
            }
            if vc > 0.5 && w.abs() > 0.1 {
                n_turn += 1;
                turn_span = Some(turn_span.map_or((v.t, v.t), |(s, _)| (s, v.t)));
            }
        }
    }
    (speed_res, n_turn, turn_span)
}

/// Linear interpolation of CAN motion at `t`: (speed, yaw rate).
fn motion_at(m: &[Motion], t: UtcNanos) -> Option<(f64, f64)> {
    let k = m.partition_point(|x| x.t <= t);
    if k == 0 || k >= m.len() {
        return None;
    }
    let (a, b) = (&m[k - 1], &m[k]);
    let f = secs(a.t, t) / secs(a.t, b.t).max(1e-9);
    Some((
        a.speed + (b.speed - a.speed) * f,
        a.yaw_rate + (b.yaw_rate - a.yaw_rate) * f,
    ))
}

/// An angle wrapped into [-π, π).
fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

#[cfg(test)]
mod tests {
    use super::super::test_drive::{self, Drive, Segment, T0};
    use super::*;
    use crate::reference::check::report::Fault;

    /// Standing 2 s, accelerating at 1 m/s² to 3 m/s, 4 s straight, a 6 s left turn at
    /// 0.3 rad/s (radius 10 m), 3 s straight, braking at 1 m/s², standing 2 s: 48 m of
    /// speed changes, straight driving and a turn, the manoeuvres each estimate needs.
    const PARKING: [Segment; 7] = [
        (2.0, 0.0, 0.0),
        (3.0, 1.0, 0.0),
        (4.0, 0.0, 0.0),
        (6.0, 0.0, 0.3),
        (3.0, 0.0, 0.0),
        (3.0, -1.0, 0.0),
        (2.0, 0.0, 0.0),
    ];

    /// The antenna's place in the rig file: 0.6 m ahead of the rear axle.
    const RIG_LEVER: Vector2<f64> = Vector2::new(0.6, 0.0);

    struct Checked {
        offset_s: f64,
        sp: Spatial,
        faults: Vec<Fault>,
        warnings: Vec<Warning>,
    }

    /// `gnss_against_can` of `gnss` and `motion` on `drive`, the rig saying [`RIG_LEVER`].
    fn check(drive: &Drive, gnss: &[GnssObs], motion: Vec<Motion>) -> Checked {
        let run = test_drive::run(motion);
        let tuples = test_drive::tuples(&run.motion);
        let all = vec![true; gnss.len()];
        let th = Thresholds::default();
        let inp = Inputs {
            run: &run,
            th: &th,
            obs: gnss,
            fixed: &all,
            good: &all,
            motion: &tuples,
            yaw_rate_sigma: 0.005,
            yaw_jerk_noise: Settings::default().yaw_jerk_noise,
            gnss_noise: GnssNoise::WHITE,
            lever: RIG_LEVER,
            gnss_period: 100_000_000,
            span: (UtcNanos(T0), drive.end()),
        };
        let traj = test_drive::smooth(gnss, &run.motion, RIG_LEVER);
        let mut sp = Spatial {
            lever_arm_x_rig_m: RIG_LEVER.x,
            ..Spatial::default()
        };
        let mut log = FaultLog::new(UtcNanos(T0));
        let mut warnings = Vec::new();
        let offset_s = gnss_against_can(&inp, &traj, &mut sp, &mut log, &mut warnings);
        Checked {
            offset_s,
            sp,
            faults: log.faults,
            warnings,
        }
    }

    /// A car that drives out 9 m and reverses back: CAN's distance is the path's length, as
    /// the GNSS track's is, not the signed sum (0 m).
    #[test]
    fn the_can_distance_of_a_drive_out_and_back_is_its_path_length() {
        let drive = Drive::new(0.0, &[(3.0, 1.0, 0.0), (6.0, -1.0, 0.0), (3.0, 1.0, 0.0)]);
        assert!((drive.length() - 18.0).abs() < 1e-6, "{}", drive.length());
        let gnss = drive.gnss(Vector2::new(0.6, 0.0), 0.0);
        let c = check(&drive, &gnss, drive.motion(1.0, 0.0));
        let can = c.sp.distance_can_m;
        assert!((can - 18.0).abs() < 0.05, "CAN distance {can} m");
    }

    fn names(f: &[Fault]) -> Vec<FaultName> {
        f.iter().map(|f| f.name).collect()
    }

    #[test]
    fn a_late_gnss_track_a_fast_can_speed_and_a_misplaced_antenna_are_measured() {
        // The truth: GNSS stamps 40 ms late, CAN reading 2 % high, the antenna 1.1 m ahead of
        // the rear axle where the rig file says 0.6 m.
        let drive = Drive::new(0.0, &PARKING);
        let gnss = drive.gnss(Vector2::new(1.1, 0.0), 40.0);
        let c = check(&drive, &gnss, drive.motion(1.02, 0.0));
        let ms = c.sp.gnss_time_offset_ms.unwrap();
        // Noise-free data: what is left is the discrete CAN and GNSS sampling of the motion.
        assert!((ms - 40.0).abs() < 0.5, "time offset {ms} ms, truth 40 ms");
        assert!((c.offset_s - ms * 1e-3).abs() < 1e-12);
        let scale = c.sp.can_speed_scale.unwrap();
        assert!(
            (scale - 1.02).abs() < 5e-4,
            "speed scale {scale}, truth 1.02"
        );
        let x = c.sp.lever_arm_x_measured_m.unwrap();
        assert!((x - 1.1).abs() < 0.01, "antenna x {x} m, truth 1.1 m");
        let mut n = names(&c.faults);
        n.sort_unstable();
        assert_eq!(
            n,
            [
                FaultName::CanSpeedScale,
                FaultName::GnssTimeOffset,
                FaultName::LeverArm
            ],
            "{:?}",
            c.faults
        );
        // With the offset and scale taken out, GNSS and CAN agree on speed but for the antenna's
        // own motion: 1.1 m ahead of the axle it moves at √(v² + (ωL)²) in the turn.
        let turning = (3.0f64.powi(2) + (0.3f64 * 1.1).powi(2)).sqrt();
        let sr = c.sp.speed_residual_mps.p95;
        assert!(
            (sr - (turning - 3.0)).abs() < 0.002,
            "speed residual p95 {sr} m/s; the antenna in the turn {} m/s",
            turning - 3.0
        );
        let yr = c.sp.yaw_rate_residual_rps.median;
        assert!(yr.abs() < 0.002, "yaw-rate residual median {yr} rad/s");
        let detail = |name| &c.faults.iter().find(|f| f.name == name).unwrap().detail;
        assert!(detail(FaultName::GnssTimeOffset).contains("later than"));
        assert!(detail(FaultName::CanSpeedScale).contains("higher"));
        // CAN's distance: the true 48 m, read 2 % long.
        let (true_len, can) = (drive.length(), c.sp.distance_can_m);
        assert!((true_len - 48.0).abs() < 1e-6, "{true_len}");
        assert!((can - 1.02 * 48.0).abs() < 0.01, "CAN distance {can} m");
        // The antenna's track.
        let turn = 6.0 * turning;
        let gnss_len = c.sp.distance_gnss_m;
        assert!(
            (gnss_len - (48.0 - 18.0 + turn)).abs() < 0.005,
            "GNSS distance {gnss_len} m, antenna track {} m",
            48.0 - 18.0 + turn
        );
    }

    #[test]
    fn a_clean_drive_raises_no_fault_and_measures_nothing_wrong() {
        let drive = Drive::new(0.0, &PARKING);
        let gnss = drive.gnss(RIG_LEVER, 0.0);
        let c = check(&drive, &gnss, drive.motion(1.0, 0.0));
        assert!(c.faults.is_empty(), "{:?}", c.faults);
        assert!(c.offset_s.abs() < 5e-4, "offset {} s", c.offset_s);
        let scale = c.sp.can_speed_scale.unwrap();
        assert!((scale - 1.0).abs() < 5e-4, "speed scale {scale}");
        let x = c.sp.lever_arm_x_measured_m.unwrap();
        assert!((x - 0.6).abs() < 0.01, "antenna x {x}");
        // GNSS and CAN agree on speed and yaw rate where both are known.
        assert!(c.sp.speed_residual_mps.median.abs() < 0.01);
        assert!(c.sp.yaw_rate_residual_rps.median.abs() < 0.002);
        assert_eq!(c.sp.jumps, 0);
    }

    #[test]
    fn a_can_yaw_rate_bias_is_the_gnss_course_rate_minus_can() {
        let drive = Drive::new(0.0, &PARKING);
        let gnss = drive.gnss(RIG_LEVER, 0.0);
        let c = check(&drive, &gnss, drive.motion(1.0, 0.01));
        let m = c.sp.yaw_rate_residual_rps.median;
        assert!(
            (m + 0.01).abs() < 0.002,
            "yaw-rate residual {m} rad/s; CAN reads 0.01 rad/s high"
        );
    }

    #[test]
    fn an_epoch_off_the_track_is_a_jump_at_its_time() {
        let drive = Drive::new(0.0, &PARKING);
        let mut gnss = drive.gnss(RIG_LEVER, 0.0);
        // The epoch at 12 s (in the turn), 30 cm off: 30 receiver sigmas. One at 6 s, 4 cm
        // off: 4 sigmas, within the 5-sigma limit, not a jump.
        gnss[120].position.y += 0.3;
        gnss[60].position.y += 0.04;
        let c = check(&drive, &gnss, drive.motion(1.0, 0.0));
        assert_eq!(names(&c.faults), [FaultName::Jump], "{:?}", c.faults);
        assert_eq!(c.sp.jumps, 1);
        let f = &c.faults[0];
        assert_eq!(f.window(), (gnss[120].t, gnss[121].t));
    }

    #[test]
    fn a_standing_drive_decides_nothing_and_says_why() {
        let drive = Drive::new(0.0, &[(20.0, 0.0, 0.0)]);
        let gnss = drive.gnss(RIG_LEVER, 0.0);
        let c = check(&drive, &gnss, drive.motion(1.0, 0.0));
        assert!(c.faults.is_empty(), "{:?}", c.faults);
        let mut n: Vec<FaultName> = c.warnings.iter().map(|w| w.name).collect();
        n.sort_unstable();
        assert_eq!(
            n,
            [
                FaultName::CanSpeedScale,
                FaultName::GnssTimeOffset,
                FaultName::LeverArm
            ]
        );
        assert!(c
            .warnings
            .iter()
            .all(|w| w.detail.contains("not determinable")));
        assert_eq!(c.sp.gnss_time_offset_ms, None);
        assert_eq!(c.sp.can_speed_scale, None);
        assert_eq!(c.offset_s, 0.0);
    }

    #[test]
    fn decisions_take_two_sigma_either_side_of_the_limit() {
        // Beyond only when even the estimate less 2 sigma exceeds the limit.
        assert_eq!(decide(15.0, 2.0, 10.0), Decision::Beyond);
        assert_eq!(decide(-15.0, 2.0, 10.0), Decision::Beyond);
        assert_eq!(decide(14.0, 2.0, 10.0), Decision::Undecided);
        assert_eq!(decide(6.0, 2.0, 10.0), Decision::Within);
        assert_eq!(decide(6.5, 2.0, 10.0), Decision::Undecided);
        assert_eq!(decide(0.0, 6.0, 10.0), Decision::Undecided);
    }

    #[test]
    fn angles_wrap_into_minus_pi_to_pi_and_can_motion_interpolates_linearly() {
        use std::f64::consts::PI;
        for (a, w) in [(1.5 * PI, -0.5 * PI), (-PI, -PI), (PI, -PI), (0.25, 0.25)] {
            assert!((wrap(a) - w).abs() < 1e-12, "{a}: {}", wrap(a));
        }
        let m = |t: i64, speed: f64, yaw_rate: f64| Motion {
            t: UtcNanos(t),
            speed,
            yaw_rate,
        };
        let motion = [m(0, 1.0, 0.0), m(20, 2.0, 0.2), m(40, 2.0, 0.2)];
        let (v, w) = motion_at(&motion, UtcNanos(5)).unwrap();
        assert!((v - 1.25).abs() < 1e-12 && (w - 0.05).abs() < 1e-12);
        assert_eq!(motion_at(&motion, UtcNanos(-1)), None);
        assert_eq!(motion_at(&motion, UtcNanos(40)), None);
    }
}
