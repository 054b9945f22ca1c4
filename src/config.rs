//! What every TOML file hilrig reads (rig, scene, model, drive, study, phases, parameter
//! ranges) must satisfy beyond its schema: every number finite.
//!
//! TOML reads `nan`, `inf` and `-inf` as floats, and serde hands them on. A NaN threshold
//! compares false with everything, so a check written "fail when above the limit" would pass
//! every run; an infinite range turns a limit off without a word. One walk over the parsed
//! document, before the typed parse, refuses them all and names the key.

/// A number of a TOML file that is not finite.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key} = {value}: every number must be finite")]
pub struct NonFinite {
    /// Its dotted key path.
    pub key: String,
    /// The value (NaN or an infinity).
    pub value: f64,
}

/// The first number in `text` that is not finite; `Ok` when there is none or the text is not
/// TOML (the typed parse then says where).
pub fn check_finite(text: &str) -> Result<(), NonFinite> {
    let Ok(doc) = text.parse::<toml::Table>() else {
        return Ok(());
    };
    let mut path = Vec::new();
    match first_non_finite(&toml::Value::Table(doc), &mut path) {
        Some(value) => Err(NonFinite {
            key: path.join("."),
            value,
        }),
        None => Ok(()),
    }
}

/// Why a TOML file cannot be read as the type it should hold.
#[derive(Debug, thiserror::Error)]
pub enum TomlFileError {
    /// The file cannot be read.
    #[error("cannot read {}: {source}", .path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// A number of it is NaN or infinite.
    #[error("{}: {source}", .path.display())]
    NonFinite {
        /// The file.
        path: std::path::PathBuf,
        /// The key and the value.
        #[source]
        source: NonFinite,
    },
    /// It is not TOML, or not of the type (an unknown key, a missing field: serde says where).
    #[error("{}: {source}", .path.display())]
    Toml {
        /// The file.
        path: std::path::PathBuf,
        /// Where and why.
        #[source]
        source: toml::de::Error,
    },
}

/// Reads the TOML file at `path` as a `T`, every number finite ([`check_finite`]).
pub fn read_toml<T: serde::de::DeserializeOwned>(
    path: &std::path::Path,
) -> Result<T, TomlFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| TomlFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    check_finite(&text).map_err(|source| TomlFileError::NonFinite {
        path: path.to_owned(),
        source,
    })?;
    toml::from_str(&text).map_err(|source| TomlFileError::Toml {
        path: path.to_owned(),
        source,
    })
}

/// Depth first; `path` holds the key path of the value found.
fn first_non_finite(v: &toml::Value, path: &mut Vec<String>) -> Option<f64> {
    match v {
        toml::Value::Float(f) if !f.is_finite() => Some(*f),
        toml::Value::Table(t) => {
            for (k, v) in t {
                path.push(k.clone());
                if let Some(f) = first_non_finite(v, path) {
                    return Some(f);
                }
                path.pop();
            }
            None
        }
        toml::Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                let last = path.pop().unwrap_or_default();
                path.push(format!("{last}[{}]", i + 1));
                if let Some(f) = first_non_finite(v, path) {
                    return Some(f);
                }
                path.pop();
                path.push(last);
            }
            None
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_the_key_of_the_first_non_finite_number() {
        assert_eq!(check_finite("a = 1.0\n[b]\nc = [1, 2.5]\n"), Ok(()));
        let e = check_finite("[thresholds]\nmax_jump_sigma = nan\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("thresholds.max_jump_sigma = NaN"), "{e}");
        let e = check_finite("[[effect]]\nx = 1.0\n[[effect]]\nx = -inf\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("effect[2].x = -inf"), "{e}");
        let e = check_finite("p = [[1.0, 2.0], [3.0, inf]]\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p[2][2] = inf"), "{e}");
        // Not TOML: left to the typed parse, which says where.
        assert_eq!(check_finite("= broken"), Ok(()));
    }
}
