//! candump log files (`candump -l`): `(1436509052.249713) can0 123#DEADBEEF`.
//!
//! Identifiers with 3 hex digits are standard, with 8 extended (the error flag 0x20000000 marks
//! error frames); `#R` with an optional length digit is a remote request; `##F` starts a CAN FD
//! payload with its flags digit. The writer produces exactly what can-utils writes (uppercase
//! hex, ten-digit seconds, six-digit microseconds), so a log read and written again is
//! byte-identical. Lines starting with `#` and blank lines are comments and skipped.

use hilrig_capture::CanFrame;
use hilrig_stamp::UtcNanos;

/// A line that is not a candump frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("candump line {line}: {what}: '{text}'")]
pub struct CandumpError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub what: &'static str,
    /// The line (cut to 80 characters).
    pub text: String,
}

/// One logged frame.
#[derive(Clone, Debug, PartialEq)]
pub struct LogFrame {
    /// Receive time (microsecond resolution in the log).
    pub time: UtcNanos,
    /// Interface name.
    pub interface: String,
    /// The frame.
    pub frame: CanFrame,
}

fn hex_digit(b: u8) -> Option<u8> {
    (b as char).to_digit(16).map(|d| d as u8)
}

fn hex_bytes(s: &str) -> Option<Vec<u8>> {
    let b = s.as_bytes();
    if !b.len().is_multiple_of(2) {
        return None;
    }
    b.chunks(2)
        .map(|p| Some(hex_digit(p[0])? << 4 | hex_digit(p[1])?))
        .collect()
}

/// Parses one line; `Ok(None)` for comments and blank lines.
pub fn parse_line(text: &str, line: usize) -> Result<Option<LogFrame>, CandumpError> {
    let err = |what| CandumpError {
        line,
        what,
        text: text.chars().take(80).collect(),
    };
    let t = text.trim_end_matches(['\r', '\n']);
    if t.trim().is_empty() || t.starts_with('#') {
        return Ok(None);
    }
    let rest = t
        .strip_prefix('(')
        .ok_or_else(|| err("no '(' before the timestamp"))?;
    let (stamp, rest) = rest
        .split_once(')')
        .ok_or_else(|| err("no ')' after the timestamp"))?;
    let (secs, frac) = stamp
        .split_once('.')
        .ok_or_else(|| err("timestamp has no '.'"))?;
    if frac.is_empty() || frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return Err(err("timestamp fraction is not 1-9 digits"));
    }
    let secs: i64 = secs
        .parse()
        .map_err(|_| err("timestamp seconds are not a number"))?;
    let nanos =
        frac.parse::<u32>().map_err(|_| err("bad fraction"))? * 10u32.pow(9 - frac.len() as u32);
    let mut parts = rest.split_whitespace();
    let interface = parts.next().ok_or_else(|| err("no interface"))?.to_owned();
    let frame_text = parts.next().ok_or_else(|| err("no frame"))?;
    if parts.next().is_some() {
        return Err(err("text after the frame"));
    }
    let (id_text, payload) = frame_text
        .split_once('#')
        .ok_or_else(|| err("no '#' in the frame"))?;
    let raw_id = u32::from_str_radix(id_text, 16).map_err(|_| err("identifier is not hex"))?;
    // candump writes extended ids as 8 digits without the EFF flag, error frames as 8 digits
    // with CAN_ERR_FLAG (0x20000000).
    let (extended, error) = match id_text.len() {
        3 => (false, false),
        8 => {
            let error = raw_id & 0x2000_0000 != 0;
            (!error, error)
        }
        _ => return Err(err("identifier must have 3 or 8 hex digits")),
    };
    let id = raw_id & 0x1FFF_FFFF;
    if !extended && !error && id > 0x7FF {
        return Err(err("standard identifier above 0x7FF"));
    }
    let frame = if let Some(fd) = payload.strip_prefix('#') {
        let flags = fd
            .bytes()
            .next()
            .and_then(hex_digit)
            .ok_or_else(|| err("CAN FD flags digit missing"))?;
        let data = hex_bytes(&fd[1..]).ok_or_else(|| err("CAN FD data is not hex pairs"))?;
        let mut f = CanFrame::new_fd(id, extended, &data, flags & 1 != 0)
            .ok_or_else(|| err("CAN FD length is not a DLC length"))?;
        f.esi = flags & 2 != 0;
        f
    } else if let Some(r) = payload.strip_prefix('R') {
        let dlc = match r.as_bytes() {
            [] => 0,
            [d] => hex_digit(*d)
                .filter(|d| *d <= 8)
                .ok_or_else(|| err("remote frame length must be 0-8"))?,
            _ => return Err(err("remote frame takes at most one length digit")),
        };
        CanFrame::new_remote(id, extended, dlc).ok_or_else(|| err("bad remote frame"))?
    } else {
        let data = hex_bytes(payload).ok_or_else(|| err("data is not hex pairs"))?;
        // Error frames carry error class bits in a 29-bit field but are not extended frames.
        let mut f = CanFrame::new(id, extended || error, &data)
            .ok_or_else(|| err("more than 8 data bytes"))?;
        if error {
            f.extended = false;
            f.error = true;
        }
        f
    };
    Ok(Some(LogFrame {
        time: UtcNanos::from_secs_nanos(secs, nanos),
        interface,
        frame,
    }))
}

