//! Writing captures: pcapng (what hilrig produces) and classic pcap (for tests of both byte orders
//! and resolutions), plus builders for the frames inside.
//!
//! Written by hand rather than with pcap-parser's `serialize` feature: the block layout is a few
//! lines, and owning it lets the writer stream (no block structs to build) and always use
//! nanosecond resolution, which pcap-parser's serializer leaves to the caller.

use crate::link::LinkType;
use hilrig_stamp::UtcNanos;
use std::io::{self, Write};
use std::net::SocketAddrV4;

const SHB_TYPE: u32 = 0x0A0D_0D0A;
const IDB_TYPE: u32 = 0x0000_0001;
const EPB_TYPE: u32 = 0x0000_0006;
const BYTE_ORDER_MAGIC: u32 = 0x1A2B_3C4D;
const OPT_END: u16 = 0;
const OPT_SHB_USERAPPL: u16 = 4;
const OPT_IF_NAME: u16 = 2;
const OPT_IF_TSRESOL: u16 = 9;

fn pad4(n: usize) -> usize {
    (4 - n % 4) % 4
}

fn push_option(out: &mut Vec<u8>, code: u16, value: &[u8]) {
    out.extend_from_slice(&code.to_le_bytes());
    out.extend_from_slice(&(value.len() as u16).to_le_bytes());
    out.extend_from_slice(value);
    out.extend(std::iter::repeat_n(0u8, pad4(value.len())));
}

/// A pcapng writer (little-endian, nanosecond timestamps on every interface).
pub struct PcapngWriter<W: Write> {
    out: W,
    interfaces: Vec<LinkType>,
    block: Vec<u8>,
}

impl<W: Write> PcapngWriter<W> {
    /// Writes the section header; `application` goes into `shb_userappl`.
    pub fn new(mut out: W, application: &str) -> io::Result<Self> {
        let mut body = Vec::new();
        body.extend_from_slice(&BYTE_ORDER_MAGIC.to_le_bytes());
        body.extend_from_slice(&1u16.to_le_bytes());
        body.extend_from_slice(&0u16.to_le_bytes());
        body.extend_from_slice(&(-1i64).to_le_bytes());
        push_option(&mut body, OPT_SHB_USERAPPL, application.as_bytes());
        push_option(&mut body, OPT_END, &[]);
        write_block(&mut out, SHB_TYPE, &body)?;
        Ok(PcapngWriter {
            out,
            interfaces: Vec::new(),
            block: Vec::with_capacity(2048),
        })
    }

    /// Declares an interface and returns its id.
    pub fn add_interface(&mut self, link: LinkType, name: &str) -> io::Result<u32> {
        let mut body = Vec::new();
        body.extend_from_slice(&link.0.to_le_bytes());
        body.extend_from_slice(&0u16.to_le_bytes());
        body.extend_from_slice(&0u32.to_le_bytes()); // no snap length limit
        push_option(&mut body, OPT_IF_NAME, name.as_bytes());
        push_option(&mut body, OPT_IF_TSRESOL, &[9]);
        push_option(&mut body, OPT_END, &[]);
        write_block(&mut self.out, IDB_TYPE, &body)?;
        self.interfaces.push(link);
        Ok((self.interfaces.len() - 1) as u32)
    }

    /// Writes one packet on an interface.
    pub fn write_packet(&mut self, interface: u32, time: UtcNanos, data: &[u8]) -> io::Result<()> {
        if interface as usize >= self.interfaces.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("interface {interface} was never declared"),
            ));
        }
        let units = u64::try_from(time.0).map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                "pcapng cannot store times before 1970",
            )
        })?;
        self.block.clear();
        self.block.extend_from_slice(&interface.to_le_bytes());
        self.block
            .extend_from_slice(&((units >> 32) as u32).to_le_bytes());
        self.block.extend_from_slice(&(units as u32).to_le_bytes());
        self.block
            .extend_from_slice(&(data.len() as u32).to_le_bytes());
        self.block
            .extend_from_slice(&(data.len() as u32).to_le_bytes());
        self.block.extend_from_slice(data);
        self.block
            .extend(std::iter::repeat_n(0u8, pad4(data.len())));
        write_block(&mut self.out, EPB_TYPE, &self.block)
    }

    /// Flushes and returns the inner writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

