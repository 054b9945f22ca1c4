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
//! `cargo bench --bench compare_floor [-- CAPTURE.pcapng[.zst] SCENE.toml [ROUNDS] [--rig RIG.toml]
//! [--no-resim]]`: another capture needs its rig (the demo rig's VLP-16 by default); with
//! `--no-resim` only `compare` and the floor are timed (resim once, for its output).

use hilrig::bag::scans::{Scan, ScanStream};
use hilrig_velodyne::{DataPacket, Decoder};
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

/// Reads every scan of a recording as `compare` does (streamed), handing each batch of scans
/// to `each`.
fn read(path: &Path, each: &mut dyn FnMut(&[Scan])) {
    let mut stream = ScanStream::open(path).expect("open the recording");
    loop {
        let batch: Vec<Scan> = stream.by_ref().take(8).collect();
        if batch.is_empty() {
            break;
        }
        each(&batch);
    }
    let damage = stream.finish();
    assert!(damage.is_none(), "{}: {damage:?}", path.display());
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
    let all: Vec<String> = std::env::args().skip(1).collect();
    let rig_arg = all
        .iter()
        .position(|a| a == "--rig")
        .and_then(|i| all.get(i + 1).cloned());
    let no_resim = all.iter().any(|a| a == "--no-resim");
    let args: Vec<String> = all
        .iter()
        .enumerate()
        .filter(|(i, a)| !(a.starts_with("--") || *i > 0 && all[*i - 1] == "--rig"))
        .map(|(_, a)| a.clone())
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
    let rig = rig_arg.map_or_else(|| root.join("rigs/demo.toml"), PathBuf::from);
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
    // The rig's lidar, as compare decodes it.
    let (_, model, calibration) = hilrig::rig::Rig::load(&rig)
        .expect("the rig")
        .lidar_sensor()
        .expect("the rig's lidar");
    let decoder = Decoder::with_calibration(model, calibration);
    let (mut t_resim, mut t_truth, mut t_compare, mut t_read, mut t_decode) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut points = 0;
    for _ in 0..rounds {
        if !no_resim {
            t_resim.push(timed(|| resim(&idealized, &sim)));
            t_truth.push(timed(|| resim(&truth, &sim_truth)));
        }
        t_compare.push(timed(compare));
        t_read.push(timed(|| {
            let (mut a, mut b) = (0, 0);
            rayon::join(
                || read(&run, &mut |s| a += s.len()),
                || read(&sim, &mut |s| b += s.len()),
            );
            assert!(a > 0 && b > 0);
        }));
        t_decode.push(timed(|| {
            let (mut a, mut b) = (0, 0);
            rayon::join(
                || read(&run, &mut |s| a += decode(&decoder, s)),
                || read(&sim, &mut |s| b += decode(&decoder, s)),
            );
            points = a + b;
        }));
    }
    if no_resim {
        let (c, rd, dc) = (median(t_compare), median(t_read), median(t_decode));
        println!(
            "{} ({} rounds, {} cores, {points} points decoded)",
            capture.display(),
            rounds,
            rayon::current_num_threads()
        );
        println!("compare                       {c:.3} s");
        println!(
            "floor: read both files        {rd:.3} s  compare is {:.2} of it",
            c / rd
        );
        println!(
            "floor: read and decode both   {dc:.3} s  compare is {:.2} of it (target: 2)",
            c / dc
        );
        return;
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
        "floor: read and decode both   {dc:.3} s  {:.2} of resim; compare is {:.2} of it (target: 2)",
        dc / r,
        c / dc
    );
}
