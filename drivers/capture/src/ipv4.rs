//! IPv4 (with options and fragments) and UDP.
//!
//! Velodyne data packets (1206 bytes) never fragment on a 1500-byte MTU, but captures taken
//! through tunnels, with jumbo payloads or from other sensors do; fragments are therefore
//! reassembled (bounded: at most [`MAX_PENDING`] datagrams in flight, each at most 64 KiB) and
//! every fragment that cannot be completed is counted, not lost silently.
//!
//! UDP checksums are not verified: NIC checksum offload leaves them wrong in most captures taken on
//! the sending host, so checking them would reject good data.

use crate::error::SkipReason;
use hilrig_stamp::UtcNanos;
use std::collections::BTreeMap;
use std::net::{Ipv4Addr, SocketAddrV4};

/// IP protocol number of UDP.
pub const PROTO_UDP: u8 = 17;
/// Datagrams being reassembled at the same time before the oldest is given up.
pub const MAX_PENDING: usize = 64;

/// A parsed IPv4 header and its payload.
#[derive(Debug, PartialEq, Eq)]
pub struct Ipv4Packet<'a> {
    /// Source address.
    pub src: Ipv4Addr,
    /// Destination address.
    pub dst: Ipv4Addr,
    /// Protocol number.
    pub protocol: u8,
    /// Identification (fragment grouping).
    pub id: u16,
    /// Fragment offset in bytes.
    pub fragment_offset: usize,
    /// More-fragments flag.
    pub more_fragments: bool,
    /// Payload (after options, up to the total length, or to the end of the bytes present
    /// when `length_quirk`).
    pub payload: &'a [u8],
    /// The header's total length runs past the bytes present although the frame was captured
    /// whole (see [`parse_ipv4`]).
    pub length_quirk: bool,
}

/// Parses an IPv4 header (options skipped via IHL); the payload is cut to the total length so that
/// Ethernet padding is not taken for data.
///
/// `whole` says the capture holds the whole frame (captured length = original length). Then a
/// total length beyond the bytes present is not a cut packet but a firmware quirk: early VLP-16
/// firmware writes its data packets' total length (1234) into its 554-byte position frames. Such
/// an unfragmented packet is accepted with `length_quirk` set and the payload running to the end
/// of the frame (the UDP length, checked by [`parse_udp`], then says where the datagram ends).
/// Without `whole` it stays a truncated packet.
pub fn parse_ipv4(bytes: &[u8], whole: bool) -> Result<Ipv4Packet<'_>, SkipReason> {
    if bytes.len() < 20 {
        return Err(SkipReason::TruncatedIpv4);
    }
    if bytes[0] >> 4 != 4 {
        return Err(SkipReason::NotIpv4);
    }
    let ihl = usize::from(bytes[0] & 0x0f) * 4;
    if ihl < 20 {
        return Err(SkipReason::BadIpv4Header);
    }
    let total = usize::from(u16::from_be_bytes([bytes[2], bytes[3]]));
    if total < ihl {
        return Err(SkipReason::BadIpv4Header);
    }
    let flags_frag = u16::from_be_bytes([bytes[6], bytes[7]]);
    let fragmented = flags_frag & 0x3fff != 0;
    let length_quirk = bytes.len() < total;
    if length_quirk && (!whole || fragmented || bytes.len() < ihl) {
        return Err(SkipReason::TruncatedIpv4);
    }
    let end = total.min(bytes.len());
    Ok(Ipv4Packet {
        src: Ipv4Addr::new(bytes[12], bytes[13], bytes[14], bytes[15]),
        dst: Ipv4Addr::new(bytes[16], bytes[17], bytes[18], bytes[19]),
        protocol: bytes[9],
        id: u16::from_be_bytes([bytes[4], bytes[5]]),
        fragment_offset: usize::from(flags_frag & 0x1fff) * 8,
        more_fragments: flags_frag & 0x2000 != 0,
        payload: &bytes[ihl..end],
        length_quirk,
    })
}

