//! `hilrig replay`: the options into destinations and play options, one call into
//! [`hilrig::replay`], and the pacing summary.

use anyhow::{bail, Result};
use hilrig::replay::{ReplayError, ReplayItem, Streamed};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};

#[derive(clap::Args)]
pub struct ReplayArgs {
    /// The recording or capture; several are merged by time (files recorded side by side on
    /// one clock, such as lidar and CAN captures of the same drive, or the parts of a split
    /// recording).
    #[arg(required = true)]
    files: Vec<PathBuf>,
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
    /// Start this many seconds after the first item.
    #[arg(long)]
    start: Option<f64>,
    /// End this many seconds after the first item.
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
    use hilrig::replay::{play_stream, stop_on_signals, Destinations, PlayOptions};
    use std::io::Write;
    if !(args.speed > 0.0 && args.speed.is_finite()) {
        bail!("--speed must be a positive number");
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
    let reading: Reading = Arc::new(Mutex::new(args.files.iter().map(|_| None).collect()));
    let pass = || Pass::open(&args, reading.clone());
    let played = play_stream(pass, &mut dest, &options, &stop)?;
    let read: Vec<Option<Result<Streamed, ReplayError>>> = reading
        .lock()
        .map(|mut r| std::mem::take(&mut *r))
        .unwrap_or_default();
    let mut streamed = Vec::new();
    for (path, r) in args.files.iter().zip(read) {
        match r {
            Some(Ok(s)) => streamed.push((path, s)),
            Some(Err(e)) => return Err(e.into()),
            None => streamed.push((path, Streamed::default())),
        }
    }
    let names = args
        .files
        .iter()
        .map(|f| f.display().to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let p = &played.pacing;
    if p.sent + played.without_destination == 0 {
        match streamed
            .iter()
            .find_map(|(f, s)| Some((f, s.damage.as_ref()?)))
        {
            Some((f, e)) => bail!("{}: {e}: nothing could be replayed", f.display()),
            None => bail!("{names}: nothing to replay (in the chosen --start/--end window)"),
        }
    }
    eprintln!(
        "replayed {} items ({} without a destination); lag p50 {:.1} us, p99 {:.1} us, max {:.1} us",
        p.sent, played.without_destination, p.p50_us, p.p99_us, p.max_us
    );
    // The line's baud rate, not the recording, set the serial pace: say how far behind.
    if played.serial_behind > std::time::Duration::from_millis(100) {
        eprintln!(
            "warning: the serial line at {} baud carried the GNSS stream up to {:.1} s behind its recorded pace (a faster --baud keeps up)",
            args.baud,
            played.serial_behind.as_secs_f64()
        );
    }
    let mut damaged = false;
    for (path, s) in &streamed {
        if s.out_of_order > 0 {
            eprintln!(
                "warning: {}: {} items came more than {} s after later ones in the file and were sent out of time order",
                path.display(),
                s.out_of_order,
                hilrig::replay::load::REORDER_HORIZON_NS / 1_000_000_000
            );
        }
        if s.not_replayed > 0 {
            eprintln!(
                "error: {}: {} recorded CAN frames were not replayed (CAN FD frames, or frames that are not classic CAN frames: the CAN sink sends classic frames only)",
                path.display(),
                s.not_replayed
            );
            damaged = true;
        }
        for (reason, n) in &s.capture_records.damaged {
            eprintln!(
                "error: {}: {n} capture records were damaged ({reason}) and not replayed",
                path.display()
            );
            damaged = true;
        }
        if s.lidar_wrong_size > 0 {
            eprintln!(
                "error: {}: {} datagrams to the lidar's ports were not the size of a data or position packet and were not replayed",
                path.display(),
                s.lidar_wrong_size
            );
            damaged = true;
        }
        if let Some(e) = &s.damage {
            // What was read before the damage was replayed; the exit status says it was not all.
            eprintln!(
                "error: {}: {e} (replayed the {} items before it); the rest of the input was not replayed",
                path.display(),
                s.items
            );
            damaged = true;
        }
    }
    Ok(if damaged {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// What each input's reader thread found, per file (the first pass's).
type Reading = Arc<Mutex<Vec<Option<Result<Streamed, ReplayError>>>>>;

/// Items read ahead of the player, at most (about 5 MB of lidar packets).
const READ_AHEAD: usize = 4096;

/// One pass over the inputs: a reader thread per file streams it (bounded by [`READ_AHEAD`]
/// shared among them), the streams are merged by time, and the player takes the items in the
/// `--start`/`--end` window. Dropping the pass stops the readers. The first pass's outcome per
/// file (items read, damage) is kept in `reading`.
struct Pass {
    merged: hilrig::replay::MergeByTime<std::sync::mpsc::IntoIter<ReplayItem>>,
    window: (Option<f64>, Option<f64>),
    bounds: Option<(i64, i64)>,
}

impl Pass {
    fn open(args: &ReplayArgs, reading: Reading) -> Pass {
        let per_file = (READ_AHEAD / args.files.len()).max(256);
        let mut streams = Vec::with_capacity(args.files.len());
        for (k, path) in args.files.iter().enumerate() {
            let (tx, rx) = std::sync::mpsc::sync_channel(per_file);
            let (path, data, position) = (path.clone(), args.data_port, args.position_port);
            let reading = reading.clone();
            std::thread::spawn(move || {
                let r = hilrig::replay::stream(&path, data, position, &mut |item| {
                    tx.send(item).is_ok()
                });
                if let Ok(mut slots) = reading.lock() {
                    if slots[k].is_none() {
                        slots[k] = Some(r);
                    }
                }
            });
            streams.push(rx.into_iter());
        }
        Pass {
            merged: hilrig::replay::MergeByTime::new(streams),
            window: (args.start, args.end),
            bounds: None,
        }
    }
}

impl Iterator for Pass {
    type Item = ReplayItem;

    fn next(&mut self) -> Option<ReplayItem> {
        loop {
            let item = self.merged.next()?;
            let (from, to) = *self.bounds.get_or_insert_with(|| {
                let first = item.time.0;
                (
                    self.window.0.map_or(i64::MIN, |s| first + (s * 1e9) as i64),
                    self.window.1.map_or(i64::MAX, |s| first + (s * 1e9) as i64),
                )
            });
            // Past the window's end by more than the reorder horizon, nothing later can fall
            // inside it: stop reading instead of reading the rest of the files.
            if item.time.0 > to.saturating_add(hilrig::replay::load::REORDER_HORIZON_NS) {
                return None;
            }
            if item.time.0 >= from && item.time.0 <= to {
                return Some(item);
            }
        }
    }
}