/// Formats one frame as can-utils does.
pub fn format_line(f: &LogFrame) -> String {
    let (secs, nanos) = f.time.secs_nanos();
    let fr = &f.frame;
    let id = if fr.error {
        format!("{:08X}", fr.id | 0x2000_0000)
    } else if fr.extended {
        format!("{:08X}", fr.id)
    } else {
        format!("{:03X}", fr.id)
    };
    let mut s = format!("({secs:010}.{:06}) {} {id}#", nanos / 1000, f.interface);
    if fr.fd {
        s.push('#');
        s.push(
            char::from_digit(u32::from(u8::from(fr.brs) | (u8::from(fr.esi) << 1)), 16)
                .unwrap_or('0')
                .to_ascii_uppercase(),
        );
    } else if fr.rtr {
        s.push('R');
        if !fr.is_empty() {
            s.push_str(&format!("{:X}", fr.len()));
        }
        return s;
    }
    for b in fr.data() {
        s.push_str(&format!("{b:02X}"));
    }
    s
}

/// Parses a whole log; stops at the first bad line.
pub fn parse_log(text: &str) -> Result<Vec<LogFrame>, CandumpError> {
    let mut out = Vec::new();
    for (i, l) in text.lines().enumerate() {
        if let Some(f) = parse_line(l, i + 1)? {
            out.push(f);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn lines_of_every_kind_round_trip() {
        for line in [
            "(1436509052.249713) vcan0 044#2A366C2BBA",
            "(1436509052.449847) vcan0 0F6#",
            "(1436509053.650004) can1 18DAF110#0210030000000000",
            "(1436509054.000001) can0 123#R",
            "(1436509054.000002) can0 123#R5",
            "(1436509055.100000) can0 20000080#0000000000000000",
            "(1436509056.000000) can0 1F334455##1112233445566778899AABBCC",
            "(0000000001.000000) can0 7FF##3",
        ] {
            let f = parse_line(line, 1).unwrap().unwrap();
            assert_eq!(format_line(&f), line);
        }
    }

    #[test]
    fn errors_say_line_and_what() {
        let e = parse_log("(1.0) can0 123#00\n(2.0) can0 1234#00\n").unwrap_err();
        assert_eq!(e.line, 2);
        assert!(
            e.to_string()
                .contains("identifier must have 3 or 8 hex digits"),
            "{e}"
        );
        assert!(parse_line("(1.0) can0 800#00", 1).is_err());
        assert!(parse_line("(1.0) can0 123#0", 1).is_err());
        assert!(parse_line("# comment", 1).unwrap().is_none());
    }

    proptest! {
        #[test]
        fn parse_never_panics(s in "\\PC{0,60}") {
            let _ = parse_line(&s, 1);
        }

        #[test]
        fn written_lines_parse_back(secs in 0i64..4_000_000_000, us in 0u32..1_000_000, id in 0u32..0x1FFF_FFFF,
                                     ext in any::<bool>(), data in proptest::collection::vec(any::<u8>(), 0..=8)) {
            let id = if ext { id } else { id & 0x7FF };
            let f = LogFrame { time: UtcNanos::from_secs_nanos(secs, us * 1000), interface: "can0".into(), frame: CanFrame::new(id, ext, &data).unwrap() };
            let line = format_line(&f);
            prop_assert_eq!(parse_line(&line, 1).unwrap().unwrap(), f);
        }
    }
}
