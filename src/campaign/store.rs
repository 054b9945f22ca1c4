//! Object storage: a campaign's files and outputs at `s3://`, `gs://` or `az://` URLs, run by
//! workers that share no disk.
//!
//! The commands themselves read and write local files: `check` and `compare` seek in MCAP
//! files, `resim` streams a recording while it writes another, and a re-simulation quotes its
//! input files. So a task runs on a local mirror of the objects it names; this module is the
//! mirror and the clients, staged.rs moves the files. Before a task runs its inputs are
//! fetched into the mirror (a copy is kept while the object's ETag is unchanged, so a worker
//! fetches a drive once); after it ran its outputs and log are put back, and its stamp last, so
//! that a stamp in the bucket means every output it names is there too. The mirror of
//! `s3://bucket/key` is `CACHE/objects/s3/bucket/key`, with `CACHE` from `HILRIG_CACHE`, else
//! `$XDG_CACHE_HOME/hilrig`, else `~/.cache/hilrig`.
//!
//! Credentials come from the environment as each cloud's SDK reads them (`AWS_ACCESS_KEY_ID`,
//! `AWS_ENDPOINT_URL` for an S3-compatible server, `GOOGLE_APPLICATION_CREDENTIALS`,
//! `AZURE_STORAGE_ACCOUNT_KEY`, ...). They are never printed. A URL whose cloud has no
//! credentials in the environment is refused before anything is asked of the network: without
//! them the clients would try the instance metadata service, which on a workstation fails only
//! after its retries.

use super::mirror::{parent, scheme_len, Mirror, UrlError};
use object_store::path::Path as ObjectPath;
use object_store::ObjectStore;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use tokio::io::AsyncWriteExt;

/// What went wrong with object storage.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// No credentials for the URL's cloud in the environment.
    #[error("{url}: no credentials for {cloud} in the environment: set {vars}")]
    NoCredentials {
        /// The URL.
        url: String,
        /// The cloud.
        cloud: &'static str,
        /// The variables that would give them.
        vars: &'static str,
    },
    /// Not a URL this module reads, or not one object.
    #[error(transparent)]
    Url(#[from] UrlError),
    /// The store refused or failed a request.
    #[error("{url}: {source}")]
    Object {
        /// The object's URL.
        url: String,
        /// The client's error.
        source: object_store::Error,
    },
    /// The local mirror.
    #[error("{path}: {source}")]
    Io {
        /// The mirror's file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
}

/// The clients of the buckets a process reaches, and the mirror.
pub struct Store {
    runtime: tokio::runtime::Runtime,
    clients: Mutex<HashMap<String, Arc<dyn ObjectStore>>>,
    /// Where objects are kept here.
    pub mirror: Mirror,
}

impl std::fmt::Debug for Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Store")
            .field("mirror", &self.mirror)
            .finish()
    }
}

/// The process's store, made on first use.
pub fn shared() -> Result<&'static Store, StoreError> {
    static STORE: OnceLock<Store> = OnceLock::new();
    if let Some(s) = STORE.get() {
        return Ok(s);
    }
    let mirror = Mirror::from_env().map_err(|source| StoreError::Io {
        path: "HILRIG_CACHE".into(),
        source,
    })?;
    let s = Store::new(mirror)?;
    Ok(STORE.get_or_init(|| s))
}

