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
    thread: Option<std::thread::JoinHandle<Result<(), WriteError>>>,
}

/// Why the simulation's file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The MCAP writer failed (its error names the file).
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    /// The writer's thread could not be started.
    #[error("starting the writer: {0}")]
    Spawn(#[source] std::io::Error),
    /// The writer stopped on an error, which `finish` returns.
    #[error("writing stopped (see the error that follows)")]
    Stopped,
    /// The writer's thread panicked.
    #[error("the writer thread failed")]
    Panicked,
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
    ) -> Result<Writer, WriteError> {
        let mut bag = BagWriter::create(out, &BagOptions::default())?;
        bag.metadata("sim", meta)?;
        bag.attach(
            "model.toml",
            "application/toml",
            model_toml.as_bytes(),
            first_log,
        )?;
        let (tx, rx) = std::sync::mpsc::sync_channel::<ScanMessages>(WRITE_AHEAD_SCANS);
        let thread = std::thread::Builder::new()
            .name("resim writer".into())
            .spawn(move || -> Result<(), WriteError> {
                for m in rx {
                    bag.write(
                        topics::VELODYNE_PACKETS,
                        &msgs::velodyne_scan_type(),
                        m.log,
                        m.publish,
                        &m.packets_cdr,
                    )?;
                    if let Some(cloud) = &m.cloud_cdr {
                        bag.write(
                            SIM_POINTS,
                            &msgs::point_cloud2_type(),
                            m.log,
                            m.publish,
                            cloud,
                        )?;
                    }
                }
                bag.finish()?;
                Ok(())
            })
            .map_err(WriteError::Spawn)?;
        Ok(Writer {
            tx: Some(tx),
            thread: Some(thread),
        })
    }

    /// Hands one scan's messages to the writer; an error when writing failed.
    pub(super) fn send(&self, m: ScanMessages) -> Result<(), WriteError> {
        // A writer that stopped on an error: its reason comes with `finish`.
        let tx = self.tx.as_ref().ok_or(WriteError::Stopped)?;
        tx.send(m).map_err(|_| WriteError::Stopped)
    }

    /// Waits for the last messages and closes the file.
    pub(super) fn finish(mut self) -> Result<(), WriteError> {
        self.tx = None;
        match self.thread.take().map(std::thread::JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(WriteError::Panicked),
            None => Ok(()),
        }
    }
}
