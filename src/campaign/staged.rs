//! A campaign's plan on object storage, as one machine runs it: the plan with every object's
//! URL replaced by this machine's copy of it (the executors run that plan as they run any), and
//! the moves around each task: its inputs fetched before, its outputs, log and stamp put after
//! (store.rs says why the commands work on copies).

use super::mirror;
use super::plan::{Plan, Task};
use super::store::{self, Store, StoreError};
use std::path::{Path, PathBuf};

/// A plan whose files are objects, as a machine runs it: the plan with every URL replaced by
/// its mirror path (the executors run that one as they run any plan), and the moves in and out
/// around each task.
pub struct Staged {
    /// The plan on this machine's mirror.
    pub plan: Plan,
    store: &'static Store,
    /// The plan's own files (gap studies): made by each machine, put but never fetched.
    made: std::collections::HashSet<PathBuf>,
}

impl Staged {
    /// The plan staged on this machine; `None` when it names no object.
    pub fn new(plan: &Plan) -> Result<Option<Staged>, StoreError> {
        let json = serde_json::to_string(plan).expect("a plan serializes");
        if !mirror::names_objects(&json) {
            return Ok(None);
        }
        let store = store::shared()?;
        let plan: Plan = serde_json::from_str(&store.mirror.localize(&json))
            .expect("a plan with its paths swapped reads back");
        let made = plan.files.iter().map(|f| f.path.clone()).collect();
        Ok(Some(Staged { plan, store, made }))
    }

    fn url(&self, p: &Path) -> Option<String> {
        self.store.mirror.url_of(p)
    }

    /// Fetches what deciding on and running `task` needs: its inputs, its outputs (to check
    /// them against its stamp) and its stamp. A missing object leaves no copy behind, so the
    /// executor sees what the bucket holds.
    pub fn pull(&self, task: &Task) -> Result<(), StoreError> {
        for p in task.inputs.iter().chain(&task.outputs) {
            if self.made.contains(p) {
                continue;
            }
            if let Some(url) = self.url(p) {
                self.store.fetch(&url)?;
            }
        }
        self.pull_stamps(std::slice::from_ref(&task.id))
    }

    /// Fetches the stamps of the tasks `ids`, each read back with this machine's paths.
    pub fn pull_stamps(&self, ids: &[String]) -> Result<(), StoreError> {
        for id in ids {
            let local = super::stamp::path(&self.plan.out, id);
            let Some(url) = self.url(&local) else {
                continue;
            };
            match self.store.get_bytes(&url)? {
                Some(b) => {
                    let text = self.store.mirror.localize(&String::from_utf8_lossy(&b));
                    store::write_whole(&local, text.as_bytes())?;
                }
                None => store::remove_copy(&local)?,
            }
        }
        Ok(())
    }

    /// Puts what `task` left: its log, and when it `stamped` a result its outputs and then its
    /// stamp (with the objects' URLs, so that any machine reads it).
    pub fn push(&self, task: &Task, stamped: bool) -> Result<(), StoreError> {
        if let Some(url) = self.url(&task.log) {
            if task.log.is_file() {
                self.store.put(&url)?;
            }
        }
        if !stamped {
            return Ok(());
        }
        for p in task.inputs.iter().filter(|p| self.made.contains(*p)) {
            if let Some(url) = self.url(p) {
                self.store.put(&url)?;
            }
        }
        for p in &task.outputs {
            if let Some(url) = self.url(p) {
                self.store.put(&url)?;
            }
        }
        let local = super::stamp::path(&self.plan.out, &task.id);
        if let Some(url) = self.url(&local) {
            let text = std::fs::read_to_string(&local).map_err(|source| StoreError::Io {
                path: local.clone(),
                source,
            })?;
            self.store
                .put_bytes(&url, self.store.mirror.globalize(&text).into_bytes())?;
        }
        Ok(())
    }

    /// Deletes what `task` put before, its outputs and its stamp, from the bucket and the
    /// mirror (see [`super::local`]'s `clear`).
    pub fn remove(&self, task: &Task) -> Result<(), StoreError> {
        let stamp = super::stamp::path(&self.plan.out, &task.id);
        for p in task.outputs.iter().chain([&stamp]) {
            if let Some(url) = self.url(p) {
                self.store.remove(&url)?;
            }
        }
        Ok(())
    }

    /// Puts a file the executor wrote into the mirror (the plan itself).
    pub fn put(&self, local: &Path) -> Result<(), StoreError> {
        match self.url(local) {
            Some(url) => self.store.put(&url),
            None => Ok(()),
        }
    }

    /// A mirror path as the user named it (its URL), for messages.
    pub fn named(&self, text: &str) -> String {
        self.store.mirror.globalize(text)
    }
}
