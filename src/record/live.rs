//! `hilrig record --rig R`: the recorder on the vehicle.
//!
//! Every source runs as its own tokio task on the drivers' I/O shells (UDP with kernel stamps,
//! the reconnecting serial port, SocketCAN) and turns what it receives into encoded messages.
//! Messages go to one writer thread through a bounded queue; a source never blocks on the queue
//! (a full queue drops the message and counts it), so a slow disk cannot stall the sockets and
//! their kernel buffers. The writer closes a chunk at least every second and keeps the file as
//! `NAME.mcap.active` until a clean finish (SIGINT/SIGTERM), so a power cut loses at most the
//! last chunk and `hilrig recover` salvages the rest. Per-source health (rate, drops, decode
//! errors, reconnects) is printed every few seconds and at the end.
//!
//! Long file: the source tasks (lidar data, position packets, GNSS serial, CAN), the writer
//! thread and the health counters share one queue and one message conversion; they are read
//! together when a message goes missing on the vehicle.

use crate::bag::msgs::{self, MessageType};
use crate::bag::{BagError, BagWriter};
use crate::record::clock::ClockEstimator;
use crate::record::gnss_stream::GnssStream;
use crate::record::rejects::{GnssRejects, GnssUndecoded, LidarRejects, RejectReason, Undecoded};
use crate::rig::Rig;
use hilrig_gnss::epoch::{NmeaEpochs, UbxEpochs};
use hilrig_gnss::framer::{Frame, Framer, Item};
use hilrig_stamp::{Stamped, UtcNanos};
use hilrig_velodyne::clock::HourResolver;
use hilrig_velodyne::source::{LidarItem, LidarSource, DEFAULT_RECV_BUFFER};
use hilrig_velodyne::{Model, ReturnMode, RotationAssembler};
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// One message for the writer.
struct Event {
    topic: &'static str,
    ty: &'static MessageType,
    log_time: UtcNanos,
    publish_time: UtcNanos,
    cdr: Vec<u8>,
}

/// Counters of one source, shared with the health printer.
#[derive(Default, Debug)]
pub struct Health {
    /// Items received.
    pub received: AtomicU64,
    /// Messages queued for writing.
    pub queued: AtomicU64,
    /// Messages dropped because the writer queue was full.
    pub dropped: AtomicU64,
    /// Items that did not decode.
    pub decode_errors: AtomicU64,
    /// Packets lost before reaching us (lidar timestamp gaps).
    pub lost: AtomicU64,
    /// Reconnects (serial).
    pub reconnects: AtomicU64,
    /// Times the port went away (serial), whether or not it came back.
    pub disconnects: AtomicU64,
    /// Of the lost packets, outages of more than two seconds (lidar).
    pub outages: AtomicU64,
    /// Jumps of the sensor's clock while its packets kept coming (lidar).
    pub time_jumps: AtomicU64,
}

fn types() -> &'static BTreeMap<&'static str, MessageType> {
    static T: std::sync::OnceLock<BTreeMap<&'static str, MessageType>> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let mut m = BTreeMap::new();
        m.insert("scan", msgs::velodyne_scan_type());
        m.insert("raw", msgs::raw_packet_type());
        m.insert("nmea", msgs::nmea_sentence_type());
        m.insert("fix", msgs::nav_sat_fix_type());
        m.insert("attitude", msgs::attitude_type());
        m.insert("can", msgs::can_frame_type());
        m.insert("points", msgs::point_cloud2_type());
        m
    })
}

