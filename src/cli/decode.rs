//! `hilrig decode`: a capture or log to points (CSV, JSON lines), fixes or frames (JSON lines),
//! or a summary; what was read, skipped and rejected is said on standard error.

use super::open_output;
use anyhow::{bail, Context, Result};
use clap::ValueEnum;
use hilrig::decode::lidar::{decode_capture, CountSink, LidarOptions, LidarSummary};
use hilrig::decode::sinks::{CsvSink, JsonlSink};
use hilrig::velodyne::{Calibration, Model};
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    /// One row per point: time_s,ring,azimuth_deg,distance_m,intensity,return_type,x,y,z.
    Csv,
    /// One JSON object per point (lidar) or per fix (gnss).
    Jsonl,
    /// No points: counts, packet loss, timing and position-packet state only.
    Summary,
}

#[derive(Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Kind {
    /// Velodyne lidar packets in a pcap/pcapng capture.
    Lidar,
    /// An RTK GNSS serial stream (NMEA, UBX, RTCM3): a raw or gpsd log, or a capture's serial
    /// interfaces.
    Gnss,
    /// CAN frames (a candump log, or a capture's SocketCAN interfaces), decoded with --dbc.
    Can,
}

#[derive(clap::Args)]
pub struct DecodeArgs {
    /// The capture or log file.
    file: PathBuf,
    /// What the file holds.
    #[arg(long, value_enum, default_value = "lidar")]
    kind: Kind,
    /// Decode as this model whatever the packets' product byte says
    /// (vlp16, puck-hires, vlp32c, hdl32e).
    #[arg(long)]
    model: Option<String>,
    /// Calibration file of the unit (lidar): ros-drivers YAML or VeloView XML.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// DBC file for --kind can.
    #[arg(long)]
    dbc: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value = "csv")]
    format: Format,
    /// Output file (default: standard output).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// UDP destination port of data packets.
    #[arg(long, default_value_t = hilrig::velodyne::DATA_PORT)]
    data_port: u16,
    /// UDP destination port of position packets.
    #[arg(long, default_value_t = hilrig::velodyne::POSITION_PORT)]
    position_port: u16,
}

