//! `hilrig replay` with real sockets and processes (issue 7): a receiver in another process gets
//! every packet byte-identical and in order; GNSS bytes through a pty arrive identical and
//! paced; a replay recorded again gives the same payloads; --speed, --loop, --start/--end and
//! SIGINT behave.

use crate::common;

use hilrig::capture::demux::Packet;
use hilrig::capture::{CaptureReader, Demux, LinkType, PcapngWriter, UtcNanos};
use std::io::{BufRead, Read};
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn udp_payloads(path: &Path) -> Vec<(UtcNanos, u16, Vec<u8>)> {
    let f = std::fs::File::open(path).unwrap();
    let mut d = Demux::new(CaptureReader::new(f).unwrap());
    let mut out = Vec::new();
    while let Some(i) = d.next_item() {
        let i = i.unwrap();
        if let Packet::Udp { dst, payload, .. } = i.packet {
            out.push((i.time, dst.port(), payload.to_vec()));
        }
    }
    out
}

/// A capture in `dir` with a 10 Hz stream of 16 NMEA sentences on a serial interface (1.5 s),
/// and the sentences.
fn nmea_capture(dir: &Path) -> (std::path::PathBuf, Vec<String>) {
    let mut w = PcapngWriter::new(Vec::new(), "test").unwrap();
    let ser = w.add_interface(LinkType::USER0, "/dev/ttyACM0").unwrap();
    let mut sentences = Vec::new();
    for i in 0..16i64 {
        let s = hilrig::gnss::framer::nmea_sentence(&format!(
            "GNGGA,1200{:02}.{}0,4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.0,0042",
            i / 10,
            i % 10
        ));
        w.write_packet(
            ser,
            UtcNanos(1_700_000_000_000_000_000 + i * 100_000_000),
            s.as_bytes(),
        )
        .unwrap();
        sentences.push(s);
    }
    let cap = dir.join("gnss.pcapng");
    std::fs::write(&cap, w.finish().unwrap()).unwrap();
    (cap, sentences)
}

/// A capture in `dir` with `frames` on a SocketCAN interface, 10 ms apart.
fn can_capture(dir: &Path, frames: &[hilrig::capture::CanFrame]) -> std::path::PathBuf {
    let mut w = PcapngWriter::new(Vec::new(), "test").unwrap();
    let can = w.add_interface(LinkType::CAN_SOCKETCAN, "can0").unwrap();
    for (i, f) in frames.iter().enumerate() {
        w.write_packet(
            can,
            UtcNanos(1_700_000_000_000_000_000 + i as i64 * 10_000_000),
            &f.encode_socketcan(),
        )
        .unwrap();
    }
    let cap = dir.join("can.pcapng");
    std::fs::write(&cap, w.finish().unwrap()).unwrap();
    cap
}

/// What a receiver got: data payloads, position payloads, data arrival instants, replay stderr.
type Received = (Vec<Vec<u8>>, Vec<Vec<u8>>, Vec<Instant>, String);

/// Replays `file` to two local sockets and collects what arrives, with arrival instants; the
/// replay must succeed.
fn receive(file: &Path, extra: &[&str], until_quiet: Duration) -> Received {
    let (code, got) = receive_with_status(file, extra, until_quiet);
    assert_eq!(code, Some(0), "{}", got.3);
    got
}

/// [`receive`] with the replay's exit code, whatever it is.
fn receive_with_status(
    file: &Path,
    extra: &[&str],
    until_quiet: Duration,
) -> (Option<i32>, Received) {
    let data = UdpSocket::bind("127.0.0.1:0").unwrap();
    let pos = UdpSocket::bind("127.0.0.1:0").unwrap();
    data.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    pos.set_nonblocking(true).unwrap();
    let child = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(file)
        .arg("--lidar-to")
        .arg(data.local_addr().unwrap().to_string())
        .arg("--position-to")
        .arg(pos.local_addr().unwrap().to_string())
        .args(extra)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (mut d, mut p, mut at) = (Vec::new(), Vec::new(), Vec::new());
    let mut buf = [0u8; 2048];
    let mut last = Instant::now();
    let started = Instant::now();
    while last.elapsed() < until_quiet || started.elapsed() < Duration::from_millis(500) {
        if let Ok(n) = data.recv(&mut buf) {
            d.push(buf[..n].to_vec());
            at.push(Instant::now());
            last = Instant::now();
        }
        while let Ok(n) = pos.recv(&mut buf) {
            p.push(buf[..n].to_vec());
            last = Instant::now();
        }
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        (d, p, at, String::from_utf8_lossy(&out.stderr).into_owned()),
    )
}

