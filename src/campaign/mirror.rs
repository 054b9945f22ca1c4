//! Object URLs (`s3://bucket/key`) and where this machine keeps a copy of each: pure functions
//! of text, no I/O, so that the executors' path handling is testable without a bucket.

use std::path::{Path, PathBuf};

/// The URL schemes read through object storage.
pub(super) const SCHEMES: [&str; 7] = ["s3", "s3a", "gs", "az", "azure", "abfs", "abfss"];

/// A URL that is not one object.
#[derive(Debug, thiserror::Error)]
#[error("{url}: {what}")]
pub struct UrlError {
    /// The URL.
    pub url: String,
    /// What is wrong with it.
    pub what: String,
}

/// Whether `p` names an object (`s3://bucket/key`, ...), not a local file.
pub fn is_url(p: &Path) -> bool {
    p.to_str().is_some_and(|s| scheme_len(s).is_some())
}

/// The length of `s`'s `scheme://` when it starts with one of ours.
pub(super) fn scheme_len(s: &str) -> Option<usize> {
    let (scheme, _) = s.split_once("://")?;
    SCHEMES.contains(&scheme).then_some(scheme.len() + 3)
}

/// `rel` resolved against the object "directory" `base` (`s3://b/dir`), with `.` and `..`
/// removed the way a file system would; `rel` itself when it is a URL.
pub fn join(base: &str, rel: &str) -> Result<String, UrlError> {
    if scheme_len(rel).is_some() {
        return normalize(rel);
    }
    normalize(&format!("{}/{rel}", base.trim_end_matches('/')))
}

/// `url` with `.` and `..` segments applied; an error when `..` leaves the bucket.
fn normalize(url: &str) -> Result<String, UrlError> {
    let n = scheme_len(url).ok_or_else(|| UrlError {
        url: url.into(),
        what: format!("not an object URL (schemes: {})", SCHEMES.join(", ")),
    })?;
    let (head, rest) = url.split_at(n);
    let mut parts = rest.split('/');
    let bucket = parts.next().unwrap_or_default();
    let mut key: Vec<&str> = Vec::new();
    for p in parts {
        match p {
            "" | "." => {}
            ".." => {
                if key.pop().is_none() {
                    return Err(UrlError {
                        url: url.into(),
                        what: "`..` leaves the bucket".into(),
                    });
                }
            }
            p => key.push(p),
        }
    }
    if bucket.is_empty() {
        return Err(UrlError {
            url: url.into(),
            what: "no bucket".into(),
        });
    }
    Ok(format!("{head}{bucket}/{}", key.join("/")))
}

/// The object `to` relative to the object "directory" `from` (`../../rec/rep-01.mcap`), the
/// same on every machine's mirror (scheme and bucket are its first two folders); `None` unless
/// both are object URLs.
pub fn relative(from: &str, to: &str) -> Option<String> {
    let segments = |u: &str| -> Option<Vec<String>> {
        let n = scheme_len(u)?;
        let mut v = vec![u[..n - 3].to_owned()];
        v.extend(
            u[n..]
                .split('/')
                .filter(|s| !s.is_empty())
                .map(str::to_owned),
        );
        Some(v)
    };
    let (from, to) = (segments(from)?, segments(to)?);
    let common = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
    let mut parts = vec![".."; from.len() - common];
    parts.extend(to[common..].iter().map(String::as_str));
    Some(parts.join("/"))
}

/// The parent "directory" of an object URL.
pub fn parent(url: &str) -> String {
    match url.rsplit_once('/') {
        Some((p, _)) if p.len() > scheme_len(url).unwrap_or(0) => p.to_owned(),
        _ => url.to_owned(),
    }
}

/// Whether `text` names an object anywhere (one of our schemes at a token's start).
pub fn names_objects(text: &str) -> bool {
    let marker = Mirror {
        root: PathBuf::new(),
        prefix: "\0".into(),
    };
    marker.localize(text) != text
}

/// Where objects are kept on this machine: `URL` ↔ `root/scheme/bucket/key`.
#[derive(Clone, Debug)]
pub struct Mirror {
    pub(super) root: PathBuf,
    /// `root/`, as text, for the prefix swap.
    prefix: String,
}

impl Mirror {
    /// The mirror under `cache` (`cache/objects`).
    pub fn new(cache: &Path) -> std::io::Result<Mirror> {
        let root = std::path::absolute(cache.join("objects"))?;
        let prefix = format!("{}/", root.display());
        // The swap runs over JSON and TOML text; a quote or backslash would need escaping there.
        if root.to_str().is_none()
            || prefix.contains(['"', '\\'])
            || prefix.contains(char::is_control)
        {
            return Err(std::io::Error::other(format!(
                "{}: the cache directory's path must be plain UTF-8 without quotes or backslashes",
                root.display()
            )));
        }
        Ok(Mirror { root, prefix })
    }

