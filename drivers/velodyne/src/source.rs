//! Live UDP source: the thin I/O shell around the packet decoders.
//!
//! Each datagram is stamped with the kernel's receive time (`SO_TIMESTAMPNS`), which is taken when
//! the packet reaches the socket rather than when this task gets scheduled, so a loaded logger
//! does not smear host stamps. Where the kernel gives no stamp the system clock is read right
//! after the receive, and the datagram says so. The receive buffer is raised (with
//! `SO_RCVBUFFORCE` when running with CAP_NET_ADMIN) so that bursts survive a busy CPU.

use crate::packet::{DataPacket, ReturnMode};
use crate::position::PositionPacket;
use crate::rotation::LossCounter;
use crate::{DecodeError, Decoder, Model, DATA_PACKET_SIZE, POSITION_PACKET_SIZE};
use hilrig_stamp::{Stamped, UtcNanos};
use nix::sys::socket::{
    recvmsg, setsockopt, sockopt, ControlMessageOwned, MsgFlags, SockaddrStorage,
};
use std::io::{self, IoSliceMut};
use std::net::SocketAddr;
use std::os::fd::AsRawFd;
use tokio::io::Interest;
use tokio::net::UdpSocket;

/// Default receive buffer: 16 MiB holds ~13,000 Velodyne packets, several seconds of a VLP-32C.
pub const DEFAULT_RECV_BUFFER: usize = 16 * 1024 * 1024;

/// A received datagram's metadata (the bytes are in the caller's buffer).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Datagram {
    /// Payload length.
    pub len: usize,
    /// Receive time.
    pub host: UtcNanos,
    /// Whether `host` is the kernel's stamp (false: system clock after the receive).
    pub kernel_stamp: bool,
    /// Sender.
    pub from: Option<SocketAddr>,
}

/// Counters of a UDP source.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct UdpStats {
    /// Datagrams received.
    pub datagrams: u64,
    /// Payload bytes received.
    pub bytes: u64,
    /// Datagrams larger than the receive buffer given (cut).
    pub truncated: u64,
    /// Datagrams stamped by the system clock because the kernel gave no stamp.
    pub without_kernel_stamp: u64,
}

/// A bound UDP socket that yields stamped datagrams.
pub struct UdpSource {
    socket: UdpSocket,
    recv_buffer: usize,
    /// Counters.
    pub stats: UdpStats,
}

impl UdpSource {
    /// Binds to `addr` with a receive buffer of `recv_buffer` bytes (best effort: the kernel may
    /// grant less; see [`UdpSource::recv_buffer`]). Must be called inside a tokio runtime.
    pub fn bind(addr: SocketAddr, recv_buffer: usize) -> io::Result<UdpSource> {
        let socket = socket2::Socket::new(
            socket2::Domain::for_address(addr),
            socket2::Type::DGRAM,
            Some(socket2::Protocol::UDP),
        )?;
        socket.set_reuse_address(true)?;
        // Privileged processes may exceed net.core.rmem_max; others get what the kernel allows.
        if setsockopt(&socket, sockopt::RcvBufForce, &recv_buffer).is_err() {
            let _ = socket.set_recv_buffer_size(recv_buffer);
        }
        let _ = setsockopt(&socket, sockopt::ReceiveTimestampns, &true);
        socket.bind(&addr.into())?;
        socket.set_nonblocking(true)?;
        // Linux reports twice the requested size (bookkeeping overhead); report what we can use.
        let granted = socket.recv_buffer_size().unwrap_or(0) / 2;
        let socket = UdpSocket::from_std(socket.into())?;
        Ok(UdpSource {
            socket,
            recv_buffer: granted,
            stats: UdpStats::default(),
        })
    }

    /// Local address (useful after binding port 0).
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Receive buffer the kernel granted, bytes.
    pub fn recv_buffer(&self) -> usize {
        self.recv_buffer
    }

    /// Waits for the next datagram and writes its payload into `buf`.
    pub async fn recv(&mut self, buf: &mut [u8]) -> io::Result<Datagram> {
        let fd = self.socket.as_raw_fd();
        let d = self
            .socket
            .async_io(Interest::READABLE, || {
                let mut iov = [IoSliceMut::new(buf)];
                let mut cmsg = nix::cmsg_space!(nix::sys::time::TimeSpec);
                let msg =
                    recvmsg::<SockaddrStorage>(fd, &mut iov, Some(&mut cmsg), MsgFlags::MSG_TRUNC)
                        .map_err(io::Error::from)?;
                let mut stamp = None;
                if let Ok(cmsgs) = msg.cmsgs() {
                    for c in cmsgs {
                        if let ControlMessageOwned::ScmTimestampns(ts) = c {
                            stamp =
                                Some(UtcNanos::from_secs_nanos(ts.tv_sec(), ts.tv_nsec() as u32));
                        }
                    }
                }
                let from = msg.address.and_then(|a| {
                    a.as_sockaddr_in()
                        .map(|v4| SocketAddr::from(std::net::SocketAddrV4::from(*v4)))
                        .or_else(|| {
                            a.as_sockaddr_in6()
                                .map(|v6| SocketAddr::from(std::net::SocketAddrV6::from(*v6)))
                        })
                });
                Ok(Datagram {
                    len: msg.bytes,
                    host: stamp.unwrap_or_else(UtcNanos::now),
                    kernel_stamp: stamp.is_some(),
                    from,
                })
            })
            .await?;
        self.stats.datagrams += 1;
        if d.len > buf.len() {
            self.stats.truncated += 1;
        }
        self.stats.bytes += d.len.min(buf.len()) as u64;
        if !d.kernel_stamp {
            self.stats.without_kernel_stamp += 1;
        }
        Ok(Datagram {
            len: d.len.min(buf.len()),
            ..d
        })
    }
}