#[test]
fn a_truncated_capture_replays_everything_before_the_cut_and_exits_1() {
    let fixture = common::fixture("vlp16_room.pcapng");
    let full = std::fs::read(&fixture).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let cut = dir.path().join("cut.pcapng");
    std::fs::write(&cut, &full[..full.len() * 6 / 10 + 5]).unwrap();
    // What an independent read of the cut file gives before its error.
    let (mut expected, mut positions) = (Vec::new(), 0);
    let mut d = Demux::new(CaptureReader::new(std::fs::File::open(&cut).unwrap()).unwrap());
    let mut failed = false;
    while let Some(i) = d.next_item() {
        match i {
            Ok(i) => {
                if let Packet::Udp { dst, payload, .. } = i.packet {
                    match dst.port() {
                        2368 => expected.push(payload.to_vec()),
                        8308 => positions += 1,
                        _ => {}
                    }
                }
            }
            Err(_) => {
                failed = true;
                break;
            }
        }
    }
    assert!(failed, "the cut file must be damaged");
    assert!(expected.len() > 50, "{}", expected.len());
    let (code, (data, _, _, stderr)) =
        receive_with_status(&cut, &["--speed", "4"], Duration::from_millis(300));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("truncated"), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "the {} items before it",
            expected.len() + positions
        )),
        "{stderr}"
    );
    assert_eq!(data.len(), expected.len());
    assert!(data == expected, "payloads before the cut arrive identical");
}

#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn every_packet_of_a_real_capture_arrives_byte_identical_and_in_order() {
    let file = common::real_data().join("velodyne/hdl32e_monterey.pcap");
    let expected = udp_payloads(&file);
    let (data, pos, _, stderr) = receive(&file, &[], Duration::from_millis(500));
    let want_data: Vec<&Vec<u8>> = expected
        .iter()
        .filter(|e| e.1 == 2368)
        .map(|e| &e.2)
        .collect();
    let want_pos: Vec<&Vec<u8>> = expected
        .iter()
        .filter(|e| e.1 == 8308)
        .map(|e| &e.2)
        .collect();
    assert_eq!(data.len(), want_data.len(), "{stderr}");
    assert!(
        data.iter().zip(&want_data).all(|(a, b)| a == *b),
        "byte-identical, in order"
    );
    assert_eq!(pos.len(), want_pos.len());
    assert!(pos.iter().zip(&want_pos).all(|(a, b)| a == *b));
    println!("{stderr}");
}

/// The largest pacing lag the replay reports for itself ("max X us" on standard error).
fn reported_max_lag(stderr: &str) -> Duration {
    let us: f64 = stderr
        .split("max ")
        .nth(1)
        .and_then(|r| r.split(" us").next())
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no lag report in: {stderr}"));
    Duration::from_secs_f64(us * 1e-6)
}

/// Replays `file` to a socket that takes the kernel's receive time of every datagram
/// (`SO_TIMESTAMPNS`): on loopback that is the moment of sending, whatever the receiving thread
/// is doing. Returns the payloads with those times, and the replay's standard error.
fn receive_stamped(file: &Path, extra: &[&str]) -> (Vec<(Vec<u8>, Duration)>, String) {
    use nix::sys::socket::{recvmsg, setsockopt, sockopt, ControlMessageOwned, MsgFlags};
    use std::os::fd::AsRawFd;
    let data = UdpSocket::bind("127.0.0.1:0").unwrap();
    setsockopt(&data, sockopt::ReceiveTimestampns, &true).unwrap();
    data.set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let child = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(file)
        .arg("--lidar-to")
        .arg(data.local_addr().unwrap().to_string())
        .args(extra)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 2048];
    let mut last = Instant::now();
    let started = Instant::now();
    while last.elapsed() < Duration::from_millis(300)
        || started.elapsed() < Duration::from_millis(500)
    {
        let mut iov = [std::io::IoSliceMut::new(&mut buf)];
        let mut cmsg = nix::cmsg_space!(nix::sys::time::TimeSpec);
        let Ok(msg) = recvmsg::<()>(
            data.as_raw_fd(),
            &mut iov,
            Some(&mut cmsg),
            MsgFlags::empty(),
        ) else {
            continue;
        };
        let stamp = msg.cmsgs().unwrap().find_map(|c| match c {
            ControlMessageOwned::ScmTimestampns(ts) => Some(Duration::from(ts)),
            _ => None,
        });
        let n = msg.bytes;
        got.push((buf[..n].to_vec(), stamp.expect("a kernel receive stamp")));
        last = Instant::now();
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    (got, stderr)
}

