//! The live recorder with real sockets and a real pseudo-terminal (issue 4): lidar packets over
//! loopback UDP and NMEA through a pty are recorded into an MCAP that the Python `mcap` reader
//! opens, with every packet and sentence; SIGINT finishes the file cleanly; after `kill -9` the
//! `.active` file is salvaged by `hilrig recover` losing at most the last 1.5 s.

use crate::common;

use hilrig::capture::demux::Packet;
use hilrig::capture::{CaptureReader, Demux};
use hilrig::gnss::framer::nmea_sentence;
use hilrig::velodyne::{Model, ReturnMode};
use std::io::Write;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

struct Rig {
    _dir: tempfile::TempDir,
    path: PathBuf,
    data: u16,
    position: u16,
    gnss: std::fs::File,
    out: PathBuf,
}

fn rig() -> Rig {
    rig_with("")
}

/// A rig with `extra` TOML appended (e.g. a `[recording]` table).
fn rig_with(extra: &str) -> Rig {
    rig_for("vlp16", extra)
}

/// A rig whose lidar is a `model`, with `extra` TOML appended.
fn rig_for(model: &str, extra: &str) -> Rig {
    let dir = tempfile::tempdir().unwrap();
    let (data, position) = (free_port(), free_port());
    let (master, tty) = common::pty();
    let path = dir.path().join("rig.toml");
    std::fs::write(
        &path,
        format!("name = \"live-test\"\n[lidar]\nmodel = \"{model}\"\nbind = \"127.0.0.1\"\ndata_port = {data}\nposition_port = {position}\n[gnss]\nport = \"{tty}\"\nbaud = 115200\n{extra}"),
    )
    .unwrap();
    let out = dir.path().join("live.mcap");
    Rig {
        path,
        data,
        position,
        gnss: master,
        out,
        _dir: dir,
    }
}

fn start(r: &Rig) -> Child {
    start_with(r, std::process::Stdio::inherit())
}

/// [`start`] with the recorder's standard error going to `stderr`.
fn start_with(r: &Rig, stderr: std::process::Stdio) -> Child {
    let child = Command::new(common::hilrig_bin())
        .arg("record")
        .arg("--rig")
        .arg(&r.path)
        .arg("-o")
        .arg(&r.out)
        .stderr(stderr)
        .spawn()
        .unwrap();
    let active = PathBuf::from(format!("{}.active", r.out.display()));
    let t0 = Instant::now();
    while !active.exists() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(active.exists(), "the recorder did not start");
    std::thread::sleep(Duration::from_millis(300)); // sockets bound after the file is created
    child
}

fn fixture_payloads() -> Vec<(u16, Vec<u8>)> {
    let f = std::fs::File::open(common::fixture("vlp16_room.pcapng")).unwrap();
    let mut d = Demux::new(CaptureReader::new(f).unwrap());
    let mut out = Vec::new();
    while let Some(i) = d.next_item() {
        if let Packet::Udp { dst, payload, .. } = i.unwrap().packet {
            out.push((dst.port(), payload.to_vec()));
        }
    }
    out
}

/// The fixture's data packets (port 2368) only.
fn data_payloads() -> Vec<Vec<u8>> {
    fixture_payloads()
        .into_iter()
        .filter(|(p, _)| *p == 2368)
        .map(|(_, b)| b)
        .collect()
}

fn read(path: &Path) -> serde_json::Value {
    common::mcap_json(path, &["--decode", "/velodyne_packets"])
}

