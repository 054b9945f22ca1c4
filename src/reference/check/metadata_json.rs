//! The recording's clock-sync metadata in `check`'s JSON: MCAP metadata holds strings, the JSON
//! gives numbers as numbers, and reading the JSON back gives the text again.

use serde::Deserialize;

/// Metadata values that are numbers written as JSON numbers, the rest as strings.
pub(super) fn numbers_as_numbers<S: serde::Serializer>(
    map: &std::collections::BTreeMap<String, std::collections::BTreeMap<String, String>>,
    ser: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut outer = ser.serialize_map(Some(map.len()))?;
    for (source, values) in map {
        let inner: std::collections::BTreeMap<&str, serde_json::Value> = values
            .iter()
            .map(|(k, v)| {
                let value = match v.parse::<f64>() {
                    Ok(x) if x.is_finite() => serde_json::Value::from(x),
                    _ => serde_json::Value::from(v.as_str()),
                };
                (k.as_str(), value)
            })
            .collect();
        outer.serialize_entry(source, &inner)?;
    }
    outer.end()
}

/// Reads back what [`numbers_as_numbers`] wrote: numbers as their JSON text. (The values are
/// the recording's metadata; a typed clock-sync record would replace both.)
pub(super) fn numbers_as_text<'de, D: serde::Deserializer<'de>>(
    de: D,
) -> Result<std::collections::BTreeMap<String, std::collections::BTreeMap<String, String>>, D::Error>
{
    let map: std::collections::BTreeMap<
        String,
        std::collections::BTreeMap<String, serde_json::Value>,
    > = Deserialize::deserialize(de)?;
    Ok(map
        .into_iter()
        .map(|(source, values)| {
            let values = values
                .into_iter()
                .map(|(k, v)| match v {
                    serde_json::Value::String(s) => (k, s),
                    other => (k, other.to_string()),
                })
                .collect();
            (source, values)
        })
        .collect())
}
