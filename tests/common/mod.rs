//! Helpers shared by the integration tests: where the real data and reference tools are, and a
//! sink that keeps decoded points.
#![allow(dead_code)]

pub mod azure;
pub mod gap;
pub mod ray;
pub mod s3;

use hilrig::decode::lidar::{decode_capture, LidarOptions, LidarSummary, PointSink, PointTime};
use hilrig::velodyne::Point;
use std::path::PathBuf;

/// The real-data folder (../shared/data) from `HILRIG_REAL_DATA`.
pub fn real_data() -> PathBuf {
    let dir = std::env::var("HILRIG_REAL_DATA")
        .expect("HILRIG_REAL_DATA was set when the tests were built but is unset now; run .ci/run");
    PathBuf::from(dir)
}

/// The Python of the reference venv from `HILRIG_PYTHON`.
pub fn python() -> PathBuf {
    PathBuf::from(
        std::env::var("HILRIG_PYTHON").expect("HILRIG_PYTHON unset at run time; run .ci/run"),
    )
}

/// The built `hilrig` binary.
pub fn hilrig_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_hilrig"))
}

/// Keeps every point with its packet time.
#[derive(Default)]
pub struct Collect {
    pub points: Vec<(PointTime, Point)>,
}

impl PointSink for Collect {
    fn packet(&mut self, t: PointTime, points: &[Point]) -> std::io::Result<()> {
        self.points.extend(points.iter().map(|p| (t, *p)));
        Ok(())
    }
}

/// Decodes a capture file with the library.
pub fn decode_file(
    path: &std::path::Path,
    options: &LidarOptions,
) -> (LidarSummary, Vec<(PointTime, Point)>) {
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut sink = Collect::default();
    let summary = decode_capture(std::io::BufReader::new(f), options, &mut sink).expect("decode");
    (summary, sink.points)
}

/// A fixture made by this project (fixtures/).
pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// Runs `hilrig decode ARGS`: exit code, stdout, stderr.
pub fn hilrig_decode(args: &[&str]) -> (Option<i32>, String, String) {
    let out = std::process::Command::new(hilrig_bin())
        .arg("decode")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A pseudo-terminal pair in raw mode: the master as a file, and the slave's path (what a
/// serial source opens).
pub fn pty() -> (std::fs::File, String) {
    use nix::fcntl::OFlag;
    use std::os::fd::AsFd;
    use std::os::unix::fs::OpenOptionsExt;
    // Opened close-on-exec in the same call (openpty(3) cannot): a recorder, or any child
    // another test starts meanwhile, would otherwise hold the master, and closing it here
    // would not hang up the terminal.
    let master = nix::pty::posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY | OFlag::O_CLOEXEC)
        .expect("posix_openpt");
    nix::pty::grantpt(&master).expect("grantpt");
    nix::pty::unlockpt(&master).expect("unlockpt");
    let name = nix::pty::ptsname_r(&master).expect("ptsname");
    // Raw mode is the terminal's, set through the slave side once (std opens close-on-exec).
    let slave = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(nix::libc::O_NOCTTY)
        .open(&name)
        .expect("open the slave");
    let mut t = nix::sys::termios::tcgetattr(slave.as_fd()).unwrap();
    nix::sys::termios::cfmakeraw(&mut t);
    nix::sys::termios::tcsetattr(slave.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
    drop(slave);
    (
        std::fs::File::from(std::os::fd::OwnedFd::from(master)),
        name,
    )
}

/// Reads an MCAP with the Python `mcap` reader (CRC validation on) and `rosbags`
/// (tests/interop/mcap_read.py); `args` are the script's options (`--decode TOPIC`, ...).
pub fn mcap_json(path: &std::path::Path, args: &[&str]) -> serde_json::Value {
    let o = std::process::Command::new(python())
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/interop/mcap_read.py"
        ))
        .arg(path)
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "mcap reader failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

/// `hilrig decode --kind gnss LOG --format jsonl`: its attitude records (`"kind":
/// "attitude"`) in stream order, and its stderr (the summary).
pub fn decode_attitudes(log: &std::path::Path) -> (Vec<serde_json::Value>, String) {
    let out = std::process::Command::new(hilrig_bin())
        .args(["decode", "--kind", "gnss", "--format", "jsonl"])
        .arg(log)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let records = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["kind"] == "attitude")
        .collect();
    (records, stderr)
}

/// Foxglove's own MCAP libraries (tests/interop/foxglove/read_mcap.mjs, from
/// `HILRIG_FOXGLOVE`) run over `files`: one JSON line per file on stdout.
pub fn foxglove_read(files: &[&std::path::Path]) -> std::process::Output {
    let dir = PathBuf::from(std::env::var("HILRIG_FOXGLOVE").unwrap());
    std::process::Command::new("node")
        .arg(dir.join("read_mcap.mjs"))
        .args(files)
        .current_dir(&dir)
        .output()
        .expect("run node")
}