#[test]
fn speed_and_window_options() {
    let file = common::fixture("vlp16_room.pcapng");
    let all = udp_payloads(&file);
    let first = all[0].0;
    let data: Vec<_> = all.iter().filter(|e| e.1 == 2368).collect();
    // --start/--end: exactly the packets inside the window.
    let (got, _, _, _) = receive(
        &file,
        &["--start", "0.05", "--end", "0.12"],
        Duration::from_millis(300),
    );
    let want: Vec<&Vec<u8>> = data
        .iter()
        .filter(|e| (50_000_000..=120_000_000).contains(&(e.0 .0 - first.0)))
        .map(|e| &e.2)
        .collect();
    assert_eq!(got.len(), want.len());
    assert!(got.iter().zip(&want).all(|(a, b)| a == *b));
    // --speed 10: the same packets, sent on a schedule ten times as fast as the file's. Item i
    // is due (t_i - t_0) / 10 after the first and is sent between its deadline and the largest
    // lag the replay reports, so the interval between any two sends is the scheduled one within
    // that lag. Judged on the kernel's receive stamps (the send instants on loopback) and the
    // replay's own lag report from the same run, it holds on a loaded machine as on an idle one;
    // a replay that ignored --speed (or pacing) is off by up to the whole 0.2 s (or 21 ms).
    let (got, stderr) = receive_stamped(&file, &["--speed", "10"]);
    assert_eq!(got.len(), data.len());
    assert!(got.iter().zip(&data).all(|(a, b)| a.0 == b.2), "in order");
    let lag = reported_max_lag(&stderr);
    let slack = lag + Duration::from_micros(100);
    for (k, ((_, at), want)) in got.iter().zip(&data).enumerate() {
        let sent = at.abs_diff(got[0].1);
        let due = Duration::from_nanos((want.0 .0 - data[0].0 .0) as u64) / 10;
        assert!(
            sent + slack >= due && sent <= due + slack,
            "packet {k} sent {sent:?} after the first, due {due:?} (replay's max lag {lag:?})"
        );
    }
}

#[test]
fn loop_runs_until_sigint_and_then_finishes_cleanly() {
    let file = common::fixture("vlp16_room.pcapng");
    let n = udp_payloads(&file).iter().filter(|e| e.1 == 2368).count();
    let data = UdpSocket::bind("127.0.0.1:0").unwrap();
    data.set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let child = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(&file)
        .args(["--loop", "--speed", "4", "--lidar-to"])
        .arg(data.local_addr().unwrap().to_string())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut got = 0;
    let mut buf = [0u8; 2048];
    let t0 = Instant::now();
    while got < 3 * n && t0.elapsed() < Duration::from_secs(10) {
        if data.recv(&mut buf).is_ok() {
            got += 1;
        }
    }
    assert!(
        got >= 3 * n,
        "looped: {got} packets of a {n}-packet capture"
    );
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "Ctrl-C ends cleanly");
    assert!(String::from_utf8_lossy(&out.stderr).contains("lag p50"));
}

