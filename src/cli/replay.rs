//! `hilrig replay`: the options into destinations and play options, one call into
//! [`hilrig::replay`], and the pacing summary.

use anyhow::{bail, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct ReplayArgs {
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

pub fn run(args: ReplayArgs) -> Result<ExitCode> {
    use hilrig::replay::sink::{udp_socket, CanSink, SerialSink, UdpSink};
    use hilrig::replay::{load, play, stop_on_signals, window, Destinations, PlayOptions};
    use std::io::Write;
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
    let udp = udp_socket()?;
    let mut dest = Destinations::default();
    if let Some(to) = args.lidar_to {
        dest.lidar_data = Some(Box::new(UdpSink::new(udp.clone(), to)));
    }
    if let Some(to) = args.position_to {
        dest.lidar_position = Some(Box::new(UdpSink::new(udp.clone(), to)));
    }
    match args.gnss_to.as_deref() {
        None => {}
        Some("pty") => {
            let (sink, name) = SerialSink::pty()?;
            println!("gnss pty: {}", name.display());
            std::io::stdout().flush()?;
            dest.serial = Some(Box::new(sink));
        }
        Some(dev) => dest.serial = Some(Box::new(SerialSink::device(dev, args.baud)?)),
    }
    if let Some(i) = &args.can_to {
        dest.can = Some(Box::new(CanSink::open(i)?));
    }
    let stop = stop_on_signals();
    let options = PlayOptions {
        speed: args.speed,
        repeat: args.repeat,
        now: args.now,
        baud: args.baud,
    };
    let played = play(&items, &mut dest, &options, &stop)?;
    let p = &played.pacing;
    eprintln!(
        "replayed {} items ({} without a destination); lag p50 {:.1} us, p99 {:.1} us, max {:.1} us",
        p.sent, played.without_destination, p.p50_us, p.p99_us, p.max_us
    );
    Ok(match damage {
        None => ExitCode::SUCCESS,
        Some(e) => {
            eprintln!("error: {e}: the rest of the input was not replayed");
            ExitCode::from(1)
        }
    })
}
