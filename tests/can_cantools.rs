//! cantools as the oracle for the CAN driver (issue 3, item 5): for the opendbc VW MQB and Hyundai
//! files and cantools' own multiplexing test file (read in place from ../shared/data/can), frames
//! encoded from random signal values, and frames of random bytes, decode to exactly the values
//! cantools decodes (multiplexed and Motorola signals included); and a candump log of such frames
//! goes through decode -> encode -> candump byte-identically.

use crate::common;

use hilrig::can::candump::{format_line, parse_log, LogFrame};
use hilrig::can::{CanFrame, Database, MessageDef};
use hilrig::stamp::UtcNanos;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// splitmix64: a deterministic generator, so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// A frame from random raw values of every signal (multiplexors set to values that select
/// something, half of the time).
fn random_values_frame(m: &MessageDef, rng: &mut Rng) -> Vec<u8> {
    let mut values = Vec::new();
    for (i, s) in m.signals.iter().enumerate() {
        let mask = if s.size >= 64 {
            u64::MAX
        } else {
            (1u64 << s.size) - 1
        };
        let mut raw = rng.next() & mask;
        if s.is_multiplexor && rng.next().is_multiple_of(2) {
            // Pick a value some multiplexed signal wants.
            let wanted: Vec<u64> = m
                .signals
                .iter()
                .filter_map(|t| match &t.presence {
                    hilrig::can::dbc::Presence::When {
                        multiplexor,
                        ranges,
                    } if *multiplexor == i => Some(ranges[0].0),
                    _ => None,
                })
                .collect();
            if !wanted.is_empty() {
                raw = wanted[(rng.next() % wanted.len() as u64) as usize];
            }
        }
        if matches!(
            s.repr,
            hilrig::can::dbc::Repr::Float32 | hilrig::can::dbc::Repr::Float64
        ) {
            raw = rng.next() % 1000; // finite values only
        }
        values.push((i, s.physical(raw)));
    }
    m.encode(&values)
}

/// Whether two signals of the message share a bit (in a payload where both are present).
fn overlapping(m: &MessageDef) -> bool {
    let bits = |s: &hilrig::can::SignalDef| {
        let mut d = vec![0u8; m.size.max(8)];
        let mask = if s.size >= 64 {
            u64::MAX
        } else {
            (1u64 << s.size) - 1
        };
        hilrig::can::codec::insert(&mut d, s.order, s.start, s.size, mask);
        d
    };
    let all: Vec<Vec<u8>> = m.signals.iter().map(bits).collect();
    (0..all.len())
        .any(|i| (i + 1..all.len()).any(|j| all[i].iter().zip(&all[j]).any(|(a, b)| a & b != 0)))
}

fn hex(b: &[u8]) -> String {
    b.iter().fold(String::new(), |mut s, x| {
        let _ = write!(s, "{x:02x}");
        s
    })
}

