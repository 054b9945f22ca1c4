//! Live serial source: the thin I/O shell that feeds the framer.
//!
//! Reads a serial port (tokio-serial) and stamps every chunk with the host time right after the
//! read returns (ttys have no kernel receive stamps; the chunk's first byte arrived at most one
//! chunk's transmission time earlier, which the clock model absorbs as transport delay). A cable
//! pulled or a USB adapter re-enumerated ends the read with an error or end of file; the source
//! then reopens the same path with exponential back-off (50 ms to 2 s) until it is back, so a
//! recording survives unplug and re-plug without restarting. Configure the port by a stable
//! name (`/dev/serial/by-id/...`) so that re-plugging finds it again.

use hilrig_stamp::UtcNanos;
use std::io;
use std::time::Duration;
use tokio::io::AsyncReadExt;
use tokio_serial::SerialPortBuilderExt;

/// A chunk of the byte stream with its receive time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chunk {
    /// Host time right after the read returned.
    pub host: UtcNanos,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// Counters of a serial source.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SerialStats {
    /// Bytes read.
    pub bytes: u64,
    /// Reads that returned data.
    pub chunks: u64,
    /// Times the port went away (error or end of file).
    pub disconnects: u64,
    /// Times it was opened again after a disconnect.
    pub reconnects: u64,
    /// Failed attempts to open.
    pub open_failures: u64,
    /// The last error seen, for the health report.
    pub last_error: Option<String>,
}

/// A serial port that reconnects by itself.
pub struct SerialSource {
    path: String,
    baud: u32,
    port: Option<tokio_serial::SerialStream>,
    backoff: Duration,
    retry_at: Option<tokio::time::Instant>,
    buf: Vec<u8>,
    /// Counters.
    pub stats: SerialStats,
}

const MIN_BACKOFF: Duration = Duration::from_millis(50);
const MAX_BACKOFF: Duration = Duration::from_secs(2);

impl SerialSource {
    /// Opens `path` at `baud`. Fails when the port cannot be opened the first time (a wrong path
    /// in the rig file should stop the recorder at start, not be retried forever).
    pub fn open(path: &str, baud: u32) -> io::Result<SerialSource> {
        let port = tokio_serial::new(path, baud)
            .open_native_async()
            .map_err(|e| {
                io::Error::other(format!(
                    "cannot open serial port {path} at {baud} baud: {e}"
                ))
            })?;
        Ok(SerialSource {
            path: path.to_owned(),
            baud,
            port: Some(port),
            backoff: MIN_BACKOFF,
            retry_at: None,
            buf: vec![0u8; 4096],
            stats: SerialStats::default(),
        })
    }

    /// The port path.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Whether the port is open right now.
    pub fn connected(&self) -> bool {
        self.port.is_some()
    }

    /// The next chunk of bytes; waits through disconnects (reopening with back-off). Cancel-safe:
    /// dropping the future loses no bytes and no reconnect progress.
    pub async fn next_chunk(&mut self) -> Chunk {
        loop {
            let Some(port) = self.port.as_mut() else {
                // The retry instant lives in `self`, so a caller that drops this future (a
                // timeout, a select) loses no progress: the next call waits for the same instant.
                let at = *self
                    .retry_at
                    .get_or_insert_with(|| tokio::time::Instant::now() + self.backoff);
                tokio::time::sleep_until(at).await;
                self.retry_at = None;
                match tokio_serial::new(&self.path, self.baud).open_native_async() {
                    Ok(p) => {
                        self.port = Some(p);
                        self.stats.reconnects += 1;
                        self.backoff = MIN_BACKOFF;
                    }
                    Err(e) => {
                        self.stats.open_failures += 1;
                        self.stats.last_error = Some(e.to_string());
                        self.backoff = (self.backoff * 2).min(MAX_BACKOFF);
                    }
                }
                continue;
            };
            match port.read(&mut self.buf).await {
                Ok(0) => self.disconnect("end of file".into()),
                Ok(n) => {
                    let host = UtcNanos::now();
                    self.stats.bytes += n as u64;
                    self.stats.chunks += 1;
                    return Chunk {
                        host,
                        bytes: self.buf[..n].to_vec(),
                    };
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => self.disconnect(e.to_string()),
            }
        }
    }

    fn disconnect(&mut self, why: String) {
        self.port = None;
        self.stats.disconnects += 1;
        self.stats.last_error = Some(why);
        self.backoff = MIN_BACKOFF;
    }
}
