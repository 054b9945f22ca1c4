//! Any bytes as a recording to check (the rest after an odd first byte becomes the records of an
//! MCAP): `hilrig check` reads what a crash or a full disk left behind, so it must end in a
//! report (pass, fail or unusable), never a panic.
#![no_main]
use hilrig::reference::check::check;
use hilrig::reference::run::Run;
use hilrig::rig::Rig;
use libfuzzer_sys::fuzz_target;

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

fuzz_target!(|data: &[u8]| {
    let bytes = if data.first().is_some_and(|b| b % 2 == 1) {
        [MCAP_MAGIC, &data[1..]].concat()
    } else {
        data.to_vec()
    };
    let run = Run::from_bytes(&bytes);
    let rig = Rig::from_toml(
        "name = \"fuzz\"\n[gnss]\nport = \"/dev/null\"\nbaud = 115200\nframe_id = \"gnss\"\nantenna = { x = 0.6, y = 0.0, z = 2.0 }\n",
        "fuzz",
    )
    .expect("rig");
    let report = check(&run, &rig, None);
    let _ = report.text();
});
