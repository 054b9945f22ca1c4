//! Marks tests that need data or tools outside this repository.
//!
//! Real sensor captures from other projects live in ../shared/data (never committed here) and
//! are found through `HILRIG_REAL_DATA`; the reference decoders run in a Python venv found through
//! `HILRIG_PYTHON`. Both are set by `.ci/run`. Where one is missing, the tests that need it are
//! compiled as ignored with a reason, so `cargo test` reports them as not run instead of passed.
//! The same holds for SocketCAN tests, which need a `vcan0` interface (a kernel module that is
//! not available everywhere), the report's browser test (`HILRIG_CHROMIUM`, a chromium binary)
//! the Foxglove reader test (`HILRIG_FOXGLOVE`, the folder with Foxglove's npm packages) and the
//! campaign test in Azure Blob Storage (`HILRIG_AZURITE`, the folder with the Azurite emulator).
//!
//! It also names the source the binary is built from (`HILRIG_SOURCE`: the SHA-256 of every
//! file of the workspace's crates, their manifests and lock file, and the compiler's version),
//! which a campaign's stamps record: a task made by another build is made again.

use sha2::{Digest, Sha256};
use std::env;
use std::path::{Path, PathBuf};

/// Every file under `dir`, sorted (build output folders left out).
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            if p.file_name().is_some_and(|n| n != "target") {
                files_under(&p, out);
            }
        } else {
            out.push(p);
        }
    }
}

/// The SHA-256 of the source the binary is built from: the crates' files (path and bytes),
/// the manifests and lock file, and `rustc -V`.
fn source_hash() -> String {
    let root = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let mut files = Vec::new();
    for top in ["Cargo.toml", "Cargo.lock", "build.rs"] {
        files.push(root.join(top));
        println!("cargo:rerun-if-changed={top}");
    }
    for dir in ["src", "drivers"] {
        files_under(&root.join(dir), &mut files);
        println!("cargo:rerun-if-changed={dir}");
    }
    files.sort();
    let mut h = Sha256::new();
    for f in &files {
        let rel = f.strip_prefix(&root).unwrap_or(f);
        h.update(rel.to_string_lossy().as_bytes());
        h.update([0]);
        h.update(std::fs::read(f).unwrap_or_default());
        h.update([0]);
    }
    let rustc = env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    if let Ok(v) = std::process::Command::new(rustc).arg("-V").output() {
        h.update(&v.stdout);
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

fn main() {
    println!("cargo:rustc-env=HILRIG_SOURCE={}", source_hash());
    println!("cargo::rustc-check-cfg=cfg(hilrig_real_data)");
    println!("cargo::rustc-check-cfg=cfg(hilrig_python)");
    println!("cargo::rustc-check-cfg=cfg(hilrig_vcan)");
    println!("cargo::rustc-check-cfg=cfg(hilrig_chromium)");
    println!("cargo::rustc-check-cfg=cfg(hilrig_foxglove)");
    println!("cargo::rustc-check-cfg=cfg(hilrig_azurite)");
    println!("cargo:rerun-if-changed=/sys/class/net");
    // A virtual CAN interface for SocketCAN tests (.ci/run tries to create vcan0).
    if Path::new("/sys/class/net/vcan0").exists() {
        println!("cargo:rustc-cfg=hilrig_vcan");
    }
    println!("cargo:rerun-if-env-changed=HILRIG_REAL_DATA");
    println!("cargo:rerun-if-env-changed=HILRIG_PYTHON");
    println!("cargo:rerun-if-env-changed=HILRIG_CHROMIUM");
    println!("cargo:rerun-if-env-changed=HILRIG_FOXGLOVE");
    println!("cargo:rerun-if-env-changed=HILRIG_AZURITE");
    // A headless browser for the report test (Debian's chromium, installed by .ci/run).
    if let Ok(c) = env::var("HILRIG_CHROMIUM") {
        if Path::new(&c).exists() {
            println!("cargo:rustc-cfg=hilrig_chromium");
        } else {
            println!("cargo:warning=HILRIG_CHROMIUM={c} does not exist: the report's browser test will not run");
        }
    }
    // Foxglove's readers (npm packages installed by .ci/run into tests/interop/foxglove).
    if let Ok(d) = env::var("HILRIG_FOXGLOVE") {
        if Path::new(&d).join("node_modules/@mcap/core").is_dir() {
            println!("cargo:rustc-cfg=hilrig_foxglove");
        } else {
            println!("cargo:warning=HILRIG_FOXGLOVE={d} has no node_modules/@mcap/core: the Foxglove test will not run");
        }
    }
    // Azurite (npm, installed by .ci/run into tests/interop/azurite).
    if let Ok(d) = env::var("HILRIG_AZURITE") {
        if Path::new(&d)
            .join("node_modules/.bin/azurite-blob")
            .exists()
        {
            println!("cargo:rustc-cfg=hilrig_azurite");
        } else {
            println!("cargo:warning=HILRIG_AZURITE={d} has no node_modules/.bin/azurite-blob: the campaign test in Azure Blob Storage will not run");
        }
    }
    if let Ok(dir) = env::var("HILRIG_REAL_DATA") {
        // The real-data tests read all three folders (lidar captures, GNSS logs with gpsd's
        // output, DBC files): one missing and they do not run, rather than fail half-way.
        let missing: Vec<&str> = ["velodyne", "gnss", "can"]
            .into_iter()
            .filter(|d| !Path::new(&dir).join(d).is_dir())
            .collect();
        if missing.is_empty() {
            println!("cargo:rustc-cfg=hilrig_real_data");
        } else {
            println!(
                "cargo:warning=HILRIG_REAL_DATA={dir} has no {} folder: real-data tests will not run",
                missing.join(", ")
            );
        }
    }
    if let Ok(py) = env::var("HILRIG_PYTHON") {
        if Path::new(&py).exists() {
            println!("cargo:rustc-cfg=hilrig_python");
        } else {
            println!("cargo:warning=HILRIG_PYTHON={py} does not exist: interop tests will not run");
        }
    }
}