/// A UDP datagram's addresses and payload.
#[derive(Debug, PartialEq, Eq)]
pub struct UdpDatagram<'a> {
    /// Sender.
    pub src: SocketAddrV4,
    /// Receiver.
    pub dst: SocketAddrV4,
    /// Payload bytes.
    pub payload: &'a [u8],
}

/// Parses a UDP header inside a (complete, reassembled) IPv4 payload.
pub fn parse_udp(
    src: Ipv4Addr,
    dst: Ipv4Addr,
    bytes: &[u8],
) -> Result<UdpDatagram<'_>, SkipReason> {
    if bytes.len() < 8 {
        return Err(SkipReason::TruncatedUdp);
    }
    let len = usize::from(u16::from_be_bytes([bytes[4], bytes[5]]));
    if len < 8 || len > bytes.len() {
        return Err(SkipReason::BadUdpLength);
    }
    Ok(UdpDatagram {
        src: SocketAddrV4::new(src, u16::from_be_bytes([bytes[0], bytes[1]])),
        dst: SocketAddrV4::new(dst, u16::from_be_bytes([bytes[2], bytes[3]])),
        payload: &bytes[8..len],
    })
}

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
struct FragKey {
    src: Ipv4Addr,
    dst: Ipv4Addr,
    protocol: u8,
    id: u16,
}

struct Pending {
    first_seen: u64,
    parts: BTreeMap<usize, Vec<u8>>,
    total_len: Option<usize>,
}

/// Reassembles fragmented IPv4 datagrams.
#[derive(Default)]
pub struct Reassembler {
    pending: BTreeMap<FragKey, Pending>,
    sequence: u64,
    /// Fragments discarded because their datagram never completed (evicted or overlapping).
    pub fragments_dropped: u64,
}

/// A complete IPv4 payload, either borrowed (never fragmented) or reassembled.
#[derive(Debug, PartialEq, Eq)]
pub struct Complete {
    /// Source address.
    pub src: Ipv4Addr,
    /// Destination address.
    pub dst: Ipv4Addr,
    /// Protocol number.
    pub protocol: u8,
    /// Reassembled payload.
    pub payload: Vec<u8>,
}

impl Reassembler {
    /// Feeds one fragment; returns the datagram when it is complete.
    pub fn push(&mut self, pkt: &Ipv4Packet<'_>, _time: UtcNanos) -> Option<Complete> {
        let key = FragKey {
            src: pkt.src,
            dst: pkt.dst,
            protocol: pkt.protocol,
            id: pkt.id,
        };
        if pkt.fragment_offset + pkt.payload.len() > 65_535 {
            self.fragments_dropped += 1;
            return None;
        }
        if !self.pending.contains_key(&key) && self.pending.len() >= MAX_PENDING {
            // Evict the oldest datagram still waiting for fragments.
            if let Some((&old, _)) = self.pending.iter().min_by_key(|(_, p)| p.first_seen) {
                if let Some(p) = self.pending.remove(&old) {
                    self.fragments_dropped += p.parts.len() as u64;
                }
            }
        }
        self.sequence += 1;
        let seq = self.sequence;
        let entry = self.pending.entry(key).or_insert_with(|| Pending {
            first_seen: seq,
            parts: BTreeMap::new(),
            total_len: None,
        });
        if !pkt.more_fragments {
            entry.total_len = Some(pkt.fragment_offset + pkt.payload.len());
        }
        entry
            .parts
            .insert(pkt.fragment_offset, pkt.payload.to_vec());
        let total = entry.total_len?;
        // Complete when the parts tile [0, total) without gaps.
        let mut covered = 0;
        for (&off, part) in &entry.parts {
            if off > covered {
                return None;
            }
            covered = covered.max(off + part.len());
        }
        if covered < total {
            return None;
        }
        let done = self.pending.remove(&key)?;
        let mut payload = vec![0u8; total];
        for (off, part) in done.parts {
            let end = (off + part.len()).min(total);
            payload[off..end].copy_from_slice(&part[..end - off]);
        }
        Some(Complete {
            src: key.src,
            dst: key.dst,
            protocol: key.protocol,
            payload,
        })
    }