fn check(name: &str, per_message: usize) {
    let path = common::real_data().join("can").join(format!("{name}.dbc"));
    let db = Database::from_file(&path).unwrap();
    let mut rng = Rng(0x5EED ^ name.len() as u64);
    let mut frames: Vec<CanFrame> = Vec::new();
    for m in db.messages() {
        for k in 0..per_message {
            let data = if k % 2 == 0 {
                random_values_frame(m, &mut rng)
            } else {
                (0..m.size).map(|_| rng.next() as u8).collect()
            };
            let f = if m.size > 8 {
                CanFrame::new_fd(m.id, m.extended, &data, false)
            } else {
                CanFrame::new(m.id, m.extended, &data)
            };
            frames.push(f.expect("frame"));
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("frames.jsonl");
    let output = dir.path().join("decoded.jsonl");
    let mut text = String::new();
    for f in &frames {
        let _ = writeln!(
            text,
            "{{\"id\": {}, \"extended\": {}, \"data\": \"{}\"}}",
            f.id,
            f.extended,
            hex(f.data())
        );
    }
    std::fs::write(&input, text).unwrap();
    let status = std::process::Command::new(common::python())
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/interop/cantools_decode.py"
        ))
        .args([&path, &input, &output])
        .status()
        .unwrap();
    assert!(status.success(), "cantools failed on {name}");
    let theirs: Vec<serde_json::Value> = std::fs::read_to_string(&output)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(theirs.len(), frames.len());
    let (mut signals, mut muxed_frames) = (0usize, 0usize);
    let mut cantools_failed = std::collections::BTreeSet::new();
    let mut unselected = 0usize;
    for (f, t) in frames.iter().zip(&theirs) {
        let ours = db.decode(f).expect("in the DBC");
        assert_eq!(
            t["name"].as_str(),
            Some(ours.message.name.as_str()),
            "{name}: message of {:#x}",
            f.id
        );
        if let Some(err) = t.get("error").and_then(|e| e.as_str()) {
            if err.contains("expected multiplexer id") {
                // Explained: when the multiplexor selects no signal, cantools raises; hilrig
                // reports the signals that are present, i.e. none of the multiplexed ones.
                assert!(
                    ours.values.iter().all(|&(i, _)| matches!(
                        ours.message.signals[i].presence,
                        hilrig::can::dbc::Presence::Always
                    )),
                    "{name}: {}: multiplexed signals decoded for an unselected multiplexor value",
                    ours.message.name
                );
                unselected += 1;
                continue;
            }
            // Explained: cantools cannot unpack a message whose signals share bits; hilrig reads
            // each signal on its own. Only such messages may fail there.
            assert!(
                overlapping(ours.message),
                "{name}: cantools failed on {} ({err}) without overlapping signals",
                ours.message.name
            );
            cantools_failed.insert(ours.message.name.clone());
            continue;
        }
        let ours_map: BTreeMap<&str, f64> = ours
            .values
            .iter()
            .map(|&(i, v)| (ours.message.signals[i].name.as_str(), v))
            .collect();
        let theirs_map: BTreeMap<&str, f64> = t["signals"]
            .as_object()
            .unwrap()
            .iter()
            .map(|(k, v)| (k.as_str(), v.as_f64().unwrap()))
            .collect();
        assert_eq!(
            ours_map.keys().collect::<Vec<_>>(),
            theirs_map.keys().collect::<Vec<_>>(),
            "{name}: {} {}: active signals",
            ours.message.name,
            hex(f.data())
        );
        for (k, v) in &ours_map {
            let w = theirs_map[k];
            assert!(
                (v - w).abs() <= 1e-9 * v.abs().max(1.0),
                "{name}: {}.{k}: hilrig {v}, cantools {w} ({})",
                ours.message.name,
                hex(f.data())
            );
        }
        signals += ours_map.len();
        if ours.message.signals.iter().any(|s| s.is_multiplexor) {
            muxed_frames += 1;
        }
    }
    let motorola = db
        .messages()
        .iter()
        .flat_map(|m| &m.signals)
        .filter(|s| s.order == hilrig::can::codec::Order::Motorola)
        .count();
    println!("{name}: {} frames, {signals} signal values equal to cantools ({muxed_frames} multiplexed frames, {motorola} Motorola signals in the DBC)", frames.len());
    println!("{name}: messages cantools cannot decode (overlapping signals): {cantools_failed:?}; frames whose multiplexor selects nothing (cantools raises): {unselected}");
    assert!(signals > frames.len());

    // candump -> decode -> encode -> candump, on frames made from signal values (unused bits 0).
    let mut log = String::new();
    let mut t = 1_700_000_000_000_000i64;
    for m in db.messages() {
        let data = random_values_frame(m, &mut rng);
        t += 1234;
        let f = if m.size > 8 {
            CanFrame::new_fd(m.id, m.extended, &data, true)
        } else {
            CanFrame::new(m.id, m.extended, &data)
        }
        .unwrap();
        // Written by this test's own formatting, not by the writer under test.
        let id = if m.extended {
            format!("{:08X}", m.id)
        } else {
            format!("{:03X}", m.id)
        };
        let sep = if f.fd { "##1" } else { "#" };
        let _ = writeln!(
            log,
            "({:010}.{:06}) can0 {id}{sep}{}",
            t / 1_000_000,
            t % 1_000_000,
            hex(&data).to_uppercase()
        );
    }
    let parsed = parse_log(&log).unwrap();
    let mut written = String::new();
    for lf in &parsed {
        let decoded = db.decode(&lf.frame).unwrap();
        let data = decoded.message.encode(&decoded.values);
        let frame = lf.frame;
        let again = if frame.fd {
            CanFrame::new_fd(frame.id, frame.extended, &data, frame.brs)
        } else {
            CanFrame::new(frame.id, frame.extended, &data)
        }
        .unwrap();
        let _ = writeln!(
            written,
            "{}",
            format_line(&LogFrame {
                time: UtcNanos(lf.time.0),
                interface: lf.interface.clone(),
                frame: again
            })
        );
    }
    assert_eq!(written, log, "{name}: candump round trip");
}

macro_rules! oracle {
    ($($test:ident => $file:literal, $n:literal);*) => {$(
        #[test]
        #[cfg_attr(not(all(hilrig_real_data, hilrig_python)), ignore = "needs HILRIG_REAL_DATA and HILRIG_PYTHON (set by .ci/run): did not run")]
        fn $test() {
            check($file, $n);
        }
    )*};
}

oracle!(vw_mqb => "vw_mqb", 20; hyundai_can => "hyundai_can", 20; cantools_multiplex => "cantools_multiplex", 400);
