//! `scripts/layout-check` finds a circle between folders (top-level modules) even where no two
//! files import each other, names the folders and prints the imports behind each edge, fewest
//! first; the same workspace without the wrong-way import passes.

use std::path::Path;
use std::process::Command;

fn write(root: &Path, rel: &str, text: &str) {
    let p = root.join(rel);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, text).unwrap();
}

/// A crate of two folders: `a` uses `b` twice, `b` uses `a` once, in different files.
fn workspace(b_reaches_back: bool) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let r = dir.path();
    write(r, "src/lib.rs", "pub mod a;\npub mod b;\n");
    write(
        r,
        "src/a/mod.rs",
        "pub mod four;\npub mod one;\npub mod five;\n",
    );
    write(
        r,
        "src/a/one.rs",
        "use crate::b::two::X;\npub fn f(_: X) {}\n",
    );
    write(r, "src/a/five.rs", "pub fn g(_: crate::b::two::X) {}\n");
    write(r, "src/a/four.rs", "pub struct Y;\n");
    write(r, "src/b/mod.rs", "pub mod three;\npub mod two;\n");
    write(r, "src/b/two.rs", "pub struct X;\n");
    let three = if b_reaches_back {
        "use crate::a::four::Y;\npub fn h(_: Y) {}\n"
    } else {
        "pub fn h() {}\n"
    };
    write(r, "src/b/three.rs", three);
    write(r, "src/main.rs", "fn main() {}\n");
    dir
}

fn check(root: &Path) -> (Option<i32>, String) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/layout-check");
    let out = Command::new("python3")
        .arg(script)
        .arg("--root")
        .arg(root)
        .output()
        .expect("python3 runs scripts/layout-check");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn a_circle_between_folders_fails_and_names_the_wrong_way_edge() {
    let circle = workspace(true);
    let (code, out) = check(circle.path());
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("folder circle in src: a <-> b"), "{out}");
    // The edge with fewer imports first: that is the one to turn around.
    let back = out.find("b -> a (1 import(s))").expect("the edge back");
    let forth = out.find("a -> b (2 import(s))").expect("the edge forth");
    assert!(back < forth, "{out}");
    assert!(out.contains("src/b/three.rs -> src/a/four.rs"), "{out}");
    // No file circle: only the folders go round.
    assert!(!out.contains("import circle:"), "{out}");

    let clean = workspace(false);
    let (code, out) = check(clean.path());
    assert_eq!(code, Some(0), "{out}");
    assert!(
        out.contains("no import circle between files or folders"),
        "{out}"
    );
}
