//! The ego mapping of rigs/ego-vw-mqb.toml against the real opendbc VW MQB DBC: frames made
//! from known vehicle motion come out as SI samples with ISO 8855 signs.

use crate::common;

use hilrig::can::ego::{EgoMapping, EgoSample, EgoTracker, Quantity};
use hilrig::can::{CanFrame, Database};
use hilrig::stamp::UtcNanos;

fn mapping() -> EgoMapping {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/rigs/ego-vw-mqb.toml"))
            .unwrap();
    toml::from_str(&text).unwrap()
}

fn frame(db: &Database, message: &str, values: &[(&str, f64)]) -> CanFrame {
    let m = db.message_by_name(message).unwrap();
    let v: Vec<(usize, f64)> = values
        .iter()
        .map(|(n, x)| (m.signals.iter().position(|s| s.name == *n).unwrap(), *x))
        .collect();
    CanFrame::new(m.id, m.extended, &m.encode(&v)).unwrap()
}

#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn vw_mqb_frames_give_si_samples_with_iso_signs() {
    let db = Database::from_file(&common::real_data().join("can/vw_mqb.dbc")).unwrap();
    let tracker = EgoTracker::new(&mapping(), &db).unwrap();
    let t = UtcNanos(1_700_000_000_000_000_000);
    let frames = [
        frame(&db, "ESP_21", &[("ESP_v_Signal", 36.0)]),
        // Turning right at 12.5 deg/s: magnitude with the sign flag set.
        frame(
            &db,
            "ESP_02",
            &[("ESP_Gierrate", 12.5), ("ESP_VZ_Gierrate", 1.0)],
        ),
        frame(
            &db,
            "LWI_01",
            &[("LWI_Lenkradwinkel", 90.0), ("LWI_VZ_Lenkradwinkel", 0.0)],
        ),
        frame(
            &db,
            "ESP_19",
            &[
                ("ESP_VL_Radgeschw_02", 36.0),
                ("ESP_VR_Radgeschw_02", 35.25),
                ("ESP_HL_Radgeschw_02", 36.75),
                ("ESP_HR_Radgeschw_02", 34.5),
            ],
        ),
    ];
    let mut out: Vec<EgoSample> = Vec::new();
    for f in &frames {
        tracker.handle(t, &db.decode(f).unwrap(), &mut out);
    }
    let get = |q: Quantity| {
        out.iter()
            .find(|s| s.quantity == q)
            .unwrap_or_else(|| panic!("{q:?}"))
            .value
    };
    assert!((get(Quantity::Speed) - 10.0).abs() < 1e-9);
    assert!(
        (get(Quantity::YawRate) + 12.5f64.to_radians()).abs() < 1e-9,
        "right turn is negative"
    );
    assert!((get(Quantity::SteeringWheelAngle) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    assert!((get(Quantity::WheelSpeed(1)) - 35.25 / 3.6).abs() < 1e-9);
    assert!((get(Quantity::WheelSpeed(3)) - 34.5 / 3.6).abs() < 1e-9);
    assert_eq!(out.len(), 7);
}

#[test]
fn mapping_errors_name_the_entry_and_unknown_keys_are_rejected() {
    let db = Database::from_dbc_text(
        "VERSION \"\"\n\nBO_ 1 A: 8 X\n SG_ V : 0|16@1+ (0.01,0) [0|1] \"\" X\n",
    )
    .unwrap();
    let bad: EgoMapping =
        toml::from_str("[speed]\nmessage = \"A\"\nsignal = \"W\"\nunit = \"m/s\"\n").unwrap();
    let e = EgoTracker::new(&bad, &db).err().unwrap();
    assert_eq!(
        e.to_string(),
        "ego mapping Speed: signal W is not in message A"
    );
    let e = toml::from_str::<EgoMapping>(
        "[speed]\nmessage = \"A\"\nsignal = \"V\"\nunit = \"m/s\"\nsacle = 2.0\n",
    )
    .unwrap_err();
    assert!(e.to_string().contains("unknown field `sacle`"), "{e}");
    let e = toml::from_str::<EgoMapping>(
        "[speed]\nmessage = \"A\"\nsignal = \"V\"\nunit = \"furlong/fortnight\"\n",
    )
    .unwrap_err();
    assert!(e.to_string().contains("unknown variant"), "{e}");
}
