//! Azure Blob Storage for the tests: Azurite, Microsoft's own emulator (npm `azurite`, installed
//! by .ci/run into `HILRIG_AZURITE`), on a free port of this machine with its data in a temporary
//! folder, killed when dropped. Its account is the emulator's public development account.

use std::process::{Child, Command, Stdio};

/// A running emulator.
pub struct Server {
    child: Child,
    _data: tempfile::TempDir,
    /// Its blob endpoint, `http://127.0.0.1:PORT`.
    pub endpoint: String,
}

impl Server {
    /// Starts it and waits until it answers.
    pub fn start() -> Server {
        let dir = std::path::PathBuf::from(
            std::env::var("HILRIG_AZURITE").expect("HILRIG_AZURITE unset at run time; run .ci/run"),
        );
        let data = tempfile::tempdir().unwrap();
        let port = super::ray::free_port();
        let child = Command::new(dir.join("node_modules/.bin/azurite-blob"))
            .args(["--blobHost", "127.0.0.1", "--blobPort", &port.to_string()])
            .arg("--location")
            .arg(data.path())
            .args(["--silent", "--skipApiVersionCheck"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let server = Server {
            child,
            _data: data,
            endpoint: format!("http://127.0.0.1:{port}"),
        };
        super::wait_until("Azurite", || {
            std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
        });
        server
    }

    /// `command` with the environment a user of the emulator sets (object_store's names).
    pub fn env<'a>(&self, command: &'a mut Command) -> &'a mut Command {
        command
            .env("AZURE_STORAGE_USE_EMULATOR", "true")
            .env("AZURITE_BLOB_STORAGE_URL", &self.endpoint)
    }

    /// Puts the tree `dir` under `container/prefix` (the Azure SDK for Python; the container is
    /// made if missing).
    pub fn put(&self, container: &str, prefix: &str, dir: &std::path::Path) {
        super::objects_script(
            "azure_objects.py",
            &self.endpoint,
            "put",
            container,
            prefix,
            dir,
        );
    }

    /// Gets everything under `container/prefix` into `dir` (the Azure SDK for Python); how many
    /// objects there were.
    pub fn get(&self, container: &str, prefix: &str, dir: &std::path::Path) -> usize {
        let out = super::objects_script(
            "azure_objects.py",
            &self.endpoint,
            "get",
            container,
            prefix,
            dir,
        );
        String::from_utf8_lossy(&out).trim().parse().unwrap()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
