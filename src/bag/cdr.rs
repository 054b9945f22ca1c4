//! CDR (XCDR1, little-endian), the serialization of ROS 2 messages in MCAP files.
//!
//! A message is a 4-byte encapsulation header (`00 01 00 00`: plain CDR, little-endian) followed
//! by the fields in order, each aligned to its own size counted from the end of the header.
//! Strings are a `u32` length including the terminating NUL, the bytes and the NUL; sequences a
//! `u32` element count and the elements; fixed arrays just the elements.

use hilrig_stamp::UtcNanos;

/// Writes one CDR message.
#[derive(Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        CdrWriter::new()
    }
}

impl CdrWriter {
    /// A writer with the little-endian encapsulation header written.
    pub fn new() -> CdrWriter {
        CdrWriter::with_capacity(64)
    }

    /// Same, with room for `n` bytes.
    pub fn with_capacity(n: usize) -> CdrWriter {
        let mut buf = Vec::with_capacity(n + 4);
        buf.extend_from_slice(&[0x00, 0x01, 0x00, 0x00]);
        CdrWriter { buf }
    }

    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - 4;
        let pad = (n - pos % n) % n;
        self.buf.extend(std::iter::repeat_n(0u8, pad));
    }

    /// `uint8`, `byte`, `char`.
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }
    /// `int8`.
    pub fn i8(&mut self, v: i8) -> &mut Self {
        self.buf.push(v as u8);
        self
    }
    /// `bool`.
    pub fn bool(&mut self, v: bool) -> &mut Self {
        self.buf.push(u8::from(v));
        self
    }
    /// `uint16`.
    pub fn u16(&mut self, v: u16) -> &mut Self {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// `string`.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
        self
    }
    /// `uint8[]` (sequence).
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u32(b.len() as u32);
        self.buf.extend_from_slice(b);
        self
    }
    /// `uint8[N]` (fixed array).
    pub fn fixed_bytes(&mut self, b: &[u8]) -> &mut Self {
        self.buf.extend_from_slice(b);
        self
    }
    /// Sequence length prefix (the caller writes the elements).
    pub fn sequence_len(&mut self, n: usize) -> &mut Self {
        self.u32(n as u32)
    }

    /// Bytes written so far, the encapsulation header included: where the next field starts
    /// in [`CdrWriter::finish`]'s bytes (for a length that is only known at the end, written as
    /// a placeholder and set there).
    pub fn len(&self) -> usize {
        self.buf.len()
    }

    /// True before anything but the encapsulation header is written.
    pub fn is_empty(&self) -> bool {
        self.buf.len() == 4
    }

    /// The encoded message.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads the recorder's own message layouts back (replay): each read is `None` past the end, so a
/// damaged message is reported, never a panic.
#[derive(Debug)]
pub struct CdrReader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// A reader after the encapsulation header; `None` when even that is missing.
    pub fn new(b: &'a [u8]) -> Option<Self> {
        (b.len() >= 4).then_some(CdrReader { b, pos: 4 })
    }

    fn align(&mut self, n: usize) {
        let rel = self.pos - 4;
        self.pos += (n - rel % n) % n;
    }

    /// A `u32`.
    pub fn u32(&mut self) -> Option<u32> {
        self.align(4);
        let v = self.b.get(self.pos..self.pos + 4)?;
        self.pos += 4;
        Some(u32::from_le_bytes([v[0], v[1], v[2], v[3]]))
    }

    /// An `f64`.
    pub fn f64(&mut self) -> Option<f64> {
        self.align(8);
        let v = self.b.get(self.pos..self.pos + 8)?;
        self.pos += 8;
        Some(f64::from_le_bytes(v.try_into().ok()?))
    }

    /// A `builtin_interfaces/Time`.
    pub fn time(&mut self) -> Option<UtcNanos> {
        let s = self.u32()? as i32;
        let n = self.u32()?;
        Some(UtcNanos::from_secs_nanos(i64::from(s), n))
    }

    /// `n` bytes (a fixed array, or a sequence's elements after its length).
    pub fn bytes(&mut self, n: usize) -> Option<&'a [u8]> {
        let v = self.b.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        Some(v)
    }

    /// A string, without its terminating NUL.
    pub fn string(&mut self) -> Option<&'a str> {
        let n = self.u32()? as usize;
        let s = self.bytes(n)?;
        std::str::from_utf8(s.strip_suffix(&[0]).unwrap_or(s)).ok()
    }

    /// A `std_msgs/Header`: its stamp (the frame id is read past).
    pub fn header(&mut self) -> Option<UtcNanos> {
        let t = self.time()?;
        self.string()?;
        Some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header() {
        let mut w = CdrWriter::new();
        w.u8(1).u32(2).string("ab").f64(1.5);
        let b = w.finish();
        assert_eq!(&b[..4], &[0, 1, 0, 0]);
        assert_eq!(&b[4..8], &[1, 0, 0, 0]); // u8 + 3 padding
        assert_eq!(&b[8..12], &2u32.to_le_bytes());
        assert_eq!(&b[12..16], &3u32.to_le_bytes()); // "ab\0"
        assert_eq!(&b[16..19], b"ab\0");
        assert_eq!(
            b.len(),
            4 + 24,
            "f64 aligned to 8: at 16..24 after the header"
        );
    }

    #[test]
    fn the_reader_reads_what_the_writer_wrote_and_stops_at_the_end() {
        let mut w = CdrWriter::new();
        w.i32(12)
            .u32(345)
            .string("lidar")
            .u32(7)
            .fixed_bytes(&[1, 2, 3]);
        let b = w.finish();
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.header(), Some(UtcNanos::from_secs_nanos(12, 345)));
        assert_eq!(r.u32(), Some(7));
        assert_eq!(r.bytes(3), Some(&[1u8, 2, 3][..]));
        assert_eq!(r.u32(), None);
        assert!(CdrReader::new(&b[..3]).is_none());
    }
}