fn send(tx: &SyncSender<Event>, h: &Health, e: Event) {
    match tx.try_send(e) {
        Ok(()) => {
            h.queued.fetch_add(1, Ordering::Relaxed);
        }
        Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
            h.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// What a live recording did.
#[derive(Debug, Default)]
pub struct LiveSummary {
    /// Messages per topic in the file.
    pub counts: BTreeMap<String, u64>,
    /// Health per source at the end.
    pub health: BTreeMap<String, [u64; 6]>,
    /// Lidar packets not recorded, per reason (any makes `record` exit 1).
    pub lidar_rejects: LidarRejects,
    /// GNSS serial frames not recorded (a checksum that fails, a malformed sentence), per
    /// reason (any makes `record` exit 1).
    pub gnss_rejects: GnssRejects,
    /// GNSS messages recorded whole whose fields did not decode (their fix or attitude is
    /// missing), per reason (any makes `record` exit 1).
    pub gnss_undecoded: GnssUndecoded,
    /// What the GNSS stream held: frames, bytes outside them, fixes with and without a date.
    pub gnss_stream: Option<GnssStream>,
    /// Times the GNSS serial port went away (any makes `record` exit 1: what the receiver
    /// sent meanwhile is lost).
    pub gnss_disconnects: u64,
}

/// Why the recorder stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// A source could not be opened at start.
    #[error("{source_name}: {error}")]
    Source {
        /// Which source.
        source_name: &'static str,
        /// The error.
        error: String,
    },
    /// The recording could not be started (output not writable).
    #[error("cannot start recording")]
    Create(#[source] BagError),
    /// Writing failed (disk full, unwritable). Everything written before is in the `.active` file.
    #[error("recording stopped; everything recorded before is in the .active file (run `hilrig recover` on it)")]
    Bag(#[from] BagError),
    /// The output folder could not be created.
    #[error("cannot create {path}")]
    Folder {
        /// The folder.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// The async runtime could not be started.
    #[error(transparent)]
    Runtime(std::io::Error),
}

/// Maps an error opening `source_name` to the recorder's error that names the source.
fn source_error<E: std::fmt::Display>(source_name: &'static str) -> impl FnOnce(E) -> LiveError {
    move |e| LiveError::Source {
        source_name,
        error: e.to_string(),
    }
}

impl LiveSummary {
    /// Messages dropped because the writer could not keep up, over all sources.
    pub fn dropped(&self) -> u64 {
        self.health.values().map(|v| v[2]).sum()
    }
}

/// Where a live recording goes when no output is given: the rig's `output_dir` (created if
/// needed), named after the rig and the start time, `RIG-YYYYMMDDTHHMMSSZ.mcap`.
pub fn default_output(rig: &Rig) -> Result<PathBuf, LiveError> {
    let dir = rig.resolve(&rig.recording.output_dir);
    std::fs::create_dir_all(&dir).map_err(|source| LiveError::Folder {
        path: dir.display().to_string(),
        source,
    })?;
    let now = hilrig_stamp::civil::iso8601_millis(UtcNanos::now());
    let stamp: String = now[..19]
        .chars()
        .filter(|c| c.is_ascii_digit() || *c == 'T')
        .collect();
    Ok(dir.join(format!("{}-{stamp}Z.mcap", rig.name)))
}

/// [`record_live`] on a runtime of its own until Ctrl-C (SIGINT) or SIGTERM: the recorder as
/// the command line runs it.
pub fn record_until_signal(
    rig: &Rig,
    rig_text: &str,
    output: &Path,
) -> Result<LiveSummary, LiveError> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(LiveError::Runtime)?;
    rt.block_on(async {
        let stop = async {
            use tokio::signal::unix::{signal, SignalKind};
            match signal(SignalKind::terminate()) {
                Ok(mut term) => {
                    tokio::select! {
                        _ = tokio::signal::ctrl_c() => {}
                        _ = term.recv() => {}
                    }
                }
                // Without a SIGTERM handler, Ctrl-C still finishes the file.
                Err(_) => {
                    let _ = tokio::signal::ctrl_c().await;
                }
            }
        };
        record_live(rig, rig_text, output, stop).await
    })
}

/// Runs the recorder until `stop` resolves; then finishes the file.
#[allow(
    clippy::too_many_lines,
    reason = "starts every source task and the writer thread and finishes them in the reverse order; each source loop is a function of its own"
)]
pub async fn record_live(
    rig: &Rig,
    rig_text: &str,
    output: &Path,
    stop: impl std::future::Future<Output = ()>,
) -> Result<LiveSummary, LiveError> {
    let rec = &rig.recording;
    // On the vehicle the power can go at any moment: each second's chunk goes to the disk.
    let options = crate::bag::BagOptions {
        durable: true,
        ..rec.bag_options()
    };
    let mut bag = BagWriter::create(output, &options).map_err(LiveError::Create)?;
    let mut meta = BTreeMap::new();
    meta.insert("rig".to_owned(), rig.name.clone());
    meta.insert(
        "hilrig_version".to_owned(),
        env!("CARGO_PKG_VERSION").to_owned(),
    );
    meta.insert("mode".to_owned(), "live".to_owned());
    bag.metadata("hilrig", meta)?;
    bag.attach(
        "rig.toml",
        "application/toml",
        rig_text.as_bytes(),
        UtcNanos::now(),
    )?;
    let now = UtcNanos::now();
    bag.write_static(
        crate::bag::topics::TF_STATIC,
        &msgs::tf_message_type(),
        now,
        &msgs::tf_message(now, &rig.transforms()),
    )?;

    let (tx, rx) = sync_channel::<Event>(rec.queue_messages.max(1));
    // Sources finish their pending state (the last partial rotation, the open GNSS epoch) when
    // this flips, instead of being aborted mid-message.
    let (shutdown_tx, shutdown) = tokio::sync::watch::channel(false);
    let clocks: Arc<Mutex<BTreeMap<&'static str, ClockEstimator>>> = Arc::default();
    let pps: Arc<Mutex<Option<u8>>> = Arc::default();
    let lidar_model = rig
        .lidar
        .as_ref()
        .and_then(|l| l.model.parse::<Model>().ok());
    let mut health: BTreeMap<&'static str, Arc<Health>> = BTreeMap::new();
    let rejects: Arc<Mutex<LidarRejects>> = Arc::default();
    let gnss_rejects: Arc<Mutex<GnssRejects>> = Arc::default();
    let gnss_undecoded: Arc<Mutex<GnssUndecoded>> = Arc::default();
    let gnss_stream: Arc<Mutex<GnssStream>> = Arc::default();
    let mut tasks = Vec::new();

    // Open every source before writing anything: a wrong port stops the recorder at start.
    if let Some(l) = &rig.lidar {
        let model: Model = l.model.parse().map_err(source_error("lidar"))?;
        let ip: std::net::IpAddr = l.bind.parse().map_err(|e| LiveError::Source {
            source_name: "lidar",
            error: format!("bind address {}: {e}", l.bind),
        })?;
        let source = LidarSource::bind(
            SocketAddr::new(ip, l.data_port),
            Some(SocketAddr::new(ip, l.position_port)),
            Some(model),
            DEFAULT_RECV_BUFFER,
        )
        .map_err(source_error("lidar"))?;
        let h = Arc::new(Health::default());
        health.insert("lidar", h.clone());
        let cut = (l.cut_azimuth_deg * 100.0).round() as u16;
        tasks.push(tokio::spawn(lidar_task(
            source,
            LidarSettings {
                frame: l.frame_id.clone(),
                cut,
                model,
                points: rig
                    .recording
                    .points
                    .then(|| hilrig_velodyne::Decoder::new(model)),
            },
            tx.clone(),
            LidarShared {
                health: h,
                clocks: clocks.clone(),
                pps: pps.clone(),
                rejects: rejects.clone(),
            },
            shutdown.clone(),
        )));
    }
    if let Some(g) = &rig.gnss {
        let source = hilrig_gnss::serial::SerialSource::open(&g.port, g.baud)
            .map_err(source_error("gnss"))?;
        let h = Arc::new(Health::default());
        health.insert("gnss", h.clone());
        tasks.push(tokio::spawn(gnss_task(
            source,
            g.frame_id.clone(),
            tx.clone(),
            h,
            clocks.clone(),
            GnssCounts {
                rejects: gnss_rejects.clone(),
                undecoded: gnss_undecoded.clone(),
                stream: gnss_stream.clone(),
            },
            shutdown.clone(),
        )));
    }
    if let Some(c) = &rig.can {
        let source = hilrig_can::socketcan_source::SocketCanSource::open(&c.interface)
            .map_err(source_error("can"))?;
        let h = Arc::new(Health::default());
        health.insert("can", h.clone());
        tasks.push(tokio::spawn(can_task(
            source,
            tx.clone(),
            h,
            shutdown.clone(),
        )));
    }
    drop(tx);

    // The writer: a plain thread, so file I/O never blocks the runtime.
    // When writing fails (disk full, device gone) the recorder must stop and say so, not go on
    // receiving into a queue nobody drains.
    let (failed_tx, failed_rx) = tokio::sync::oneshot::channel::<()>();
    let writer = std::thread::spawn(move || -> Result<BagWriter, BagError> {
        while let Ok(e) = rx.recv() {
            if let Err(err) = bag.write(e.topic, e.ty, e.log_time, e.publish_time, &e.cdr) {
                let _ = failed_tx.send(());
                return Err(err);
            }
        }
        Ok(bag)
    });

    let printer = {
        let health = health.clone();
        let rejects = rejects.clone();
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(Duration::from_secs(5));
            tick.tick().await;
            loop {
                tick.tick().await;
                print_health(&health, &rejects);
            }
        })
    };
    tokio::select! {
        _ = stop => {}
        _ = failed_rx => eprintln!("error: writing {} failed; stopping the recorder", output.display()),
    }
    let _ = shutdown_tx.send(true);
    for t in tasks {
        // Bounded: a source stuck in a syscall is abandoned after two seconds.
        let _ = tokio::time::timeout(Duration::from_secs(2), t).await;
    }
    printer.abort();
    // The sources' last word before anything else can fail (a full disk fails the writer's
    // join and the metadata below): the counts are final once the sources have stopped.
    print_health(&health, &rejects);
    let mut bag = writer.join().map_err(|_| BagError::Io {
        path: output.display().to_string(),
        source: std::io::Error::other("writer thread panicked"),
    })??;
    let clocks = clocks.lock().map(|c| c.clone()).unwrap_or_default();
    for (name, est) in &clocks {
        if let Some(m) = est.model() {
            let mut sync = crate::record::clock::metadata(&m, &est.residuals(), est.pairs());
            if *name == "lidar" {
                let reports = lidar_model != Some(Model::Hdl32e);
                sync.pps = pps
                    .lock()
                    .ok()
                    .and_then(|g| *g)
                    .map(|b| hilrig_velodyne::PpsStatus::from_byte(b, reports));
            }
            bag.metadata(
                &crate::bag::clock_sync::record_name(name),
                sync.to_metadata(),
            )?;
        }
    }
    let mut summary = LiveSummary::default();
    let mut end = BTreeMap::new();
    for (name, h) in &health {
        let v = [
            h.received.load(Ordering::Relaxed),
            h.queued.load(Ordering::Relaxed),
            h.dropped.load(Ordering::Relaxed),
            h.decode_errors.load(Ordering::Relaxed),
            h.lost.load(Ordering::Relaxed),
            h.reconnects.load(Ordering::Relaxed),
        ];
        end.insert(format!("{name}_received"), v[0].to_string());
        end.insert(format!("{name}_dropped"), v[2].to_string());
        end.insert(format!("{name}_decode_errors"), v[3].to_string());
        end.insert(format!("{name}_lost"), v[4].to_string());
        end.insert(format!("{name}_reconnects"), v[5].to_string());
        if *name == "lidar" {
            for (key, n) in [("outages", &h.outages), ("time_jumps", &h.time_jumps)] {
                end.insert(
                    format!("lidar_{key}"),
                    n.load(Ordering::Relaxed).to_string(),
                );
            }
        }
        summary.health.insert(name.to_string(), v);
    }
    summary.lidar_rejects = rejects.lock().map(|r| r.clone()).unwrap_or_default();
    if rig.lidar.is_some() {
        summary.lidar_rejects.write_metadata(&mut end);
    }
    summary.gnss_rejects = gnss_rejects.lock().map(|r| r.clone()).unwrap_or_default();
    summary.gnss_undecoded = gnss_undecoded.lock().map(|r| r.clone()).unwrap_or_default();
    if let Some(g) = &rig.gnss {
        let mut stream = gnss_stream.lock().map(|s| s.clone()).unwrap_or_default();
        stream.name.clone_from(&g.port);
        summary.gnss_stream = Some(stream);
    }
    summary.gnss_disconnects = health
        .get("gnss")
        .map_or(0, |h| h.disconnects.load(Ordering::Relaxed));
    if rig.gnss.is_some() {
        summary.gnss_rejects.write_metadata(&mut end);
        summary.gnss_undecoded.write_metadata(&mut end);
        GnssStream::write_metadata(summary.gnss_stream.as_slice(), &mut end);
        end.insert(
            "gnss_disconnects".to_owned(),
            summary.gnss_disconnects.to_string(),
        );
    }
    bag.metadata("hilrig/end", end)?;
    summary.counts = bag.finish()?;
    Ok(summary)
}