#[test]
fn gnss_bytes_through_a_pty_arrive_identical_and_paced() {
    // A 10 Hz NMEA stream on a serial interface of a capture, 1.5 s long.
    let dir = tempfile::tempdir().unwrap();
    let (cap, sentences) = nmea_capture(dir.path());
    let expected = sentences.concat().into_bytes();
    let mut child = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(&cap)
        .args(["--gnss-to", "pty"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.as_mut().unwrap())
        .read_line(&mut line)
        .unwrap();
    let path = line
        .trim()
        .strip_prefix("gnss pty: ")
        .expect("the pty path is printed")
        .to_owned();
    let mut tty = std::fs::File::open(&path).unwrap();
    let mut got = Vec::new();
    let mut arrivals = Vec::new();
    let mut buf = [0u8; 256];
    while got.len() < expected.len() {
        // EIO once the replay has closed the pty: the end of the stream.
        let n = tty.read(&mut buf).unwrap_or(0);
        if n == 0 {
            break;
        }
        got.extend_from_slice(&buf[..n]);
        arrivals.push((got.len(), Instant::now()));
    }
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    assert_eq!(got, expected, "bytes identical");
    // Sentences at their original times: the last is due 1.5 s after the first and is written no
    // earlier (a replay that wrote the stream at once would deliver it in milliseconds). The
    // first one may be read late if this reader wakes late, by far less than the 200 ms allowed;
    // how late the replay itself was, it reports.
    let span = arrivals.last().unwrap().1.duration_since(arrivals[0].1);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        span + Duration::from_millis(200) >= Duration::from_millis(1500),
        "span {span:?}; {stderr}"
    );
    // And it says how far behind its schedule it fell (printed, not judged: that is the
    // machine's business, measured in benches/replay_pacing.py).
    println!("replay's max lag: {:?}", reported_max_lag(&stderr));
}

#[test]
fn a_replay_recorded_again_gives_the_same_payloads() {
    // The recorder listens; the replay plays the fixture into it.
    let dir = tempfile::tempdir().unwrap();
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let pport = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let rig = dir.path().join("rig.toml");
    std::fs::write(&rig, format!("name = \"roundtrip\"\n[lidar]\nmodel = \"vlp16\"\nbind = \"127.0.0.1\"\ndata_port = {port}\nposition_port = {pport}\n")).unwrap();
    let out = dir.path().join("rt.mcap");
    let rec = Command::new(common::hilrig_bin())
        .arg("record")
        .arg("--rig")
        .arg(&rig)
        .arg("-o")
        .arg(&out)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let active = std::path::PathBuf::from(format!("{}.active", out.display()));
    let t0 = Instant::now();
    while !active.exists() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    let fixture = common::fixture("vlp16_room.pcapng");
    let st = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(&fixture)
        .args([
            "--lidar-to",
            &format!("127.0.0.1:{port}"),
            "--position-to",
            &format!("127.0.0.1:{pport}"),
        ])
        .output()
        .unwrap();
    assert!(st.status.success());
    std::thread::sleep(Duration::from_millis(300));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(rec.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    assert!(rec.wait_with_output().unwrap().status.success());
    // Replaying the recording itself must produce the fixture's payloads again.
    let (data, pos, _, _) = receive(&out, &[], Duration::from_millis(300));
    let want = udp_payloads(&fixture);
    let want_data: Vec<&Vec<u8>> = want.iter().filter(|e| e.1 == 2368).map(|e| &e.2).collect();
    assert_eq!(data.len(), want_data.len());
    assert!(
        data.iter().zip(&want_data).all(|(a, b)| a == *b),
        "same payloads after capture -> replay -> record -> replay"
    );
    assert_eq!(pos.len(), want.iter().filter(|e| e.1 == 8308).count());
}

#[test]
fn now_rewrites_sensor_time_pps_and_rmc_to_the_present() {
    let file = common::fixture("vlp16_room.pcapng");
    let before = UtcNanos::now();
    let (data, pos, _, _) = receive(&file, &["--now"], Duration::from_millis(300));
    let after = UtcNanos::now();
    assert_eq!(pos.len(), 1);
    let p = hilrig::velodyne::PositionPacket::decode(&pos[0]).unwrap();
    assert_eq!(
        hilrig::velodyne::PpsStatus::from_byte(p.pps_byte, true),
        hilrig::velodyne::PpsStatus::Locked
    );
    let rmc = p.rmc().expect("an RMC").expect("valid");
    let t = rmc.utc().unwrap();
    assert!(
        t.0 >= before.0 - 2_000_000_000 && t.0 <= after.0,
        "RMC time {t} is now ({before}..{after})"
    );
    // Data packets: microseconds past the current hour, within the replay's span.
    let toh = u32::from_le_bytes([data[0][1200], data[0][1201], data[0][1202], data[0][1203]]);
    let resolved = hilrig::velodyne::clock::resolve_toh(toh, after);
    assert!(
        resolved.0 >= before.0 - 1_000_000 && resolved.0 <= after.0,
        "packet time {resolved} is now"
    );
}

/// A capture of `n` VLP-16 data packets (the room fixture's, repeated) `every` apart.
fn long_capture(n: usize, every: Duration) -> Vec<u8> {
    use hilrig::capture::writer::udp_ethernet_frame;
    use std::net::{Ipv4Addr, SocketAddrV4};
    let payloads: Vec<Vec<u8>> = udp_payloads(&common::fixture("vlp16_room.pcapng"))
        .into_iter()
        .filter(|e| e.1 == 2368)
        .map(|e| e.2)
        .collect();
    let mut w = PcapngWriter::new(Vec::new(), "test").unwrap();
    let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
    let ep = |ip: u8| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, ip), 2368);
    for k in 0..n {
        let t = UtcNanos(1_700_000_000_000_000_000 + (every.as_nanos() * k as u128) as i64);
        let frame = udp_ethernet_frame(ep(201), ep(77), &payloads[k % payloads.len()]);
        w.write_packet(eth, t, &frame).unwrap();
    }
    w.finish().unwrap()
}

