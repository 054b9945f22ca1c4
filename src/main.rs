//! The `hilrig` command line.
//!
//! Arguments are parsed by clap and then validated once into typed settings before any work
//! starts (ripgrep's LowArgs -> HiArgs), so a bad option fails fast with a clear message.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use hilrig::lidar::{decode_capture, CountSink, LidarOptions, LidarSummary};
use hilrig::points_out::{CsvSink, JsonlSink};
use hilrig::velodyne::{Calibration, Model};
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "hilrig",
    version,
    about = "Hardware-in-the-loop recorder and replay rig for validating lidar sensor models"
)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Decode a capture or log: lidar points (pcap/pcapng) or GNSS fixes (serial logs, gpsd logs,
    /// serial interfaces of pcapng captures).
    Decode(DecodeArgs),
    /// Record the rig's sensors live (or, with --from, captures: pcap/pcapng with lidar UDP,
    /// SocketCAN and serial interfaces) into one time-synchronised MCAP (ROS 2 profile).
    Record(RecordArgs),
    /// Salvage an MCAP that was cut off (power loss, kill -9, full disk): every complete record
    /// before the cut goes into a new, valid file.
    Recover(RecoverArgs),
    /// Summarise an MCAP: channels, types, counts, rates, time span, clock synchronisation.
    Info(InfoArgs),
    /// Play a recording (.mcap) or capture (.pcap/.pcapng) back to a device under test at the
    /// original pace: lidar over UDP, GNSS to a serial port or a new pty, CAN to an interface.
    Replay(ReplayArgs),
    /// Synthesize measured drives through a scene: per repetition a capture as it would come off
    /// the vehicle (lidar, GNSS serial, CAN) with realistic reference errors, the surveyed scene
    /// and the truth.
    Synth(SynthArgs),
    /// Check a recording's reference data (seed §6): spatial and temporal accuracy, faults located
    /// in time, the smallest admissible grid cell. Exit 0 pass, 1 fail, 2 unusable input.
    Check(CheckArgs),
    /// Re-simulate a recording: the same sensor on the same trajectory through the scene with a
    /// lidar model; writes simulated VelodyneScans and /sim/points. Refuses runs that fail
    /// `check` unless --force.
    Resim(ResimArgs),
}