fn print_health(health: &BTreeMap<&'static str, Arc<Health>>, rejects: &Mutex<LidarRejects>) {
    for (name, h) in health {
        // The lidar's decode errors are its rejected packets: say why, per reason.
        let why = match rejects.lock() {
            Ok(r) if *name == "lidar" && !r.is_empty() => format!(" ({})", r.brief()),
            _ => String::new(),
        };
        eprintln!(
            // "queued": handed to the writer (messages, a scan for many lidar packets); what
            // reached the file is the per-topic count printed when the recording ends.
            "{name}: received {}, queued {}, dropped {}, decode errors {}{why}, lost {}, reconnects {}",
            h.received.load(Ordering::Relaxed),
            h.queued.load(Ordering::Relaxed),
            h.dropped.load(Ordering::Relaxed),
            h.decode_errors.load(Ordering::Relaxed),
            h.lost.load(Ordering::Relaxed),
            h.reconnects.load(Ordering::Relaxed)
        );
    }
}

fn send_scan(
    tx: &SyncSender<Event>,
    h: &Health,
    frame: &str,
    points: Option<&hilrig_velodyne::Decoder>,
    packets: &[Stamped<hilrig_velodyne::DataPacket>],
) {
    if packets.is_empty() {
        return;
    }
    let encoded: Vec<[u8; 1206]> = packets.iter().map(|p| p.value.encode()).collect();
    let list: Vec<(UtcNanos, &[u8; 1206])> = packets
        .iter()
        .zip(&encoded)
        .map(|(p, e)| (p.sensor.unwrap_or(p.host), e))
        .collect();
    let stamp = list[0].0;
    let publish = packets.last().map_or(stamp, |p| p.host);
    let cdr = msgs::velodyne_scan(stamp, frame, &list);
    send(
        tx,
        h,
        Event {
            topic: crate::bag::topics::VELODYNE_PACKETS,
            ty: &types()["scan"],
            log_time: stamp,
            publish_time: publish,
            cdr,
        },
    );
    if let Some(d) = points {
        let cdr = crate::record::messages::cloud_cdr(d, stamp, frame, &list);
        send(
            tx,
            h,
            Event {
                topic: crate::bag::topics::POINTS,
                ty: &types()["points"],
                log_time: stamp,
                publish_time: publish,
                cdr,
            },
        );
    }
}

