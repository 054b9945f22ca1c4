//! Any text as a DBC file, then every message decoded from and encoded into fuzzer bytes: errors
//! are fine, panics are not.
#![no_main]
use hilrig_can::{CanFrame, Database};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let Ok(text) = std::str::from_utf8(&data[..split]) else {
        return;
    };
    let payload = data.get(split + 1..).unwrap_or(&[]);
    let Ok(db) = Database::from_dbc_text(text) else {
        return;
    };
    for m in db.messages() {
        let mut bytes = payload.to_vec();
        bytes.resize(m.size.min(64), 0);
        let frame = if bytes.len() > 8 {
            CanFrame::new_fd(m.id, m.extended, &bytes[..bytes.len().min(64)], false)
        } else {
            CanFrame::new(m.id, m.extended, &bytes)
        };
        if let Some(f) = frame {
            if let Some(d) = db.decode(&f) {
                let _ = d.message.encode(&d.values);
            }
        }
    }
});
