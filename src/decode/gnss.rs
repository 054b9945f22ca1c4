//! GNSS logs to fixes: raw serial byte logs (gpsd regression logs included) and the serial
//! interfaces of pcap/pcapng captures, through the GNSS driver. Used by `hilrig decode --kind gnss`.

use hilrig_capture::demux::{Demux, Packet};
use hilrig_capture::{CaptureError, CaptureReader};
use hilrig_gnss::{Attitude, Fix, GnssStream};
use hilrig_stamp::civil::iso8601_millis;
use std::collections::BTreeMap;
use std::io::Read;

/// Counters of a GNSS log decode.
#[derive(Clone, Debug, Default)]
pub struct GnssSummary {
    /// Bytes of serial stream read.
    pub bytes: u64,
    /// Fixes produced.
    pub fixes: u64,
    /// NMEA sentences framed.
    pub nmea: u64,
    /// UBX frames framed.
    pub ubx: u64,
    /// RTCM3 frames passed over.
    pub rtcm3: u64,
    /// Frames rejected by checksum or form.
    pub rejected: u64,
    /// Bytes outside any frame.
    pub skipped_bytes: u64,
    /// Frames that did not decode (bad fields, an angle out of its range).
    pub decode_errors: u64,
    /// Attitude reports (heading, pitch, roll of an INS or dual-antenna receiver).
    pub attitudes: u64,
    /// Attitude messages their own flags mark invalid, by message (counted, not reported).
    pub invalid_attitudes: BTreeMap<&'static str, u64>,
    /// Serial interfaces read (captures), by name.
    pub interfaces: Vec<String>,
    /// The capture error that ended reading early, if any.
    pub capture_error: Option<String>,
}

fn add(summary: &mut GnssSummary, s: &GnssStream) {
    let f = &s.framer.stats;
    summary.bytes += f.bytes;
    summary.nmea += f.nmea;
    summary.ubx += f.ubx;
    summary.rtcm3 += f.rtcm3;
    summary.rejected += f.rejected;
    summary.skipped_bytes += f.skipped_bytes;
    summary.decode_errors += s.stats.nmea_errors + s.stats.ubx_errors;
    summary.attitudes += s.stats.attitudes;
    for (k, n) in &s.stats.invalid_attitudes {
        *summary.invalid_attitudes.entry(k).or_default() += n;
    }
}

/// One report of a GNSS log, in stream order.
#[derive(Clone, Copy, Debug)]
pub enum GnssReport<'a> {
    /// A fix.
    Fix(&'a Fix),
    /// An attitude report.
    Attitude(&'a Attitude),
}

/// Hands the stream's finished fixes and attitude reports to `sink`, attitude first (a fix
/// is finished when the next epoch begins, after the attitude messages of its own epoch).
fn hand_over(
    stream: &mut GnssStream,
    fixes: &mut Vec<Fix>,
    summary: &mut GnssSummary,
    sink: &mut dyn FnMut(GnssReport<'_>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    for a in stream.take_attitudes() {
        sink(GnssReport::Attitude(&a))?;
    }
    for f in fixes.drain(..) {
        summary.fixes += 1;
        sink(GnssReport::Fix(&f))?;
    }
    Ok(())
}

/// Decodes a GNSS log; every fix and attitude report goes to `sink` in stream order.
pub fn decode_gnss<R: Read + Send + 'static>(
    source: R,
    sink: &mut dyn FnMut(GnssReport<'_>) -> std::io::Result<()>,
) -> Result<GnssSummary, CaptureError> {
    let (is_capture, source) =
        hilrig_capture::reader::sniff(source).map_err(|e| CaptureError::Io {
            offset: 0,
            source: e,
        })?;
    let mut summary = GnssSummary::default();
    let mut fixes = Vec::new();
    let io = |e: std::io::Error| CaptureError::Io {
        offset: 0,
        source: e,
    };
    if !is_capture {
        let mut stream = GnssStream::for_gpsd_log().with_attitude();
        let mut reader = source;
        let mut buf = vec![0u8; 64 * 1024];
        loop {
            let n = reader.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            stream.push(&buf[..n], &mut fixes);
            hand_over(&mut stream, &mut fixes, &mut summary, sink).map_err(io)?;
        }
        stream.finish(&mut fixes);
        hand_over(&mut stream, &mut fixes, &mut summary, sink).map_err(io)?;
        add(&mut summary, &stream);
        return Ok(summary);
    }
    let mut demux = Demux::new(CaptureReader::new(source)?);
    let mut streams: BTreeMap<u32, GnssStream> = BTreeMap::new();
    loop {
        let item = match demux.next_item() {
            None => break,
            Some(Err(e)) => {
                summary.capture_error = Some(e.to_string());
                break;
            }
            Some(Ok(i)) => i,
        };
        if let Packet::Serial(bytes) = item.packet {
            let stream = streams
                .entry(item.interface)
                .or_insert_with(|| GnssStream::default().with_attitude());
            stream.push(bytes, &mut fixes);
            hand_over(stream, &mut fixes, &mut summary, sink).map_err(io)?;
        }
    }
    for (iface, stream) in &mut streams {
        stream.finish(&mut fixes);
        hand_over(stream, &mut fixes, &mut summary, sink).map_err(io)?;
        add(&mut summary, stream);
        let name = demux
            .interfaces()
            .get(*iface as usize)
            .and_then(|i| i.name.clone())
            .unwrap_or_else(|| format!("interface {iface}"));
        summary.interfaces.push(name);
    }
    Ok(summary)
}

/// One attitude report as hilrig's JSON object (`"kind": "attitude"`; fields the message
/// lacks are null).
pub fn attitude_json(a: &Attitude) -> serde_json::Value {
    serde_json::json!({
        "kind": "attitude",
        "of": a.of.name(),
        "time": a.time.map(iso8601_millis),
        "source": a.source.name(),
        "mode": a.mode.name(),
        "heading_deg": a.heading_deg,
        "yaw_deg": a.yaw_deg,
        "pitch_deg": a.pitch_deg,
        "roll_deg": a.roll_deg,
        "sigma_heading_deg": a.sigma_heading_deg,
        "sigma_pitch_deg": a.sigma_pitch_deg,
        "sigma_roll_deg": a.sigma_roll_deg,
    })
}

/// One fix as hilrig's JSON object (the keys `hilrig decode --kind gnss --format jsonl` writes).
pub fn fix_json(f: &Fix) -> serde_json::Value {
    serde_json::json!({
        "time": f.time.map(iso8601_millis),
        "source": match f.source { hilrig_gnss::FixSource::Nmea => "nmea", hilrig_gnss::FixSource::Ubx => "ubx" },
        "lat": f.lat,
        "lon": f.lon,
        "alt_msl": f.alt_msl,
        "quality": f.quality,
        "rtk": f.rtk.name(),
        "sigma_lat_m": f.sigma_lat_m,
        "sigma_lon_m": f.sigma_lon_m,
        "sigma_alt_m": f.sigma_alt_m,
        "correction_age_s": f.correction_age_s,
        "speed_mps": f.speed_mps,
        "heading_deg": f.heading_deg,
    })
}