/// What the lidar task is set up with.
struct LidarSettings {
    /// Frame id of the messages.
    frame: String,
    /// Where rotations are cut, hundredths of a degree.
    cut: u16,
    /// The rig's model (the packet period that loss is counted in).
    model: Model,
    /// Decoder for /points, if written.
    points: Option<hilrig_velodyne::Decoder>,
}

/// What the lidar task shares with the recorder.
struct LidarShared {
    health: Arc<Health>,
    clocks: Arc<Mutex<BTreeMap<&'static str, ClockEstimator>>>,
    pps: Arc<Mutex<Option<u8>>>,
    rejects: Arc<Mutex<LidarRejects>>,
}

async fn lidar_task(
    mut source: LidarSource,
    settings: LidarSettings,
    tx: SyncSender<Event>,
    shared: LidarShared,
    mut shutdown: tokio::sync::watch::Receiver<bool>,
) {
    let LidarSettings {
        frame,
        cut,
        model,
        points,
    } = settings;
    let h = &shared.health;
    let mut hours = HourResolver::default();
    let mut hour_source = None;
    // Started at the first packet, whose return mode sets the packet period (a dual-return
    // packet covers a third, or half, of a single-return one's time).
    let mut rotation: Option<RotationAssembler> = None;
    let t = types();
    loop {
        let item = tokio::select! {
            item = source.next() => item,
            _ = shutdown.changed() => {
                if let Some(rotation) = rotation.as_mut() {
                    if let Some(done) = rotation.finish() {
                        send_scan(&tx, h, &frame, points.as_ref(), &done.packets);
                    }
                    store_loss(h, rotation.loss());
                }
                return;
            }
        };
        let Ok(item) = item else { continue };
        h.received.fetch_add(1, Ordering::Relaxed);
        match item {
            LidarItem::Position(p) => {
                hours.handle_position(&p.value, p.host);
                if let Ok(mut b) = shared.pps.lock() {
                    *b = Some(p.value.pps_byte);
                }
                let cdr = msgs::raw_packet(p.host, &frame, &p.value.encode());
                send(
                    &tx,
                    h,
                    Event {
                        topic: crate::bag::topics::VELODYNE_POSITION,
                        ty: &t["raw"],
                        log_time: p.host,
                        publish_time: p.host,
                        cdr,
                    },
                );
            }
            LidarItem::Data(d) => {
                let resolved = hours.resolve(d.value.timestamp_us, d.host);
                let synced = match resolved {
                    Some((s, src)) => {
                        let mut c = shared.clocks.lock().unwrap_or_else(|e| e.into_inner());
                        // The hour moving from the host clock to the RMC can shift sensor times
                        // by hours: the pairs from before belong to another line.
                        if hour_source.replace(src).is_some_and(|prev| prev != src) {
                            c.insert("lidar", ClockEstimator::new());
                        }
                        let est = c.entry("lidar").or_default();
                        est.handle(s, d.host);
                        est.model().map_or(s, |m| m.to_host(s))
                    }
                    None => d.host,
                };
                let rotation = rotation.get_or_insert_with(|| {
                    let mode = d.value.return_mode.mode().unwrap_or(ReturnMode::Strongest);
                    let period = hilrig_velodyne::Decoder::new(model).packet_period_us(mode);
                    RotationAssembler::new(cut, period)
                });
                if let Some(done) = rotation.push(Stamped {
                    host: d.host,
                    sensor: Some(synced),
                    value: d.value,
                }) {
                    store_loss(h, rotation.loss());
                    send_scan(&tx, h, &frame, points.as_ref(), &done.packets);
                }
            }
            LidarItem::Rejected { host, port, error } => {
                h.decode_errors.fetch_add(1, Ordering::Relaxed);
                let reason = RejectReason::of(port, &error);
                // Counted among the rejects, not lost as well (when it may be the sensor's).
                if port == hilrig_velodyne::source::PacketPort::Data && reason.may_be_own() {
                    if let Some(r) = rotation.as_mut() {
                        r.loss_mut().rejected(host);
                    }
                }
                let mut r = shared.rejects.lock().unwrap_or_else(|e| e.into_inner());
                let at = hilrig_stamp::civil::iso8601_millis(host);
                if !r.counts.contains_key(&reason) {
                    // The first of each reason at once: on the vehicle, a wrong rig file or a
                    // second sensor on the port should not wait for the end of the drive.
                    eprintln!("lidar: packet received at {at} not recorded: {error} (further ones are counted)");
                }
                r.add(reason, || format!("received at {at}: {error}"));
            }
        }
    }
}

