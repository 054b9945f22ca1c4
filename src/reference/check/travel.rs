//! Which way the car travelled, as the check report says it (see `direction.rs` for how it is
//! told): a file of its own so that the report's types need not reach into the telling.

use serde::{Deserialize, Serialize};

/// Which way the car travelled: where CAN sends the speed as a magnitude, the check tells the
/// stretches backed up from the track (see `direction.rs`), and the smoother takes their speed
/// as negative.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Travel {
    /// What the direction of the first stretch came from (the others follow from it).
    pub direction_from: DirectionFrom,
    /// The stretches the car backed up.
    pub reversing: Vec<TravelStretch>,
    /// Stretches the car moved in whose direction the track could not tell (too short, too
    /// few fixes, or a track neither along nor against the heading): taken as forward.
    #[serde(default)]
    pub undecided: Vec<TravelStretch>,
    /// What the antenna's swing in turns showed, where the speed is a magnitude and the rig has
    /// no heading source (`swing.rs`); absent where it was not tried or too little track
    /// counted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lever_swing: Option<LeverSwing>,
}

/// What the antenna's swing in turns showed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LeverSwing {
    /// The lever arm the track shows, as a share of the rig's: +1 with the first stretch
    /// taken as forward, -1 with it backed up; near 0 neither.
    pub lever_share: f64,
    /// How much better the better way fits, in squared residual sigmas.
    pub margin: f64,
    /// Half-metre segments of track that counted (RTK fixed, crept at most 4 m/s).
    pub segments: usize,
    /// What was made of it.
    pub outcome: SwingOutcome,
}

/// What the check made of the antenna's swing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SwingOutcome {
    /// The stretches fit as the track decided them, the first one forward.
    Confirmed,
    /// They fit only turned round: the drive started backing up.
    TurnedRound,
    /// Neither way fits by far enough, or the swing is a fraction of the rig's lever arm.
    NotTold,
    /// Turned round they would fit, but the drive would then back up too far or too fast
    /// (beyond 100 m or 5 m/s): more likely the rig's lever arm has the wrong sign. The first
    /// stretch stays taken as forward; the lever-arm check says the rest.
    Implausible,
}

/// What told the car's direction of travel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DirectionFrom {
    /// Not told: the car did not move far enough, the run has no trajectory, or the report
    /// predates the field.
    #[default]
    NoMotion,
    /// The CAN speed's own sign.
    CanSpeedSign,
    /// The rig's heading source, at the first stretch the car moved.
    HeadingSource,
    /// The antenna's sideways swing in turns, against the rig's lever arm: the speed is a
    /// magnitude and the rig has no heading source, but the drive turned enough to tell which
    /// way the car went.
    LeverArmSwing,
    /// Nothing: the speed is a magnitude, the rig has no heading source and the drive has no
    /// turn that tells the way, so the first stretch is taken as forward. A drive that starts
    /// backing up then reads as the car turned round.
    AssumedForwardAtStart,
}

/// A stretch of the run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TravelStretch {
    /// Start, UTC.
    pub from: String,
    /// End, UTC.
    pub to: String,
    /// Start, s after the run's start.
    pub from_s: f64,
    /// End, s after the run's start.
    pub to_s: f64,
}

impl Travel {
    /// The report's line on the direction of travel.
    pub(super) fn text(&self) -> String {
        // Stretches as "from-to s", comma-separated.
        let spans = |v: &[TravelStretch]| {
            v.iter()
                .map(|r| format!("{:.1}-{:.1} s", r.from_s, r.to_s))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let backed = if self.reversing.is_empty() {
            "no stretch backed up".to_owned()
        } else {
            format!("backed up {}", spans(&self.reversing))
        };
        let from = match self.direction_from {
            DirectionFrom::NoMotion => "not told: the car did not move far enough",
            DirectionFrom::CanSpeedSign => "from the CAN speed's sign",
            DirectionFrom::HeadingSource => {
                "told from the track: CAN speed is a magnitude; the heading source gave the start"
            }
            DirectionFrom::LeverArmSwing => {
                "told from the track: CAN speed is a magnitude and the rig has no heading source; the antenna's swing in turns gave the start"
            }
            DirectionFrom::AssumedForwardAtStart => {
                "told from the track, the first stretch taken as forward: CAN speed is a magnitude, the rig has no heading source and no turn told the way"
            }
        };
        let undecided = if self.undecided.is_empty() {
            String::new()
        } else {
            format!("; not told, taken as forward: {}", spans(&self.undecided))
        };
        let swing = match &self.lever_swing {
            Some(s) if s.outcome == SwingOutcome::TurnedRound => {
                "; the drive started backing up".to_owned()
            }
            Some(s) if s.outcome == SwingOutcome::Implausible => format!(
                "; turned round, the swing in turns would fit (lever arm {:+.2} of the rig's), but the drive would back up too far or too fast: check the rig's lever arm",
                s.lever_share
            ),
            _ => String::new(),
        };
        format!("direction of travel: {backed}{undecided} ({from}){swing}")
    }
}
