//! The leg a parking manoeuvre backs up (`[path.reverse]`): the drive split at the turn-around
//! point into two legs, each driven forwards by the driver model, the second one turned round
//! after. A file of its own because it is the one place where the speed turns negative: the
//! driver ([`super::driven`]) knows only forward.

use super::driven::Driven;
use super::file::{DriveError, DriveFile};
use crate::scene::pose::{PoseSample, Trajectory};
use hilrig_stamp::UtcNanos;
use nalgebra::Vector2;

impl Driven {
    /// This drive followed by `back`, a leg driven forwards from where this one ends, turned
    /// round: the car backs along `back`'s path, so its heading is that path's direction turned
    /// by 180° (continuous with this drive's last heading) and its speed is negative; the yaw
    /// rate is the path direction's, as it is for the body. `back` starts 10 ms after this drive
    /// ends, with its own standing first.
    pub(super) fn then_backing(mut self, back: Driven) -> Result<Driven, String> {
        let (Some(last), Some(first)) = (
            self.ego.samples().last().copied(),
            back.ego.samples().first().copied(),
        ) else {
            return Ok(self);
        };
        let shift = last.t.0 + 10_000_000 - first.t.0;
        let turned = first.yaw + std::f64::consts::PI;
        let turns = ((last.yaw - turned) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
        let mut poses = self.ego.samples().to_vec();
        poses.extend(back.ego.samples().iter().map(|p| PoseSample {
            t: UtcNanos(p.t.0 + shift),
            yaw: p.yaw + std::f64::consts::PI + turns,
            ..*p
        }));
        self.motion
            .extend(back.motion.iter().map(|&(v, w)| (-v, w)));
        self.ego = Trajectory::new(poses).map_err(|e| e.to_string())?;
        self.span = self.ego.span();
        self.beyond_car_backing = back.beyond_car;
        Ok(self)
    }
}

impl DriveFile {
    /// The drive up to its last waypoint: the whole drive without a reversing leg; with one,
    /// ending on arrival (the standing before backing up is the leg's).
    pub(super) fn forward_leg(&self) -> DriveFile {
        let mut f = self.clone();
        if f.path.reverse.take().is_some() {
            f.path.lead_out_s = 0.0;
        }
        f
    }

    /// The reversing leg as a drive of its own, from the forward leg's last pose `end`: driven
    /// forwards along its path, and then turned round by [`Driven::then_backing`]. `None`
    /// without one.
    pub(super) fn reverse_leg(
        &self,
        end: Option<&PoseSample>,
    ) -> Result<Option<DriveFile>, DriveError> {
        let (Some(r), Some(end)) = (&self.path.reverse, end) else {
            return Ok(None);
        };
        let bad = |what: String| DriveError::Invalid {
            name: self.name.clone(),
            what,
        };
        if r.waypoints.is_empty() {
            return Err(bad(
                "path.reverse.waypoints is empty: backing up needs at least one point".into(),
            ));
        }
        if !(r.speed_mps > 0.0 && r.pause_s >= 0.0) {
            return Err(bad(format!(
                "path.reverse.speed_mps = {}, pause_s = {}: the speed must be positive, the pause 0 or more",
                r.speed_mps, r.pause_s
            )));
        }
        // Two points straight behind: the spline's first stretch is then straight, and the car
        // starts backing in the direction it stands (a car does not turn standing).
        let at = Vector2::new(end.position.x, end.position.y);
        let back = -Vector2::new(end.yaw.cos(), end.yaw.sin());
        let (b1, b2) = (at + back, at + back * 2.0);
        let mut waypoints = vec![[at.x, at.y], [b1.x, b1.y], [b2.x, b2.y]];
        waypoints.extend_from_slice(&r.waypoints);
        let mut leg = self.clone();
        leg.path = crate::sim::drive::PathSpec {
            waypoints,
            cruise_speed_mps: r.speed_mps,
            start_speed_mps: 0.0,
            lead_in_s: r.pause_s,
            reverse: None,
            ..self.path.clone()
        };
        leg.walkers.clear();
        leg.yield_to = None;
        // The human variation of the path is the forward leg's (where it ends varies, and the
        // leg starts there); a lateral wave on the leg would turn its start off the heading
        // the car stands in.
        leg.variation.lateral_m = 0.0;
        Ok(Some(leg))
    }
}
