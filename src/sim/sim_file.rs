//! A simulation's file (`resim`'s, and the gap workflow's re-simulations'), written on a thread
//! of its own: its chunks are compressed there while the next scans are cast.

use crate::bag::topics;
use crate::bag::{msgs, BagOptions, BagWriter};
use hilrig_stamp::UtcNanos;
use std::collections::BTreeMap;
use std::path::Path;

/// Topic of the simulated clouds.
pub const SIM_POINTS: &str = "/sim/points";

/// One scan's simulated messages: log and publish time, the VelodyneScan, the viewing cloud.
pub(super) struct ScanMessages {
    pub(super) log: UtcNanos,
    pub(super) publish: UtcNanos,
    pub(super) packets_cdr: Vec<u8>,
    pub(super) cloud_cdr: Option<Vec<u8>>,
}

/// The simulation's file, written on a thread of its own (chunks are compressed there while
/// the next scans are cast).
pub(super) struct Writer {
    tx: Option<std::sync::mpsc::SyncSender<ScanMessages>>,
    thread: Option<std::thread::JoinHandle<Result<(), String>>>,
}

/// Scans the writer may lag behind the casting.
const WRITE_AHEAD_SCANS: usize = 16;

impl Writer {
    /// Creates `out` with the simulation's metadata and the model attached.
    pub(super) fn start(
        out: &Path,
        meta: BTreeMap<String, String>,
        model_toml: String,
        first_log: UtcNanos,
    ) -> Result<Writer, String> {
        let mut bag = BagWriter::create(out, &BagOptions::default()).map_err(|e| e.to_string())?;
        bag.metadata("sim", meta).map_err(|e| e.to_string())?;
        bag.attach(
            "model.toml",
            "application/toml",
            model_toml.as_bytes(),
            first_log,
        )
        .map_err(|e| e.to_string())?;
        let (tx, rx) = std::sync::mpsc::sync_channel::<ScanMessages>(WRITE_AHEAD_SCANS);
        let thread = std::thread::Builder::new()
            .name("resim writer".into())
            .spawn(move || -> Result<(), String> {
                for m in rx {
                    bag.write(
                        topics::VELODYNE_PACKETS,
                        &msgs::velodyne_scan_type(),
                        m.log,
                        m.publish,
                        &m.packets_cdr,
                    )
                    .map_err(|e| e.to_string())?;
                    if let Some(cloud) = &m.cloud_cdr {
                        bag.write(
                            SIM_POINTS,
                            &msgs::point_cloud2_type(),
                            m.log,
                            m.publish,
                            cloud,
                        )
                        .map_err(|e| e.to_string())?;
                    }
                }
                bag.finish().map(|_| ()).map_err(|e| e.to_string())
            })
            .map_err(|e| e.to_string())?;
        Ok(Writer {
            tx: Some(tx),
            thread: Some(thread),
        })
    }

    /// Hands one scan's messages to the writer; an error when writing failed.
    pub(super) fn send(&self, m: ScanMessages) -> Result<(), String> {
        let Some(tx) = &self.tx else {
            return Err("the writer has stopped".into());
        };
        if tx.send(m).is_err() {
            // The writer stopped on an error: its reason comes with `finish`.
            return Err("writing stopped (see the error that follows)".into());
        }
        Ok(())
    }

    /// Waits for the last messages and closes the file.
    pub(super) fn finish(mut self) -> Result<(), String> {
        self.tx = None;
        match self.thread.take().map(std::thread::JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err("the writer thread failed".into()),
            None => Ok(()),
        }
    }
}