/// Counts a GNSS message that framed but did not decode.
fn undecodable(
    h: &Health,
    undecoded: &Mutex<GnssUndecoded>,
    reason: Undecoded,
    offset: u64,
    host: UtcNanos,
    e: &dyn std::fmt::Display,
) {
    h.decode_errors.fetch_add(1, Ordering::Relaxed);
    let mut u = undecoded.lock().unwrap_or_else(|e| e.into_inner());
    u.add(reason, || {
        format!("stream byte {offset}, received {host}: {e}")
    });
}

/// The counts behind `m`, also after a task holding them panicked (counts stay counts).
fn locked<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The serial port's disconnects and reconnects into its health counters.
fn store_serial(h: &Health, stats: &hilrig_gnss::serial::SerialStats) {
    h.reconnects.store(stats.reconnects, Ordering::Relaxed);
    h.disconnects.store(stats.disconnects, Ordering::Relaxed);
}

/// The lidar's loss counts into its health counters.
fn store_loss(h: &Health, loss: &hilrig_velodyne::LossCounter) {
    h.lost.store(loss.lost, Ordering::Relaxed);
    h.outages.store(loss.outages, Ordering::Relaxed);
    h.time_jumps.store(loss.time_jumps, Ordering::Relaxed);
}

/// What the GNSS task counts beside its health: frames rejected, messages that did not
/// decode, fixes without a time.
struct GnssCounts {
    rejects: Arc<Mutex<GnssRejects>>,
    undecoded: Arc<Mutex<GnssUndecoded>>,
    stream: Arc<Mutex<GnssStream>>,
}

