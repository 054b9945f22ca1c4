//! What one GNSS serial stream held, judged on its own: a second receiver of another protocol,
//! or one that never gives a date, must not hide behind a good one.

use hilrig_gnss::epoch::Fix;
use hilrig_gnss::framer::Framer;

/// One GNSS serial stream (a capture's serial interface, a log file, the live port): its
/// frames, the bytes outside them and its fixes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GnssStream {
    /// The interface, file or port it came from.
    pub name: String,
    /// NMEA, UBX and RTCM3 frames.
    pub frames: u64,
    /// Bytes in no frame: a frame cut off at the stream's start or end, rejected frames, bytes
    /// between frames, or a protocol the recorder does not frame (recorded as they came, on
    /// `/gnss/unframed`). A gpsd log's comment lines are the log's, not the receiver's, and not
    /// counted here.
    pub unframed_bytes: u64,
    /// A gpsd log's comment lines, skipped.
    pub comment_lines: u64,
    /// Fixes with a position and a UTC time: written to /gnss/fix.
    pub fixes_dated: u64,
    /// Fixes with a position but no UTC time (before the stream showed its date): not written
    /// to /gnss/fix, their messages only in /gnss/nmea and /gnss/ubx.
    pub fixes_untimed: u64,
}

impl GnssStream {
    /// A stream called `name`.
    pub fn named(name: impl Into<String>) -> GnssStream {
        GnssStream {
            name: name.into(),
            ..GnssStream::default()
        }
    }

    /// Counts a fix: dated or not; one without a position (no fix yet) is neither.
    pub fn count(&mut self, f: &Fix) {
        if f.lat.is_some() && f.lon.is_some() {
            if f.time.is_some() {
                self.fixes_dated += 1;
            } else {
                self.fixes_untimed += 1;
            }
        }
    }

    /// Takes the frame counts of the stream's framer, `pending` bytes of a frame cut off at
    /// the end included.
    pub fn framed_by(&mut self, framer: &Framer) {
        let st = &framer.stats;
        self.frames = st.nmea + st.ubx + st.rtcm3;
        self.unframed_bytes = st.skipped_bytes - st.comment_bytes + framer.pending() as u64;
        self.comment_lines = st.comment_lines;
    }

    /// Bytes came but none framed: another protocol, the wrong baud rate, or a gpsd log of
    /// comments only. Its bytes are recorded raw, but no fix comes of them.
    pub fn unframed(&self) -> bool {
        self.frames == 0 && (self.unframed_bytes > 0 || self.comment_lines > 0)
    }

    /// Writes the totals over `streams` into `meta` (the `hilrig/end` metadata): bytes in no
    /// frame and fixes without a date.
    pub fn write_metadata(
        streams: &[GnssStream],
        meta: &mut std::collections::BTreeMap<String, String>,
    ) {
        let total = |f: fn(&GnssStream) -> u64| streams.iter().map(f).sum::<u64>().to_string();
        meta.insert(
            "gnss_unframed_bytes".to_owned(),
            total(|s| s.unframed_bytes),
        );
        meta.insert("gnss_fixes_untimed".to_owned(), total(|s| s.fixes_untimed));
    }

    /// Positions came, but never a date (GGA without RMC or ZDA): no fix is on /gnss/fix.
    pub fn dateless(&self) -> bool {
        self.fixes_untimed > 0 && self.fixes_dated == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixes of NMEA sentences (bodies).
    fn fixes(bodies: &[&str]) -> Vec<Fix> {
        let mut e = hilrig_gnss::epoch::NmeaEpochs::default();
        let mut out = Vec::new();
        for b in bodies {
            let s = hilrig_gnss::framer::nmea_sentence(b);
            out.extend(e.push(&hilrig_gnss::nmea::parse(&s).unwrap()));
        }
        out.extend(e.finish());
        out
    }

    #[test]
    fn a_stream_is_judged_by_its_own_frames_and_dates() {
        let gga = "GPGGA,120000.00,4807.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,1.0,0001";
        let no_position = "GPGGA,120001.00,,,,,0,00,,,M,,M,,";
        let rmc = "GPRMC,120002.00,A,4807.038,N,01131.000,E,0.0,0.0,010625,,,D";
        let mut s = GnssStream::named("a");
        for f in fixes(&[gga, no_position]) {
            s.count(&f);
        }
        assert_eq!((s.fixes_dated, s.fixes_untimed), (0, 1), "{s:?}");
        assert!(s.dateless());
        for f in fixes(&[rmc]) {
            s.count(&f);
        }
        assert_eq!((s.fixes_dated, s.fixes_untimed), (1, 1), "{s:?}");
        assert!(!s.dateless());
        let mut framer = Framer::new();
        framer.push(b"\xa0\xa1\x00\x02");
        while framer.next_frame().is_some() {}
        s.framed_by(&framer);
        assert!(s.unframed(), "{s:?}");
    }
}
