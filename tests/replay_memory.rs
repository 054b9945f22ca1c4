//! Issue 14, must-hold 5 (the CI part): replay streams its input, so its peak memory does not
//! grow with the file. A capture and a recording of about 10 MB and 200 MB (the parking
//! drive's lidar packets repeated with advancing times) are replayed as fast as possible with
//! no destinations (every item is read, scheduled and counted), and the peak resident set of
//! each `hilrig replay` process is compared: 190 MB more input may not cost more than 16 MB.
//! Before streaming, replay held the whole file and a decoded copy (432 MB for 215 MB).
//!
//! Peak memory is each replay process's own, from wait4. The multi-GB measurement is
//! `benches/replay_memory.py`.

use crate::common;

use common::*;
use hilrig::capture::{CaptureReader, LinkType, PcapWriter};
use hilrig_stamp::UtcNanos;

/// Calls `each` with the parking drive's lidar frames (Ethernet) and their times, read from the
/// capture as they are needed: the test process stays small, because a child's peak memory as
/// the kernel reports it starts from its parent's size when it was started.
fn for_lidar_frames(each: &mut dyn FnMut(UtcNanos, &[u8]) -> bool) {
    let src = fixture("parking/rep-01/drive.pcapng.zst");
    let mut reader = CaptureReader::new(std::fs::File::open(&src).unwrap()).unwrap();
    while let Some(r) = reader.next_record() {
        let r = r.unwrap();
        if r.link == LinkType::ETHERNET && !each(r.time, r.data) {
            return;
        }
    }
}

/// A pcap of `mb` MB: the frames repeated, each copy after the one before.
fn capture_of(mb: usize, path: &std::path::Path) -> usize {
    let (mut first, mut last) = (None, UtcNanos(0));
    for_lidar_frames(&mut |t, _| {
        first.get_or_insert(t);
        last = t;
        true
    });
    let span = last.0 - first.unwrap().0 + 1_000_000;
    let mut w = PcapWriter::new(
        std::io::BufWriter::new(std::fs::File::create(path).unwrap()),
        LinkType::ETHERNET,
        false,
        true,
    )
    .unwrap();
    let (mut written, mut copy, mut items) = (0usize, 0i64, 0usize);
    while written < mb << 20 {
        for_lidar_frames(&mut |t, f| {
            if written >= mb << 20 {
                return false;
            }
            w.write_packet(UtcNanos(t.0 + copy * span), f).unwrap();
            written += f.len() + 16;
            items += 1;
            true
        });
        copy += 1;
    }
    w.finish().unwrap();
    items
}

/// Peak resident set (KiB) of one `hilrig replay FILE --speed 1e6` process (from wait4, so
/// no other process counts), and the items it replayed.
#[allow(
    clippy::zombie_processes,
    reason = "the child is reaped by wait4, which also gives its resource usage"
)]
fn replay_peak_kib(file: &std::path::Path) -> (i64, u64) {
    use std::io::Read;
    let mut child = std::process::Command::new(hilrig_bin())
        .arg("replay")
        .arg(file)
        .args(["--speed", "1000000"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    let mut status = 0;
    // SAFETY: `usage` is a plain C struct that wait4 fills in; the pid is our own child, which
    // std has not waited for.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let pid = unsafe { libc::wait4(child.id() as i32, &mut status, 0, &mut usage) };
    assert_eq!(pid, child.id() as i32);
    assert!(
        libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0,
        "{}: {stderr}",
        file.display()
    );
    // "replayed N items (M without a destination)": with no destination every item is M.
    let items: u64 = stderr
        .split("items (")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{stderr}"));
    (usage.ru_maxrss, items)
}

#[test]
fn replay_memory_does_not_grow_with_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (small, large) = (dir.path().join("small.pcap"), dir.path().join("large.pcap"));
    let small_items = capture_of(10, &small);
    let large_items = capture_of(200, &large);
    let (small_mcap, large_mcap) = (dir.path().join("small.mcap"), dir.path().join("large.mcap"));
    for (pcap, mcap) in [(&small, &small_mcap), (&large, &large_mcap)] {
        let o = record_from(&demo_rig(), &[pcap], mcap);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let size = |p: &std::path::Path| std::fs::metadata(p).unwrap().len() >> 20;
    let (peak_small_pcap, n) = replay_peak_kib(&small);
    assert_eq!(n as usize, small_items);
    let (peak_small_mcap, n_small_mcap) = replay_peak_kib(&small_mcap);
    let (peak_large_pcap, n) = replay_peak_kib(&large);
    assert_eq!(n as usize, large_items);
    let (peak_large_mcap, n_large_mcap) = replay_peak_kib(&large_mcap);
    assert!(
        n_large_mcap > 15 * n_small_mcap,
        "{n_small_mcap} {n_large_mcap}"
    );
    assert_eq!(
        n_large_mcap as usize, large_items,
        "the recording holds every packet"
    );
    println!(
        "peak RSS: capture {} MB -> {} KiB, {} MB -> {} KiB; recording {} MB -> {} KiB, {} MB -> {} KiB",
        size(&small),
        peak_small_pcap,
        size(&large),
        peak_large_pcap,
        size(&small_mcap),
        peak_small_mcap,
        size(&large_mcap),
        peak_large_mcap
    );
    assert!(size(&large) >= 200 && size(&large_mcap) > 10 * size(&small_mcap));
    for (what, small, large) in [
        ("capture", peak_small_pcap, peak_large_pcap),
        ("recording", peak_small_mcap, peak_large_mcap),
    ] {
        assert!(
            large < small + 16 * 1024,
            "{what}: peak grew from {small} KiB to {large} KiB with 20 times the input"
        );
    }
    // After the measurements (this grows the test process, which children would inherit).
    // Streaming hands over the same items in the same order as reading the whole file did.
    for file in [&small, &small_mcap] {
        let (whole, damage) =
            hilrig::replay::schedule(std::fs::read(file).unwrap(), 2368, 8308).unwrap();
        assert!(damage.is_none());
        let mut streamed = Vec::new();
        let s = hilrig::replay::stream(file, 2368, 8308, &mut |i| {
            streamed.push(i);
            true
        })
        .unwrap();
        assert_eq!((s.out_of_order, s.damage), (0, None));
        assert!(
            streamed == whole,
            "{}: streamed items differ",
            file.display()
        );
    }
}
