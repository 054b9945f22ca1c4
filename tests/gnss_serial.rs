//! Live serial through pseudo-terminals (issue 3, item 4): a real receiver log written at 115200
//! baud pace arrives completely, with host stamps, and a port that goes away and comes back (an
//! unplugged USB adapter, simulated by closing the pty and opening a new one behind the same
//! stable symlink, as /dev/serial/by-id/ names work) is survived without restarting the source.

use crate::common;

use hilrig::gnss::serial::SerialSource;
use hilrig::gnss::GnssStream;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

const BAUD: u32 = 115_200;

fn relink(link: &Path, target: &str) {
    let tmp = link.with_extension("new");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp).unwrap();
    std::fs::rename(&tmp, link).unwrap();
}

/// Writes at the pace of a serial line: 10 bits per byte.
fn paced_write(master: &mut std::fs::File, bytes: &[u8]) {
    let chunk = 64;
    let per_chunk = Duration::from_secs_f64(chunk as f64 * 10.0 / f64::from(BAUD));
    let start = std::time::Instant::now();
    for (i, c) in bytes.chunks(chunk).enumerate() {
        master.write_all(c).unwrap();
        let due = start + per_chunk * (i as u32 + 1);
        if let Some(wait) = due.checked_duration_since(std::time::Instant::now()) {
            std::thread::sleep(wait);
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
async fn real_log_at_115200_baud_through_a_pty_survives_unplug() {
    let log = std::fs::read(common::real_data().join("gnss/nmea-rtk.log")).unwrap();
    let split = log.len() / 2;
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("gnss0");
    let (mut master, name) = common::pty();
    relink(&link, &name);
    let mut source = SerialSource::open(link.to_str().unwrap(), BAUD).unwrap();

    let (first, second) = (log[..split].to_vec(), log[split..].to_vec());
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    let link2 = link.clone();
    let writer = std::thread::spawn(move || {
        paced_write(&mut master, &first);
        // Wait until the receiver has everything, then pull the plug.
        rx.recv().unwrap();
        drop(master);
        std::thread::sleep(Duration::from_millis(300));
        // Plugged back in: a new device behind the same stable name.
        let (mut master, name) = common::pty();
        relink(&link2, &name);
        // Give the source time to reopen before sending (data sent to a closed port is lost
        // on real hardware too).
        rx.recv().unwrap();
        paced_write(&mut master, &second);
        std::thread::sleep(Duration::from_millis(200));
    });

    let mut received = Vec::new();
    let mut stamps = Vec::new();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    let mut signalled_first = false;
    let mut signalled_second = false;
    while received.len() < log.len() {
        let chunk = tokio::time::timeout_at(deadline, source.next_chunk())
            .await
            .expect("stream within 30 s");
        stamps.push(chunk.host);
        received.extend_from_slice(&chunk.bytes);
        if !signalled_first && received.len() >= split {
            tx.send(()).unwrap();
            signalled_first = true;
            // Read until the source notices the unplug and reconnects.
            let wait = tokio::time::timeout(Duration::from_secs(10), async {
                while source.stats.reconnects == 0 {
                    // next_chunk only returns with data; poll it briefly to let it reconnect.
                    if let Ok(c) =
                        tokio::time::timeout(Duration::from_millis(50), source.next_chunk()).await
                    {
                        received.extend_from_slice(&c.bytes);
                        stamps.push(c.host);
                    }
                }
            })
            .await;
            assert!(
                wait.is_ok(),
                "the source did not reconnect: {:?}",
                source.stats
            );
            tx.send(()).unwrap();
            signalled_second = true;
        }
    }
    writer.join().unwrap();
    assert!(signalled_second);
    assert_eq!(received.len(), log.len());
    assert!(
        received == log,
        "bytes identical and in order across the unplug"
    );
    assert!(
        stamps.windows(2).all(|w| w[0] <= w[1]),
        "host stamps in order"
    );
    assert_eq!(source.stats.disconnects, 1, "{:?}", source.stats);
    assert_eq!(source.stats.reconnects, 1, "{:?}", source.stats);
    // The fixes are those of the file.
    let decode = |b: &[u8]| {
        let mut s = GnssStream::for_gpsd_log();
        let mut out = Vec::new();
        s.push(b, &mut out);
        s.finish(&mut out);
        out
    };
    assert_eq!(decode(&received), decode(&log));
    println!(
        "{} bytes in {} chunks, {:?}",
        received.len(),
        stamps.len(),
        source.stats
    );
}

#[test]
fn a_port_that_does_not_exist_fails_at_start_with_its_name() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let _g = rt.enter();
    let err = SerialSource::open("/dev/does-not-exist-gnss", BAUD)
        .err()
        .expect("must fail");
    assert!(
        err.to_string()
            .contains("cannot open serial port /dev/does-not-exist-gnss at 115200 baud"),
        "{err}"
    );
}
