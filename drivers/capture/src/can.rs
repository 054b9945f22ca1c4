//! SocketCAN frames as libpcap stores them (LINKTYPE_CAN_SOCKETCAN, 227).
//!
//! The 8-byte header is `can_id` (big-endian in capture files, as libpcap writes it, with the
//! EFF/RTR/ERR flags in its top bits), payload length, CAN FD flags, two reserved bytes; then the
//! payload. Classic frames are padded to 8 bytes on the wire of the socket; we keep only `len`.

use crate::error::SkipReason;

const EFF_FLAG: u32 = 0x8000_0000;
const RTR_FLAG: u32 = 0x4000_0000;
const ERR_FLAG: u32 = 0x2000_0000;
const EFF_MASK: u32 = 0x1fff_ffff;
const SFF_MASK: u32 = 0x0000_07ff;
/// CANFD_BRS: bit rate switch.
const FD_BRS: u8 = 0x01;
/// CANFD_ESI: error state indicator.
const FD_ESI: u8 = 0x02;
/// CANFD_FDF: marks an FD frame (set by Linux >= 5.14 and by libpcap's writers).
const FD_FDF: u8 = 0x04;

/// One CAN or CAN FD frame.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct CanFrame {
    /// Identifier without flags (11 or 29 bits).
    pub id: u32,
    /// 29-bit identifier.
    pub extended: bool,
    /// Remote transmission request (classic CAN only).
    pub rtr: bool,
    /// An error frame reported by the controller; `id` then holds the error class bits.
    pub error: bool,
    /// CAN FD frame (up to 64 bytes).
    pub fd: bool,
    /// CAN FD bit-rate switch.
    pub brs: bool,
    /// CAN FD error state indicator.
    pub esi: bool,
    len: u8,
    data: [u8; 64],
}

impl std::fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CanFrame")
            .field("id", &format_args!("{:#x}", self.id))
            .field("extended", &self.extended)
            .field("rtr", &self.rtr)
            .field("error", &self.error)
            .field("fd", &self.fd)
            .field("data", &self.data())
            .finish()
    }
}

/// Valid CAN FD payload lengths (the DLC table).
pub const FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

impl CanFrame {
    /// A classic data frame; `None` if the id or length is out of range.
    pub fn new(id: u32, extended: bool, data: &[u8]) -> Option<Self> {
        let max_id = if extended { EFF_MASK } else { SFF_MASK };
        if id > max_id || data.len() > 8 {
            return None;
        }
        let mut f = CanFrame::empty(id, extended);
        f.len = data.len() as u8;
        f.data[..data.len()].copy_from_slice(data);
        Some(f)
    }

    /// A CAN FD data frame; `None` if the id or length is invalid.
    pub fn new_fd(id: u32, extended: bool, data: &[u8], brs: bool) -> Option<Self> {
        let max_id = if extended { EFF_MASK } else { SFF_MASK };
        if id > max_id || !FD_LENGTHS.contains(&data.len()) {
            return None;
        }
        let mut f = CanFrame::empty(id, extended);
        f.fd = true;
        f.brs = brs;
        f.len = data.len() as u8;
        f.data[..data.len()].copy_from_slice(data);
        Some(f)
    }

    /// A remote request frame with a requested length.
    pub fn new_remote(id: u32, extended: bool, dlc: u8) -> Option<Self> {
        let mut f = CanFrame::new(id, extended, &[])?;
        if dlc > 8 {
            return None;
        }
        f.rtr = true;
        f.len = dlc;
        Some(f)
    }

    fn empty(id: u32, extended: bool) -> Self {
        CanFrame {
            id,
            extended,
            rtr: false,
            error: false,
            fd: false,
            brs: false,
            esi: false,
            len: 0,
            data: [0; 64],
        }
    }