fn write_block<W: Write>(out: &mut W, kind: u32, body: &[u8]) -> io::Result<()> {
    let total = (12 + body.len()) as u32;
    out.write_all(&kind.to_le_bytes())?;
    out.write_all(&total.to_le_bytes())?;
    out.write_all(body)?;
    out.write_all(&total.to_le_bytes())
}

/// A classic pcap writer.
pub struct PcapWriter<W: Write> {
    out: W,
    big_endian: bool,
    nanos: bool,
}

impl<W: Write> PcapWriter<W> {
    /// Writes the file header for one link type; byte order and resolution are selectable because
    /// real files come in all four combinations.
    pub fn new(mut out: W, link: LinkType, big_endian: bool, nanos: bool) -> io::Result<Self> {
        let magic: u32 = if nanos { 0xa1b2_3c4d } else { 0xa1b2_c3d4 };
        let mut h = Vec::with_capacity(24);
        let put32 = |h: &mut Vec<u8>, v: u32| {
            h.extend_from_slice(&if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            })
        };
        let put16 = |h: &mut Vec<u8>, v: u16| {
            h.extend_from_slice(&if big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            })
        };
        put32(&mut h, magic);
        put16(&mut h, 2);
        put16(&mut h, 4);
        put32(&mut h, 0);
        put32(&mut h, 0);
        put32(&mut h, 65_535);
        put32(&mut h, u32::from(link.0));
        out.write_all(&h)?;
        Ok(PcapWriter {
            out,
            big_endian,
            nanos,
        })
    }

    /// Writes one record.
    pub fn write_packet(&mut self, time: UtcNanos, data: &[u8]) -> io::Result<()> {
        let (secs, ns) = time.secs_nanos();
        let frac = if self.nanos { ns } else { ns / 1_000 };
        let fields = [secs as u32, frac, data.len() as u32, data.len() as u32];
        for v in fields {
            let b = if self.big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            };
            self.out.write_all(&b)?;
        }
        self.out.write_all(data)
    }

    /// Flushes and returns the inner writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// IPv4 header checksum (RFC 791).
fn ipv4_checksum(header: &[u8]) -> u16 {
    let mut sum: u32 = 0;
    for pair in header.chunks(2) {
        let word = u16::from_be_bytes([pair[0], *pair.get(1).unwrap_or(&0)]);
        sum += u32::from(word);
    }
    while sum > 0xffff {
        sum = (sum & 0xffff) + (sum >> 16);
    }
    !(sum as u16)
}

/// Builds IPv4 packets (one, or fragments when the payload exceeds `mtu`) carrying a UDP datagram.
pub fn udp_ipv4_packets(
    src: SocketAddrV4,
    dst: SocketAddrV4,
    payload: &[u8],
    id: u16,
    mtu: usize,
) -> Vec<Vec<u8>> {
    let mut udp = Vec::with_capacity(8 + payload.len());
    udp.extend_from_slice(&src.port().to_be_bytes());
    udp.extend_from_slice(&dst.port().to_be_bytes());
    udp.extend_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
    udp.extend_from_slice(&0u16.to_be_bytes()); // checksum not computed (allowed for IPv4)
    udp.extend_from_slice(payload);
    let max_frag = ((mtu.max(28) - 20) / 8) * 8;
    let mut out = Vec::new();
    let mut offset = 0;
    while offset < udp.len() || out.is_empty() {
        let end = if udp.len() - offset <= mtu - 20 {
            udp.len()
        } else {
            offset + max_frag
        };
        let more = end < udp.len();
        let mut p = Vec::with_capacity(20 + end - offset);
        p.push(0x45);
        p.push(0);
        p.extend_from_slice(&((20 + end - offset) as u16).to_be_bytes());
        p.extend_from_slice(&id.to_be_bytes());
        let frag = ((offset / 8) as u16) | if more { 0x2000 } else { 0 };
        p.extend_from_slice(&frag.to_be_bytes());
        p.push(64);
        p.push(17);
        p.extend_from_slice(&[0, 0]);
        p.extend_from_slice(&src.ip().octets());
        p.extend_from_slice(&dst.ip().octets());
        let c = ipv4_checksum(&p[..20]);
        p[10..12].copy_from_slice(&c.to_be_bytes());
        p.extend_from_slice(&udp[offset..end]);
        out.push(p);
        offset = end;
    }
    out
}

