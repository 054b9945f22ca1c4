//! Whether the run has the three sources a validation run needs: lidar data (what is
//! re-simulated and compared), GNSS fixes and CAN ego motion (the reference trajectory). A
//! recording without one (the lidar's data port wrong in the rig file, a silent serial line, a
//! DBC mapping that matches no frame) is no validation run however clean the rest is; without
//! this, a run recorded with the wrong data port passed with nothing in it to compare.

use super::names::FaultName;
use crate::reference::run::Run;
use crate::rig::Rig;

/// One fault per source the run lacks, with what was found instead and what to look at.
/// `gnss_epochs` is the number of GNSS epochs with a time and a position.
pub(super) fn missing(run: &Run, gnss_epochs: usize, rig: &Rig) -> Vec<(FaultName, String)> {
    let mut out = Vec::new();
    if run.packets.is_empty() {
        let port = rig.lidar.as_ref().map_or(String::new(), |l| {
            format!(" (the rig's data_port is {})", l.data_port)
        });
        out.push((
            FaultName::NoLidarData,
            format!(
                "no lidar data packets on /velodyne_packets: nothing to re-simulate or compare; {}",
                if run.pps.is_empty() {
                    format!("nor position packets: did the lidar send to the recorder{port}?")
                } else {
                    format!(
                        "{} position packets did arrive, so the lidar was there: is the data port right{port}? `hilrig record` names the ports it saw",
                        run.pps.len()
                    )
                }
            ),
        ));
    }
    if gnss_epochs < 2 {
        out.push((
            FaultName::NoGnssFixes,
            format!(
                "{gnss_epochs} GNSS epochs with a time and a position on /gnss/nmea or /gnss/ubx ({} fixes read in all; at least two epochs are needed): no reference trajectory; is the receiver's serial port right, and does it send GGA/RMC or UBX NAV-PVT?",
                run.fixes.len()
            ),
        ));
    }
    if run.motion.len() < 2 {
        out.push((
            FaultName::NoEgoMotion,
            format!(
                "{} ego-motion samples on /ego/twist (at least two are needed): nothing carries the trajectory between GNSS epochs; {}",
                run.motion.len(),
                if run.can_frames.is_empty() {
                    "no CAN frames on /can/frames either: is the rig's CAN interface right?"
                        .to_owned()
                } else {
                    format!(
                        "{} CAN frames on /can/frames, none that the rig's [can.ego] mapping decodes into speed and yaw rate: do its messages and signals match the DBC?",
                        run.can_frames.len()
                    )
                }
            ),
        ));
    }
    out
}