    /// Datagrams still waiting for fragments (counted as dropped at the end of a capture).
    pub fn pending_fragments(&self) -> u64 {
        self.pending.values().map(|p| p.parts.len() as u64).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(total: u16, id: u16, frag: u16, ihl_words: u8) -> Vec<u8> {
        let mut h = vec![0u8; usize::from(ihl_words) * 4];
        h[0] = 0x40 | ihl_words;
        h[2..4].copy_from_slice(&total.to_be_bytes());
        h[4..6].copy_from_slice(&id.to_be_bytes());
        h[6..8].copy_from_slice(&frag.to_be_bytes());
        h[9] = PROTO_UDP;
        h[12..16].copy_from_slice(&[192, 168, 1, 201]);
        h[16..20].copy_from_slice(&[255, 255, 255, 255]);
        h
    }

    #[test]
    fn options_are_skipped_and_padding_cut() {
        let mut p = header(24 + 3, 1, 0, 6);
        p.extend_from_slice(&[1, 2, 3, 0, 0, 0]); // 3 payload bytes + Ethernet padding
        let ip = parse_ipv4(&p, true).expect("valid");
        assert_eq!(ip.payload, &[1, 2, 3]);
    }

    #[test]
    fn fragments_reassemble_in_any_order() {
        let data: Vec<u8> = (0..40u8).collect();
        let mut r = Reassembler::default();
        let f2 = {
            let mut p = header(20 + 16, 7, 3, 5); // offset 24 bytes, last
            p.extend_from_slice(&data[24..]);
            p
        };
        let f1 = {
            let mut p = header(20 + 24, 7, 0x2000, 5);
            p.extend_from_slice(&data[..24]);
            p
        };
        assert_eq!(r.push(&parse_ipv4(&f2, true).unwrap(), UtcNanos(0)), None);
        let done = r
            .push(&parse_ipv4(&f1, true).unwrap(), UtcNanos(0))
            .expect("complete");
        assert_eq!(done.payload, data);
        assert_eq!(r.pending_fragments(), 0);
    }

    #[test]
    fn udp_length_beyond_payload_is_rejected() {
        let mut u = vec![0x09, 0x40, 0x09, 0x40, 0x04, 0xbe, 0, 0];
        u.extend_from_slice(&[0; 10]);
        assert_eq!(
            parse_udp(Ipv4Addr::LOCALHOST, Ipv4Addr::LOCALHOST, &u),
            Err(SkipReason::BadUdpLength)
        );
    }

    /// A position frame of early VLP-16 firmware: IPv4 total length 1234 in a frame whose IPv4
    /// part is 540 bytes, UDP length 520: accepted as a quirk when the frame was captured whole,
    /// its 512-byte payload intact; rejected when the capture says it was cut, or when the UDP
    /// length does not fit either.
    #[test]
    fn a_total_length_beyond_a_whole_frame_is_a_firmware_quirk() {
        let payload: Vec<u8> = (0..512).map(|i| i as u8).collect();
        let src = SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), 8308);
        let dst = SocketAddrV4::new(Ipv4Addr::new(255, 255, 255, 255), 8308);
        let mut p = crate::writer::udp_ipv4_packets(src, dst, &payload, 1, 1500).remove(0);
        p[2..4].copy_from_slice(&1234u16.to_be_bytes());
        let ip = parse_ipv4(&p, true).unwrap();
        assert!(ip.length_quirk);
        let u = parse_udp(ip.src, ip.dst, ip.payload).unwrap();
        assert_eq!(u.payload, &payload[..]);
        assert_eq!(parse_ipv4(&p, false), Err(SkipReason::TruncatedIpv4));
        // A UDP length that does not fit the bytes present either: still rejected.
        p[24..26].copy_from_slice(&1214u16.to_be_bytes());
        let ip = parse_ipv4(&p, true).unwrap();
        assert_eq!(
            parse_udp(ip.src, ip.dst, ip.payload),
            Err(SkipReason::BadUdpLength)
        );
        // A sound packet is no quirk.
        let q = crate::writer::udp_ipv4_packets(src, dst, &payload, 1, 1500).remove(0);
        assert!(!parse_ipv4(&q, true).unwrap().length_quirk);
    }
}