pub fn run(args: DecodeArgs) -> Result<ExitCode> {
    match args.kind {
        Kind::Gnss => return gnss(&args),
        Kind::Can => return can(&args),
        Kind::Lidar => {}
    }
    if args.dbc.is_some() {
        bail!("--dbc applies to --kind can");
    }
    let model = args
        .model
        .as_deref()
        .map(str::parse::<Model>)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let calibration = match &args.calibration {
        Some(path) => {
            let Some(m) = model else {
                bail!("--calibration needs --model, so that the laser count can be checked");
            };
            Some(Calibration::from_file(path, m)?)
        }
        None => None,
    };
    let options = LidarOptions {
        model,
        calibration,
        data_port: Some(args.data_port),
        position_port: Some(args.position_port),
    };
    let file =
        File::open(&args.file).with_context(|| format!("cannot open {}", args.file.display()))?;
    // Refuse the wrong kind of file before creating the output (no header-only CSV left behind).
    let (is_capture, source) =
        hilrig::capture::reader::sniff(BufReader::with_capacity(1 << 20, file))
            .with_context(|| format!("cannot read {}", args.file.display()))?;
    if !is_capture {
        let magic: Vec<u8> = source
            .get_ref()
            .0
            .get_ref()
            .iter()
            .take(4)
            .copied()
            .collect();
        let e = hilrig::capture::CaptureError::NotACapture { magic };
        bail!("decoding {}: {e}", args.file.display());
    }
    let out = open_output(args.output.as_deref())?;
    let out = BufWriter::with_capacity(1 << 20, out);
    let summary = match args.format {
        Format::Csv => {
            let mut sink = CsvSink::new(out)?;
            let s = decode_capture(source, &options, &mut sink);
            sink.finish()?;
            s
        }
        Format::Jsonl => {
            let mut sink = JsonlSink::new(out);
            let s = decode_capture(source, &options, &mut sink);
            sink.finish()?;
            s
        }
        Format::Summary => {
            let mut sink = CountSink::default();
            decode_capture(source, &options, &mut sink)
        }
    };
    let summary = match summary {
        Ok(s) => s,
        Err(
            e @ (hilrig::decode::lidar::LidarError::UnknownModel { .. }
            | hilrig::decode::lidar::LidarError::AmbiguousModel { .. }
            | hilrig::decode::lidar::LidarError::NeedsCalibration { .. }),
        ) => {
            // One line: which byte, where, and what is supported (exit 2: the input, not a
            // failure of hilrig).
            eprintln!("error: {}: {e}", args.file.display());
            return Ok(ExitCode::from(2));
        }
        Err(e) => return Err(e).with_context(|| format!("decoding {}", args.file.display())),
    };
    report(&args, &summary);
    if summary.data_packets == 0 {
        eprintln!(
            "error: {}: no Velodyne data packets (1206-byte UDP payloads to port {}) found",
            args.file.display(),
            args.data_port
        );
        return Ok(ExitCode::from(2));
    }
    Ok(if summary.capture_error.is_some() {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn report(args: &DecodeArgs, s: &LidarSummary) {
    let path = args.file.display();
    if let Some(m) = &s.model_mismatch {
        tracing::warn!("{path}: {m}");
        eprintln!("warning: {path}: {m}");
    }
    if let (Some(forced), Some(product)) = (s.model, s.product) {
        if Model::from_product(product) != Some(forced) {
            eprintln!(
                "note: packets carry product byte {:#04x}; decoded as {forced} as requested",
                product.0
            );
        }
    }
    for p in &s.first_problems {
        eprintln!("error: {path}: packet at byte {}: {}", p.offset, p.error);
    }
    if let Some(e) = &s.capture_error {
        eprintln!("error: {path}: {e}");
    }
    let mut lines = vec![
        format!("model: {}", s.model.map(|m| m.name()).unwrap_or("none")),
        format!("data packets: {}", s.data_packets),
        format!("points: {}", s.points),
        format!("position packets: {}", s.position_packets),
        format!(
            "lost packets: {} (sensor time jumps: {})",
            s.lost_packets, s.time_jumps
        ),
        format!(
            "hour of timestamps from: {}",
            match s.hour_source {
                Some(hilrig::velodyne::clock::HourSource::Rmc) => "position packet RMC",
                Some(hilrig::velodyne::clock::HourSource::Host) => "capture time",
                None => "unknown (times are seconds past the hour)",
            }
        ),
    ];
    if let Some(pps) = s.pps {
        lines.push(format!("PPS: {pps:?}"));
    }
    if let Some(rmc) = &s.last_rmc {
        lines.push(format!(
            "last RMC: {} UTC, {}",
            rmc.utc()
                .map(|t| t.to_string())
                .unwrap_or_else(|| "(no date)".into()),
            if rmc.valid { "valid" } else { "not valid" }
        ));
    }
    if !s.rejected.is_empty() {
        let r: Vec<String> = s
            .rejected
            .iter()
            .map(|(k, v)| format!("{k}: {v}"))
            .collect();
        lines.push(format!("rejected packets: {}", r.join(", ")));
    }
    if s.other_udp + s.non_udp > 0 || s.capture.skipped_total() > 0 {
        let mut r: Vec<String> = s
            .capture
            .skipped
            .iter()
            .map(|(k, v)| format!("{k}: {v}"))
            .collect();
        if s.other_udp > 0 {
            r.push(format!("other UDP: {}", s.other_udp));
        }
        if s.non_udp > 0 {
            r.push(format!("CAN/serial records: {}", s.non_udp));
        }
        lines.push(format!("skipped records: {}", r.join(", ")));
    }
    if s.capture.ipv4_length_quirks > 0 {
        lines.push(format!(
            "{} frames whose IPv4 total length runs past the frame although it was captured whole (a firmware quirk: early VLP-16 position packets); read by their UDP length, first at byte {}",
            s.capture.ipv4_length_quirks,
            s.capture.first_ipv4_length_quirk.unwrap_or(0)
        ));
    }
    let mut err = io::stderr().lock();
    for l in lines {
        let _ = writeln!(err, "{path}: {l}");
    }
}

fn gnss(args: &DecodeArgs) -> Result<ExitCode> {
    if matches!(args.format, Format::Csv) {
        bail!("--kind gnss writes --format jsonl or --format summary");
    }
    if args.model.is_some() || args.calibration.is_some() {
        bail!("--model and --calibration are lidar options; they do not apply to --kind gnss");
    }
    let file =
        File::open(&args.file).with_context(|| format!("cannot open {}", args.file.display()))?;
    let out = open_output(args.output.as_deref())?;
    let mut out = BufWriter::new(out);
    let write = matches!(args.format, Format::Jsonl);
    let summary = hilrig::decode::gnss::decode_gnss(BufReader::new(file), &mut |r| {
        use hilrig::decode::gnss::{attitude_json, fix_json, GnssReport};
        if write {
            match r {
                GnssReport::Fix(f) => writeln!(out, "{}", fix_json(f))?,
                GnssReport::Attitude(a) => writeln!(out, "{}", attitude_json(a))?,
            }
        }
        Ok(())
    })
    .with_context(|| format!("decoding {}", args.file.display()))?;
    out.flush()?;
    let path = args.file.display();
    eprintln!(
        "{path}: fixes: {}, NMEA sentences: {}, UBX frames: {}, RTCM3 frames: {}, rejected frames: {}, undecodable frames: {}, bytes outside frames: {} of {}",
        summary.fixes, summary.nmea, summary.ubx, summary.rtcm3, summary.rejected, summary.decode_errors, summary.skipped_bytes, summary.bytes
    );
    if summary.attitudes > 0 || !summary.invalid_attitudes.is_empty() {
        let invalid: Vec<String> = summary
            .invalid_attitudes
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        eprintln!(
            "{path}: attitude reports: {}, attitude messages flagged invalid (not used): {}",
            summary.attitudes,
            if invalid.is_empty() {
                "none".to_owned()
            } else {
                invalid.join(", ")
            }
        );
    }
    if !summary.interfaces.is_empty() {
        eprintln!(
            "{path}: serial interfaces: {}",
            summary.interfaces.join(", ")
        );
    }
    if let Some(e) = &summary.capture_error {
        eprintln!("error: {path}: {e}");
        return Ok(ExitCode::from(1));
    }
    if summary.fixes == 0 {
        eprintln!("error: {path}: no GNSS fix found (no NMEA position sentence or UBX NAV-PVT)");
        return Ok(ExitCode::from(2));
    }
    Ok(ExitCode::SUCCESS)
}

fn can(args: &DecodeArgs) -> Result<ExitCode> {
    if matches!(args.format, Format::Csv) {
        bail!("--kind can writes --format jsonl or --format summary");
    }
    let Some(dbc) = &args.dbc else {
        bail!("--kind can needs --dbc FILE to decode frames");
    };
    let db = hilrig::can::Database::from_file(dbc)?;
    let file =
        File::open(&args.file).with_context(|| format!("cannot open {}", args.file.display()))?;
    let out = open_output(args.output.as_deref())?;
    let mut out = BufWriter::new(out);
    let write = matches!(args.format, Format::Jsonl);
    let summary = hilrig::decode::can::decode_can(BufReader::new(file), &db, &mut |t, f, d| {
        if write {
            writeln!(out, "{}", hilrig::decode::can::frame_json(t, f, d))?;
        }
        Ok(())
    })
    .with_context(|| format!("decoding {}", args.file.display()))?;
    out.flush()?;
    let path = args.file.display();
    eprintln!(
        "{path}: frames: {}, decoded: {}, ids not in the DBC: {}, remote/error frames: {}",
        summary.frames, summary.decoded, summary.unknown_id, summary.remote_or_error
    );
    if let Some(e) = &summary.error {
        eprintln!("error: {path}: {e}");
        return Ok(ExitCode::from(1));
    }
    if summary.frames == 0 {
        eprintln!("error: {path}: no CAN frames found");
        return Ok(ExitCode::from(2));
    }
    Ok(ExitCode::SUCCESS)
}