/// At 1x over 3 s and 1500 packets, every packet leaves at its time in the file, measured from
/// the first, within the lag the replay reports: deadlines are absolute, so nothing drifts (a
/// replay that slept from item to item would fall behind by its per-item overhead, 1500 times).
#[test]
fn one_x_replay_keeps_the_file_s_time_over_a_long_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("long.pcapng");
    let every = Duration::from_millis(2);
    std::fs::write(&file, long_capture(1500, every)).unwrap();
    let (got, stderr) = receive_stamped(&file, &[]);
    assert_eq!(got.len(), 1500, "{stderr}");
    let lag = reported_max_lag(&stderr);
    let slack = lag + Duration::from_micros(100);
    let mut worst = Duration::ZERO;
    for (k, (_, at)) in got.iter().enumerate() {
        let sent = at.abs_diff(got[0].1);
        let due = every * k as u32;
        worst = worst.max(sent.abs_diff(due));
        assert!(
            sent + slack >= due && sent <= due + slack,
            "packet {k} sent {sent:?} after the first, due {due:?} (replay's max lag {lag:?})"
        );
    }
    println!("worst deviation from the file's time {worst:?}; replay's max lag {lag:?}");
}

/// `--gnss-to DEVICE --baud B` on a real serial device's stand-in (a pty's slave side): the
/// bytes arrive identical, and no faster than the line carries them. 16 sentences of about
/// 85 bytes every 100 ms at 4800 baud (480 bytes/s, 177 ms a sentence) are line-bound: the last
/// byte cannot arrive before all bytes after the first sentence have crossed the line.
#[test]
fn gnss_to_a_serial_device_is_paced_at_its_baud_rate() {
    let dir = tempfile::tempdir().unwrap();
    let (cap, sentences) = nmea_capture(dir.path());
    let expected = sentences.concat().into_bytes();
    let first_len = sentences[0].len();
    let (mut master, device) = common::pty();
    let mut child = Command::new(common::hilrig_bin())
        .arg("replay")
        .arg(&cap)
        .args(["--gnss-to", &device, "--baud", "4800"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut got = Vec::new();
    let mut arrivals = Vec::new();
    let mut buf = [0u8; 256];
    let t0 = Instant::now();
    while got.len() < expected.len() && t0.elapsed() < Duration::from_secs(20) {
        // The master reads EIO while no one has the device open: before the replay opens it
        // and after it has closed it.
        match master.read(&mut buf) {
            Ok(n) if n > 0 => {
                got.extend_from_slice(&buf[..n]);
                arrivals.push(Instant::now());
            }
            _ => {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        }
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(got, expected, "bytes identical");
    let line = Duration::from_secs_f64((expected.len() - first_len) as f64 * 10.0 / 4800.0);
    let span = arrivals.last().unwrap().duration_since(arrivals[0]);
    // 200 ms for this reader waking late on the first bytes (see the pty test above).
    assert!(
        span + Duration::from_millis(200) >= line,
        "span {span:?}, the line needs {line:?}; {stderr}"
    );
}

/// `--can-to IFACE`: the frames of a capture's SocketCAN interface go out on a CAN interface,
/// identical and in order. Needs `vcan0` (a kernel module this machine may lack).
#[test]
#[cfg_attr(
    not(hilrig_vcan),
    ignore = "no vcan0 interface on this machine (the vcan kernel module is missing): did not run"
)]
fn can_frames_go_out_on_a_can_interface() {
    use hilrig::capture::CanFrame;
    let frames: Vec<CanFrame> = (0..20u32)
        .map(|i| CanFrame::new(0x100 + i, i % 2 == 1, &[i as u8; 8]).unwrap())
        .collect();
    let _vcan0 = common::vcan0();
    let dir = tempfile::tempdir().unwrap();
    let cap = can_capture(dir.path(), &frames);
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let mut rx = hilrig::can::socketcan_source::SocketCanSource::open("vcan0").expect("vcan0");
        let child = Command::new(common::hilrig_bin())
            .arg("replay")
            .arg(&cap)
            .args(["--can-to", "vcan0"])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        for f in &frames {
            let got = tokio::time::timeout(Duration::from_secs(5), rx.next())
                .await
                .expect("a frame within 5 s")
                .unwrap();
            assert_eq!(&got.value, f);
        }
        assert!(child.wait_with_output().unwrap().status.success());
    });
}

