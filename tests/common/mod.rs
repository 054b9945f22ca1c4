//! Helpers shared by the integration tests: where the real data and reference tools are, and a
//! sink that keeps decoded points.
#![allow(dead_code)]

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
    use std::os::fd::AsFd;
    let p = nix::pty::openpty(None, None).expect("openpty");
    let name = nix::unistd::ttyname(p.slave.as_fd())
        .expect("ttyname")
        .display()
        .to_string();
    let mut t = nix::sys::termios::tcgetattr(p.slave.as_fd()).unwrap();
    nix::sys::termios::cfmakeraw(&mut t);
    nix::sys::termios::tcsetattr(p.slave.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
    drop(p.slave);
    (std::fs::File::from(p.master), name)
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
            hilrig_ok(&[
                "resim".as_ref(),
                run.as_os_str(),
                "--scene".as_ref(),
                src.join("scene.toml").as_os_str(),
                "--model".as_ref(),
                fixture(&format!("parking/{model}.toml")).as_os_str(),
                "-o".as_ref(),
                sim.as_os_str(),
            ]);
            sim
        })
        .collect();
    (run, sims)
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