#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn live_recording_of_udp_and_pty_finishes_cleanly_on_sigint() {
    let mut r = rig();
    let mut child = start(&r);
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let payloads = fixture_payloads();
    let (mut data, mut position) = (0, 0);
    for (port, p) in &payloads {
        let to = if *port == 2368 {
            data += 1;
            r.data
        } else {
            position += 1;
            r.position
        };
        sock.send_to(p, ("127.0.0.1", to)).unwrap();
    }
    let mut sentences = 0;
    // The date first, so that the attitude sentences (THS, PASHR: an INS beside the
    // receiver) have a UTC; an invalid THS (mode V) is recorded raw and not as an attitude.
    let mut attitudes = 0;
    r.gnss
        .write_all(
            nmea_sentence("GNRMC,120000.00,A,4807.038,N,01131.000,E,0.0,0.0,251126,,,R").as_bytes(),
        )
        .unwrap();
    sentences += 1;
    for i in 0..50 {
        let body = format!(
            "GNGGA,1200{:02}.{}0,4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042",
            i / 10,
            i % 10
        );
        r.gnss.write_all(nmea_sentence(&body).as_bytes()).unwrap();
        sentences += 1;
        let extra = match i % 10 {
            0 => format!("GNTHS,{}.50,A", 100 + i),
            5 => format!(
                "PASHR,1200{:02}.{}0,{}.25,T,-0.30,+0.31,+0.01,0.029,0.029,0.059,2,1",
                i / 10,
                i % 10,
                100 + i
            ),
            7 => "GNTHS,10.00,V".to_owned(),
            _ => continue,
        };
        r.gnss.write_all(nmea_sentence(&extra).as_bytes()).unwrap();
        sentences += 1;
        attitudes += usize::from(i % 10 != 7);
    }
    r.gnss.flush().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let status = child.wait().unwrap();
    assert!(status.success(), "recorder exit {status}");
    assert!(
        r.out.exists() && !PathBuf::from(format!("{}.active", r.out.display())).exists(),
        "renamed on a clean finish"
    );
    let v = read(&r.out);
    assert_eq!(v["profile"], "ros2");
    let packets: usize = v["messages"]["/velodyne_packets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["packets"].as_array().unwrap().len())
        .sum();
    assert_eq!(packets, data, "every data packet");
    assert_eq!(v["channels"]["/velodyne_position"]["count"], position);
    assert_eq!(v["channels"]["/gnss/nmea"]["count"], sentences);
    // Every epoch a fix, the last one too: it was complete with its last sentence, and is
    // written when the recorder stops.
    assert_eq!(v["channels"]["/gnss/fix"]["count"], 50);
    assert_eq!(v["channels"]["/gnss/attitude"]["count"], attitudes);
    assert_eq!(
        v["channels"]["/gnss/attitude"]["type"],
        "hilrig_msgs/msg/Attitude"
    );
    assert_eq!(v["metadata"]["hilrig/end"]["lidar_dropped"], "0");
    // Pairs since the hour source settled (the fixture's position packet may arrive after the
    // first data packets: then the model restarts on the RMC's hour).
    let pairs: usize = v["metadata"]["clock_sync/lidar"]["pairs"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(pairs > data / 2 && pairs <= data, "pairs {pairs}");
}

#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn kill_9_mid_recording_is_recovered_losing_at_most_one_and_a_half_seconds() {
    let mut r = rig();
    let mut child = start(&r);
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let payloads = data_payloads();
    // Stream at the VLP-16 pace, with NMEA at 10 Hz, then pull the plug.
    let start_t = Instant::now();
    let period = Duration::from_micros(1327);
    let mut i = 0usize;
    let mut next_nmea = Instant::now();
    // A moment between 2 and 3 s, drawn from a seed so that a failure can be reproduced:
    // HILRIG_KILL_SEED=N picks another one (printed below).
    let seed: u64 = std::env::var("HILRIG_KILL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2026);
    let run_for = Duration::from_millis(
        2000 + rand::Rng::random_range(
            &mut <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(seed),
            0..1000,
        ),
    );
    while start_t.elapsed() < run_for {
        let mut p = payloads[i % payloads.len()].clone();
        // Advance the sensor timestamp so packets look like one continuous stream.
        let ts = 1_000_000u32 + (i as u32) * 1327;
        p[1200..1204].copy_from_slice(&ts.to_le_bytes());
        sock.send_to(&p, ("127.0.0.1", r.data)).unwrap();
        i += 1;
        if Instant::now() >= next_nmea {
            r.gnss.write_all(nmea_sentence("GNGGA,120000.00,4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042").as_bytes()).unwrap();
            next_nmea += Duration::from_millis(100);
        }
        let due = start_t + period * i as u32;
        if let Some(w) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(w);
        }
    }
    let killed_at = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let active = PathBuf::from(format!("{}.active", r.out.display()));
    assert!(active.exists());
    let recovered = r.out.with_extension("recovered.mcap");
    common::recover(&active, &recovered);
    let v = read(&recovered);
    let last = v["last_log_time"].as_u64().expect("messages recovered");
    let lost = (killed_at - last) as f64 * 1e-9;
    println!(
        "killed after {run_for:?} (HILRIG_KILL_SEED={seed}), {i} packets sent; recovered up to {lost:.3} s before the kill"
    );
    assert!(lost <= 1.5, "lost {lost} s");
    assert_eq!(v["metadata"]["hilrig"]["rig"], "live-test");
}