/// What the lidar source yields.
// A data packet is moved once per item; boxing it would cost an allocation per packet.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum LidarItem {
    /// A data packet with host stamp.
    Data(Stamped<DataPacket>),
    /// A position packet with host stamp.
    Position(Stamped<PositionPacket>),
    /// A datagram that is not a valid packet (counted; the stream goes on).
    Rejected {
        /// Receive time.
        host: UtcNanos,
        /// The socket it came in on.
        port: PacketPort,
        /// Why.
        error: DecodeError,
    },
}

/// Which of the sensor's sockets a datagram came in on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PacketPort {
    /// The data port (1206-byte data packets).
    Data,
    /// The position port (512-byte position packets).
    Position,
}

/// Counters of the lidar source.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LidarStats {
    /// Data packets accepted.
    pub data_packets: u64,
    /// Position packets accepted.
    pub position_packets: u64,
    /// Datagrams rejected.
    pub rejected: u64,
    /// Data packets lost: sensor timestamp gaps, and outages of more than two seconds told by
    /// the receive times ([`crate::rotation::LossCounter`]).
    pub lost: u64,
    /// Sensor timestamp jumps.
    pub time_jumps: u64,
}

/// Data and position sockets of one sensor.
pub struct LidarSource {
    data: UdpSource,
    position: Option<UdpSource>,
    model: Option<Model>,
    loss: Option<LossCounter>,
    data_buf: Vec<u8>,
    pos_buf: Vec<u8>,
    /// Counters.
    pub stats: LidarStats,
}

impl LidarSource {
    /// Binds the data port and, if given, the position port. `model` fixes the packet period for
    /// loss counting (otherwise it is taken from the first packet's product byte), and data
    /// packets are checked to be that model's ([`crate::check::data_packet`]): another sensor's
    /// packets on the port come out as [`LidarItem::Rejected`].
    pub fn bind(
        data: SocketAddr,
        position: Option<SocketAddr>,
        model: Option<Model>,
        recv_buffer: usize,
    ) -> io::Result<LidarSource> {
        Ok(LidarSource {
            data: UdpSource::bind(data, recv_buffer)?,
            position: position.map(|p| UdpSource::bind(p, 1 << 20)).transpose()?,
            model,
            loss: None,
            data_buf: vec![0u8; 2048],
            pos_buf: vec![0u8; 2048],
            stats: LidarStats::default(),
        })
    }

    /// The data socket (for its address and counters).
    pub fn data_socket(&self) -> &UdpSource {
        &self.data
    }

    /// The position socket, if bound.
    pub fn position_socket(&self) -> Option<&UdpSource> {
        self.position.as_ref()
    }

    /// The next item from either socket.
    pub async fn next(&mut self) -> io::Result<LidarItem> {
        let (is_data, d) = match self.position.as_mut() {
            Some(pos) => tokio::select! {
                d = self.data.recv(&mut self.data_buf) => (true, d?),
                d = pos.recv(&mut self.pos_buf) => (false, d?),
            },
            None => (true, self.data.recv(&mut self.data_buf).await?),
        };
        if is_data {
            let bytes = &self.data_buf[..d.len];
            let checked = match self.model {
                Some(m) => crate::check::data_packet(bytes, m).map(|_| ()),
                None if bytes.len() != DATA_PACKET_SIZE => Err(DecodeError::WrongSize {
                    expected: DATA_PACKET_SIZE,
                    got: bytes.len(),
                }),
                None => Ok(()),
            };
            if let Err(error) = checked {
                self.stats.rejected += 1;
                return Ok(LidarItem::Rejected {
                    host: d.host,
                    port: PacketPort::Data,
                    error,
                });
            }
            match DataPacket::decode(bytes) {
                Ok(pkt) => {
                    if self.loss.is_none() {
                        // A byte shared by two models (0x23, VLP-32A/B) still gives the packet
                        // rate: the two fire alike.
                        let model = self.model.or_else(|| {
                            Model::from_product(pkt.product)
                                .or_else(|| Model::ambiguous_product(pkt.product).first().copied())
                        });
                        if let Some(m) = model {
                            let mode = pkt.return_mode.mode().unwrap_or(ReturnMode::Strongest);
                            self.loss =
                                Some(LossCounter::new(Decoder::new(m).packet_period_us(mode)));
                        }
                    }
                    if let Some(l) = self.loss.as_mut() {
                        l.observe(pkt.timestamp_us, d.host);
                        self.stats.lost = l.lost;
                        self.stats.time_jumps = l.time_jumps;
                    }
                    self.stats.data_packets += 1;
                    Ok(LidarItem::Data(Stamped::host(d.host, pkt)))
                }
                Err(error) => {
                    self.stats.rejected += 1;
                    Ok(LidarItem::Rejected {
                        host: d.host,
                        port: PacketPort::Data,
                        error,
                    })
                }
            }
        } else {
            let bytes = &self.pos_buf[..d.len];
            if bytes.len() != POSITION_PACKET_SIZE {
                self.stats.rejected += 1;
                return Ok(LidarItem::Rejected {
                    host: d.host,
                    port: PacketPort::Position,
                    error: DecodeError::WrongSize {
                        expected: POSITION_PACKET_SIZE,
                        got: bytes.len(),
                    },
                });
            }
            match PositionPacket::decode(bytes) {
                Ok(p) => {
                    self.stats.position_packets += 1;
                    Ok(LidarItem::Position(Stamped::host(d.host, p)))
                }
                Err(error) => {
                    self.stats.rejected += 1;
                    Ok(LidarItem::Rejected {
                        host: d.host,
                        port: PacketPort::Position,
                        error,
                    })
                }
            }
        }
    }
}
