//! Forcing a recording's data onto the disk ([`super::BagOptions::durable`]) without holding
//! the writer.

/// A sync of the file's data to the disk (`fdatasync` on the file's second handle).
pub(super) type SyncFn = Box<dyn FnMut() -> std::io::Result<()> + Send>;

/// Forces a file's data onto the disk on a thread of its own, so that the writer never waits
/// for the disk. On an SD card or a USB stick an `fdatasync` can take seconds; made on the
/// writer thread it held every message behind it, the recorder's queue filled and its
/// sources dropped messages (counted, exit 1): a slow disk cost data for certain to make the
/// data before it safe. Here the writer asks and goes on; what it wrote meanwhile stays in
/// the kernel until the next sync, which starts when the last one ends. A request made
/// while another still waits is the same sync (one `fdatasync` covers every byte written
/// before it starts), so a stalled disk queues one, never a backlog. A sync that fails is
/// reported by a later call of the writer, and by [`Syncer::finish`].
pub(super) struct Syncer {
    requests: Option<std::sync::mpsc::SyncSender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
    /// The failed sync's error (its kind and message: every later call reports it again).
    failed: std::sync::Arc<std::sync::Mutex<Option<(std::io::ErrorKind, String)>>>,
    /// Requests made (chunks closed for the disk), and when the last one was.
    pub(super) asked: u64,
    pub(super) last: std::time::Instant,
}

impl Syncer {
    /// Starts the syncing thread (an error when the system cannot start one: a durable
    /// recording must not go on without its syncs).
    pub(super) fn start(mut sync: SyncFn) -> std::io::Result<Syncer> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<()>(1);
        let failed = std::sync::Arc::new(std::sync::Mutex::new(None));
        let f = failed.clone();
        let thread = std::thread::Builder::new()
            .name("mcap-sync".into())
            .spawn(move || {
                for () in rx {
                    if let Err(e) = sync() {
                        *f.lock().unwrap_or_else(std::sync::PoisonError::into_inner) =
                            Some((e.kind(), e.to_string()));
                        return;
                    }
                }
            })?;
        Ok(Syncer {
            requests: Some(tx),
            thread: Some(thread),
            failed,
            asked: 0,
            last: std::time::Instant::now(),
        })
    }

    /// Asks for a sync of everything written so far.
    pub(super) fn request(&mut self) {
        self.asked += 1;
        self.last = std::time::Instant::now();
        if let Some(tx) = &self.requests {
            // Full: a sync waits that has not started, and covers these bytes too.
            let _ = tx.try_send(());
        }
    }

    /// The error of a sync that failed: from then on, on every call (the thread has stopped,
    /// and nothing written after it is safe).
    pub(super) fn failure(&self) -> Option<std::io::Error> {
        self.failed
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .as_ref()
            .map(|(kind, text)| std::io::Error::new(*kind, text.clone()))
    }

    /// Waits for the syncs asked for, and reports one that failed.
    pub(super) fn finish(&mut self) -> Result<(), std::io::Error> {
        self.requests = None;
        if let Some(t) = self.thread.take() {
            if t.join().is_err() {
                return Err(std::io::Error::other("the thread syncing the file stopped"));
            }
        }
        self.failure().map_or(Ok(()), Err)
    }
}
