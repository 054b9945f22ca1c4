//! Live SocketCAN source (feature `tokio`): the thin shell around the `socketcan` crate.
//!
//! Every frame carries the kernel's receive stamp (`SO_TIMESTAMPNS`), taken when the frame
//! reaches the socket, not when the task runs. Classic, FD, remote and error frames are all
//! delivered (error frames are the bus telling us something is wrong) as the capture layer's
//! [`CanFrame`], so live data, captures and candump logs meet in one type.

use hilrig_capture::CanFrame;
use hilrig_stamp::{Stamped, UtcNanos};
use socketcan::{CanAnyFrame, EmbeddedFrame, Frame, SocketOptions};
use std::io;

/// Counters of a SocketCAN source.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SocketCanStats {
    /// Frames received.
    pub frames: u64,
    /// Error frames among them.
    pub error_frames: u64,
    /// Frames the conversion could not represent (should stay 0).
    pub unconvertible: u64,
}

/// A bound SocketCAN interface.
pub struct SocketCanSource {
    socket: socketcan::tokio::CanFdSocket,
    interface: String,
    /// Counters.
    pub stats: SocketCanStats,
}

impl SocketCanSource {
    /// Opens `interface` (e.g. `can0`, `vcan0`) for classic and FD frames with kernel receive
    /// stamps. Must be called inside a tokio runtime.
    pub fn open(interface: &str) -> io::Result<SocketCanSource> {
        let socket = socketcan::tokio::CanFdSocket::open(interface).map_err(|e| {
            io::Error::new(
                e.kind(),
                format!("cannot open CAN interface {interface}: {e}"),
            )
        })?;
        socket.set_recv_timestamp(true)?;
        let _ = socket.set_error_filter_accept_all();
        Ok(SocketCanSource {
            socket,
            interface: interface.to_owned(),
            stats: SocketCanStats::default(),
        })
    }

    /// The interface name.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// The next frame with its kernel receive stamp.
    pub async fn next(&mut self) -> io::Result<Stamped<CanFrame>> {
        loop {
            let (frame, at) = self.socket.read_frame_with_timestamp().await?;
            let host = at
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| UtcNanos(d.as_nanos() as i64))
                .unwrap_or(UtcNanos::EPOCH);
            self.stats.frames += 1;
            match convert(&frame) {
                Some(f) => {
                    if f.error {
                        self.stats.error_frames += 1;
                    }
                    return Ok(Stamped::host(host, f));
                }
                None => self.stats.unconvertible += 1,
            }
        }
    }

    /// Sends a frame (for replay).
    pub async fn send(&self, frame: &CanFrame) -> io::Result<()> {
        let any = to_socketcan(frame).ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("cannot send {frame:?}"),
            )
        })?;
        self.socket.write_frame(&any).await
    }
}

/// Through the LINKTYPE_CAN_SOCKETCAN layout, which both sides already speak exactly.
fn convert(frame: &CanAnyFrame) -> Option<CanFrame> {
    let mut bytes = frame.raw_id().to_be_bytes().to_vec();
    let (len, flags, data): (usize, u8, &[u8]) = match frame {
        CanAnyFrame::Normal(f) => (f.data().len(), 0, f.data()),
        CanAnyFrame::Remote(f) => (f.dlc(), 0, &[]),
        CanAnyFrame::Error(f) => (f.data().len(), 0, f.data()),
        CanAnyFrame::Fd(f) => (
            f.data().len(),
            0x04 | u8::from(f.is_brs()) | (u8::from(f.is_esi()) << 1),
            f.data(),
        ),
    };
    bytes.push(len as u8);
    bytes.push(flags);
    bytes.extend_from_slice(&[0, 0]);
    bytes.extend_from_slice(data);
    if !matches!(frame, CanAnyFrame::Fd(_)) {
        bytes.resize(16, 0);
    }
    CanFrame::decode_socketcan(&bytes).ok()
}

fn to_socketcan(f: &CanFrame) -> Option<CanAnyFrame> {
    let id: socketcan::Id = if f.extended {
        socketcan::ExtendedId::new(f.id)?.into()
    } else {
        socketcan::StandardId::new(f.id as u16)?.into()
    };
    if f.fd {
        let mut fd = socketcan::CanFdFrame::new(id, f.data())?;
        fd.set_brs(f.brs);
        fd.set_esi(f.esi);
        Some(CanAnyFrame::Fd(fd))
    } else if f.rtr {
        Some(CanAnyFrame::Remote(socketcan::CanRemoteFrame::new_remote(
            id,
            f.len(),
        )?))
    } else {
        Some(CanAnyFrame::Normal(socketcan::CanDataFrame::new(
            id,
            f.data(),
        )?))
    }
}
