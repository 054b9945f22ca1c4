//! The `clock_sync/<source>` metadata records: how each source's clock relates to the host's
//! (the recorder's model of it), and for the lidar its PPS state. `record` (from captures and
//! live) writes them, `check`, `resim`, `compare` and `gap` read them; one type does both, so
//! that a key renamed on one side cannot leave the other reading nothing (before, each side
//! spelled the keys, and "PPS locked" was a string compared in several places).
//!
//! MCAP metadata hold strings. The record is written and read through serde: its fields as JSON
//! values, numbers as their shortest text, strings as they are; the numbers are rounded to what
//! the clock model resolves (whole nanoseconds, a thousandth of a ppm), which is also what the
//! record held before it was typed.

use hilrig_velodyne::PpsStatus;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The metadata record name of a source's clock synchronisation: `clock_sync/<source>`.
pub fn record_name(source: &str) -> String {
    format!("{PREFIX}{source}")
}

/// What every clock-sync record's name starts with.
pub const PREFIX: &str = "clock_sync/";

/// One source's clock synchronisation.
///
/// Keys it does not know are passed over when read (a newer recorder may add some); a key it
/// needs and does not find is an error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClockSync {
    /// The sensor time the model is referenced to, ns.
    pub reference_sensor_ns: i64,
    /// Host minus sensor time at the reference, ns.
    pub offset_ns: i64,
    /// Change of host minus sensor time per second of sensor time, ppm (negative: the sensor's
    /// clock runs ahead of the host's).
    pub drift_ppm: f64,
    /// Residuals above the model (transport latency jitter): median, ns.
    pub residual_p50_ns: i64,
    /// Their 95th percentile, ns.
    pub residual_p95_ns: i64,
    /// Their largest, ns.
    pub residual_max_ns: i64,
    /// Sensor/host time pairs the model was fitted to.
    pub pairs: u64,
    /// Lidar: where the top of the hour came from (the position packets' NMEA, the host clock).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hour_source: Option<String>,
    /// Lidar: the PPS state its position packets reported.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "pps_text")]
    pub pps: Option<PpsStatus>,
}

/// Why a clock-sync record does not read.
#[derive(Debug, thiserror::Error)]
#[error("metadata {record}: {source}")]
pub struct ClockSyncError {
    /// The record's name.
    pub record: String,
    /// Which key and why.
    #[source]
    pub source: serde_json::Error,
}

impl ClockSync {
    /// The record of a model fitted to `pairs` sensor/host pairs: offset and drift in host minus
    /// sensor time, residuals above the model.
    pub fn of_model(
        reference_sensor_ns: i64,
        offset_ns: f64,
        drift: f64,
        residual_ns: [f64; 3],
        pairs: u64,
    ) -> ClockSync {
        ClockSync {
            reference_sensor_ns,
            offset_ns: offset_ns.round() as i64,
            drift_ppm: (drift * 1e9).round() / 1e3,
            residual_p50_ns: residual_ns[0].round() as i64,
            residual_p95_ns: residual_ns[1].round() as i64,
            residual_max_ns: residual_ns[2].round() as i64,
            pairs,
            hour_source: None,
            pps: None,
        }
    }

    /// The metadata record's key/value pairs.
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let Ok(serde_json::Value::Object(fields)) = serde_json::to_value(self) else {
            return BTreeMap::new();
        };
        fields
            .into_iter()
            .map(|(k, v)| match v {
                serde_json::Value::String(s) => (k, s),
                other => (k, other.to_string()),
            })
            .collect()
    }

    /// Reads a record (`record` names it in the error).
    pub fn from_metadata(
        record: &str,
        values: &BTreeMap<String, String>,
    ) -> Result<ClockSync, ClockSyncError> {
        let fields: serde_json::Map<String, serde_json::Value> = values
            .iter()
            .map(|(k, v)| {
                // Text fields are text even where they look like numbers; a whole number is
                // read as one even where it was written as a float ("-0", "12.000").
                let text = matches!(k.as_str(), "hour_source" | "pps");
                let number = if text { None } else { number(v) };
                let value = number.map_or_else(
                    || serde_json::Value::String(v.clone()),
                    serde_json::Value::Number,
                );
                (k.clone(), value)
            })
            .collect();
        serde_json::from_value(serde_json::Value::Object(fields)).map_err(|source| ClockSyncError {
            record: record.to_owned(),
            source,
        })
    }

    /// The PPS state alone of a record, read whatever else the record holds (the one key that
    /// decides whether the lidar's stamps are GNSS time: a record that does not read otherwise
    /// must not turn a locked lidar into a free-running one).
    pub fn pps_of(values: &BTreeMap<String, String>) -> Option<PpsStatus> {
        #[derive(Deserialize)]
        struct Pps {
            #[serde(default, with = "pps_text")]
            pps: Option<PpsStatus>,
        }
        let v = values.get("pps")?;
        let one = serde_json::json!({ "pps": v });
        serde_json::from_value::<Pps>(one).ok()?.pps
    }

    /// Every clock-sync record of a recording's metadata, by source; the records that do not
    /// read, with why.
    pub fn of_recording(
        metadata: &BTreeMap<String, BTreeMap<String, String>>,
    ) -> (BTreeMap<String, ClockSync>, Vec<ClockSyncError>) {
        let (mut ok, mut bad) = (BTreeMap::new(), Vec::new());
        for (name, values) in metadata {
            let Some(source) = name.strip_prefix(PREFIX) else {
                continue;
            };
            match ClockSync::from_metadata(name, values) {
                Ok(c) => {
                    ok.insert(source.to_owned(), c);
                }
                Err(e) => bad.push(e),
            }
        }
        (ok, bad)
    }

    /// Whether the lidar's packet stamps are GNSS time: its position packets reported PPS lock.
    pub fn pps_locked(&self) -> bool {
        self.pps == Some(PpsStatus::Locked)
    }

    /// The sensor time of a host time: the model inverted (host − sensor = offset + drift ×
    /// (sensor − reference)). The drift term is taken at the host time less the offset; a
    /// clock's drift is a few ppm, so that is off by its square, nanoseconds over days.
    pub fn sensor_of_host(&self, host: i64) -> i64 {
        let sensor = host.saturating_sub(self.offset_ns);
        let drift = self.drift_ppm * 1e-6 * sensor.saturating_sub(self.reference_sensor_ns) as f64;
        sensor.saturating_sub(drift.round() as i64)
    }
}