#[derive(clap::Args)]
struct ResimArgs {
    /// The recording (.mcap).
    run: PathBuf,
    /// The scene.
    #[arg(long)]
    scene: PathBuf,
    /// The lidar model (model.toml).
    #[arg(long)]
    model: PathBuf,
    /// The output MCAP.
    #[arg(short, long)]
    output: PathBuf,
    /// The rig file; default: the one attached to the recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Take the ego poses from this trajectory file (t, x, y, z, yaw_deg in the scene frame)
    /// instead of the run's RTK+CAN trajectory.
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Re-simulate even when the run fails `check`.
    #[arg(long)]
    force: bool,
    /// Seed of the model's random effects.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(clap::Args)]
struct CheckArgs {
    /// The recording (.mcap).
    run: PathBuf,
    /// The scene (origin of the local frame, survey accuracy of static objects).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// The rig file (lever arm, thresholds); default: the one attached to the recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Also write the report as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(clap::Args)]
struct SynthArgs {
    /// The true scene (TOML).
    #[arg(long)]
    scene: PathBuf,
    /// The drive (TOML: path, walkers, stream errors, rig).
    #[arg(long)]
    drive: PathBuf,
    /// The truth lidar model (model.toml).
    #[arg(long)]
    truth: PathBuf,
    /// Number of repetitions.
    #[arg(long, default_value_t = 5)]
    reps: u32,
    /// Base seed (each repetition derives its own).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory (rep-01, rep-02, ... are created in it).
    #[arg(short, long)]
    output: PathBuf,
    /// Write zstd-compressed captures (drive.pcapng.zst; hilrig reads them directly).
    #[arg(long)]
    compress: bool,
    /// The planned drive exactly, without human variation, reference errors or packet loss.
    #[arg(long)]
    no_errors: bool,
}

#[derive(clap::Args)]
struct ReplayArgs {
    /// The recording or capture.
    file: PathBuf,
    /// Where lidar data packets go (e.g. 192.168.1.77:2368).
    #[arg(long)]
    lidar_to: Option<std::net::SocketAddr>,
    /// Where lidar position packets go (e.g. 192.168.1.77:8308).
    #[arg(long)]
    position_to: Option<std::net::SocketAddr>,
    /// Serial device for the GNSS stream, or `pty` to open a pseudo-terminal (its path is printed).
    #[arg(long)]
    gnss_to: Option<String>,
    /// Baud rate of the GNSS serial output (bytes are paced at this rate).
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// SocketCAN interface for CAN frames.
    #[arg(long)]
    can_to: Option<String>,
    /// Playback speed factor (2 = twice as fast).
    #[arg(long, default_value_t = 1.0)]
    speed: f64,
    /// Start again at the end, until Ctrl-C.
    #[arg(long = "loop")]
    repeat: bool,
    /// Start this many seconds into the file.
    #[arg(long)]
    start: Option<f64>,
    /// End this many seconds into the file.
    #[arg(long)]
    end: Option<f64>,
    /// Rewrite Velodyne timestamps and position packets (PPS locked, RMC) to the present.
    #[arg(long)]
    now: bool,
    /// UDP ports of data and position packets in captures.
    #[arg(long, default_value_t = hilrig::velodyne::DATA_PORT)]
    data_port: u16,
    /// UDP port of position packets in captures.
    #[arg(long, default_value_t = hilrig::velodyne::POSITION_PORT)]
    position_port: u16,
}

#[derive(clap::Args)]
struct InfoArgs {
    /// The MCAP file.
    file: PathBuf,
}

#[derive(clap::Args)]
struct RecoverArgs {
    /// The cut-off file (e.g. drive.mcap.active).
    file: PathBuf,
    /// Output file (default: the input name without `.active`, or with `.recovered.mcap`).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

#[derive(clap::Args)]
struct RecordArgs {
    /// The rig file.
    #[arg(long)]
    rig: PathBuf,
    /// Capture files to record from instead of the live sensors.
    #[arg(long, num_args = 1..)]
    from: Vec<PathBuf>,
    /// Output MCAP file (written as OUT.active until finished); live recordings default to
    /// the rig's output_dir/RIG-YYYYMMDDTHHMMSSZ.mcap.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum Format {
    /// One row per point: time_s,ring,azimuth_deg,distance_m,intensity,return_type,x,y,z.
    Csv,
    /// One JSON object per point (lidar) or per fix (gnss).
    Jsonl,
    /// No points: counts, packet loss, timing and position-packet state only.
    Summary,
}

#[derive(Clone, Copy, ValueEnum, PartialEq, Eq)]
enum Kind {
    /// Velodyne lidar packets in a pcap/pcapng capture.
    Lidar,
    /// An RTK GNSS serial stream (NMEA, UBX, RTCM3): a raw or gpsd log, or a capture's serial
    /// interfaces.
    Gnss,
    /// CAN frames (a candump log, or a capture's SocketCAN interfaces), decoded with --dbc.
    Can,
}

#[derive(clap::Args)]
struct DecodeArgs {
    /// The capture or log file.
    file: PathBuf,
    /// What the file holds.
    #[arg(long, value_enum, default_value = "lidar")]
    kind: Kind,
    /// Decode as this model whatever the packets' product byte says
    /// (vlp16, puck-hires, vlp32c, hdl32e).
    #[arg(long)]
    model: Option<String>,
    /// Calibration file in the ros-drivers YAML format (lidar).
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

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(io::stderr)
        .with_target(false)
        .init();
}

fn main() -> ExitCode {
    // A file-size limit (or a quota) must end in a write error the recorder can report and
    // stop on, not in SIGXFSZ killing it mid-chunk.
    // SAFETY: setting a signal to SIG_IGN at startup, before any thread exists, installs no
    // handler code and cannot race.
    let _ = unsafe {
        nix::sys::signal::signal(
            nix::sys::signal::Signal::SIGXFSZ,
            nix::sys::signal::SigHandler::SigIgn,
        )
    };
    let cli = Cli::parse();
    init_logging(cli.verbose);
    let result = match cli.command {
        Command::Decode(args) => run_decode(args),
        Command::Record(args) => run_record(args),
        Command::Recover(args) => run_recover(args),
        Command::Info(args) => run_info(args),
        Command::Replay(args) => run_replay(args),
        Command::Synth(args) => run_synth(args),
        Command::Check(args) => run_check(args),
        Command::Resim(args) => run_resim(args),
    };
    match result {
        Ok(code) => code,
        // A closed pipe (`hilrig decode ... | head`) is the reader's choice, not an error.
        Err(e)
            if e.chain().any(|c| {
                c.downcast_ref::<io::Error>()
                    .is_some_and(|io| io.kind() == io::ErrorKind::BrokenPipe)
            }) =>
        {
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {}", describe(&e));
            ExitCode::from(2)
        }
    }
}

/// The error and its causes, each said once: library errors already quote their cause in
/// their message, so a cause whose text is already there is not repeated.
fn describe(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

fn run_decode(args: DecodeArgs) -> Result<ExitCode> {
    match args.kind {
        Kind::Gnss => return run_decode_gnss(&args),
        Kind::Can => return run_decode_can(&args),
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
    }
    .with_context(|| format!("decoding {}", args.file.display()))?;
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
    let mut err = io::stderr().lock();
    for l in lines {
        let _ = writeln!(err, "{path}: {l}");
    }
}

fn run_decode_gnss(args: &DecodeArgs) -> Result<ExitCode> {
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
    let summary = hilrig::gnss_log::decode_gnss(BufReader::new(file), &mut |fix| {
        if write {
            writeln!(out, "{}", hilrig::gnss_log::fix_json(fix))?;
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

fn run_decode_can(args: &DecodeArgs) -> Result<ExitCode> {
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
    let summary = hilrig::can_log::decode_can(BufReader::new(file), &db, &mut |t, f, d| {
        if write {
            writeln!(out, "{}", hilrig::can_log::frame_json(t, f, d))?;
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

/// The output file, or standard output.
fn open_output(path: Option<&std::path::Path>) -> Result<Box<dyn Write>> {
    Ok(match path {
        Some(p) => {
            Box::new(File::create(p).with_context(|| format!("cannot create {}", p.display()))?)
        }
        None => Box::new(io::stdout().lock()),
    })
}

fn run_record(args: RecordArgs) -> Result<ExitCode> {
    let rig = hilrig::rig::Rig::load(&args.rig)?;
    let text = std::fs::read_to_string(&args.rig)
        .with_context(|| format!("cannot read {}", args.rig.display()))?;
    if args.from.is_empty() {
        return run_record_live(&rig, &text, args.output);
    }
    let Some(output) = args.output else {
        bail!("record --from needs -o OUT.mcap");
    };
    let summary = hilrig::record::record_from(&rig, &text, &args.from, &output)?;
    let out = output.display();
    for (topic, n) in &summary.counts {
        eprintln!("{out}: {topic}: {n} messages");
    }
    for (name, m, r, pairs) in &summary.clocks {
        eprintln!(
            "{out}: clock {name}: offset {:.3} ms, drift {:.2} ppm, residual p50 {:.0} us, p95 {:.0} us, max {:.0} us ({pairs} pairs)",
            m.offset_ns * 1e-6,
            m.drift * 1e6,
            r.p50_ns * 1e-3,
            r.p95_ns * 1e-3,
            r.max_ns * 1e-3
        );
    }
    eprintln!("{out}: lidar packets lost: {}", summary.lidar_lost);
    for e in &summary.input_errors {
        eprintln!("error: {e} (everything before it was recorded)");
    }
    Ok(if summary.input_errors.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

fn run_resim(args: ResimArgs) -> Result<ExitCode> {
    use hilrig::sim::resim::{resim, PoseSource, ResimError};
    // Without --rig, resim takes the rig file attached to the recording (reading it once).
    let rig = args
        .rig
        .as_ref()
        .map(|p| hilrig::rig::Rig::load(p))
        .transpose()?;
    let scene = hilrig::scene::Scene::load(&args.scene)?;
    let model = hilrig::sim::ModelFile::load(&args.model)?;
    let poses = match &args.trajectory {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let t = hilrig::pose::Trajectory::from_csv(&text)
                .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
            PoseSource::File(t, p.display().to_string())
        }
        None => PoseSource::Run,
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("resim [{bar:30}] {pos}/{len} scans, {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    match resim(
        &args.run,
        rig.as_ref(),
        &scene,
        &args.scene,
        &model,
        poses,
        args.force,
        args.seed,
        &args.output,
        &progress,
    ) {
        Ok(s) => {
            bar.finish_and_clear();
            eprintln!(
                "{}: {} scans, {} packets re-simulated with model '{}' ({} of {} firings returned; check: {:?})",
                args.output.display(),
                s.scans,
                s.packets,
                model.name,
                s.stats.returns,
                s.stats.firings,
                s.verdict.unwrap_or(hilrig::reference::check::Verdict::Unusable)
            );
            if s.stats.outside_trajectory > 0 {
                eprintln!(
                    "{}: {} firings lie outside the trajectory and have no returns",
                    args.output.display(),
                    s.stats.outside_trajectory
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(ResimError::Refused(report)) => {
            bar.finish_and_clear();
            eprint!("{}", report.text());
            eprintln!("error: {}", ResimError::Refused(report.clone()));
            Ok(ExitCode::from(1))
        }
        Err(e) => Err(e.into()),
    }
}

fn run_check(args: CheckArgs) -> Result<ExitCode> {
    use hilrig::reference::{check, run::Run};
    let run = match Run::read(&args.run) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("verdict: UNUSABLE\n  {e}");
            return Ok(ExitCode::from(2));
        }
    };
    let rig = match (&args.rig, &run.rig_toml) {
        (Some(p), _) => hilrig::rig::Rig::load(p)?,
        (None, Some(text)) => {
            hilrig::rig::Rig::from_toml(text, "rig.toml attached to the recording")?
        }
        (None, None) => {
            eprintln!("verdict: UNUSABLE\n  the recording has no rig.toml attached: give --rig");
            return Ok(ExitCode::from(2));
        }
    };
    let scene = args
        .scene
        .as_ref()
        .map(|p| hilrig::scene::Scene::load(p))
        .transpose()?;
    let report = check::check(&run, &rig, scene.as_ref());
    print!("{}", report.text());
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(ExitCode::from(report.verdict.exit_code()))
}

fn run_synth(args: SynthArgs) -> Result<ExitCode> {
    use hilrig::sim::synth::{synth_rep, SynthJob};
    let scene_text = std::fs::read_to_string(&args.scene)
        .with_context(|| format!("cannot read {}", args.scene.display()))?;
    let scene_file: hilrig::scene::SceneFile =
        toml::from_str(&scene_text).with_context(|| format!("{}", args.scene.display()))?;
    // Load once to check the whole scene (meshes, trajectories) before any work.
    hilrig::scene::Scene::load(&args.scene)?;
    let drive = hilrig::sim::drive::DriveFile::load(&args.drive).map_err(anyhow::Error::msg)?;
    let truth = hilrig::sim::ModelFile::load(&args.truth)?;
    let base = |p: &std::path::Path| p.parent().unwrap_or(std::path::Path::new(".")).to_owned();
    let (scene_base, drive_base) = (base(&args.scene), base(&args.drive));
    let job = SynthJob {
        scene_file: &scene_file,
        scene_base: &scene_base,
        drive: &drive,
        drive_base: &drive_base,
        truth: &truth,
        seed: args.seed,
        compress: args.compress,
        errors: !args.no_errors,
    };
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    std::fs::write(args.output.join("truth-model.toml"), truth.to_toml())?;
    let bar = indicatif::ProgressBar::new(u64::from(args.reps));
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg} [{bar:30}] {pos}/{len} repetitions, {elapsed}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message("synth");
    for rep in 1..=args.reps {
        let dir = args.output.join(format!("rep-{rep:02}"));
        let s = synth_rep(&job, rep, &dir)?;
        bar.suspend(|| eprintln!(
            "{}: {:.1} s, {} lidar packets ({} lost), {} position, {} NMEA, {} CAN, returns {:.0} %, waited {:.1} s for the walker",
            dir.join(&s.capture).display(),
            s.duration_s,
            s.lidar_packets,
            s.lidar_packets_lost,
            s.position_packets,
            s.sentences,
            s.can_frames,
            s.return_share * 100.0,
            s.yield_stop_s
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(ExitCode::SUCCESS)
}

fn run_recover(args: RecoverArgs) -> Result<ExitCode> {
    let output = match &args.output {
        Some(o) => o.clone(),
        None => {
            let name = args.file.to_string_lossy();
            match name.strip_suffix(".active") {
                Some(stem) if !std::path::Path::new(stem).exists() => PathBuf::from(stem),
                _ => PathBuf::from(format!(
                    "{}.recovered.mcap",
                    name.trim_end_matches(".active")
                )),
            }
        }
    };
    if output == args.file {
        bail!("the output would overwrite the input; give -o");
    }
    let r =
        hilrig::bag::recover::recover(&args.file, &output, &hilrig::bag::BagOptions::default())?;
    let out = output.display();
    for (topic, n) in &r.counts {
        eprintln!("{out}: {topic}: {n} messages");
    }
    match &r.stopped_by {
        Some(why) => eprintln!(
            "{}: cut off; reading stopped at: {why}",
            args.file.display()
        ),
        None => eprintln!("{}: the file was complete", args.file.display()),
    }
    eprintln!("{out}: {} messages recovered", r.messages);
    Ok(ExitCode::SUCCESS)
}

fn run_info(args: InfoArgs) -> Result<ExitCode> {
    let i = hilrig::bag::info::info(&args.file)?;
    let mut out = io::stdout().lock();
    writeln!(out, "file: {}", args.file.display())?;
    writeln!(out, "profile: {}", i.profile)?;
    let secs = i.span.map(|(a, b)| (b - a) as f64 * 1e-9);
    match i.span {
        Some((a, b)) => writeln!(
            out,
            "time: {} .. {} ({:.3} s)",
            hilrig::stamp::civil::iso8601_millis(hilrig::stamp::UtcNanos(a as i64)),
            hilrig::stamp::civil::iso8601_millis(hilrig::stamp::UtcNanos(b as i64)),
            secs.unwrap_or(0.0)
        )?,
        None => writeln!(out, "time: (no messages)")?,
    }
    writeln!(out, "chunks: {}", i.chunks)?;
    writeln!(out, "channels:")?;
    for c in &i.channels {
        let rate = secs
            .filter(|s| *s > 0.0)
            .map(|s| format!("{:9.2} Hz", c.count as f64 / s))
            .unwrap_or_default();
        writeln!(
            out,
            "  {:24} {:36} {:>9} msgs {rate}",
            c.topic, c.message_type, c.count
        )?;
    }
    for (name, m) in &i.metadata {
        let kv: Vec<String> = m.iter().map(|(k, v)| format!("{k}={v}")).collect();
        writeln!(out, "metadata {name}: {}", kv.join(", "))?;
    }
    for (name, ty, size) in &i.attachments {
        writeln!(out, "attachment {name} ({ty}, {size} bytes)")?;
    }
    Ok(ExitCode::SUCCESS)
}

fn run_record_live(
    rig: &hilrig::rig::Rig,
    text: &str,
    output: Option<PathBuf>,
) -> Result<ExitCode> {
    let output = match output {
        Some(o) => o,
        None => {
            let dir = rig.resolve(&rig.recording.output_dir);
            std::fs::create_dir_all(&dir)
                .with_context(|| format!("cannot create {}", dir.display()))?;
            let now = hilrig::stamp::civil::iso8601_millis(hilrig::stamp::UtcNanos::now());
            let stamp: String = now[..19]
                .chars()
                .filter(|c| c.is_ascii_digit() || *c == 'T')
                .collect();
            dir.join(format!("{}-{stamp}Z.mcap", rig.name))
        }
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let summary = rt.block_on(async {
        let stop = async {
            let mut term =
                tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
                    .expect("SIGTERM handler");
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
        };
        eprintln!("recording to {} (Ctrl-C to finish)", output.display());
        hilrig::record_live::record_live(rig, text, &output, stop).await
    })?;
    for (topic, n) in &summary.counts {
        eprintln!("{}: {topic}: {n} messages", output.display());
    }
    let dropped: u64 = summary.health.values().map(|v| v[2]).sum();
    Ok(if dropped == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// Shifts a position packet to `at`: timestamp, PPS locked, RMC time and date.
fn position_now(p: &[u8], at: hilrig::stamp::UtcNanos) -> Vec<u8> {
    let Ok(mut pkt) = hilrig::velodyne::PositionPacket::decode(p) else {
        return p.to_vec();
    };
    pkt.timestamp_us = (at.nanos_past_hour() / 1000) as u32;
    pkt.pps_byte = 2;
    if let Some(s) = pkt.nmea() {
        if let Ok(body) = hilrig::gnss::nmea::body(s) {
            let mut f: Vec<String> = body.split(',').map(str::to_owned).collect();
            if f.len() > 9 && f[0].ends_with("RMC") {
                let iso = hilrig::stamp::civil::iso8601_millis(hilrig::stamp::UtcNanos(
                    at.0 - at.0.rem_euclid(1_000_000_000),
                ));
                f[1] = format!("{}{}{}", &iso[11..13], &iso[14..16], &iso[17..19]);
                f[2] = "A".into();
                f[9] = format!("{}{}{}", &iso[8..10], &iso[5..7], &iso[2..4]);
                let sentence = hilrig::gnss::framer::nmea_sentence(&f.join(","));
                pkt = hilrig::velodyne::PositionPacket::new(
                    pkt.timestamp_us,
                    hilrig::velodyne::PpsStatus::Locked,
                    &sentence,
                );
            }
        }
    }
    pkt.encode().to_vec()
}

fn run_replay(args: ReplayArgs) -> Result<ExitCode> {
    use hilrig::replay::{load, wait_until, window, Pacing, Payload};
    use std::sync::atomic::{AtomicBool, Ordering};
    if !(args.speed > 0.0 && args.speed.is_finite()) {
        bail!("--speed must be a positive number");
    }
    let (items, damage) = load(&args.file, args.data_port, args.position_port)?;
    if let Some(e) = &damage {
        // Replay what was read before the damage; the exit status still says it was incomplete.
        eprintln!("error: {e} (replaying the {} items before it)", items.len());
    }
    let items = window(items, args.start, args.end);
    if items.is_empty() {
        bail!(
            "{}: nothing to replay (in the chosen --start/--end window)",
            args.file.display()
        );
    }
    let udp = std::net::UdpSocket::bind("0.0.0.0:0").context("cannot open a UDP socket")?;
    let mut gnss: Option<Box<dyn Write>> = match args.gnss_to.as_deref() {
        None => None,
        Some("pty") => {
            use std::os::fd::AsFd;
            let p = nix::pty::openpty(None, None).context("cannot open a pseudo-terminal")?;
            let mut t = nix::sys::termios::tcgetattr(p.slave.as_fd())?;
            nix::sys::termios::cfmakeraw(&mut t);
            nix::sys::termios::tcsetattr(p.slave.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t)?;
            let name = nix::unistd::ttyname(p.slave.as_fd())?;
            println!("gnss pty: {}", name.display());
            io::stdout().flush()?;
            // The slave stays open here too, so a reader that opens and closes it loses nothing.
            std::mem::forget(p.slave);
            Some(Box::new(std::fs::File::from(p.master)))
        }
        Some(dev) => Some(Box::new(
            tokio_serial::new(dev, args.baud)
                .open()
                .with_context(|| format!("cannot open serial port {dev}"))?,
        )),
    };
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let can = match &args.can_to {
        Some(i) => {
            Some(rt.block_on(async { hilrig::can::socketcan_source::SocketCanSource::open(i) })?)
        }
        None => None,
    };
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        std::thread::spawn(move || {
            if let Ok(rt) = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            {
                rt.block_on(async {
                    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).ok();
                    tokio::select! {
                        _ = tokio::signal::ctrl_c() => {}
                        _ = async { if let Some(t) = term.as_mut() { t.recv().await; } else { std::future::pending::<()>().await } } => {}
                    }
                });
            }
            stop.store(true, Ordering::SeqCst);
        });
    }
    let first = items[0].time;
    let mut lags = Vec::with_capacity(items.len());
    let byte_time = std::time::Duration::from_secs_f64(10.0 / f64::from(args.baud));
    let mut skipped = 0u64;
    'outer: loop {
        let wall0 = std::time::Instant::now();
        let utc0 = hilrig::stamp::UtcNanos::now();
        let mut serial_free = wall0;
        for item in &items {
            if stop.load(Ordering::Relaxed) {
                break 'outer;
            }
            let offset = std::time::Duration::from_nanos(
                ((item.time.0 - first.0) as f64 / args.speed) as u64,
            );
            let mut deadline = wall0 + offset;
            if let Payload::Serial(b) = &item.payload {
                // A serial line cannot carry bytes faster than its baud rate.
                deadline = deadline.max(serial_free);
                serial_free = deadline + byte_time * b.len() as u32;
            }
            wait_until(deadline);
            let lag = std::time::Instant::now().saturating_duration_since(deadline);
            let at = hilrig::stamp::UtcNanos(utc0.0 + offset.as_nanos() as i64);
            let sent = match &item.payload {
                Payload::LidarData(b) => match args.lidar_to {
                    Some(to) => {
                        if args.now {
                            let mut b = b.clone();
                            b[1200..1204].copy_from_slice(
                                &((at.nanos_past_hour() / 1000) as u32).to_le_bytes(),
                            );
                            udp.send_to(&b, to)?;
                        } else {
                            udp.send_to(b, to)?;
                        }
                        true
                    }
                    None => false,
                },
                Payload::LidarPosition(b) => match args.position_to {
                    Some(to) => {
                        let b = if args.now {
                            position_now(b, at)
                        } else {
                            b.clone()
                        };
                        udp.send_to(&b, to)?;
                        true
                    }
                    None => false,
                },
                Payload::Serial(b) => match gnss.as_mut() {
                    Some(w) => {
                        w.write_all(b)?;
                        w.flush()?;
                        true
                    }
                    None => false,
                },
                Payload::Can(f) => match &can {
                    Some(c) => {
                        rt.block_on(c.send(f))?;
                        true
                    }
                    None => false,
                },
            };
            if sent {
                lags.push(lag.as_nanos() as i64);
            } else {
                skipped += 1;
            }
        }
        if !args.repeat {
            break;
        }
    }
    if args.gnss_to.as_deref() == Some("pty") {
        // Closing the pty's master discards what the reader has not read yet: give it time.
        std::thread::sleep(std::time::Duration::from_millis(500));
    }
    let p = Pacing::from_lags(lags);
    eprintln!(
        "replayed {} items ({} without a destination); lag p50 {:.1} us, p99 {:.1} us, max {:.1} us",
        p.sent, skipped, p.p50_us, p.p99_us, p.max_us
    );
    Ok(match damage {
        None => ExitCode::SUCCESS,
        Some(e) => {
            eprintln!("error: {e}: the rest of the input was not replayed");
            ExitCode::from(1)
        }
    })
}
