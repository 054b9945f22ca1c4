//! A local Ray cluster for the tests (PyPI `ray` in the test venv): a head that takes no tasks
//! and two worker nodes, started with `ray start`; its processes are found by its own temp dir
//! in their command lines, so that dropping it stops this cluster and no other.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::Command;

/// The `ray` command of the test venv.
pub fn ray() -> PathBuf {
    super::python().with_file_name("ray")
}

/// A cluster started for this test; its processes (found by its own temp dir in their command
/// lines) are killed when it is dropped, and no other cluster on the machine is touched.
pub struct Cluster {
    temp: tempfile::TempDir,
    /// HOST:PORT of its head.
    pub address: String,
    /// One cluster at a time in the test process: the tests are one binary, and two clusters
    /// started together contend for Ray's fixed default ports (the client server's 10001
    /// among them) and for two cores between some twenty processes.
    _alone: std::sync::MutexGuard<'static, ()>,
}

/// Held by the cluster that runs.
static ONE_CLUSTER: std::sync::Mutex<()> = std::sync::Mutex::new(());

impl Cluster {
    /// Starts a head and two worker nodes of one CPU each.
    pub fn start() -> Cluster {
        // A test that failed while holding it leaves it poisoned; its cluster is gone all the same.
        let alone = ONE_CLUSTER
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let temp = tempfile::Builder::new()
            .prefix("ray")
            .tempdir_in("/tmp")
            .unwrap();
        let port = free_port();
        let address = format!("127.0.0.1:{port}");
        let start = |args: &[&str]| {
            let out = Command::new(ray())
                .arg("start")
                .args(args)
                .env("RAY_USAGE_STATS_ENABLED", "0")
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "ray start {args:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        };
        // The head takes no tasks: they run on the two workers.
        start(&[
            "--head",
            "--port",
            &port.to_string(),
            "--num-cpus",
            "0",
            "--include-dashboard",
            "false",
            "--temp-dir",
            &temp.path().display().to_string(),
            "--disable-usage-stats",
        ]);
        let cluster = Cluster {
            temp,
            address,
            _alone: alone,
        };
        for _ in 0..2 {
            start(&["--address", &cluster.address, "--num-cpus", "1"]);
        }
        cluster
    }

    /// Processes of this cluster: (pid, command line).
    pub fn processes(&self) -> Vec<(i32, String)> {
        let needle = self.temp.path().display().to_string();
        let mut found = Vec::new();
        for e in std::fs::read_dir("/proc").unwrap().flatten() {
            let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else {
                continue;
            };
            if let Ok(cmdline) = std::fs::read(e.path().join("cmdline")) {
                let text = String::from_utf8_lossy(&cmdline).replace('\0', " ");
                if text.contains(&needle) {
                    found.push((pid, text));
                }
            }
        }
        found
    }

    /// Kills a worker node that has finished a task of `program` and is running another (its
    /// raylet and every process it started), waiting up to ten minutes for one while `running`
    /// says the work goes on. A busy node, not whichever raylet comes first, makes the loss
    /// real (an idle node's death costs the run nothing); one that has finished a task makes
    /// both nodes' work show in the outcomes, whatever Ray's placement (a node killed during
    /// its first task leaves only the other's). Returns the node's id (its raylet's
    /// `--node_id`), as a task's `ray.get_runtime_context().get_node_id()` gives it.
    pub fn kill_a_worker_node_mid_task(
        &self,
        program: &std::path::Path,
        running: &mut dyn FnMut() -> bool,
    ) -> String {
        let program = program.display().to_string();
        let started = std::time::Instant::now();
        // Per worker raylet, the task processes seen under it.
        let mut seen: std::collections::BTreeMap<i32, BTreeSet<i32>> = Default::default();
        let (raylet, tree) = 'found: loop {
            let raylets: Vec<i32> = self
                .processes()
                .into_iter()
                .filter(|(_, c)| c.contains("raylet/raylet") && !c.contains(" --head"))
                .map(|(pid, _)| pid)
                .collect();
            for raylet in raylets {
                let tree = descendants_of(raylet);
                let now: BTreeSet<i32> = tree
                    .iter()
                    .copied()
                    .filter(|&p| cmdline(p).starts_with(&program))
                    .collect();
                let before = seen.entry(raylet).or_default();
                let finished_one = before.iter().any(|p| !now.contains(p));
                if finished_one && !now.is_empty() {
                    break 'found (raylet, tree);
                }
                before.extend(now);
            }
            assert!(
                running(),
                "the run ended before a worker node had finished a task and begun another"
            );
            assert!(
                started.elapsed() < std::time::Duration::from_secs(600),
                "no worker node finished a task of {program} and began another"
            );
            std::thread::sleep(std::time::Duration::from_millis(10));
        };
        let node = cmdline(raylet)
            .split(' ')
            .find_map(|a| a.strip_prefix("--node_id="))
            .unwrap_or_else(|| panic!("raylet {raylet} names no --node_id"))
            .to_owned();
        for pid in std::iter::once(raylet).chain(tree) {
            let _ = nix::sys::signal::kill(
                nix::unistd::Pid::from_raw(pid),
                nix::sys::signal::Signal::SIGKILL,
            );
        }
        node
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Ray's agents rename themselves (`ray::DashboardAgent`), so their command lines no
        // longer name the temp dir: they are found as descendants, before their parents die
        // and leave them to init.
        let mut all: BTreeSet<i32> = BTreeSet::new();
        for (pid, _) in self.processes() {
            all.insert(pid);
            all.extend(descendants_of(pid));
        }
        for pid in all {
            let _ = nix::sys::signal::kill(
                nix::unistd::Pid::from_raw(pid),
                nix::sys::signal::Signal::SIGKILL,
            );
        }
    }
}

pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The command line of `pid` (arguments joined by spaces; empty when it is gone).
fn cmdline(pid: i32) -> String {
    std::fs::read(format!("/proc/{pid}/cmdline"))
        .map(|b| String::from_utf8_lossy(&b).replace('\0', " "))
        .unwrap_or_default()
}

/// Every process below `pid`: its children, theirs, and so on.
pub fn descendants_of(pid: i32) -> Vec<i32> {
    let mut out = children_of(pid);
    let mut k = 0;
    while k < out.len() {
        let next = children_of(out[k]);
        out.extend(next);
        k += 1;
    }
    out
}

/// Direct children of `pid`.
pub fn children_of(pid: i32) -> Vec<i32> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(child) = e.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        if let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) {
            // pid (comm) state ppid ...: the command may hold spaces, the fields after ')' not.
            let ppid = stat
                .rsplit_once(')')
                .and_then(|(_, rest)| rest.split_whitespace().nth(1)?.parse::<i32>().ok());
            if ppid == Some(pid) {
                out.push(child);
            }
        }
    }
    out
}