/// A number's text as a JSON number: whole numbers as integers (so that they fit the integer
/// fields however they were written), others as floats; `None` for text that is no number.
fn number(text: &str) -> Option<serde_json::Number> {
    if let Ok(i) = text.parse::<i64>() {
        return Some(i.into());
    }
    if let Ok(u) = text.parse::<u64>() {
        return Some(u.into());
    }
    let x = text.parse::<f64>().ok().filter(|x| x.is_finite())?;
    if x.fract() == 0.0 && x.abs() < 9.0e15 {
        return Some((x as i64).into());
    }
    serde_json::Number::from_f64(x)
}

/// A PPS state as its name (`Locked`, `Unknown(7)`), as the records have always held it.
mod pps_text {
    use hilrig_velodyne::PpsStatus;
    use serde::{Deserialize, Deserializer, Serializer};

    const NAMED: [PpsStatus; 5] = [
        PpsStatus::Absent,
        PpsStatus::Synchronizing,
        PpsStatus::Locked,
        PpsStatus::Error,
        PpsStatus::NotReported,
    ];

    fn text(p: PpsStatus) -> String {
        format!("{p:?}")
    }

    #[allow(clippy::ref_option)]
    pub fn serialize<S: Serializer>(p: &Option<PpsStatus>, s: S) -> Result<S::Ok, S::Error> {
        match p {
            Some(p) => s.serialize_str(&text(*p)),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<PpsStatus>, D::Error> {
        let t = String::deserialize(d)?;
        if let Some(p) = NAMED.into_iter().find(|p| text(*p) == t) {
            return Ok(Some(p));
        }
        t.strip_prefix("Unknown(")
            .and_then(|r| r.strip_suffix(')'))
            .and_then(|b| b.parse::<u8>().ok())
            .map(|b| Some(PpsStatus::Unknown(b)))
            .ok_or_else(|| serde::de::Error::custom(format!("{t:?} is not a PPS state")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Written and read back to the same record, the keys and texts as the recorder wrote them
    /// before the record was typed; a misspelt key or a PPS state no sensor reports is refused
    /// with the record named.
    #[test]
    fn a_record_reads_back_as_written() {
        let mut c = ClockSync::of_model(
            1_795_255_200_000_000_000,
            -1_234_567.4,
            -12.345_678e-6,
            [800.2, 2_400.6, 9_000.0],
            4096,
        );
        c.hour_source = Some("PositionNmea".into());
        for pps in [
            PpsStatus::Locked,
            PpsStatus::Absent,
            PpsStatus::NotReported,
            PpsStatus::Unknown(7),
        ] {
            c.pps = Some(pps);
            let m = c.to_metadata();
            assert_eq!(m["offset_ns"], "-1234567");
            assert_eq!(m["drift_ppm"], "-12.346");
            assert_eq!(m["residual_p95_ns"], "2401");
            assert_eq!(m["pps"], format!("{pps:?}"));
            assert_eq!(ClockSync::from_metadata("clock_sync/lidar", &m).unwrap(), c);
        }
        assert!(c.to_metadata().len() == 9);
        // A misspelt key: the one it should have been is missing, and named.
        let mut m = c.to_metadata();
        let drift = m.remove("drift_ppm").unwrap();
        m.insert("drift_pmm".into(), drift);
        let e = ClockSync::from_metadata("clock_sync/lidar", &m).unwrap_err();
        assert!(e.to_string().contains("clock_sync/lidar") && e.to_string().contains("drift_ppm"));
        // The PPS state reads alone whatever else is wrong: a locked lidar stays locked.
        assert_eq!(ClockSync::pps_of(&m), Some(PpsStatus::Unknown(7)));
        let mut m = c.to_metadata();
        m.insert("pps".into(), "Lokced".into());
        assert!(ClockSync::from_metadata("clock_sync/lidar", &m).is_err());
        assert_eq!(ClockSync::pps_of(&m), None);
        // What older recorders wrote: "-0" and "12.000" for whole numbers, a key this type
        // does not know; all read.
        let mut m = c.to_metadata();
        m.insert("offset_ns".into(), "-0".into());
        m.insert("pairs".into(), "12.000".into());
        m.insert("residual_p99_ns".into(), "3000".into());
        let old = ClockSync::from_metadata("clock_sync/lidar", &m).unwrap();
        assert_eq!((old.offset_ns, old.pairs), (0, 12));
        // A GNSS clock has no PPS key and no hour source.
        c.pps = None;
        c.hour_source = None;
        let m = c.to_metadata();
        assert!(!m.contains_key("pps") && !m.contains_key("hour_source"));
        assert_eq!(ClockSync::from_metadata("clock_sync/gnss", &m).unwrap(), c);
    }
}
