//! The live UDP source on real loopback sockets (issue 2, item 7): every packet of a capture sent
//! to the source arrives, byte-identical, in order, with a host receive stamp from the kernel.

use crate::common;

use hilrig::capture::demux::Packet;
use hilrig::capture::{CaptureReader, Demux};
use hilrig::velodyne::source::{LidarItem, LidarSource, DEFAULT_RECV_BUFFER};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

fn payloads(path: &Path) -> Vec<(u16, Vec<u8>)> {
    let f = std::fs::File::open(path).unwrap();
    let mut d = Demux::new(CaptureReader::new(std::io::BufReader::new(f)).unwrap());
    let mut out = Vec::new();
    while let Some(item) = d.next_item() {
        if let Packet::Udp { dst, payload, .. } = item.unwrap().packet {
            out.push((dst.port(), payload.to_vec()));
        }
    }
    out
}

fn now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i64
}

async fn send_and_receive(path: &Path) {
    let packets = payloads(path);
    let lo: SocketAddr = "127.0.0.1:0".parse().unwrap();
    let mut source = LidarSource::bind(lo, Some(lo), None, DEFAULT_RECV_BUFFER).unwrap();
    let data_addr = source.data_socket().local_addr().unwrap();
    let pos_addr = source.position_socket().unwrap().local_addr().unwrap();
    println!(
        "receive buffer granted: {} bytes",
        source.data_socket().recv_buffer()
    );
    let expected_data: Vec<Vec<u8>> = packets
        .iter()
        .filter(|(p, _)| *p == 2368)
        .map(|(_, b)| b.clone())
        .collect();
    let expected_pos: Vec<Vec<u8>> = packets
        .iter()
        .filter(|(p, _)| *p == 8308)
        .map(|(_, b)| b.clone())
        .collect();
    let total = packets.len();
    let t0 = now_ns();
    let sender = std::thread::spawn(move || {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        for (i, (port, bytes)) in packets.iter().enumerate() {
            let to = if *port == 8308 { pos_addr } else { data_addr };
            s.send_to(bytes, to).unwrap();
            // A short pause every 200 packets keeps us inside any receive buffer the kernel grants
            // to a non-root user, without pretending to be a sensor's exact pace.
            if i % 200 == 199 {
                std::thread::sleep(Duration::from_millis(2));
            }
        }
    });
    let (mut data, mut pos) = (Vec::new(), Vec::new());
    let mut last_host = 0;
    for _ in 0..total {
        let item = tokio::time::timeout(Duration::from_secs(10), source.next())
            .await
            .expect("a packet within 10 s")
            .unwrap();
        match item {
            LidarItem::Data(s) => {
                assert!(
                    s.host.0 >= t0 && s.host.0 <= now_ns(),
                    "host stamp inside the test's wall-clock window"
                );
                assert!(s.host.0 >= last_host, "data stamps in order");
                last_host = s.host.0;
                data.push(s.value.encode().to_vec());
            }
            LidarItem::Position(s) => {
                assert!(s.host.0 >= t0 && s.host.0 <= now_ns());
                pos.push(s.value.encode().to_vec());
            }
            LidarItem::Rejected { error, .. } => panic!("rejected: {error}"),
        }
    }
    sender.join().unwrap();
    assert_eq!(data.len(), expected_data.len());
    assert!(
        data == expected_data,
        "data packets byte-identical and in order"
    );
    assert!(
        pos == expected_pos,
        "position packets byte-identical and in order"
    );
    let stats = &source.data_socket().stats;
    assert_eq!(stats.truncated, 0);
    assert_eq!(
        stats.without_kernel_stamp, 0,
        "every datagram has a kernel receive stamp"
    );
    println!(
        "{}: {} data + {} position packets received, lost {} (sensor gaps)",
        path.display(),
        data.len(),
        pos.len(),
        source.stats.lost
    );
}

#[tokio::test]
async fn fixture_over_loopback() {
    send_and_receive(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/vlp16_room.pcapng"))
        .await;
}

#[tokio::test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
async fn real_monterey_capture_over_loopback() {
    send_and_receive(&common::real_data().join("velodyne/hdl32e_monterey.pcap")).await;
}