#[allow(
    clippy::too_many_lines,
    reason = "one task's loop: each chunk's frames, the bytes between them, fixes and attitude in the stream's order, and the stop"
)]
async fn gnss_task(
    mut source: hilrig_gnss::serial::SerialSource,
    frame: String,
    tx: SyncSender<Event>,
    h: Arc<Health>,
    clocks: Arc<Mutex<BTreeMap<&'static str, ClockEstimator>>>,
    counts: GnssCounts,
    mut shutdown: tokio::sync::watch::Receiver<bool>,
) {
    let GnssCounts {
        rejects,
        undecoded,
        stream,
    } = counts;
    // Bytes in no frame are recorded too (`/gnss/unframed`): nothing the receiver sent is lost.
    let mut framer = Framer::new().keeping_unframed();
    let mut nmea = NmeaEpochs::default();
    let mut ubx = UbxEpochs::default();
    let mut last_host: Option<UtcNanos> = None;
    // When the last bytes came (of a frame or not).
    let mut last_chunk: Option<UtcNanos> = None;
    let t = types();
    // A fix is sent with the receive time of its epoch's last frame.
    let send_fix = |fix: hilrig_gnss::epoch::Fix, epoch_host: UtcNanos| {
        locked(&stream).count(&fix);
        let Some(time) = fix.time else {
            return;
        };
        let synced = gnss_on_host(&clocks, time, Some(epoch_host));
        if let Some(nav) = crate::record::messages::nav_sat_fix(&fix) {
            send(
                &tx,
                &h,
                Event {
                    topic: crate::bag::topics::GNSS_FIX,
                    ty: &t["fix"],
                    log_time: synced,
                    publish_time: epoch_host,
                    cdr: msgs::nav_sat_fix(time, &frame, &nav),
                },
            );
        }
    };
    // The bytes in no frame the framer has kept, received at `host`, as they came.
    let send_unframed = |framer: &mut Framer, host: UtcNanos| {
        while let Some(run) = framer.take_unframed() {
            send(
                &tx,
                &h,
                Event {
                    topic: crate::bag::topics::GNSS_UNFRAMED,
                    ty: &t["raw"],
                    log_time: host,
                    publish_time: host,
                    cdr: msgs::raw_packet(host, &frame, &run.bytes),
                },
            );
        }
    };
    loop {
        let (chunk, stopping) = tokio::select! {
            c = source.next_chunk() => (c, false),
            _ = shutdown.changed() => {
                // The stream ends here: a frame cut off by the stop is bytes in no frame, as
                // they came, and the frames a bogus length had swallowed behind it are read
                // below like any others (as `record --from` reads a stream's end).
                framer.finish();
                let host = last_chunk.unwrap_or_else(UtcNanos::now);
                (hilrig_gnss::serial::Chunk { host, bytes: Vec::new() }, true)
            }
        };
        store_serial(&h, &source.stats);
        last_chunk = Some(chunk.host);
        framer.push(&chunk.bytes);
        loop {
            let item = framer.next_frame();
            let host = chunk.host;
            // The bytes in no frame before the item (or at the end of the chunk), as they came.
            send_unframed(&mut framer, host);
            let Some(item) = item else { break };
            let epoch_host = last_host.unwrap_or(host);
            let (f, offset) = match item {
                Item::Frame { frame, offset } => (frame, offset),
                Item::Rejected { offset, reason } => {
                    h.decode_errors.fetch_add(1, Ordering::Relaxed);
                    let mut r = rejects.lock().unwrap_or_else(|e| e.into_inner());
                    r.add(reason, || format!("stream byte {offset}, received {host}"));
                    continue;
                }
            };
            last_host = Some(host);
            h.received.fetch_add(1, Ordering::Relaxed);
            let mut fixes = Vec::new();
            let mut attitude = None;
            match f {
                Frame::Nmea(s) => {
                    send(
                        &tx,
                        &h,
                        Event {
                            topic: crate::bag::topics::GNSS_NMEA,
                            ty: &t["nmea"],
                            log_time: host,
                            publish_time: host,
                            cdr: msgs::nmea_sentence(host, &frame, &s),
                        },
                    );
                    match hilrig_gnss::nmea::parse(&s) {
                        Ok(sentence) => {
                            let time = nmea.attitude_time(&sentence);
                            attitude = Some(hilrig_gnss::attitude::from_nmea(&sentence, time));
                            fixes.extend(nmea.push(&sentence));
                        }
                        Err(e) => {
                            undecodable(&h, &undecoded, Undecoded::NmeaFields, offset, host, &e)
                        }
                    }
                }
                Frame::Ubx { class, id, payload } => {
                    let raw = hilrig_gnss::framer::ubx_frame(class, id, &payload);
                    send(
                        &tx,
                        &h,
                        Event {
                            topic: crate::bag::topics::GNSS_UBX,
                            ty: &t["raw"],
                            log_time: host,
                            publish_time: host,
                            cdr: msgs::raw_packet(host, &frame, &raw),
                        },
                    );
                    match hilrig_gnss::ubx::decode(class, id, &payload) {
                        Ok(m) => {
                            fixes.extend(ubx.push(&m));
                            let time = ubx.attitude_time(&m);
                            attitude = Some(hilrig_gnss::attitude::from_ubx(&m, time));
                        }
                        Err(e) => {
                            undecodable(&h, &undecoded, Undecoded::UbxPayload, offset, host, &e)
                        }
                    }
                }
                Frame::Rtcm3 { bytes, .. } => send(
                    &tx,
                    &h,
                    Event {
                        topic: crate::bag::topics::GNSS_RTCM,
                        ty: &t["raw"],
                        log_time: host,
                        publish_time: host,
                        cdr: msgs::raw_packet(host, &frame, &bytes),
                    },
                ),
            }
            // An attitude report at its own UTC on the GNSS clock (one without a time, before
            // the stream showed its date, stays in the raw topics only).
            if let Some(hilrig_gnss::attitude::Reading::Attitude(a)) = attitude {
                if let Some(time) = a.time {
                    let synced = gnss_on_host(&clocks, time, None);
                    send(
                        &tx,
                        &h,
                        Event {
                            topic: crate::bag::topics::GNSS_ATTITUDE,
                            ty: &t["attitude"],
                            log_time: synced,
                            publish_time: host,
                            cdr: msgs::attitude(time, &frame, &a),
                        },
                    );
                }
            }
            for fix in fixes {
                send_fix(fix, epoch_host);
            }
        }
        if stopping {
            // The epoch in progress, as far as it came: written, not dropped.
            if let Some(host) = last_host {
                for fix in nmea.finish().into_iter().chain(ubx.finish()) {
                    send_fix(fix, host);
                }
            }
            locked(&stream).framed_by(&framer);
            return;
        }
    }
}