/// A full disk, made real with a file-size limit on the recorder process (the kernel then fails
/// writes with EFBIG, as with ENOSPC): the recorder stops with a clear error and its sources'
/// final counts, and everything it wrote before is recovered. Needs only `prlimit` (util-linux, part of every Debian system).
#[test]
fn a_full_disk_stops_the_recorder_with_a_clear_error_and_keeps_what_was_written() {
    let r = rig();
    let child = Command::new("prlimit")
        .arg("--fsize=400000")
        .arg(common::hilrig_bin())
        .arg("record")
        .arg("--rig")
        .arg(&r.path)
        .arg("-o")
        .arg(&r.out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("prlimit (util-linux)");
    let active = PathBuf::from(format!("{}.active", r.out.display()));
    let t0 = Instant::now();
    while !active.exists() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let payloads = data_payloads();
    // Random-looking payloads so compression cannot hide them; far more than 400 kB.
    let mut sent = 0u32;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(6) {
        let mut p = payloads[sent as usize % payloads.len()].clone();
        for (k, b) in p[4..1200].iter_mut().enumerate() {
            *b = (k as u32)
                .wrapping_mul(2_654_435_761)
                .wrapping_add(sent.wrapping_mul(40_503))
                .to_le_bytes()[1];
        }
        for b in 0..12 {
            p[b * 100] = 0xFF;
            p[b * 100 + 1] = 0xEE;
            let az = (((sent * 12 + b as u32) * 40) % 36_000) as u16;
            p[b * 100 + 2..b * 100 + 4].copy_from_slice(&az.to_le_bytes());
        }
        p[1200..1204].copy_from_slice(&(1_000_000 + sent * 1327).to_le_bytes());
        sock.send_to(&p, ("127.0.0.1", r.data)).unwrap();
        sent += 1;
        std::thread::sleep(Duration::from_micros(500));
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("writing MCAP failed") || stderr.contains("File too large"),
        "{stderr}"
    );
    assert!(stderr.contains("run `hilrig recover`"), "{stderr}");
    // The sources' final counts are printed although the writer failed (they used to be
    // lost with the error: the disk fills long before the first periodic health line).
    assert!(stderr.contains("lidar: received "), "{stderr}");
    let recovered = r.out.with_extension("recovered.mcap");
    common::recover(&active, &recovered);
    // Read back with the replay's checked reader (the independent readers are tested on whole
    // recordings in bag_interop).
    let (items, damage) = hilrig::replay::load(&recovered, 2368, 8308).unwrap();
    assert!(damage.is_none(), "{damage:?}");
    let packets = items
        .iter()
        .filter(|i| matches!(i.payload, hilrig::replay::Payload::LidarData(_)))
        .count();
    println!("sent {sent} packets, {packets} recovered from the full disk's file\n{stderr}");
    assert!(
        packets > 100,
        "what was written before the disk filled is readable"
    );
}

fn peak_rss_kib(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

/// Load (issue 4, item 5): lidar packets over loopback UDP on a 20,000 packets/s schedule and
/// NMEA at 20 Hz through a pty, for 5 s. Counted, not timed: every packet and sentence sent is in
/// the file, nothing was dropped, and the recorder's peak RSS stays below 200 MB. The rate the
/// sender reached on this machine is printed beside the result (a slow machine sends fewer
/// packets per second; the claim holds for what it sent); the sustained 30 s figure is
/// `benches/record_load.py`.
#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn a_sustained_load_loses_nothing() {
    const SECONDS: u64 = 5;
    let mut r = rig();
    let mut child = start(&r);
    let pid = child.id();
    let payloads = data_payloads();
    let data_port = r.data;
    let sender = std::thread::spawn(move || {
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        let t0 = Instant::now();
        let mut sent = 0u64;
        // 20 packets every millisecond.
        while t0.elapsed() < Duration::from_secs(SECONDS) {
            for _ in 0..20 {
                let mut p = payloads[(sent % payloads.len() as u64) as usize].clone();
                let ts = ((1_000_000 + sent * 50) % 3_600_000_000) as u32;
                p[1200..1204].copy_from_slice(&ts.to_le_bytes());
                sock.send_to(&p, ("127.0.0.1", data_port)).unwrap();
                sent += 1;
            }
            let due = t0 + Duration::from_micros(sent / 20 * 1000);
            if let Some(w) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(w);
            }
        }
        (sent, t0.elapsed())
    });
    // The date first: a stream without one has no fix with a UTC time (an error).
    r.gnss
        .write_all(
            nmea_sentence("GNRMC,120000.00,A,4807.038,N,01131.000,E,0.0,0.0,251126,,,R").as_bytes(),
        )
        .unwrap();
    let mut sentences = 1u64;
    let t0 = Instant::now();
    let mut peak = 0;
    while t0.elapsed() < Duration::from_secs(SECONDS) {
        let body = format!("GNGGA,12{:02}{:02}.{:02},4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042", sentences / 1200 % 60, sentences / 20 % 60, sentences % 20 * 5);
        r.gnss.write_all(nmea_sentence(&body).as_bytes()).unwrap();
        sentences += 1;
        std::thread::sleep(Duration::from_millis(50));
        if sentences.is_multiple_of(20) {
            peak = peak.max(peak_rss_kib(pid).unwrap_or(0));
        }
    }
    let (sent, took) = sender.join().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    peak = peak.max(peak_rss_kib(pid).unwrap_or(0));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(pid as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let status = child.wait().unwrap();
    let v = common::mcap_json(&r.out, &["--count-scan-packets"]);
    let in_file = v["scan_packets"].as_u64().unwrap();
    println!("sent {sent} packets ({:.0} packets/s reached) and {sentences} sentences; file holds {in_file} packets and {} sentences; peak RSS {:.1} MB", sent as f64 / took.as_secs_f64(), v["channels"]["/gnss/nmea"]["count"], peak as f64 / 1024.0);
    assert!(
        status.success(),
        "the recorder reports drops through its exit status: {status}"
    );
    assert_eq!(in_file, sent, "every lidar packet");
    assert_eq!(
        v["channels"]["/gnss/nmea"]["count"].as_u64().unwrap(),
        sentences,
        "every sentence"
    );
    assert_eq!(v["metadata"]["hilrig/end"]["lidar_dropped"], "0");
    assert!(peak > 0 && peak < 200 * 1024, "peak RSS {peak} KiB");
}

/// A writer that falls behind drops messages rather than stall the sockets, and says so: with a
/// queue of one message between the sources and the writer (`queue_messages = 1`), a burst of
/// 20,000 packets and 2,000 sentences outruns it (each closed chunk is compressed while the
/// sources go on). The drops are counted per source, printed, written into the file's
/// `hilrig/end` metadata, and the exit status is 1; the file is complete and readable.
#[test]
fn a_writer_that_falls_behind_drops_counted_messages_and_exits_1() {
    let mut r = rig_with("[recording]\nqueue_messages = 1\nchunk_size_mib = 1\n");
    let child = start_with(&r, std::process::Stdio::piped());
    let pid = child.id();
    let payloads = data_payloads();
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    for k in 0..20_000u32 {
        let mut p = payloads[k as usize % payloads.len()].clone();
        p[1200..1204].copy_from_slice(&(1_000_000 + k * 50).to_le_bytes());
        sock.send_to(&p, ("127.0.0.1", r.data)).unwrap();
    }
    let mut burst = Vec::new();
    for k in 0..2000u32 {
        burst.extend(nmea_sentence(&format!("GNGGA,12{:02}{:02}.{:02},4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042", k / 1200 % 60, k / 20 % 60, k % 20 * 5)).bytes());
    }
    r.gnss.write_all(&burst).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(pid as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stderr}");
    assert_eq!(
        out.status.code(),
        Some(1),
        "drops give exit status 1: {stderr}"
    );
    let info = hilrig::bag::info::info(&r.out).expect("a complete file");
    let end = &info.metadata["hilrig/end"];
    let dropped: u64 = end
        .iter()
        .filter(|(k, _)| k.ends_with("_dropped"))
        .map(|(_, v)| v.parse::<u64>().unwrap())
        .sum();
    assert!(dropped > 0, "drops counted in the file: {end:?}");
    // The health lines say the same, source by source.
    let printed: u64 = stderr
        .lines()
        .filter_map(|l| l.split("dropped ").nth(1))
        .filter_map(|r| r.split(',').next()?.trim().parse::<u64>().ok())
        .sum();
    assert!(
        printed >= dropped,
        "printed {printed}, in the file {dropped}"
    );
}

/// Sends `payloads` to the rig's data port over loopback, a few at a time (a sensor's pace is
/// far slower than a burst from one thread).
fn send_all(r: &Rig, payloads: &[Vec<u8>]) {
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    for (i, p) in payloads.iter().enumerate() {
        sock.send_to(p, ("127.0.0.1", r.data)).unwrap();
        if i % 50 == 49 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// Stops the recorder with SIGINT; its exit code and standard error.
fn stop(child: Child) -> (Option<i32>, String) {
    std::thread::sleep(Duration::from_millis(500));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    println!("{stderr}");
    (out.status.code(), stderr)
}

/// VLS-128 packets (all four bank flags) over real UDP on loopback, single and dual return:
/// every one is in the recording, byte for byte and in order (read back with the project's
/// checked MCAP reader), nothing rejected, exit 0.
#[test]
fn vls128_packets_over_udp_are_all_recorded() {
    for mode in [ReturnMode::Strongest, ReturnMode::Dual] {
        let r = rig_for("vls128", "");
        let child = start_with(&r, std::process::Stdio::piped());
        let drive = common::lidar_capture(Model::Vls128, mode, 400, false);
        send_all(&r, &drive.payloads);
        let (code, stderr) = stop(child);
        assert_eq!(code, Some(0), "{mode:?}: {stderr}");
        let got = common::lidar_data(&r.out);
        assert_eq!(got.len(), 400, "{mode:?}: data packets");
        assert!(got == drive.payloads, "{mode:?}: byte for byte, in order");
        assert!(
            common::recorded_rejects::<hilrig::record::rejects::RejectReason>(&r.out).is_empty()
        );
        assert!(stderr.contains("lidar: received 400,"), "{stderr}");
    }
}

/// Another sensor's packets and malformed ones on a VLS-128's port, live: the VLS-128's are
/// all recorded; the others are named as they first come, counted per reason in the health
/// line, at the end and in the file's `hilrig/end`, and the exit status is 1.
#[test]
fn another_sensor_s_and_malformed_packets_on_the_live_port_are_counted_and_exit_1() {
    let r = rig_for("vls128", "");
    let child = start_with(&r, std::process::Stdio::piped());
    let drive = common::lidar_capture(Model::Vls128, ReturnMode::Strongest, 200, false);
    let stranger = common::lidar_capture(Model::Vlp16, ReturnMode::Strongest, 3, false);
    let mut stream = drive.payloads.clone();
    for (k, p) in stranger.payloads.iter().enumerate() {
        stream.insert(40 + 30 * k, p.clone());
    }
    stream.insert(150, drive.payloads[9][..600].to_vec());
    stream.insert(170, drive.payloads[9][..1205].to_vec());
    send_all(&r, &stream);
    let (code, stderr) = stop(child);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        common::lidar_data(&r.out) == drive.payloads,
        "every VLS-128 packet"
    );
    for text in [
        "not recorded: product byte 0x22 at byte 1205 is a vlp16's, not the vls128's (0xa1)",
        "decode errors 5 (wrong size 2, another sensor (product byte 0x22) 3)",
        "5 lidar packets were not recorded",
        "  another sensor (product byte 0x22): 3 (first: received at ",
        "  wrong size: 2 (first: received at ",
    ] {
        assert!(stderr.contains(text), "{text:?} in {stderr}");
    }
    let rejects = common::recorded_rejects::<hilrig::record::rejects::RejectReason>(&r.out);
    use hilrig::record::rejects::RejectReason as R;
    assert_eq!(
        rejects.counts.into_iter().collect::<Vec<_>>(),
        [(R::WrongSize, 2), (R::OtherSensor(0x22), 3)]
    );
}

/// `hilrig replay` of a VLS-128 capture (dual return, with a position packet) into the live
/// recorder: every data packet comes through replay and recorder unchanged, and the position
/// packet too.
#[test]
fn a_vls128_capture_replayed_into_the_live_recorder_loses_no_packet() {
    let r = rig_for("vls128", "");
    let child = start_with(&r, std::process::Stdio::piped());
    let drive = common::lidar_capture(Model::Vls128, ReturnMode::Dual, 500, true);
    let capture = r.out.with_extension("pcapng");
    std::fs::write(&capture, &drive.capture).unwrap();
    let st = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(&capture)
        .args([
            "--lidar-to",
            &format!("127.0.0.1:{}", r.data),
            "--position-to",
            &format!("127.0.0.1:{}", r.position),
        ])
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let (code, stderr) = stop(child);
    assert_eq!(code, Some(0), "{stderr}");
    let got = common::lidar_data(&r.out);
    assert_eq!(got.len(), 500, "data packets");
    assert!(got == drive.payloads, "byte for byte, in order");
    let info = hilrig::bag::info::info(&r.out).unwrap();
    let positions = info
        .channels
        .iter()
        .find(|c| c.topic == "/velodyne_position")
        .map_or(0, |c| c.count);
    assert_eq!(positions, 1);
    assert!(common::recorded_rejects::<hilrig::record::rejects::RejectReason>(&r.out).is_empty());
}

/// A sentence whose checksum fails, and a UBX frame whose checksum fails, among good NMEA on the
/// live serial port: the recorder keeps every good sentence, counts and names the two it could
/// not frame (in its output and the file's `hilrig/end` metadata) and exits 1.
#[test]
fn gnss_frames_that_fail_their_checksum_on_the_live_port_are_counted_and_exit_1() {
    let mut r = rig();
    let child = start_with(&r, std::process::Stdio::piped());
    std::thread::sleep(Duration::from_millis(300));
    let mut good = 0u64;
    for i in 0..20 {
        let body = format!(
            "GNGGA,1200{:02}.{}0,4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042",
            i / 10,
            i % 10
        );
        let mut line = nmea_sentence(&body);
        if i == 7 {
            // One character changed after the checksum was taken.
            line = line.replacen("4807.038", "4807.039", 1);
        } else {
            good += 1;
        }
        r.gnss.write_all(line.as_bytes()).unwrap();
        if i == 9 {
            // A checksum that holds over a field that does not read: recorded, not decoded.
            let bad = nmea_sentence(
                "GNGGA,120009.50,48x7.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042",
            );
            r.gnss.write_all(bad.as_bytes()).unwrap();
            good += 1;
        }
        if i == 12 {
            let mut ubx = hilrig::gnss::framer::ubx_frame(0x01, 0x05, &[0u8; 32]);
            let n = ubx.len();
            ubx[n - 1] ^= 0xFF;
            r.gnss.write_all(&ubx).unwrap();
        }
    }
    r.gnss.flush().unwrap();
    let (code, stderr) = stop(child);
    assert_eq!(code, Some(1), "{stderr}");
    for text in [
        "2 GNSS serial frames were not recorded",
        "  NMEA sentence with a wrong checksum: 1 (first: stream byte ",
        "  UBX frame with a wrong checksum: 1 (first: stream byte ",
        "1 GNSS messages are recorded but did not decode",
        "  NMEA sentence whose fields do not read: 1 (first: stream byte ",
    ] {
        assert!(stderr.contains(text), "{text:?} in {stderr}");
    }
    let info = hilrig::bag::info::info(&r.out).unwrap();
    let nmea = info
        .channels
        .iter()
        .find(|c| c.topic == "/gnss/nmea")
        .map_or(0, |c| c.count);
    assert_eq!(nmea, good, "every good sentence is recorded");
    let rejects: hilrig::record::rejects::GnssRejects = common::recorded_rejects(&r.out);
    use hilrig::gnss::framer::RejectReason as F;
    assert_eq!(
        rejects.counts.into_iter().collect::<Vec<_>>(),
        [(F::NmeaChecksum, 1), (F::UbxChecksum, 1)]
    );
}

/// A UBX header whose length is bogus swallows the last epoch the receiver sent before the
/// recorder stops: at the stop the header is bytes in no frame, and the epoch behind it is
/// read and recorded (it was written as unframed bytes, its fix lost).
#[test]
fn the_epoch_a_bogus_length_swallowed_before_the_stop_is_recorded() {
    let mut r = rig();
    let child = start_with(&r, std::process::Stdio::piped());
    std::thread::sleep(Duration::from_millis(300));
    let epoch = |i: u32| {
        let t = format!("1200{i:02}.00");
        [
            format!("GNGGA,{t},4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042"),
            format!("GNRMC,{t},A,4807.038,N,01131.000,E,0.0,0.0,251126,,,R"),
        ]
        .map(|b| nmea_sentence(&b))
        .concat()
    };
    for i in 0..5 {
        r.gnss.write_all(epoch(i).as_bytes()).unwrap();
    }
    let header = [0xB5, 0x62, 0x01, 0x07, 0xE8, 0x03];
    r.gnss.write_all(&header).unwrap();
    r.gnss.write_all(epoch(5).as_bytes()).unwrap();
    r.gnss.flush().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let (code, stderr) = stop(child);
    assert_eq!(code, Some(0), "{stderr}");
    let info = hilrig::bag::info::info(&r.out).unwrap();
    let count = |topic: &str| {
        info.channels
            .iter()
            .find(|c| c.topic == topic)
            .map_or(0, |c| c.count)
    };
    assert_eq!(count("/gnss/fix"), 6, "{stderr}");
    assert_eq!(count("/gnss/nmea"), 12, "{stderr}");
    assert_eq!(
        info.metadata["hilrig/end"]["gnss_unframed_bytes"],
        header.len().to_string(),
        "{stderr}"
    );
}

/// The GNSS port goes away mid-recording (the receiver's cable pulled: the pseudo-terminal's
/// other end closed) and does not come back: what it would have sent is lost, so the recorder
/// says so and exits 1, with the count in `hilrig/end`; what came before is recorded.
#[test]
fn a_gnss_port_that_goes_away_is_counted_and_exit_1() {
    let mut r = rig();
    let child = start_with(&r, std::process::Stdio::piped());
    std::thread::sleep(Duration::from_millis(300));
    let mut gnss = std::mem::replace(&mut r.gnss, std::fs::File::open("/dev/null").unwrap());
    gnss.write_all(
        nmea_sentence("GNRMC,120000.00,A,4807.038,N,01131.000,E,0.0,0.0,251126,,,R").as_bytes(),
    )
    .unwrap();
    gnss.flush().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    drop(gnss);
    std::thread::sleep(Duration::from_millis(500));
    let (code, stderr) = stop(child);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("the GNSS serial port was lost 1 times (0 reopened)"),
        "{stderr}"
    );
    let info = hilrig::bag::info::info(&r.out).unwrap();
    assert_eq!(info.metadata["hilrig/end"]["gnss_disconnects"], "1");
    let nmea = info.channels.iter().find(|c| c.topic == "/gnss/nmea");
    assert_eq!(
        nmea.map(|c| c.count),
        Some(1),
        "what came before is recorded"
    );
}
