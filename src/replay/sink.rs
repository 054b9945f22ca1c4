//! Where replayed items go: lidar packets to UDP addresses, the GNSS byte stream to a serial
//! device or a new pseudo-terminal, CAN frames to a SocketCAN interface. Each is a [`Sink`]; the
//! player only knows the trait, so it runs in tests against sinks that record what they get.

use super::load::Payload;
use std::io::{self, Write};
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;

/// Why a destination cannot be opened or written.
#[derive(Debug, thiserror::Error)]
pub enum SinkError {
    /// No UDP socket could be opened.
    #[error("cannot open a UDP socket")]
    Udp(#[source] io::Error),
    /// No pseudo-terminal could be opened.
    #[error("cannot open a pseudo-terminal")]
    Pty(#[source] nix::Error),
    /// The serial device could not be opened.
    #[error("cannot open serial port {device}")]
    Serial {
        /// The device.
        device: String,
        /// Cause.
        #[source]
        source: tokio_serial::Error,
    },
    /// Sending or configuring failed.
    #[error(transparent)]
    Io(#[from] io::Error),
    /// Configuring the terminal failed.
    #[error(transparent)]
    Terminal(#[from] nix::Error),
}

/// One destination.
pub trait Sink {
    /// Sends one item (a datagram, a piece of the serial stream, a CAN frame).
    fn send(&mut self, payload: &Payload) -> Result<(), SinkError>;
    /// Called once after the last item of a replay that ended normally.
    fn finish(&mut self) {}
}

/// The destination of each kind of item; items without one are counted and not sent.
#[derive(Default)]
pub struct Destinations {
    /// Velodyne data packets.
    pub lidar_data: Option<Box<dyn Sink>>,
    /// Velodyne position packets.
    pub lidar_position: Option<Box<dyn Sink>>,
    /// The GNSS serial stream.
    pub serial: Option<Box<dyn Sink>>,
    /// CAN frames.
    pub can: Option<Box<dyn Sink>>,
}

impl Destinations {
    /// The sink for `payload`'s kind.
    pub fn for_payload(&mut self, payload: &Payload) -> Option<&mut Box<dyn Sink>> {
        match payload {
            Payload::LidarData(_) => self.lidar_data.as_mut(),
            Payload::LidarPosition(_) => self.lidar_position.as_mut(),
            Payload::Serial(_) => self.serial.as_mut(),
            Payload::Can(_) => self.can.as_mut(),
        }
    }

    /// [`Sink::finish`] on every destination.
    pub fn finish(&mut self) {
        for s in [
            &mut self.lidar_data,
            &mut self.lidar_position,
            &mut self.serial,
            &mut self.can,
        ]
        .into_iter()
        .flatten()
        {
            s.finish();
        }
    }
}

/// A UDP socket of this host, bound to any port; lidar data and position packets share one.
pub fn udp_socket() -> Result<Arc<UdpSocket>, SinkError> {
    UdpSocket::bind("0.0.0.0:0")
        .map(Arc::new)
        .map_err(SinkError::Udp)
}

/// Datagrams to one address.
pub struct UdpSink {
    socket: Arc<UdpSocket>,
    to: SocketAddr,
}

impl UdpSink {
    /// Sends through `socket` to `to`.
    pub fn new(socket: Arc<UdpSocket>, to: SocketAddr) -> UdpSink {
        UdpSink { socket, to }
    }
}

impl Sink for UdpSink {
    fn send(&mut self, payload: &Payload) -> Result<(), SinkError> {
        if let Payload::LidarData(b) | Payload::LidarPosition(b) = payload {
            self.socket.send_to(b, self.to)?;
        }
        Ok(())
    }
}

/// The GNSS byte stream to a serial device or a pseudo-terminal.
pub struct SerialSink {
    out: Box<dyn Write>,
    /// A pty's master discards what its reader has not read yet when it closes.
    linger: bool,
}

impl SerialSink {
    /// A new pseudo-terminal in raw mode; returns the sink and the path a device under test
    /// opens. The slave side stays open here too, so a reader that opens and closes it loses
    /// nothing.
    pub fn pty() -> Result<(SerialSink, std::path::PathBuf), SinkError> {
        use std::os::fd::AsFd;
        let p = nix::pty::openpty(None, None).map_err(SinkError::Pty)?;
        let mut t = nix::sys::termios::tcgetattr(p.slave.as_fd())?;
        nix::sys::termios::cfmakeraw(&mut t);
        nix::sys::termios::tcsetattr(p.slave.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t)?;
        let name = nix::unistd::ttyname(p.slave.as_fd())?;
        std::mem::forget(p.slave);
        Ok((
            SerialSink {
                out: Box::new(std::fs::File::from(p.master)),
                linger: true,
            },
            name,
        ))
    }

    /// A serial device at `baud`.
    pub fn device(device: &str, baud: u32) -> Result<SerialSink, SinkError> {
        let port = tokio_serial::new(device, baud)
            .open()
            .map_err(|source| SinkError::Serial {
                device: device.to_owned(),
                source,
            })?;
        Ok(SerialSink {
            out: Box::new(port),
            linger: false,
        })
    }
}

impl Sink for SerialSink {
    fn send(&mut self, payload: &Payload) -> Result<(), SinkError> {
        if let Payload::Serial(b) = payload {
            self.out.write_all(b)?;
            self.out.flush()?;
        }
        Ok(())
    }

    fn finish(&mut self) {
        if self.linger {
            // Closing the pty's master discards what the reader has not read yet: give it time.
            std::thread::sleep(std::time::Duration::from_millis(500));
        }
    }
}

/// CAN frames to a SocketCAN interface (the driver's async socket on a runtime of its own).
pub struct CanSink {
    rt: tokio::runtime::Runtime,
    socket: hilrig_can::socketcan_source::SocketCanSource,
}

impl CanSink {
    /// Opens `interface` (e.g. `vcan0`).
    pub fn open(interface: &str) -> Result<CanSink, SinkError> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        let socket =
            rt.block_on(async { hilrig_can::socketcan_source::SocketCanSource::open(interface) })?;
        Ok(CanSink { rt, socket })
    }
}

impl Sink for CanSink {
    fn send(&mut self, payload: &Payload) -> Result<(), SinkError> {
        if let Payload::Can(f) = payload {
            let (rt, socket) = (&self.rt, &self.socket);
            send_while_queue_full(|| rt.block_on(socket.send(f)), CAN_QUEUE_PATIENCE)?;
        }
        Ok(())
    }
}

/// How long a frame is retried while the interface's transmit queue is full.
const CAN_QUEUE_PATIENCE: std::time::Duration = std::time::Duration::from_secs(1);

/// Sends with `send`, retrying while it fails with ENOBUFS, for at most `patience`; returns
/// how many times it retried.
///
/// Why: SocketCAN answers a full transmit queue (a burst of frames recorded within
/// microseconds, a slow bus, a short `txqueuelen`) with ENOBUFS at once instead of blocking,
/// and the socket polls writable all the same. The queue drains at the bus's pace, so the frame
/// is sent a little late (the pacing's lag shows it) rather than ending the replay. A queue
/// that does not drain within `patience` (the bus off or unplugged) is an error.
fn send_while_queue_full(
    mut send: impl FnMut() -> io::Result<()>,
    patience: std::time::Duration,
) -> io::Result<u32> {
    let start = std::time::Instant::now();
    let mut retries = 0u32;
    loop {
        match send() {
            Err(e)
                if e.raw_os_error() == Some(nix::libc::ENOBUFS) && start.elapsed() < patience =>
            {
                retries += 1;
                std::thread::sleep(std::time::Duration::from_micros(100));
            }
            other => return other.map(|()| retries),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A full queue is waited out; one that stays full, and any other error, end the send.
    #[test]
    fn a_full_can_queue_is_retried_until_it_drains_or_patience_runs_out() {
        let full = || io::Error::from_raw_os_error(nix::libc::ENOBUFS);
        let mut left = 3;
        let sent = send_while_queue_full(
            || {
                if left > 0 {
                    left -= 1;
                    Err(full())
                } else {
                    Ok(())
                }
            },
            std::time::Duration::from_secs(5),
        );
        assert_eq!(sent.unwrap(), 3);
        let stuck = send_while_queue_full(|| Err(full()), std::time::Duration::from_millis(20));
        assert_eq!(stuck.unwrap_err().raw_os_error(), Some(nix::libc::ENOBUFS));
        let mut calls = 0;
        let other = send_while_queue_full(
            || {
                calls += 1;
                Err(io::Error::from_raw_os_error(nix::libc::ENETDOWN))
            },
            std::time::Duration::from_secs(5),
        );
        assert_eq!(other.unwrap_err().raw_os_error(), Some(nix::libc::ENETDOWN));
        assert_eq!(calls, 1);
    }
}