/// Wraps an IPv4 packet in an Ethernet II frame, optionally with an 802.1Q tag.
pub fn ethernet_frame(ipv4: &[u8], vlan: Option<u16>) -> Vec<u8> {
    let mut f = Vec::with_capacity(18 + ipv4.len());
    f.extend_from_slice(&[0xff; 6]);
    f.extend_from_slice(&[0x60, 0x76, 0x88, 0x00, 0x00, 0x00]); // Velodyne OUI
    if let Some(tci) = vlan {
        f.extend_from_slice(&0x8100u16.to_be_bytes());
        f.extend_from_slice(&tci.to_be_bytes());
    }
    f.extend_from_slice(&0x0800u16.to_be_bytes());
    f.extend_from_slice(ipv4);
    f
}

/// One Ethernet frame carrying a UDP datagram (no fragmentation).
pub fn udp_ethernet_frame(src: SocketAddrV4, dst: SocketAddrV4, payload: &[u8]) -> Vec<u8> {
    let pkts = udp_ipv4_packets(src, dst, payload, 0, 65_535);
    ethernet_frame(&pkts[0], None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demux::{Demux, Packet};
    use crate::reader::CaptureReader;
    use std::io::Cursor;
    use std::net::Ipv4Addr;

    fn addr(port: u16) -> SocketAddrV4 {
        SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), port)
    }

    #[test]
    fn checksum_of_a_known_header() {
        // Example from RFC 1071 style test vectors (Wikipedia's IPv4 header checksum example).
        let h = [
            0x45, 0x00, 0x00, 0x73, 0x00, 0x00, 0x40, 0x00, 0x40, 0x11, 0x00, 0x00, 0xc0, 0xa8,
            0x00, 0x01, 0xc0, 0xa8, 0x00, 0xc7,
        ];
        assert_eq!(ipv4_checksum(&h), 0xb861);
    }

    #[test]
    fn pcapng_with_udp_can_and_serial_interfaces_reads_back() {
        let mut w = PcapngWriter::new(Vec::new(), "hilrig test").unwrap();
        let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
        let can = w.add_interface(LinkType::CAN_SOCKETCAN, "can0").unwrap();
        let ser = w.add_interface(LinkType::USER0, "/dev/ttyUSB0").unwrap();
        let t0 = UtcNanos(1_700_000_000_123_456_789);
        w.write_packet(
            eth,
            t0,
            &udp_ethernet_frame(addr(2368), addr(2368), &[7; 1206]),
        )
        .unwrap();
        let frame = crate::can::CanFrame::new(0x101, false, &[1, 2, 3, 4]).unwrap();
        w.write_packet(can, UtcNanos(t0.0 + 1), &frame.encode_socketcan())
            .unwrap();
        w.write_packet(ser, UtcNanos(t0.0 + 2), b"$GPGGA,...*00\r\n")
            .unwrap();
        let bytes = w.finish().unwrap();

        let mut d = Demux::new(CaptureReader::new(Cursor::new(bytes)).unwrap());
        let a = d.next_item().unwrap().unwrap();
        assert_eq!(a.time, t0);
        assert!(
            matches!(a.packet, Packet::Udp { dst, payload, .. } if dst.port() == 2368 && payload.len() == 1206)
        );
        let b = d.next_item().unwrap().unwrap();
        assert_eq!(b.packet, Packet::Can(frame));
        let c = d.next_item().unwrap().unwrap();
        assert_eq!(c.time, UtcNanos(t0.0 + 2));
        assert_eq!(c.packet, Packet::Serial(&b"$GPGGA,...*00\r\n"[..]));
        assert!(d.next_item().is_none());
        assert_eq!(d.interfaces()[2].name.as_deref(), Some("/dev/ttyUSB0"));
    }

    #[test]
    fn pcap_in_all_byte_orders_and_resolutions_reads_back() {
        for big in [false, true] {
            for nanos in [false, true] {
                let mut w = PcapWriter::new(Vec::new(), LinkType::ETHERNET, big, nanos).unwrap();
                let t = UtcNanos(1_355_263_594_293_504_123);
                w.write_packet(t, &udp_ethernet_frame(addr(1), addr(8308), &[1; 512]))
                    .unwrap();
                let bytes = w.finish().unwrap();
                let mut d = Demux::new(CaptureReader::new(Cursor::new(bytes)).unwrap());
                let item = d.next_item().unwrap().unwrap();
                let expected = if nanos {
                    t
                } else {
                    UtcNanos(t.0 / 1000 * 1000)
                };
                assert_eq!(item.time, expected, "big={big} nanos={nanos}");
                assert!(matches!(item.packet, Packet::Udp { payload, .. } if payload.len() == 512));
            }
        }
    }

    #[test]
    fn fragmented_vlan_tagged_datagram_is_reassembled() {
        let payload: Vec<u8> = (0..3000u32).map(|i| i as u8).collect();
        let mut w = PcapngWriter::new(Vec::new(), "t").unwrap();
        let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
        let mut frags = udp_ipv4_packets(addr(5), addr(2368), &payload, 42, 1500);
        assert_eq!(frags.len(), 3);
        frags.reverse();
        for (i, f) in frags.iter().enumerate() {
            w.write_packet(eth, UtcNanos(i as i64 + 1), &ethernet_frame(f, Some(7)))
                .unwrap();
        }
        let mut d = Demux::new(CaptureReader::new(Cursor::new(w.finish().unwrap())).unwrap());
        let item = d.next_item().unwrap().unwrap();
        assert_eq!(
            item.packet,
            Packet::Udp {
                src: addr(5),
                dst: addr(2368),
                payload: &payload
            }
        );
        assert!(d.next_item().is_none());
        assert_eq!(d.stats().fragments, 2);
        assert_eq!(d.stats().fragments_dropped, 0);
    }

    #[test]
    fn zstd_compressed_captures_read_like_plain_ones() {
        let mut w = PcapngWriter::new(Vec::new(), "t").unwrap();
        let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
        for i in 0..50u8 {
            let f = udp_ethernet_frame(addr(1), addr(2368), &[i; 100]);
            w.write_packet(eth, UtcNanos(i64::from(i) * 1000), &f)
                .unwrap();
        }
        let plain = w.finish().unwrap();
        let packed = zstd::encode_all(&plain[..], 3).unwrap();
        assert!(packed.len() < plain.len() / 4);
        let read = |bytes: Vec<u8>| {
            let mut d = Demux::new(CaptureReader::new(Cursor::new(bytes)).unwrap());
            let mut v = Vec::new();
            while let Some(item) = d.next_item() {
                let item = item.unwrap();
                if let Packet::Udp { payload, .. } = item.packet {
                    v.push((item.time, payload.to_vec()));
                }
            }
            v
        };
        let a = read(plain);
        assert_eq!(a.len(), 50);
        assert_eq!(a, read(packed));
        // zstd around something else is still refused with the inner magic.
        let text = zstd::encode_all(&b"not a capture at all"[..], 3).unwrap();
        match CaptureReader::new(Cursor::new(text)) {
            Err(crate::CaptureError::NotACapture { magic }) => assert_eq!(magic, b"not ".to_vec()),
            other => panic!("{:?}", other.map(|_| ())),
        }
    }
}