/// CAN frames recorded into an MCAP come back out of it as they were: standard and extended
/// ids, remote frames, data (what `--can-to` then sends).
#[test]
fn can_frames_replayed_from_a_recording_are_the_captured_ones() {
    use hilrig::capture::CanFrame;
    let frames = vec![
        CanFrame::new(0x123, false, &[1, 2, 3]).unwrap(),
        CanFrame::new(0x18DA_F110, true, &[0xAA; 8]).unwrap(),
        CanFrame::new_remote(0x321, false, 4).unwrap(),
        CanFrame::new(0x7FF, false, &[]).unwrap(),
    ];
    let dir = tempfile::tempdir().unwrap();
    let cap = can_capture(dir.path(), &frames);
    let out = dir.path().join("can.mcap");
    let st = common::record_from(&common::demo_rig(), &[&cap], &out);
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    let (items, damage) = hilrig::replay::load(&out, 2368, 8308).unwrap();
    assert!(damage.is_none());
    let got: Vec<CanFrame> = items
        .into_iter()
        .filter_map(|i| match i.payload {
            hilrig::replay::Payload::Can(f) => Some(f),
            _ => None,
        })
        .collect();
    assert_eq!(got, frames);
}

/// A CAN FD frame in a recording (a raw packet on /can/fd_frames): the CAN sink sends classic
/// frames only, so replay counts it, says so and exits 1 instead of passing over it.
#[test]
fn a_recorded_can_fd_frame_that_replay_cannot_send_is_counted_and_exit_1() {
    use hilrig::capture::CanFrame;
    let frames = vec![
        CanFrame::new(0x123, false, &[1, 2, 3]).unwrap(),
        CanFrame::new_fd(0x124, false, &[7; 24], true).unwrap(),
        CanFrame::new(0x125, false, &[4]).unwrap(),
    ];
    let dir = tempfile::tempdir().unwrap();
    let cap = can_capture(dir.path(), &frames);
    let out = dir.path().join("fd.mcap");
    let st = common::record_from(&common::demo_rig(), &[&cap], &out);
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    // On its own topic: /can/frames holds can_msgs/msg/Frame only (it once took the FD
    // frame's raw packet too, which every reader then decoded as a classic frame).
    let info = hilrig::bag::info::info(&out).unwrap();
    let channel = |topic: &str| {
        info.channels
            .iter()
            .find(|c| c.topic == topic)
            .map(|c| (c.message_type.clone(), c.count))
    };
    assert_eq!(
        channel("/can/frames"),
        Some(("can_msgs/msg/Frame".to_owned(), 2))
    );
    assert_eq!(
        channel("/can/fd_frames"),
        Some(("hilrig_msgs/msg/RawPacket".to_owned(), 1))
    );
    let (code, (_, _, _, stderr)) = receive_with_status(&out, &[], Duration::from_millis(200));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("1 recorded CAN frames were not replayed (CAN FD frames"),
        "{stderr}"
    );
    assert!(stderr.contains("(2 without a destination)"), "{stderr}");
}

