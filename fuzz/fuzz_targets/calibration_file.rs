//! Any text as a calibration file (VeloView XML or ros-drivers YAML) for every model: an error
//! that says what is wrong, or a calibration with one laser per id and finite values; never a
//! panic.
#![no_main]
use hilrig_velodyne::{Calibration, Model};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for model in Model::ALL {
        match Calibration::from_text(text, model) {
            Ok(c) => {
                assert_eq!(c.lasers.len(), model.lasers());
                assert!(c.distance_resolution_m > 0.0);
                for l in &c.lasers {
                    assert!(l.vertical_rad.is_finite() && l.distance_correction_m.is_finite());
                    assert!(usize::from(l.ring) < model.lasers());
                }
            }
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
});
