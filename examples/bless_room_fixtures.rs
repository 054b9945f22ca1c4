//! Rewrites the round-room captures in fixtures/ from the generator in `tests/room/`, after an
//! intended change of it: `cargo run --example bless_room_fixtures`. `tests/fixtures.rs` then
//! checks them byte for byte; review the diff of the decoded points before committing.

#[path = "../tests/room/mod.rs"]
mod room;

fn main() {
    for (name, model, mode, packets) in room::FIXTURES {
        let path = room::fixture_path(name);
        let bytes = room::generate(model, mode, packets);
        std::fs::write(&path, &bytes)
            .unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
        println!("{}: {} bytes", path.display(), bytes.len());
    }
}
