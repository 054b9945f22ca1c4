//! `compare` against `resim` on a parking repetition (issue 13, must-hold 8: `compare` at most a
//! tenth of `resim`'s time on the same run), and the floor under `compare`: what any comparison
//! of the two files must do before it computes a single metric.
//!
//! The repetition (fixtures/parking/rep-01, or the capture given as the first argument) is
//! recorded and re-simulated with the idealized model by the `hilrig` binary. Then, in
//! alternating rounds so that every figure sees the same machine load:
//! - `resim` of the run (the binary, wall time), with the idealized model and with the parking
//!   truth model (whose beam divergence casts 3 x 3 sub-rays a firing);
//! - `compare` of the run with its re-simulation (the binary, wall time);
//! - reading both files: every chunk decompressed and every lidar scan message parsed
//!   (`read_scans`, one file per core, as `compare` reads them);
//! - reading and decoding: the same, then every packet of both files decoded into points with
//!   the rig's decoder, the scans spread over the cores.
//!
//! Medians over the rounds, and each as a ratio to `resim`'s. Reading and decoding is a floor:
//! `compare` cannot pair a measured firing with its simulated twin without both.
//!
//! `cargo bench --bench compare_floor [-- CAPTURE.pcapng[.zst] SCENE.toml [ROUNDS]]`

use hilrig::bag::scans::{read_scans, Scan};
use hilrig_velodyne::{DataPacket, Decoder, Model};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

fn hilrig(args: &[&std::ffi::OsStr]) {
    let out = Command::new(env!("CARGO_BIN_EXE_hilrig"))
        .args(args)
        .output()
        .expect("run hilrig");
    assert!(
        out.status.success(),
        "hilrig {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn timed(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64()
}

fn read(path: &Path) -> Vec<Scan> {
    let bytes = std::fs::read(path).expect("read the recording");
    let (scans, damage) = read_scans(&bytes);
    assert!(damage.is_none(), "{}: {damage:?}", path.display());
    scans
}

/// Points of every packet of `scans`, scans spread over the cores.
fn decode(decoder: &Decoder, scans: &[Scan]) -> usize {
    scans
        .par_iter()
        .map(|s| {
            let mut points = Vec::new();
            let mut n = 0;
            for (_, bytes) in &s.packets {
                if let Ok(p) = DataPacket::decode(&bytes[..]) {
                    points.clear();
                    if decoder.decode_into(&p, &mut points).is_ok() {
                        n += points.len();
                    }
                }
            }
            n
        })
        .sum()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let capture = args.first().map_or_else(
        || root.join("fixtures/parking/rep-01/drive.pcapng.zst"),
        PathBuf::from,
    );
    let scene = args.get(1).map_or_else(
        || root.join("fixtures/parking/rep-01/scene.toml"),
        PathBuf::from,
    );
    let rounds: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(5);
    let rig = root.join("rigs/demo.toml");
    let (idealized, truth) = (
        root.join("fixtures/parking/idealized.toml"),
        root.join("fixtures/parking/truth-model.toml"),
    );
    let dir = tempfile::tempdir().expect("temporary directory");
    let (run, sim) = (dir.path().join("run.mcap"), dir.path().join("sim.mcap"));
    hilrig(&[
        "record".as_ref(),
        "--rig".as_ref(),
        rig.as_os_str(),
        "--from".as_ref(),
        capture.as_os_str(),
        "-o".as_ref(),
        run.as_os_str(),
    ]);
    let resim = |model: &Path, out: &Path| {
        hilrig(&[
            "resim".as_ref(),
            run.as_os_str(),
            "--scene".as_ref(),
            scene.as_os_str(),
            "--model".as_ref(),
            model.as_os_str(),
            "-o".as_ref(),
            out.as_os_str(),
        ]);
    };
    resim(&idealized, &sim);
    let sim_truth = dir.path().join("sim-truth.mcap");
    let compare = || {
        hilrig(&[
            "compare".as_ref(),
            run.as_os_str(),
            sim.as_os_str(),
            "--scene".as_ref(),
            scene.as_os_str(),
        ]);
    };
    // The demo rig's lidar, as compare decodes it (the built-in VLP-16 geometry).
    let decoder = Decoder::new(Model::Vlp16);
    let (mut t_resim, mut t_truth, mut t_compare, mut t_read, mut t_decode) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut points = 0;
    for _ in 0..rounds {
        t_resim.push(timed(|| resim(&idealized, &sim)));
        t_truth.push(timed(|| resim(&truth, &sim_truth)));
        t_compare.push(timed(compare));
        t_read.push(timed(|| {
            let (a, b) = rayon::join(|| read(&run), || read(&sim));
            assert!(!a.is_empty() && !b.is_empty());
        }));
        t_decode.push(timed(|| {
            let (a, b) = rayon::join(|| read(&run), || read(&sim));
            points = decode(&decoder, &a) + decode(&decoder, &b);
        }));
    }
    let (r, rt, c, rd, dc) = (
        median(t_resim),
        median(t_truth),
        median(t_compare),
        median(t_read),
        median(t_decode),
    );
    println!(
        "{} ({} rounds, {} cores, {points} points decoded)",
        capture.display(),
        rounds,
        rayon::current_num_threads()
    );
    println!("resim (idealized model)       {r:.3} s  1.00 of resim");
    println!(
        "resim (truth model)           {rt:.3} s  {:.2} of resim; compare is {:.2} of it",
        rt / r,
        c / rt
    );
    println!(
        "compare                       {c:.3} s  {:.2} of resim",
        c / r
    );
    println!(
        "floor: read both files        {rd:.3} s  {:.2} of resim",
        rd / r
    );
    println!(
        "floor: read and decode both   {dc:.3} s  {:.2} of resim (the target for compare: 0.10)",
        dc / r
    );
}