/// The environment variables that give a cloud's credentials (any one suffices), as the cloud's
/// SDK reads them.
fn credentials(scheme: &str) -> (&'static str, &'static [&'static str], &'static str) {
    match scheme {
        "s3" | "s3a" => (
            "S3",
            &[
                "AWS_ACCESS_KEY_ID",
                "AWS_WEB_IDENTITY_TOKEN_FILE",
                "AWS_CONTAINER_CREDENTIALS_RELATIVE_URI",
                "AWS_CONTAINER_CREDENTIALS_FULL_URI",
                "AWS_METADATA_ENDPOINT",
                "AWS_SKIP_SIGNATURE",
            ],
            "AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (and AWS_ENDPOINT_URL for a server other than AWS), or AWS_WEB_IDENTITY_TOKEN_FILE; on an EC2 instance with a role, AWS_METADATA_ENDPOINT",
        ),
        "gs" => (
            "Google Cloud Storage",
            &[
                "GOOGLE_APPLICATION_CREDENTIALS",
                "GOOGLE_SERVICE_ACCOUNT",
                "GOOGLE_SERVICE_ACCOUNT_PATH",
                "GOOGLE_SERVICE_ACCOUNT_KEY",
                "GOOGLE_SKIP_SIGNATURE",
            ],
            "GOOGLE_APPLICATION_CREDENTIALS (a service account's key file)",
        ),
        _ => (
            "Azure Blob Storage",
            &[
                "AZURE_STORAGE_ACCOUNT_KEY",
                "AZURE_STORAGE_ACCESS_KEY",
                "AZURE_STORAGE_SAS_KEY",
                "AZURE_STORAGE_TOKEN",
                "AZURE_CLIENT_SECRET",
                "AZURE_FEDERATED_TOKEN_FILE",
                "AZURE_USE_AZURE_CLI",
                "AZURE_STORAGE_USE_EMULATOR",
                "AZURE_SKIP_SIGNATURE",
            ],
            "AZURE_STORAGE_ACCOUNT_NAME and AZURE_STORAGE_ACCOUNT_KEY (or a SAS key, or a client secret)",
        ),
    }
}

impl Store {
    /// A store that keeps its objects in `mirror`.
    pub fn new(mirror: Mirror) -> Result<Store, StoreError> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|source| StoreError::Io {
                path: mirror.root.clone(),
                source,
            })?;
        Ok(Store {
            runtime,
            clients: Mutex::new(HashMap::new()),
            mirror,
        })
    }

    /// The client of `url`'s bucket and the object's key in it.
    fn client(&self, url: &str) -> Result<(Arc<dyn ObjectStore>, ObjectPath), StoreError> {
        let bad = |what: String| UrlError {
            url: url.into(),
            what,
        };
        let n = scheme_len(url).ok_or_else(|| bad("not an object URL".into()))?;
        let scheme = &url[..n - 3];
        let parsed = url::Url::parse(url).map_err(|e| bad(e.to_string()))?;
        let key = ObjectPath::from_url_path(parsed.path()).map_err(|e| bad(e.to_string()))?;
        let bucket = format!("{scheme}://{}", parsed.host_str().unwrap_or_default());
        let mut clients = self.clients.lock().expect("not poisoned");
        if let Some(c) = clients.get(&bucket) {
            return Ok((c.clone(), key));
        }
        let (cloud, vars, hint) = credentials(scheme);
        if !vars
            .iter()
            .any(|v| std::env::var_os(v).is_some_and(|x| !x.is_empty()))
        {
            return Err(StoreError::NoCredentials {
                url: url.into(),
                cloud,
                vars: hint,
            });
        }
        let object = |source| StoreError::Object {
            url: url.into(),
            source,
        };
        let client: Arc<dyn ObjectStore> = match scheme {
            "s3" | "s3a" => Arc::new(
                object_store::aws::AmazonS3Builder::from_env()
                    .with_url(&bucket)
                    .build()
                    .map_err(object)?,
            ),
            "gs" => Arc::new(
                object_store::gcp::GoogleCloudStorageBuilder::from_env()
                    .with_url(&bucket)
                    .build()
                    .map_err(object)?,
            ),
            _ => Arc::new(
                object_store::azure::MicrosoftAzureBuilder::from_env()
                    .with_url(&bucket)
                    .build()
                    .map_err(object)?,
            ),
        };
        clients.insert(bucket, client.clone());
        Ok((client, key))
    }

    /// The object's ETag (or size and time where a store gives none); `None` when it does not
    /// exist.
    fn version(&self, url: &str) -> Result<Option<String>, StoreError> {
        let (c, key) = self.client(url)?;
        match self.runtime.block_on(c.head(&key)) {
            Ok(m) => Ok(Some(m.e_tag.unwrap_or_else(|| {
                format!("{} {}", m.size, m.last_modified.to_rfc3339())
            }))),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(source) => Err(StoreError::Object {
                url: url.into(),
                source,
            }),
        }
    }

    /// Whether the object exists.
    pub fn exists(&self, url: &str) -> Result<bool, StoreError> {
        Ok(self.version(url)?.is_some())
    }

    /// That the bucket of `url` answers with these credentials (a listing of one key under it).
    pub fn reachable(&self, url: &str) -> Result<(), StoreError> {
        use futures::StreamExt;
        let (c, key) = self.client(url)?;
        let first = self
            .runtime
            .block_on(async { c.list(Some(&key)).next().await });
        match first {
            Some(Err(source)) => Err(StoreError::Object {
                url: url.into(),
                source,
            }),
            _ => Ok(()),
        }
    }

    /// The objects whose URL matches the glob `pattern` (`*` within one path segment), sorted.
    pub fn glob(&self, pattern: &str) -> Result<Vec<String>, StoreError> {
        use futures::TryStreamExt;
        let bad = |what: String| UrlError {
            url: pattern.into(),
            what,
        };
        let matcher = glob::Pattern::new(pattern).map_err(|e| bad(e.to_string()))?;
        let options = glob::MatchOptions {
            require_literal_separator: true,
            ..Default::default()
        };
        // Listed from the last `/` before the first wildcard.
        let literal = &pattern[..pattern.find(['*', '?', '[']).unwrap_or(pattern.len())];
        let dir = parent(&format!("{literal}x"));
        let (c, key) = self.client(&dir)?;
        let bucket = &dir[..dir.len() - key.as_ref().len()];
        let listed: Vec<object_store::ObjectMeta> = self
            .runtime
            .block_on(c.list(Some(&key)).try_collect())
            .map_err(|source| StoreError::Object {
                url: dir.clone(),
                source,
            })?;
        let mut found: Vec<String> = listed
            .into_iter()
            .map(|m| format!("{}{}", bucket, m.location))
            .filter(|u| matcher.matches_with(u, options))
            .collect();
        found.sort();
        Ok(found)
    }

    /// The object `url` in the mirror, fetched unless the copy there is of the same version;
    /// `None` (and no copy left) when the object does not exist.
    pub fn fetch(&self, url: &str) -> Result<Option<PathBuf>, StoreError> {
        let local = self.mirror.local(url);
        let noted = self.mirror.etag_path(&local);
        let io = |path: &Path| {
            let path = path.to_owned();
            move |source| StoreError::Io { path, source }
        };
        let Some(version) = self.version(url)? else {
            remove_copy(&local)?;
            remove_copy(&noted)?;
            return Ok(None);
        };
        if local.is_file() && std::fs::read_to_string(&noted).ok().as_deref() == Some(&version) {
            return Ok(Some(local));
        }
        let (c, key) = self.client(url)?;
        for p in [&local, &noted] {
            let dir = p.parent().expect("under the mirror");
            std::fs::create_dir_all(dir).map_err(io(dir))?;
        }
        // Into a file renamed into place: tasks on one machine may fetch the same drive at once.
        let tmp = unique(&local);
        let got = self.runtime.block_on(async {
            use futures::TryStreamExt;
            let mut stream = c.get(&key).await?.into_stream();
            let mut file =
                tokio::fs::File::create(&tmp)
                    .await
                    .map_err(|e| object_store::Error::Generic {
                        store: "mirror",
                        source: Box::new(e),
                    })?;
            while let Some(chunk) = stream.try_next().await? {
                file.write_all(&chunk)
                    .await
                    .map_err(|e| object_store::Error::Generic {
                        store: "mirror",
                        source: Box::new(e),
                    })?;
            }
            file.flush()
                .await
                .map_err(|e| object_store::Error::Generic {
                    store: "mirror",
                    source: Box::new(e),
                })
        });
        if let Err(source) = got {
            let _ = std::fs::remove_file(&tmp);
            return Err(StoreError::Object {
                url: url.into(),
                source,
            });
        }
        std::fs::rename(&tmp, &local).map_err(io(&local))?;
        write_whole(&noted, version.as_bytes())?;
        Ok(Some(local))
    }

    /// Puts the mirror's copy of `url` into the store (in parts, so a re-simulation of any size
    /// goes up in bounded memory) and notes the version it made.
    pub fn put(&self, url: &str) -> Result<(), StoreError> {
        let local = self.mirror.local(url);
        let (c, key) = self.client(url)?;
        let put = self.runtime.block_on(async {
            let mut file = tokio::fs::File::open(&local).await?;
            let mut w = object_store::buffered::BufWriter::new(c.clone(), key.clone());
            tokio::io::copy(&mut file, &mut w).await?;
            w.shutdown().await
        });
        put.map_err(|e| StoreError::Object {
            url: url.into(),
            source: object_store::Error::Generic {
                store: "upload",
                source: Box::new(e),
            },
        })?;
        if let Some(version) = self.version(url)? {
            write_whole(&self.mirror.etag_path(&local), version.as_bytes())?;
        }
        Ok(())
    }

    /// The object's bytes (`None` when it does not exist), without the mirror.
    pub fn get_bytes(&self, url: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let (c, key) = self.client(url)?;
        let got = self
            .runtime
            .block_on(async { c.get(&key).await?.bytes().await });
        match got {
            Ok(b) => Ok(Some(b.to_vec())),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(source) => Err(StoreError::Object {
                url: url.into(),
                source,
            }),
        }
    }

    /// Deletes the object `url` and the mirror's copy of it (one that is not there is no
    /// error).
    pub fn remove(&self, url: &str) -> Result<(), StoreError> {
        let (c, key) = self.client(url)?;
        match self.runtime.block_on(c.delete(&key)) {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => {}
            Err(source) => {
                return Err(StoreError::Object {
                    url: url.into(),
                    source,
                })
            }
        }
        let local = self.mirror.local(url);
        remove_copy(&self.mirror.etag_path(&local))?;
        remove_copy(&local)
    }

    /// Writes `bytes` as the object `url`.
    pub fn put_bytes(&self, url: &str, bytes: Vec<u8>) -> Result<(), StoreError> {
        let (c, key) = self.client(url)?;
        self.runtime
            .block_on(c.put(&key, bytes.into()))
            .map(|_| ())
            .map_err(|source| StoreError::Object {
                url: url.into(),
                source,
            })
    }
}

/// Writes `bytes` as the file `p` through a file renamed into place (another process on this
/// machine may read it meanwhile), its folder made first.
pub(super) fn write_whole(p: &Path, bytes: &[u8]) -> Result<(), StoreError> {
    let io = |path: &Path| {
        let path = path.to_owned();
        move |source| StoreError::Io { path, source }
    };
    let dir = p.parent().expect("under the mirror");
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let tmp = unique(p);
    std::fs::write(&tmp, bytes).map_err(io(&tmp))?;
    std::fs::rename(&tmp, p).map_err(io(p))
}

/// Removes the copy `p`, if there is one.
pub(super) fn remove_copy(p: &Path) -> Result<(), StoreError> {
    match std::fs::remove_file(p) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StoreError::Io {
            path: p.to_owned(),
            source: e,
        }),
        _ => Ok(()),
    }
}

/// A name next to `p` no other process or thread uses.
fn unique(p: &Path) -> PathBuf {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut name = p.file_name().unwrap_or_default().to_owned();
    name.push(format!(".part-{}-{n}", std::process::id()));
    p.with_file_name(name)
}