    /// Payload (empty for remote frames, whose `len` is the requested DLC).
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            &self.data[..usize::from(self.len)]
        }
    }

    /// Payload length field (for remote frames the requested length).
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// True when the frame carries no payload bytes.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// `can_id` with flag bits, as the kernel and libpcap represent it.
    pub fn raw_id(&self) -> u32 {
        let mut raw = self.id;
        if self.extended {
            raw |= EFF_FLAG;
        }
        if self.rtr {
            raw |= RTR_FLAG;
        }
        if self.error {
            raw |= ERR_FLAG;
        }
        raw
    }

    /// Decodes a LINKTYPE_CAN_SOCKETCAN record.
    pub fn decode_socketcan(bytes: &[u8]) -> Result<Self, SkipReason> {
        if bytes.len() < 8 {
            return Err(SkipReason::BadCanFrame);
        }
        let raw = u32::from_be_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        let len = bytes[4];
        let flags = bytes[5];
        let extended = raw & EFF_FLAG != 0;
        let error = raw & ERR_FLAG != 0;
        let rtr = raw & RTR_FLAG != 0;
        let id = if extended || error {
            raw & EFF_MASK
        } else {
            raw & SFF_MASK
        };
        let fd = flags & FD_FDF != 0 || len > 8;
        if fd && !FD_LENGTHS.contains(&usize::from(len)) || len > 64 {
            return Err(SkipReason::BadCanFrame);
        }
        let payload = &bytes[8..];
        let carried = if rtr { 0 } else { usize::from(len) };
        if payload.len() < carried {
            return Err(SkipReason::BadCanFrame);
        }
        let mut f = CanFrame::empty(id, extended);
        f.error = error;
        f.rtr = rtr;
        f.fd = fd;
        f.brs = fd && flags & FD_BRS != 0;
        f.esi = fd && flags & FD_ESI != 0;
        f.len = len;
        f.data[..carried].copy_from_slice(&payload[..carried]);
        Ok(f)
    }

    /// Encodes as a LINKTYPE_CAN_SOCKETCAN record (classic frames padded to 8 bytes, as the
    /// kernel delivers them).
    pub fn encode_socketcan(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(16);
        out.extend_from_slice(&self.raw_id().to_be_bytes());
        out.push(self.len);
        let mut flags = 0;
        if self.fd {
            flags |= FD_FDF;
            if self.brs {
                flags |= FD_BRS;
            }
            if self.esi {
                flags |= FD_ESI;
            }
        }
        out.push(flags);
        out.extend_from_slice(&[0, 0]);
        let payload_len = if self.fd { usize::from(self.len) } else { 8 };
        let mut payload = [0u8; 64];
        payload[..self.data().len()].copy_from_slice(self.data());
        out.extend_from_slice(&payload[..payload_len]);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn extended_id_is_big_endian_with_flag() {
        let f = CanFrame::new(0x18DAF110, true, &[1, 2, 3]).unwrap();
        let b = f.encode_socketcan();
        assert_eq!(&b[..4], &[0x98, 0xDA, 0xF1, 0x10]);
        assert_eq!(b.len(), 16);
        assert_eq!(CanFrame::decode_socketcan(&b).unwrap(), f);
    }

    #[test]
    fn fd_length_must_be_a_dlc_length() {
        let mut b = CanFrame::new_fd(0x101, false, &[0; 12], true)
            .unwrap()
            .encode_socketcan();
        b[4] = 13;
        assert_eq!(CanFrame::decode_socketcan(&b), Err(SkipReason::BadCanFrame));
    }

    proptest! {
        #[test]
        fn socketcan_round_trips(id in 0u32..0x1fff_ffff, ext in any::<bool>(), fd in any::<bool>(),
                                 n in 0usize..16, brs in any::<bool>(), byte in any::<u8>()) {
            let id = if ext { id } else { id & 0x7ff };
            let f = if fd {
                CanFrame::new_fd(id, ext, &vec![byte; FD_LENGTHS[n]], brs).unwrap()
            } else {
                CanFrame::new(id, ext, &vec![byte; n.min(8)]).unwrap()
            };
            prop_assert_eq!(CanFrame::decode_socketcan(&f.encode_socketcan()).unwrap(), f);
        }

        #[test]
        fn decode_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
            let _ = CanFrame::decode_socketcan(&bytes);
        }
    }
}
