//! Bit-level packing of signals into payload bytes.
//!
//! Intel (little-endian) signals occupy bits `start .. start + size` counting from bit 0 of byte
//! 0 upwards. Motorola (big-endian) signals start at their most significant bit, numbered the
//! DBC way (bit 7 of byte 0 is 7, bit 0 of byte 1 is 8), and continue towards less significant
//! bits: down within a byte, then to bit 7 of the next byte.

/// Byte order of a signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Little-endian (DBC `@1`).
    Intel,
    /// Big-endian (DBC `@0`).
    Motorola,
}

/// Whether every bit of the signal lies inside a payload of `len` bytes.
pub fn fits(order: Order, start: u32, size: u32, len: usize) -> bool {
    if size == 0 || size > 64 {
        return false;
    }
    let bits = len as u32 * 8;
    match order {
        Order::Intel => start + size <= bits,
        Order::Motorola => {
            // Position of the last (least significant) bit in the sawtooth numbering.
            let msb_linear = (start / 8) * 8 + (7 - start % 8);
            msb_linear + size <= bits
        }
    }
}

/// Reads an unsigned raw value. The caller has checked [`fits`].
pub fn extract(data: &[u8], order: Order, start: u32, size: u32) -> u64 {
    match order {
        Order::Intel => {
            let mut v: u64 = 0;
            for i in 0..size {
                let b = start + i;
                let bit = (data[(b / 8) as usize] >> (b % 8)) & 1;
                v |= u64::from(bit) << i;
            }
            v
        }
        Order::Motorola => {
            let mut v: u64 = 0;
            let mut b = start;
            for _ in 0..size {
                let bit = (data[(b / 8) as usize] >> (b % 8)) & 1;
                v = (v << 1) | u64::from(bit);
                b = if b.is_multiple_of(8) { b + 15 } else { b - 1 };
            }
            v
        }
    }
}

/// Writes an unsigned raw value (its low `size` bits). The caller has checked [`fits`].
pub fn insert(data: &mut [u8], order: Order, start: u32, size: u32, value: u64) {
    match order {
        Order::Intel => {
            for i in 0..size {
                let b = start + i;
                let bit = ((value >> i) & 1) as u8;
                let byte = &mut data[(b / 8) as usize];
                *byte = (*byte & !(1 << (b % 8))) | (bit << (b % 8));
            }
        }
        Order::Motorola => {
            let mut b = start;
            for i in (0..size).rev() {
                let bit = ((value >> i) & 1) as u8;
                let byte = &mut data[(b / 8) as usize];
                *byte = (*byte & !(1 << (b % 8))) | (bit << (b % 8));
                b = if b.is_multiple_of(8) { b + 15 } else { b - 1 };
            }
        }
    }
}

/// Sign-extends the low `size` bits.
pub fn sign_extend(v: u64, size: u32) -> i64 {
    if size >= 64 {
        return v as i64;
    }
    let shift = 64 - size;
    ((v << shift) as i64) >> shift
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn motorola_example() {
        // A 12-bit Motorola signal starting at bit 7 (MSB of byte 0): bytes 0 and high nibble of 1.
        let mut d = [0u8; 8];
        insert(&mut d, Order::Motorola, 7, 12, 0xABC);
        assert_eq!(&d[..2], &[0xAB, 0xC0]);
        assert_eq!(extract(&d, Order::Motorola, 7, 12), 0xABC);
        // A 64-bit Motorola signal from bit 7 fills 8 bytes exactly: not 7, and not from bit 15.
        assert!(fits(Order::Motorola, 7, 64, 8));
        assert!(!fits(Order::Motorola, 7, 64, 7));
        assert!(!fits(Order::Motorola, 15, 64, 8));
        // Two bits from bit 0 (the last bit of byte 0) run on into bit 15 (the first of byte 1).
        assert!(!fits(Order::Motorola, 0, 2, 1));
        assert!(fits(Order::Motorola, 0, 2, 2));
        let mut d = [0u8; 2];
        insert(&mut d, Order::Motorola, 0, 2, 0b11);
        assert_eq!(d, [0x01, 0x80]);
        assert_eq!(extract(&d, Order::Motorola, 0, 2), 0b11);
        // Intel counts upwards: 4 bits from bit 60 end at bit 63; from 61 they do not fit.
        assert!(fits(Order::Intel, 60, 4, 8));
        assert!(!fits(Order::Intel, 61, 4, 8));
        assert!(!fits(Order::Intel, 0, 0, 8) && !fits(Order::Intel, 0, 65, 16));
    }

    #[test]
    fn intel_example() {
        let mut d = [0u8; 8];
        insert(&mut d, Order::Intel, 4, 12, 0xABC);
        assert_eq!(&d[..2], &[0xC0, 0xAB]);
        assert_eq!(sign_extend(0xFFF, 12), -1);
    }

    proptest! {
        #[test]
        fn insert_extract_round_trip(intel in any::<bool>(), start in 0u32..64, size in 1u32..=64, v in any::<u64>(), fill in any::<u8>()) {
            let order = if intel { Order::Intel } else { Order::Motorola };
            prop_assume!(fits(order, start, size, 8));
            let mut d = [fill; 8];
            let before = d;
            let v = if size == 64 { v } else { v & ((1 << size) - 1) };
            insert(&mut d, order, start, size, v);
            prop_assert_eq!(extract(&d, order, start, size), v);
            // Only the signal's bits changed.
            let mut back = d;
            insert(&mut back, order, start, size, extract(&before, order, start, size));
            prop_assert_eq!(back, before);
        }
    }
}
