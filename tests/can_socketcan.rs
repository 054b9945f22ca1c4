//! SocketCAN on a virtual CAN interface (issue 3, item 6). The test needs `vcan0`; .ci/run tries
//! to create it (`ip link add dev vcan0 type vcan`). Where the kernel has no vcan module the test
//! is compiled as ignored, and cargo reports it as not run, never as passed.

use hilrig::can::socketcan_source::SocketCanSource;
use hilrig::can::CanFrame;
use std::time::Duration;

#[tokio::test]
#[cfg_attr(
    not(hilrig_vcan),
    ignore = "no vcan0 interface on this machine (the vcan kernel module is missing): did not run"
)]
#[allow(
    clippy::await_holding_lock,
    reason = "the lock only keeps the other vcan0 test out; nothing this task awaits takes it"
)]
async fn frames_sent_on_vcan_arrive_identical_with_kernel_stamps() {
    let _vcan0 = crate::common::vcan0();
    let mut rx = SocketCanSource::open("vcan0").expect("vcan0");
    let tx = SocketCanSource::open("vcan0").expect("vcan0");
    let frames = vec![
        CanFrame::new(0x101, false, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        CanFrame::new(0x18DA_F110, true, &[0xAA]).unwrap(),
        CanFrame::new_remote(0x123, false, 4).unwrap(),
        CanFrame::new_fd(0x7FF, false, &[9; 24], true).unwrap(),
    ];
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i64;
    for f in &frames {
        tx.send(f).await.unwrap();
    }
    for f in &frames {
        let got = tokio::time::timeout(Duration::from_secs(2), rx.next())
            .await
            .expect("frame within 2 s")
            .unwrap();
        assert_eq!(&got.value, f);
        assert!(got.host.0 >= before, "kernel stamp after the send started");
    }
}

#[test]
fn a_missing_interface_is_named_in_the_error() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let _g = rt.enter();
    let e = SocketCanSource::open("nosuchcan7")
        .err()
        .expect("must fail");
    assert!(
        e.to_string()
            .contains("cannot open CAN interface nosuchcan7"),
        "{e}"
    );
}
