//! Link layers: from a captured frame to its IPv4 packet (or a SocketCAN frame, or serial bytes).
//!
//! Pure functions of bytes. Everything a lidar logger meets in practice is handled: Ethernet II
//! with any number of 802.1Q / 802.1ad tags, Linux cooked captures (`tcpdump -i any`: SLL and
//! SLL2), raw IPv4, and BSD loopback (`NULL`). Anything else is reported as a skip with the
//! reason, never silently dropped.

use crate::error::SkipReason;

/// A pcap link-layer type number (LINKTYPE_*).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LinkType(pub u16);

impl LinkType {
    /// BSD loopback: 4-byte address family in host byte order.
    pub const NULL: LinkType = LinkType(0);
    /// Ethernet II.
    pub const ETHERNET: LinkType = LinkType(1);
    /// Raw IP (v4 or v6, by the version nibble).
    pub const RAW: LinkType = LinkType(101);
    /// Linux cooked capture v1.
    pub const LINUX_SLL: LinkType = LinkType(113);
    /// OpenBSD loopback: like NULL but network byte order.
    pub const LOOP: LinkType = LinkType(108);
    /// hilrig's serial-port convention: payload is a chunk of the port's byte stream.
    pub const USER0: LinkType = LinkType(147);
    /// SocketCAN frames, can_id big-endian as libpcap writes it.
    pub const CAN_SOCKETCAN: LinkType = LinkType(227);
    /// Raw IPv4.
    pub const IPV4: LinkType = LinkType(228);
    /// Linux cooked capture v2.
    pub const LINUX_SLL2: LinkType = LinkType(276);
}

const ETHERTYPE_IPV4: u16 = 0x0800;
const ETHERTYPE_VLAN: u16 = 0x8100;
const ETHERTYPE_QINQ: u16 = 0x88a8;
const ETHERTYPE_QINQ_OLD: u16 = 0x9100;

/// Finds the IPv4 packet inside a frame of the given link type.
pub fn ipv4_payload(link: LinkType, frame: &[u8]) -> Result<&[u8], SkipReason> {
    match link {
        LinkType::ETHERNET => {
            if frame.len() < 14 {
                return Err(SkipReason::TruncatedLinkHeader);
            }
            ethertype_payload(u16::from_be_bytes([frame[12], frame[13]]), &frame[14..])
        }
        LinkType::LINUX_SLL => {
            if frame.len() < 16 {
                return Err(SkipReason::TruncatedLinkHeader);
            }
            ethertype_payload(u16::from_be_bytes([frame[14], frame[15]]), &frame[16..])
        }
        LinkType::LINUX_SLL2 => {
            if frame.len() < 20 {
                return Err(SkipReason::TruncatedLinkHeader);
            }
            ethertype_payload(u16::from_be_bytes([frame[0], frame[1]]), &frame[20..])
        }
        LinkType::RAW | LinkType::IPV4 => match frame.first() {
            Some(b) if b >> 4 == 4 => Ok(frame),
            Some(_) => Err(SkipReason::NotIpv4),
            None => Err(SkipReason::TruncatedLinkHeader),
        },
        LinkType::NULL | LinkType::LOOP => {
            if frame.len() < 4 {
                return Err(SkipReason::TruncatedLinkHeader);
            }
            // AF_INET is 2 on every platform; the field's byte order depends on the writer.
            let le = u32::from_le_bytes([frame[0], frame[1], frame[2], frame[3]]);
            let be = u32::from_be_bytes([frame[0], frame[1], frame[2], frame[3]]);
            if le == 2 || be == 2 {
                Ok(&frame[4..])
            } else {
                Err(SkipReason::NotIpv4)
            }
        }
        other => Err(SkipReason::UnsupportedLinkType(other.0)),
    }
}

fn ethertype_payload(mut ethertype: u16, mut rest: &[u8]) -> Result<&[u8], SkipReason> {
    // Peel any stack of VLAN tags (each: 2 bytes TCI, 2 bytes inner ethertype).
    while matches!(
        ethertype,
        ETHERTYPE_VLAN | ETHERTYPE_QINQ | ETHERTYPE_QINQ_OLD
    ) {
        if rest.len() < 4 {
            return Err(SkipReason::TruncatedLinkHeader);
        }
        ethertype = u16::from_be_bytes([rest[2], rest[3]]);
        rest = &rest[4..];
    }
    if ethertype == ETHERTYPE_IPV4 {
        Ok(rest)
    } else {
        Err(SkipReason::NotIpv4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eth(ethertype: u16, payload: &[u8]) -> Vec<u8> {
        let mut f = vec![0u8; 12];
        f.extend_from_slice(&ethertype.to_be_bytes());
        f.extend_from_slice(payload);
        f
    }

    #[test]
    fn stacked_vlan_tags_are_peeled() {
        let mut inner = vec![0x00, 0x05];
        inner.extend_from_slice(&ETHERTYPE_VLAN.to_be_bytes());
        inner.extend_from_slice(&[0x00, 0x07]);
        inner.extend_from_slice(&ETHERTYPE_IPV4.to_be_bytes());
        inner.extend_from_slice(&[0x45, 1, 2, 3]);
        let frame = eth(ETHERTYPE_QINQ, &inner);
        assert_eq!(
            ipv4_payload(LinkType::ETHERNET, &frame),
            Ok(&[0x45, 1, 2, 3][..])
        );
    }

    #[test]
    fn arp_is_not_ipv4() {
        assert_eq!(
            ipv4_payload(LinkType::ETHERNET, &eth(0x0806, &[0; 28])),
            Err(SkipReason::NotIpv4)
        );
    }

    #[test]
    fn truncated_vlan_tag_is_reported() {
        assert_eq!(
            ipv4_payload(LinkType::ETHERNET, &eth(ETHERTYPE_VLAN, &[0x00])),
            Err(SkipReason::TruncatedLinkHeader)
        );
    }

    #[test]
    fn sll2_protocol_is_read_from_the_front() {
        let mut f = ETHERTYPE_IPV4.to_be_bytes().to_vec();
        f.extend_from_slice(&[0; 18]);
        f.push(0x45);
        assert_eq!(ipv4_payload(LinkType::LINUX_SLL2, &f), Ok(&[0x45][..]));
    }
}