/// The demo rig file.
pub fn demo_rig() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/rigs/demo.toml"))
}

/// Runs `hilrig record --rig RIG --from INPUTS... -o OUT` to the end; the caller checks the exit.
pub fn record_from(
    rig: &std::path::Path,
    inputs: &[&std::path::Path],
    out: &std::path::Path,
) -> std::process::Output {
    std::process::Command::new(hilrig_bin())
        .arg("record")
        .arg("--rig")
        .arg(rig)
        .arg("--from")
        .args(inputs)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

/// Runs `hilrig recover CUT -o OUT`, asserts that it succeeded and returns its stderr.
pub fn recover(cut: &std::path::Path, out: &std::path::Path) -> String {
    let o = std::process::Command::new(hilrig_bin())
        .arg("recover")
        .arg(cut)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "recover failed: {stderr}");
    stderr
}

/// A parking drive (fixtures/parking) synthesized here with `extra` appended to its drive file
/// (a `[faults]` table, say), the idealized model, one repetition, then recorded with
/// `record --from`. The files live as long as the value.
#[allow(dead_code)]
pub struct SynthRun {
    pub dir: tempfile::TempDir,
    /// The repetition's directory (capture, surveyed scene, truth).
    pub rep: PathBuf,
    /// The recorded MCAP.
    pub run: PathBuf,
}

#[allow(dead_code)]
pub fn synth_and_record(extra: &str, seed: u64, errors: bool) -> SynthRun {
    synth_and_record_edited(|text| text, extra, seed, errors)
}