/// The room capture with its position frames as early VLP-16 firmware writes them: the IPv4
/// total length of a data packet (1234) in a 554-byte frame, the UDP length right. Returns the
/// file and the original position payloads.
fn quirky_position_frames(dir: &Path) -> (std::path::PathBuf, Vec<Vec<u8>>) {
    let src = common::fixture("vlp16_room.pcapng");
    let mut r = CaptureReader::new(std::fs::File::open(&src).unwrap()).unwrap();
    let mut w = PcapngWriter::new(Vec::new(), "hilrig test").unwrap();
    let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
    let mut positions = Vec::new();
    while let Some(rec) = r.next_record() {
        let rec = rec.unwrap();
        let mut frame = rec.data.to_vec();
        // Ethernet (14) + IPv4 (20) + UDP: destination port at 36..38.
        if frame.len() == 554 && u16::from_be_bytes([frame[36], frame[37]]) == 8308 {
            positions.push(frame[42..].to_vec());
            frame[16..18].copy_from_slice(&1234u16.to_be_bytes());
        }
        w.write_packet(eth, rec.time, &frame).unwrap();
    }
    assert!(!positions.is_empty(), "the fixture has position frames");
    let out = dir.join("quirky.pcapng");
    std::fs::write(&out, w.finish().unwrap()).unwrap();
    (out, positions)
}

/// Early VLP-16 firmware's position frames (IPv4 total length 1234 in 554 bytes): decoded, with
/// the hour and the PPS state from their RMC as from the sound capture, counted as a firmware
/// quirk, and sent by `replay`; a frame really cut by the snap length is still rejected and
/// counted as such.
#[test]
fn position_frames_with_a_data_packet_s_ipv4_length_are_read_and_replayed() {
    let dir = tempfile::tempdir().unwrap();
    let (file, positions) = quirky_position_frames(dir.path());
    let options = hilrig::decode::lidar::LidarOptions::default();
    let (sound, _) = common::decode_file(&common::fixture("vlp16_room.pcapng"), &options);
    let (quirky, points) = common::decode_file(&file, &options);
    assert_eq!(quirky.position_packets, positions.len() as u64);
    assert_eq!(quirky.position_packets, sound.position_packets);
    assert_eq!(quirky.capture.ipv4_length_quirks, positions.len() as u64);
    assert!(quirky.capture.first_ipv4_length_quirk.is_some());
    assert_eq!(
        quirky.capture.skipped_total(),
        0,
        "{:?}",
        quirky.capture.skipped
    );
    assert_eq!(quirky.hour_source, sound.hour_source);
    assert!(quirky.hour_source.is_some());
    assert_eq!(quirky.pps, sound.pps);
    assert!(!points.is_empty());

    let (_, got_positions, _, _) = receive(&file, &[], Duration::from_millis(300));
    assert_eq!(got_positions, positions);

    // The same frame cut by the snap length (a classic pcap whose record says 554 bytes were on
    // the wire and 300 captured) is rejected and counted, not read as a quirk.
    let mut frame = Vec::new();
    let mut r = CaptureReader::new(std::fs::File::open(&file).unwrap()).unwrap();
    while let Some(rec) = r.next_record() {
        let rec = rec.unwrap();
        if rec.data.len() == 554 {
            frame = rec.data.to_vec();
            break;
        }
    }
    let mut pcap = Vec::new();
    for v in [0xa1b2_c3d4u32, 0x0004_0002, 0, 0, 300, 1] {
        pcap.extend_from_slice(&v.to_le_bytes());
    }
    for v in [1_795_255_200u32, 0, 300, 554] {
        pcap.extend_from_slice(&v.to_le_bytes());
    }
    pcap.extend_from_slice(&frame[..300]);
    let cut = dir.path().join("cut.pcap");
    std::fs::write(&cut, pcap).unwrap();
    let mut d = Demux::new(CaptureReader::new(std::fs::File::open(&cut).unwrap()).unwrap());
    while let Some(i) = d.next_item() {
        assert!(
            !matches!(i.unwrap().packet, Packet::Udp { .. }),
            "a cut frame was delivered"
        );
    }
    let stats = d.stats();
    assert_eq!(stats.skipped_total(), 1, "{:?}", stats.skipped);
    assert_eq!(stats.ipv4_length_quirks, 0);
    assert!(stats
        .skipped
        .contains_key(&hilrig::capture::SkipReason::CutBySnapLength));
}

