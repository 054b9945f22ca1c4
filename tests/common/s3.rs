//! An S3-compatible server for the tests: moto's server mode (PyPI `moto[server]` in the test
//! venv), on a free port of this machine, killed when dropped.

use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A running server.
pub struct Server {
    child: Child,
    /// Its endpoint, `http://127.0.0.1:PORT`.
    pub endpoint: String,
}

/// Whether an HTTP server answers on `port`: a response, not only a connection (a connection
/// to a port in the ephemeral range that nothing listens on can be the socket's own, which
/// Linux lets a loop of connects make once in a while, and which reads back the request).
fn answers(port: u16) -> bool {
    use std::io::{Read, Write};
    let Ok(mut c) = std::net::TcpStream::connect(("127.0.0.1", port)) else {
        return false;
    };
    let _ = c.set_read_timeout(Some(Duration::from_secs(5)));
    let mut head = [0u8; 5];
    c.write_all(b"GET / HTTP/1.0\r\n\r\n").is_ok()
        && c.read_exact(&mut head).is_ok()
        && &head == b"HTTP/"
}

impl Server {
    /// Starts it and waits until it answers.
    pub fn start() -> Server {
        let port = super::ray::free_port();
        let child = Command::new(super::python())
            .args([
                "-m",
                "moto.server",
                "-H",
                "127.0.0.1",
                "-p",
                &port.to_string(),
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let server = Server {
            child,
            endpoint: format!("http://127.0.0.1:{port}"),
        };
        super::wait_until("the S3 server", || answers(port));
        server
    }

    /// `command` with the environment a user of this server sets: credentials (any, for moto),
    /// the endpoint, plain HTTP allowed.
    pub fn env<'a>(&self, command: &'a mut Command) -> &'a mut Command {
        command
            .env("AWS_ACCESS_KEY_ID", "hilrig-test")
            .env("AWS_SECRET_ACCESS_KEY", "hilrig-test")
            .env("AWS_REGION", "us-east-1")
            .env("AWS_ENDPOINT_URL", &self.endpoint)
            .env("AWS_ALLOW_HTTP", "true")
    }

    /// Puts the tree `dir` under `bucket/prefix` (boto3; the bucket is made if missing).
    pub fn put(&self, bucket: &str, prefix: &str, dir: &std::path::Path) {
        super::objects_script("s3_objects.py", &self.endpoint, "put", bucket, prefix, dir);
    }

    /// Gets everything under `bucket/prefix` into `dir` (boto3); how many objects there were.
    pub fn get(&self, bucket: &str, prefix: &str, dir: &std::path::Path) -> usize {
        let out =
            super::objects_script("s3_objects.py", &self.endpoint, "get", bucket, prefix, dir);
        String::from_utf8_lossy(&out).trim().parse().unwrap()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