/// [`synth_and_record`] with the parking drive file's text passed through `edit` first (to change
/// a stream setting such as the lidar's host jitter).
pub fn synth_and_record_edited(
    edit: impl Fn(String) -> String,
    extra: &str,
    seed: u64,
    errors: bool,
) -> SynthRun {
    let dir = tempfile::tempdir().unwrap();
    let text = edit(std::fs::read_to_string(fixture("parking/drive.toml")).unwrap()).replace(
        "rig = \"../../rigs/demo.toml\"",
        &format!("rig = {:?}", demo_rig().display().to_string()),
    );
    let drive = dir.path().join("drive.toml");
    std::fs::write(&drive, format!("{text}\n{extra}\n")).unwrap();
    let mut cmd = std::process::Command::new(hilrig_bin());
    cmd.args(["synth", "--scene"])
        .arg(fixture("parking/scene.toml"))
        .arg("--drive")
        .arg(&drive)
        .arg("--truth")
        .arg(fixture("parking/idealized.toml"))
        .args(["--reps", "1", "--seed", &seed.to_string(), "-o"])
        .arg(dir.path().join("out"));
    if !errors {
        cmd.arg("--no-errors");
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rep = dir.path().join("out/rep-01");
    let run = dir.path().join("run.mcap");
    let rec = record_from(&demo_rig(), &[&rep.join("drive.pcapng")], &run);
    assert!(
        rec.status.success(),
        "{}",
        String::from_utf8_lossy(&rec.stderr)
    );
    SynthRun { dir, rep, run }
}

/// Runs `hilrig ARGS` and asserts that it succeeded (its stderr in the message if not).
pub fn hilrig_ok(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let out = std::process::Command::new(hilrig_bin())
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "hilrig {:?}: {}",
        args,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Records the parking fixture's repetition `rep` into `dir/run{rep}.mcap` with the demo rig
/// and re-simulates it with each of `models` (fixture model files: "idealized", "truth") in its
/// surveyed scene into `dir/{model}{rep}.mcap`.
pub fn record_and_resim(
    dir: &std::path::Path,
    rep: u32,
    models: &[&str],
) -> (PathBuf, Vec<PathBuf>) {
    let src = fixture(&format!("parking/rep-{rep:02}"));
    let run = dir.join(format!("run{rep}.mcap"));
    hilrig_ok(&[
        "record".as_ref(),
        "--rig".as_ref(),
        demo_rig().as_os_str(),
        "--from".as_ref(),
        src.join("drive.pcapng.zst").as_os_str(),
        "-o".as_ref(),
        run.as_os_str(),
    ]);
    let sims = models
        .iter()
        .map(|model| {
            let sim = dir.join(format!("{model}{rep}.mcap"));
            resim(
                &run,
                &src.join("scene.toml"),
                &fixture(&format!("parking/{model}.toml")),
                &sim,
            );
            sim
        })
        .collect();
    (run, sims)
}

/// Re-simulates `run` in `scene` with the model file `model` into `out` and asserts that it
/// succeeded.
pub fn resim(
    run: &std::path::Path,
    scene: &std::path::Path,
    model: &std::path::Path,
    out: &std::path::Path,
) {
    hilrig_ok(&[
        "resim".as_ref(),
        run.as_os_str(),
        "--scene".as_ref(),
        scene.as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
}

/// Waits until `ready` holds, at most a minute, else fails naming `what` did not start.
pub fn wait_until(what: &str, ready: impl Fn() -> bool) {
    let started = std::time::Instant::now();
    while !ready() {
        assert!(
            started.elapsed() < std::time::Duration::from_secs(60),
            "{what} did not start"
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// An object store's test client (`s3_objects.py`, `azure_objects.py`): `op` (put or get) of the
/// tree `dir` under `bucket/prefix` on the server at `endpoint`; its standard output.
pub fn objects_script(
    script: &str,
    endpoint: &str,
    op: &str,
    bucket: &str,
    prefix: &str,
    dir: &std::path::Path,
) -> Vec<u8> {
    interop_script(
        script,
        &[
            endpoint.as_ref(),
            op.as_ref(),
            bucket.as_ref(),
            prefix.as_ref(),
            dir.as_os_str(),
        ],
    )
}

/// Runs `tests/interop/SCRIPT` with the reference venv's Python and `args`; asserts it
/// succeeded and returns its standard output.
pub fn interop_script(script: &str, args: &[&std::ffi::OsStr]) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/interop")
        .join(script);
    let out = std::process::Command::new(python())
        .arg(&path)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{script}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// A generated lidar capture: the pcapng bytes and the data packets' payloads in it, in order.
pub struct LidarCapture {
    pub capture: Vec<u8>,
    pub payloads: Vec<Vec<u8>>,
}

/// `packets` data packets of `model` in `mode` as the project's encoder writes them (the
/// VLS-128's four bank flags, the HDL-64E's two), turning at 10 Hz from 2025-11-21T04:40Z on,
/// each to UDP port 2368 of an Ethernet pcapng, received 100 µs after its first firing; with
/// `rmc`, a position packet (port 8308, a valid GPRMC) first.
pub fn lidar_capture(
    model: hilrig::velodyne::Model,
    mode: hilrig::velodyne::ReturnMode,
    packets: usize,
    rmc: bool,
) -> LidarCapture {
    lidar_capture_at(model, mode, packets, rmc, 1_763_700_000_000_000_000)
}

/// [`lidar_capture`] starting at `t0` (UTC ns): a capture's clock that was never set reads 1970.
pub fn lidar_capture_at(
    model: hilrig::velodyne::Model,
    mode: hilrig::velodyne::ReturnMode,
    packets: usize,
    rmc: bool,
    t0: i64,
) -> LidarCapture {
    use hilrig::capture::writer::udp_ethernet_frame;
    use hilrig::capture::{LinkType, PcapngWriter, UtcNanos};
    use hilrig::velodyne::{Channel, PacketEncoder, PositionPacket, PpsStatus, Sequence};
    use std::net::{Ipv4Addr, SocketAddrV4};
    let ep = |port| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), port);
    let mut w = PcapngWriter::new(Vec::new(), "hilrig tests/common").unwrap();
    let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
    // The sensor's time of the first firing: the true time (the capture's clock may be unset).
    let sensor0 = 1_763_700_000_000_000_000i64;
    if rmc {
        let body = "GPRMC,044000.00,A,4807.0380,N,01131.0000,E,0.0,0.0,211125,,,A";
        let toh = (UtcNanos(sensor0).nanos_past_hour() / 1000) as u32;
        let p = PositionPacket::new(toh, PpsStatus::Locked, &nmea(body));
        w.write_packet(
            eth,
            UtcNanos(t0 - 1_000_000),
            &udp_ethernet_frame(ep(8308), ep(8308), &p.encode()),
        )
        .unwrap();
    }
    let seq_us = model.timing().sequence_us;
    let mut enc = PacketEncoder::new(model, mode);
    let mut payloads = Vec::new();
    let mut k = 0usize;
    let mut first_of_packet = 0usize;
    while payloads.len() < packets {
        let t_ns = (k as f64 * seq_us * 1000.0) as i64;
        let strongest: Vec<Channel> = (0..model.lasers())
            .map(|l| Channel {
                distance: (1000 + (k * 7 + l * 13) % 20_000) as u16,
                reflectivity: (k + l) as u8,
            })
            .collect();
        let last = (mode == hilrig::velodyne::ReturnMode::Dual).then(|| {
            strongest
                .iter()
                .map(|c| Channel {
                    distance: c.distance + 300 * (k % 2) as u16,
                    ..*c
                })
                .collect()
        });
        let seq = Sequence {
            azimuth: ((t_ns as f64 * 1e-9 * 10.0 * 36_000.0) as u64 % 36_000) as u16,
            strongest,
            last,
        };
        let toh = (UtcNanos(sensor0 + t_ns).nanos_past_hour() / 1000) as u32;
        if k.is_multiple_of(enc.sequences_per_packet()) {
            first_of_packet = k;
        }
        if let Some(p) = enc.push(&seq, toh).unwrap() {
            let first_ns = (first_of_packet as f64 * seq_us * 1000.0) as i64;
            let bytes = p.encode().to_vec();
            w.write_packet(
                eth,
                UtcNanos(t0 + first_ns + 100_000),
                &udp_ethernet_frame(ep(2368), ep(2368), &bytes),
            )
            .unwrap();
            payloads.push(bytes);
        }
        k += 1;
    }
    LidarCapture {
        capture: w.finish().unwrap(),
        payloads,
    }
}

/// An NMEA sentence with its checksum and line end.
pub fn nmea(body: &str) -> String {
    hilrig::gnss::framer::nmea_sentence(body)
}

/// The lidar data packets of a capture or recording, in the order replay would send them (the
/// project's checked MCAP reader for recordings).
pub fn lidar_data(path: &std::path::Path) -> Vec<Vec<u8>> {
    let (items, damage) = hilrig::replay::load(path, 2368, 8308).unwrap();
    assert!(damage.is_none(), "{}: {damage:?}", path.display());
    items
        .into_iter()
        .filter_map(|i| match i.payload {
            hilrig::replay::Payload::LidarData(b) => Some(b),
            _ => None,
        })
        .collect()
}

/// What a recording says it left out of one kind (its `hilrig/end` metadata): the lidar
/// packets (`LidarRejects`) or the GNSS serial frames (`GnssRejects`).
pub fn recorded_rejects<R: hilrig::record::rejects::Reason>(
    path: &std::path::Path,
) -> hilrig::record::rejects::Rejects<R> {
    let info = hilrig::bag::info::info(path).unwrap();
    let end = info
        .metadata
        .get("hilrig/end")
        .expect("hilrig/end metadata");
    hilrig::record::rejects::Rejects::from_metadata(end)
        .unwrap()
        .expect("reject counts in hilrig/end")
}

/// `capture` (UDP only) rewritten as a classic pcap whose snap length is `snap`, as `tcpdump
/// -s SNAP` writes it: frames longer than that cut. Returns the file and how many were cut
/// (panics when none stayed whole).
pub fn snapped_pcap(capture: &[u8], snap: usize) -> (Vec<u8>, u64) {
    // Classic pcap, microseconds, Ethernet.
    let mut pcap = Vec::new();
    pcap.extend_from_slice(&0xa1b2_c3d4u32.to_le_bytes());
    pcap.extend_from_slice(&2u16.to_le_bytes());
    pcap.extend_from_slice(&4u16.to_le_bytes());
    pcap.extend_from_slice(&[0; 8]);
    pcap.extend_from_slice(&(snap as u32).to_le_bytes());
    pcap.extend_from_slice(&1u32.to_le_bytes());
    let mut r = hilrig::capture::Demux::new(
        hilrig::capture::CaptureReader::new(std::io::Cursor::new(capture.to_vec())).unwrap(),
    );
    let (mut cut, mut whole) = (0u64, 0u64);
    while let Some(item) = r.next_item() {
        let item = item.unwrap();
        let hilrig::capture::demux::Packet::Udp { src, dst, payload } = item.packet else {
            panic!("only UDP in the capture");
        };
        let frame = hilrig::capture::writer::udp_ethernet_frame(src, dst, payload);
        let kept = &frame[..frame.len().min(snap)];
        if kept.len() < frame.len() {
            cut += 1;
        } else {
            whole += 1;
        }
        let us = item.time.0 / 1000;
        pcap.extend_from_slice(&((us / 1_000_000) as u32).to_le_bytes());
        pcap.extend_from_slice(&((us % 1_000_000) as u32).to_le_bytes());
        pcap.extend_from_slice(&(kept.len() as u32).to_le_bytes());
        pcap.extend_from_slice(&(frame.len() as u32).to_le_bytes());
        pcap.extend_from_slice(kept);
    }
    assert!(whole > 0, "some frames fit");
    (pcap, cut)
}

/// `vcan0` is one interface for the whole test process (the tests are one binary): a test that
/// sends on it and asserts on exactly the frames it receives holds this meanwhile, so that no
/// other test's frames arrive in between.
pub fn vcan0() -> std::sync::MutexGuard<'static, ()> {
    static VCAN0: std::sync::Mutex<()> = std::sync::Mutex::new(());
    VCAN0
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}