    /// The mirror this machine uses (see the module's documentation).
    pub fn from_env() -> std::io::Result<Mirror> {
        let var = |k: &str| {
            std::env::var_os(k)
                .filter(|v| !v.is_empty())
                .map(PathBuf::from)
        };
        let cache = var("HILRIG_CACHE")
            .or_else(|| var("XDG_CACHE_HOME").map(|p| p.join("hilrig")))
            .or_else(|| var("HOME").map(|p| p.join(".cache/hilrig")))
            .unwrap_or_else(|| std::env::temp_dir().join("hilrig-cache"));
        Mirror::new(&cache)
    }

    /// Where the object `url` is kept here.
    pub fn local(&self, url: &str) -> PathBuf {
        PathBuf::from(self.localize(url))
    }

    /// The object a mirror path stands for, if it is one.
    pub fn url_of(&self, path: &Path) -> Option<String> {
        let s = path.to_str()?;
        let rest = s.strip_prefix(&self.prefix)?;
        let (scheme, key) = rest.split_once('/')?;
        SCHEMES
            .contains(&scheme)
            .then(|| format!("{scheme}://{key}"))
    }

    /// `text` with every object URL in it replaced by its mirror path.
    pub fn localize(&self, text: &str) -> String {
        let mut out = String::with_capacity(text.len());
        let mut rest = text;
        while let Some(i) = rest.find("://") {
            let head = &rest[..i];
            // The scheme: the letters right before `://`, at a token's start.
            let start = head
                .rfind(|c: char| !c.is_ascii_alphanumeric())
                .map_or(0, |k| k + 1);
            let scheme = &head[start..];
            out.push_str(&head[..start]);
            if SCHEMES.contains(&scheme) {
                out.push_str(&self.prefix);
                out.push_str(scheme);
                out.push('/');
            } else {
                out.push_str(scheme);
                out.push_str("://");
            }
            rest = &rest[i + 3..];
        }
        out.push_str(rest);
        out
    }

    /// `text` with every mirror path in it replaced by its object URL (the inverse of
    /// [`Mirror::localize`]).
    pub fn globalize(&self, text: &str) -> String {
        let mut out = String::with_capacity(text.len());
        let mut rest = text;
        while let Some(i) = rest.find(&self.prefix) {
            out.push_str(&rest[..i]);
            let after = &rest[i + self.prefix.len()..];
            match SCHEMES
                .iter()
                .find(|s| after.strip_prefix(**s).is_some_and(|a| a.starts_with('/')))
            {
                Some(s) => {
                    out.push_str(s);
                    out.push_str("://");
                    rest = &after[s.len() + 1..];
                }
                None => {
                    out.push_str(&self.prefix);
                    rest = after;
                }
            }
        }
        out.push_str(rest);
        out
    }

    /// Where the ETag of the copy at `local` is noted.
    pub(super) fn etag_path(&self, local: &Path) -> PathBuf {
        let rel = local.strip_prefix(&self.root).unwrap_or(local);
        self.root
            .parent()
            .unwrap_or(&self.root)
            .join("etags")
            .join(rel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_join_like_paths_and_stay_in_their_bucket() {
        assert_eq!(
            join("s3://b/fixtures/parking", "../../rigs/demo.toml").unwrap(),
            "s3://b/rigs/demo.toml"
        );
        assert_eq!(
            join("s3://b/d", "./rep-01/x.mcap").unwrap(),
            "s3://b/d/rep-01/x.mcap"
        );
        assert_eq!(join("s3://b/d", "gs://c/k").unwrap(), "gs://c/k");
        assert!(join("s3://b/d", "../../x").is_err());
        assert_eq!(parent("s3://b/d/x.mcap"), "s3://b/d");
        assert_eq!(
            relative("s3://b/out/gap/p", "s3://b/fixtures/rep-01/scene.toml").as_deref(),
            Some("../../../fixtures/rep-01/scene.toml")
        );
        assert_eq!(
            relative("s3://b/out", "gs://c/x").as_deref(),
            Some("../../../gs/c/x")
        );
        assert_eq!(relative("s3://b/out", "/local/x"), None);
        assert!(is_url(Path::new("az://c/x")));
        assert!(!is_url(Path::new("/data/s3://x")));
        assert!(!is_url(Path::new("http://host/x")));
    }

    #[test]
    fn the_mirror_swaps_urls_for_paths_and_back() {
        let m = Mirror::new(Path::new("/cache")).unwrap();
        let text = r#"{"a":"s3://b/rec/rep-01.mcap","b":"/local/x","c":"https://h/x","t":"run = \"gs://c/k\""}"#;
        let local = m.localize(text);
        assert_eq!(
            local,
            r#"{"a":"/cache/objects/s3/b/rec/rep-01.mcap","b":"/local/x","c":"https://h/x","t":"run = \"/cache/objects/gs/c/k\""}"#
        );
        assert_eq!(m.globalize(&local), text);
        assert_eq!(
            m.url_of(Path::new("/cache/objects/s3/b/rec/x")).as_deref(),
            Some("s3://b/rec/x")
        );
        assert_eq!(m.url_of(Path::new("/cache/objects/http/b/x")), None);
        assert_eq!(m.url_of(Path::new("/elsewhere/s3/b/x")), None);
        assert!(Mirror::new(Path::new("/ca\"che")).is_err());
    }
}
