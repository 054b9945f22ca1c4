//! What each fault (and mark) of `check` is called. One enum, so that a fault is raised, found
//! (`FaultLog::has`), listed in a segment's reasons and read back downstream by the same
//! name: a misspelt string would silently match nothing. In the JSON, the text and the report
//! each is its snake_case name, as before it was typed.

use serde::Serialize;

/// The name of a fault or a mark.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultName {
    /// Epochs with an RTK float solution.
    RtkFloat,
    /// Epochs without an RTK solution.
    RtkNone,
    /// Fixed epochs whose sigma exceeds the rig's limit.
    SigmaSpike,
    /// Epochs whose corrections are older than the limit.
    CorrectionAge,
    /// Too few RTK-fixed epochs over the run.
    RtkFixedShare,
    /// GNSS epochs the trajectory from CAN motion cannot explain.
    Jump,
    /// CAN speed off the GNSS speed by more than the limit.
    CanSpeedScale,
    /// GNSS stamps off the instants they describe by more than the limit.
    GnssTimeOffset,
    /// The antenna elsewhere than the rig file says.
    LeverArm,
    /// Position packets without PPS lock where the rig requires it.
    LidarNotPpsLocked,
    /// The free-running lidar clock's model residuals above the limit.
    LidarClockResidual,
    /// No lidar data for longer than the gap limit.
    LidarGap,
    /// No GNSS epoch for longer than the gap limit.
    GnssGap,
    /// No CAN ego message for longer than the gap limit.
    CanGap,
    /// Every stretch of the run marked not usable.
    NothingUsable,
    /// A mark: the smoothed heading less certain than the limit.
    HeadingUncertain,
    /// Consecutive heading-source reports beyond 3 sigma of the smoothed heading.
    HeadingSourceDisagrees,
    /// Heading-source reports in a mode other than measured (estimated, manual, simulator).
    HeadingSourceNotMeasured,
    /// The heading source's offset against the track beyond the rig's limit.
    HeadingSourceOffset,
    /// The rig has a heading source that reported no measured heading.
    HeadingSourceMissing,
    /// No lidar data packets at all: nothing to re-simulate or compare.
    NoLidarData,
    /// No (or one) GNSS epoch with a position: no reference trajectory.
    NoGnssFixes,
    /// No ego motion from CAN: no trajectory between GNSS epochs.
    NoEgoMotion,
}

impl FaultName {
    /// The snake_case name (what the JSON holds).
    pub fn as_str(self) -> &'static str {
        match self {
            FaultName::RtkFloat => "rtk_float",
            FaultName::RtkNone => "rtk_none",
            FaultName::SigmaSpike => "sigma_spike",
            FaultName::CorrectionAge => "correction_age",
            FaultName::RtkFixedShare => "rtk_fixed_share",
            FaultName::Jump => "jump",
            FaultName::CanSpeedScale => "can_speed_scale",
            FaultName::GnssTimeOffset => "gnss_time_offset",
            FaultName::LeverArm => "lever_arm",
            FaultName::LidarNotPpsLocked => "lidar_not_pps_locked",
            FaultName::LidarClockResidual => "lidar_clock_residual",
            FaultName::LidarGap => "lidar_gap",
            FaultName::GnssGap => "gnss_gap",
            FaultName::CanGap => "can_gap",
            FaultName::NothingUsable => "nothing_usable",
            FaultName::HeadingUncertain => "heading_uncertain",
            FaultName::HeadingSourceDisagrees => "heading_source_disagrees",
            FaultName::HeadingSourceNotMeasured => "heading_source_not_measured",
            FaultName::HeadingSourceOffset => "heading_source_offset",
            FaultName::HeadingSourceMissing => "heading_source_missing",
            FaultName::NoLidarData => "no_lidar_data",
            FaultName::NoGnssFixes => "no_gnss_fixes",
            FaultName::NoEgoMotion => "no_ego_motion",
        }
    }

    /// The recording's topics whose absence the fault reports (a missing source), else none.
    pub fn topics(self) -> &'static [&'static str] {
        use crate::bag::topics;
        match self {
            FaultName::NoLidarData => &[topics::VELODYNE_PACKETS],
            FaultName::NoGnssFixes => &[topics::GNSS_NMEA, topics::GNSS_UBX],
            FaultName::NoEgoMotion => &[topics::EGO_TWIST],
            _ => &[],
        }
    }
}

impl std::fmt::Display for FaultName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

/// Ordered by name, as the segments' reasons are listed.
impl Ord for FaultName {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.as_str().cmp(other.as_str())
    }
}

impl PartialOrd for FaultName {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Hashed as its name, so that it hashes as the `str` it borrows as.
impl std::hash::Hash for FaultName {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.as_str().hash(state);
    }
}

/// A list of names joins into text (`names.join(", ")`) as the strings they were.
impl std::borrow::Borrow<str> for FaultName {
    fn borrow(&self) -> &str {
        self.as_str()
    }
}

impl PartialEq<&str> for FaultName {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_json_name_is_the_text_name() {
        for n in [
            FaultName::RtkFloat,
            FaultName::LidarNotPpsLocked,
            FaultName::HeadingUncertain,
            FaultName::NoLidarData,
            FaultName::NoGnssFixes,
            FaultName::NoEgoMotion,
        ] {
            assert_eq!(
                serde_json::to_value(n).unwrap(),
                serde_json::Value::from(n.as_str())
            );
            assert_eq!(n.to_string(), n.as_str());
            // Padded in the text report's columns.
            assert_eq!(format!("{n:<24}|").len(), 25);
        }
        let mut v = [FaultName::RtkFloat, FaultName::Jump, FaultName::CanGap];
        v.sort();
        assert_eq!(v.join(", "), "can_gap, jump, rtk_float");
        assert_eq!(FaultName::NoLidarData.topics(), ["/velodyne_packets"]);
        assert!(FaultName::Jump.topics().is_empty());
    }
}