/// A GNSS time on the host clock through the GNSS clock model; `pair` (the host time the
/// epoch was received at) first teaches the model, as a fix does (an attitude report only
/// reads it).
fn gnss_on_host(
    clocks: &Mutex<BTreeMap<&'static str, ClockEstimator>>,
    time: UtcNanos,
    pair: Option<UtcNanos>,
) -> UtcNanos {
    let mut c = clocks.lock().unwrap_or_else(|e| e.into_inner());
    let est = c.entry("gnss").or_default();
    if let Some(host) = pair {
        est.handle(time, host);
    }
    est.model().map_or(time, |m| m.to_host(time))
}

async fn can_task(
    mut source: hilrig_can::socketcan_source::SocketCanSource,
    tx: SyncSender<Event>,
    h: Arc<Health>,
    mut shutdown: tokio::sync::watch::Receiver<bool>,
) {
    let t = types();
    let iface = source.interface().to_owned();
    loop {
        let f = tokio::select! {
            f = source.next() => f,
            _ = shutdown.changed() => return,
        };
        let Ok(f) = f else { continue };
        h.received.fetch_add(1, Ordering::Relaxed);
        let host = f.host;
        let (topic, ty, cdr) = if f.value.fd {
            (
                crate::bag::topics::CAN_FD_FRAMES,
                &t["raw"],
                msgs::raw_packet(host, &iface, &f.value.encode_socketcan()),
            )
        } else {
            (
                crate::bag::topics::CAN_FRAMES,
                &t["can"],
                msgs::can_frame(host, &iface, &f.value),
            )
        };
        send(
            &tx,
            &h,
            Event {
                topic,
                ty,
                log_time: host,
                publish_time: host,
                cdr,
            },
        );
    }
}