/// Several inputs play as one drive, merged by time: the room capture's UDP frames dealt
/// alternately into two captures (every other frame each, so each file has gaps the other
/// fills) arrive as the original sequence, byte-identical and in the original order.
#[test]
fn two_captures_are_merged_by_time() {
    let fixture = common::fixture("vlp16_room.pcapng");
    let mut reader = CaptureReader::new(std::fs::File::open(&fixture).unwrap()).unwrap();
    let mut parts = [
        PcapngWriter::new(Vec::new(), "test").unwrap(),
        PcapngWriter::new(Vec::new(), "test").unwrap(),
    ];
    let ifaces: Vec<u32> = parts
        .iter_mut()
        .map(|w| w.add_interface(LinkType::ETHERNET, "eth0").unwrap())
        .collect();
    let mut n = 0usize;
    while let Some(r) = reader.next_record() {
        let r = r.unwrap();
        if r.link == LinkType::ETHERNET {
            parts[n % 2]
                .write_packet(ifaces[n % 2], r.time, r.data)
                .unwrap();
            n += 1;
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let [a, b] = parts.map(|w| w.finish().unwrap());
    let (pa, pb) = (dir.path().join("a.pcapng"), dir.path().join("b.pcapng"));
    std::fs::write(&pa, a).unwrap();
    std::fs::write(&pb, b).unwrap();
    let expected = udp_payloads(&fixture);
    let want: Vec<&Vec<u8>> = expected
        .iter()
        .filter(|e| e.1 == 2368)
        .map(|e| &e.2)
        .collect();
    let (data, pos, _, stderr) = receive(&pa, &[pb.to_str().unwrap()], Duration::from_millis(300));
    assert!(n > 100, "{n} frames");
    assert_eq!(data.len(), want.len(), "{stderr}");
    assert!(
        data.iter().zip(&want).all(|(a, b)| a == *b),
        "byte-identical, in the original order"
    );
    assert_eq!(
        pos.len(),
        expected.iter().filter(|e| e.1 == 8308).count(),
        "{stderr}"
    );
}

/// A capture cut by its snap length (`tcpdump -s 1000`): its lidar data packets cannot be
/// replayed, and replay says so per reason and exits 1 instead of sending the position
/// packets alone; a datagram to the lidar's port of another size is counted the same way.
#[test]
fn a_capture_s_damaged_records_are_named_and_exit_1() {
    use hilrig::velodyne::{Model, ReturnMode};
    let drive = common::lidar_capture(Model::Vlp16, ReturnMode::Strongest, 50, true);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("snapped.pcap");
    let (pcap, cut) = common::snapped_pcap(&drive.capture, 1000);
    std::fs::write(&input, pcap).unwrap();
    let s = hilrig::replay::stream(&input, 2368, 8308, &mut |_| true).unwrap();
    assert_eq!(
        s.capture_records.damaged.get("cut_by_snap_length"),
        Some(&cut)
    );
    let (code, (_, _, _, stderr)) = receive_with_status(&input, &[], Duration::from_millis(200));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{cut} capture records were damaged (cut_by_snap_length) and not replayed"
        )),
        "{stderr}"
    );
    // A 100-byte datagram to the data port among whole packets.
    let mut w = hilrig::capture::PcapngWriter::new(Vec::new(), "test").unwrap();
    let eth = w
        .add_interface(hilrig::capture::LinkType::ETHERNET, "eth0")
        .unwrap();
    let ep = |port| std::net::SocketAddrV4::new(std::net::Ipv4Addr::new(192, 168, 1, 201), port);
    let mut r = hilrig::capture::Demux::new(
        hilrig::capture::CaptureReader::new(std::io::Cursor::new(drive.capture.clone())).unwrap(),
    );
    while let Some(item) = r.next_item() {
        let item = item.unwrap();
        let hilrig::capture::demux::Packet::Udp { src, dst, payload } = item.packet else {
            continue;
        };
        let frame = hilrig::capture::writer::udp_ethernet_frame(src, dst, payload);
        w.write_packet(eth, item.time, &frame).unwrap();
    }
    let stray = hilrig::capture::writer::udp_ethernet_frame(ep(2368), ep(2368), &[0u8; 100]);
    w.write_packet(eth, hilrig::stamp::UtcNanos(1), &stray)
        .unwrap();
    let odd = dir.path().join("odd.pcapng");
    std::fs::write(&odd, w.finish().unwrap()).unwrap();
    let s = hilrig::replay::stream(&odd, 2368, 8308, &mut |_| true).unwrap();
    assert_eq!(s.lidar_wrong_size, 1);
    assert!(s.capture_records.damaged.is_empty());
}
