//! `hilrig campaign` (issue 31): the parking study as a campaign from and into a bucket of an S3
//! server, then here killed mid-run, resumed without redoing finished work and finished on a Ray
//! cluster that loses a worker node, gives the same files as its commands typed one by one; its
//! Parquet tables read in DuckDB give the JSON's numbers; and a campaign that cannot run says
//! why before anything runs.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Two of the parking fixture's five repetitions, the fewest `validate` takes: the campaign
/// tests run the same study two or three ways (local, a bucket, Ray, and the commands one by
/// one), and what they show (each executor's files byte for byte, skipping what is done,
/// resuming) does not need more. (Three took 164 CPU-seconds for the Ray test alone, most of
/// them in `resim`.)
const REPS: [&str; 2] = ["rep-01", "rep-02"];
/// The tasks of the campaign of [`campaign_text`] on [`REPS`]: 2 record + 2 check + 4 resim +
/// 4 compare + 2 validate + 1 report, and a table task for each of the 8 JSON files.
const TASKS: usize = 23;
const MODELS: [(&str, &str); 2] = [
    ("idealized", "idealized.toml"),
    ("truth", "truth-model.toml"),
];

/// The parking campaign without the gap workflow (a minute and a half on its own, and not
/// what these tests are about), with the parking fixture at `parking` and the rig at `rig`.
fn campaign_text(parking: &str, rig: &str) -> String {
    format!(
        r#"name = "parking"
steps = ["record", "check", "resim", "compare", "validate", "tables", "report"]
rig = "{rig}"

[[drive]]
recordings = "{parking}/rep-0[12]/drive.pcapng.zst"
scene = "{{dir}}/scene.toml"
scenario = "parking"

[[scenario]]
name = "parking"
phases = "{parking}/phases.toml"

[[model]]
name = "idealized"
file = "{parking}/idealized.toml"

[[model]]
name = "truth"
file = "{parking}/truth-model.toml"
"#
    )
}

/// [`campaign_text`] of the parking fixture with the gap step, studied against the truth
/// model.
fn with_gap_step() -> String {
    let parking = common::fixture("parking");
    campaign_text(
        &parking.to_string_lossy(),
        &common::demo_rig().to_string_lossy(),
    )
    .replace(
        "\"validate\", \"tables\"",
        "\"validate\", \"gap\", \"tables\"",
    )
    .replace(
        "phases.toml\"\n",
        "phases.toml\"\nreference_model = \"truth\"\n",
    )
}

/// The commands a user would type for the same study, in two threads, into `dir` with the
/// campaign's layout.
fn one_by_one(dir: &Path, parking: &Path, rig: &Path) {
    let parking = parking.to_owned();
    for d in [
        "rec",
        "sim/idealized",
        "sim/truth",
        "compare/idealized",
        "compare/truth",
        "validate/parking",
    ] {
        std::fs::create_dir_all(dir.join(d)).unwrap();
    }
    let rec = |rep: &str| dir.join(format!("rec/{rep}.mcap"));
    let sim = |model: &str, rep: &str| dir.join(format!("sim/{model}/{rep}.mcap"));
    std::thread::scope(|s| {
        for pair in REPS.chunks(REPS.len().div_ceil(2)) {
            let parking = &parking;
            s.spawn(move || {
                for rep in pair {
                    let scene = parking.join(rep).join("scene.toml");
                    common::hilrig_ok(&[
                        OsStr::new("record"),
                        OsStr::new("--rig"),
                        rig.as_os_str(),
                        OsStr::new("--from"),
                        parking.join(rep).join("drive.pcapng.zst").as_os_str(),
                        OsStr::new("-o"),
                        rec(rep).as_os_str(),
                    ]);
                    for (model, file) in MODELS {
                        common::hilrig_ok(&[
                            OsStr::new("resim"),
                            rec(rep).as_os_str(),
                            OsStr::new("--scene"),
                            scene.as_os_str(),
                            OsStr::new("--model"),
                            parking.join(file).as_os_str(),
                            OsStr::new("-o"),
                            sim(model, rep).as_os_str(),
                        ]);
                        common::hilrig_ok(&[
                            OsStr::new("compare"),
                            rec(rep).as_os_str(),
                            sim(model, rep).as_os_str(),
                            OsStr::new("--scene"),
                            scene.as_os_str(),
                            OsStr::new("--json"),
                            dir.join(format!("compare/{model}/{rep}.json")).as_os_str(),
                        ]);
                    }
                }
            });
        }
    });
    for (model, _) in MODELS {
        let mut cmd = Command::new(common::hilrig_bin());
        cmd.arg("validate");
        for rep in REPS {
            cmd.arg("--real").arg(rec(rep));
        }
        for rep in REPS {
            cmd.arg("--sim").arg(sim(model, rep));
        }
        cmd.arg("--phases")
            .arg(parking.join("phases.toml"))
            .arg("--json")
            .arg(dir.join(format!("validate/parking/{model}.json")));
        let out = cmd.output().unwrap();
        // 0 valid, 1 partly valid or invalid: both are results.
        assert!(
            matches!(out.status.code(), Some(0 | 1)),
            "validate {model}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

fn campaign(file: &Path, out: &Path) -> Command {
    let mut cmd = Command::new(common::hilrig_bin());
    cmd.args([
        OsStr::new("campaign"),
        file.as_os_str(),
        OsStr::new("--out"),
        out.as_os_str(),
    ])
    .args(["--jobs", "2"]);
    cmd
}

/// The tasks with a stamp: those a run finished.
fn finished(out: &Path) -> BTreeSet<String> {
    fn walk(dir: &Path, base: &Path, out: &mut BTreeSet<String>) {
        for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, base, out);
            } else if p.extension().is_some_and(|x| x == "json") {
                let id = p.strip_prefix(base).unwrap().with_extension("");
                out.insert(id.display().to_string());
            }
        }
    }
    let base = out.join("campaign/done");
    let mut ids = BTreeSet::new();
    walk(&base, &base, &mut ids);
    ids
}

/// Runs the campaign here until `n` tasks have finished, then kills it; asserts that its tasks
/// died with it (they would write on into the next run's files). Its standard output.
fn run_until_killed(file: &Path, out: &Path, n: usize) -> String {
    let mut child = campaign(file, out)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Read as it comes, so that the pipe never fills.
    let mut pipe = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        std::io::Read::read_to_string(&mut pipe, &mut text).unwrap();
        text
    });
    let started = Instant::now();
    while finished(out).len() < n {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the campaign ended before it was killed"
        );
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no progress: {:?}",
            finished(out)
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let stdout = reader.join().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(
        processes_naming(&out.display().to_string()),
        Vec::<String>::new(),
        "tasks outlived the campaign"
    );
    stdout
}

/// Processes whose command line names `needle` (a campaign's output folder).
fn processes_naming(needle: &str) -> Vec<String> {
    let mut found = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        if let Ok(cmdline) = std::fs::read(e.path().join("cmdline")) {
            let text = String::from_utf8_lossy(&cmdline).replace('\0', " ");
            if text.contains(needle) {
                found.push(text);
            }
        }
    }
    found
}

/// Lines of a campaign's output that start with `word` (ran, current), by task id.
fn tasks_reported(stdout: &str, word: &str) -> BTreeSet<String> {
    stdout
        .lines()
        .filter_map(|l| l.strip_prefix(word))
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_owned)
        .collect()
}

#[test]
fn a_campaign_from_a_bucket_killed_mid_run_here_resumed_on_ray_gives_the_same_files_as_one_by_one()
{
    let dir = tempfile::tempdir().unwrap();
    // First from and into a bucket. Then the local executor and Ray on the same files, at the
    // paths the bucket's tasks saw (this machine's copies: a re-simulation quotes its inputs'
    // paths), so that every executor's files compare byte for byte.
    let server = common::s3::Server::start();
    let from_bucket = dir.path().join("from-bucket");
    let (file, out) = in_a_bucket(&server, dir.path(), &from_bucket);
    // A gap step's trials on an engine: its workers would not see the copies of objects that
    // a task reads, so with the outputs in a bucket an engine is refused before anything runs
    // (local jobs, on the gap task's node, are not).
    for (table, code) in [
        ("jobs = 2", Some(0)),
        ("engine = \"python -m hilrig_ray --address auto\"", Some(2)),
    ] {
        let gap = dir.path().join("gap-in-a-bucket.toml");
        std::fs::write(&gap, format!("{}\n[gap]\n{table}\n", with_gap_step())).unwrap();
        let mut cmd = Command::new(common::hilrig_bin());
        cmd.args(["campaign", "plan"]).arg(&gap).args([
            "--out",
            "s3://hilrig-drives/gap-out",
            "--json",
        ]);
        let o = server.env(&mut cmd).output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), code, "[gap] {table}: {e}");
        if code == Some(2) {
            assert!(
                e.contains("[gap] engine") && e.contains("is an object"),
                "{e}"
            );
        }
    }
    let total = TASKS;

    // Killed once 5 tasks are done (records, checks, the first re-simulation).
    run_until_killed(&file, &out, 5);
    let first = finished(&out);
    // The next run, here, skips every finished task (and runs none of them again); it too is
    // killed, after three tasks more: re-simulations and comparisons are left for Ray, whose
    // worker node is lost while it runs one.
    let second = run_until_killed(&file, &out, first.len() + 3);
    assert!(
        tasks_reported(&second, "current").is_superset(&first),
        "{second}"
    );
    assert!(
        tasks_reported(&second, "ran").is_disjoint(&first),
        "{second}"
    );
    let before = finished(&out);
    assert!(before.is_superset(&first) && before.len() >= first.len() + 3);
    assert!(before.len() < total, "everything finished before the kill");

    // The third run, on a Ray cluster that loses a worker node while it runs tasks, skips every
    // finished task and runs the rest.
    let ray = on_ray(&file, &out, dir.path());
    let outcomes = ray["outcomes"].as_array().unwrap();
    let with = |word: &str| -> BTreeSet<String> {
        outcomes
            .iter()
            .filter(|o| o["outcome"] == word)
            .map(|o| o["task"].as_str().unwrap().to_owned())
            .collect()
    };
    // Every task the local runs finished is skipped, none is run again. A task the lost worker
    // finished and stamped before Ray heard of it is skipped too, on its retry: so the skipped
    // may be more than those.
    let (skipped, ran) = (with("up_to_date"), with("ran"));
    assert!(skipped.is_superset(&before), "{ray}");
    assert!(ran.is_disjoint(&before), "{ray}");
    assert_eq!(skipped.len() + ran.len(), total, "{ray}");
    assert_eq!(finished(&out).len(), total);
    // And a fourth, here, finds nothing to do.
    let fourth = campaign(&file, &out).output().unwrap();
    let stdout = String::from_utf8_lossy(&fourth.stdout);
    assert!(fourth.status.success(), "{stdout}");
    assert_eq!(tasks_reported(&stdout, "current").len(), total, "{stdout}");
    assert!(tasks_reported(&stdout, "ran").is_empty(), "{stdout}");

    // The Parquet tables, read by DuckDB: the mean OCR^K per model over every scan of every
    // drive is the one the comparisons' JSON gives.
    duckdb_agrees(&out);
    // The report was built from every JSON the campaign wrote.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["inputs"].as_array().unwrap().len(), 2 + 4 + 2);

    // The commands typed one by one, into the same paths (a re-simulation and a validation
    // quote their input files' paths): every recording, re-simulation, comparison and
    // validation the campaign made, whichever executor ran it, is the same file byte for byte.
    // The bucket's outputs are the local executor's, every one of them.
    let (ours, theirs) = (outputs(&out), outputs(&from_bucket));
    assert_eq!(
        ours.keys().collect::<Vec<_>>(),
        theirs.keys().collect::<Vec<_>>()
    );
    for (rel, bytes) in &ours {
        assert!(theirs[rel] == *bytes, "{} differs", rel.display());
    }
    // 2 recordings, 4 re-simulations, 2 checks, 4 comparisons, 2 validations, 10 tables and
    // the report (HTML and JSON).
    assert_eq!(ours.len(), 2 + 4 + 2 + 4 + 2 + 10 + 2);
    let campaign_out = dir.path().join("out-campaign");
    std::fs::rename(&out, &campaign_out).unwrap();
    let mirror = out.parent().unwrap();
    one_by_one(
        &out,
        &mirror.join("fixtures/parking"),
        &mirror.join("rigs/demo.toml"),
    );
    let mut compared = 0;
    for (rel, bytes) in tree(&out) {
        let theirs = std::fs::read(campaign_out.join(&rel)).unwrap();
        assert!(
            bytes == theirs,
            "{} differs from the campaign's",
            rel.display()
        );
        compared += 1;
    }
    // 2 recordings, 4 re-simulations, 4 comparisons, 2 validations.
    assert_eq!(compared, 12);
}

/// The campaign in Azure Blob Storage (`az://`), on Microsoft's own emulator (Azurite): two
/// drives recorded and checked from and into a container, read back with the Azure SDK for
/// Python, equal byte for byte to the local executor's files on the same inputs; a worker with
/// an empty cache finds every task done.
#[test]
#[cfg_attr(
    not(hilrig_azurite),
    ignore = "needs HILRIG_AZURITE (set by .ci/run): did not run"
)]
fn a_campaign_in_azure_blob_storage_gives_the_local_executor_s_files() {
    let dir = tempfile::tempdir().unwrap();
    let server = common::azure::Server::start();
    let container = "hilrig-drives";
    server.put(container, "fixtures/parking", &common::fixture("parking"));
    server.put(container, "rigs", common::demo_rig().parent().unwrap());
    let upload = dir.path().join("upload");
    std::fs::create_dir_all(&upload).unwrap();
    std::fs::write(
        upload.join("campaign-az.toml"),
        "name = \"az\"\nsteps = [\"record\", \"check\"]\nrig = \"../../rigs/demo.toml\"\n\
         [[drive]]\nrecordings = \"rep-0[12]/drive.pcapng.zst\"\nscene = \"{dir}/scene.toml\"\n\
         scenario = \"parking\"\n[[scenario]]\nname = \"parking\"\n",
    )
    .unwrap();
    server.put(container, "fixtures/parking", &upload);
    let file = format!("az://{container}/fixtures/parking/campaign-az.toml");
    let out = format!("az://{container}/out");
    // Run where nothing is on disk: whatever it writes outside the cache shows up here.
    let work = dir.path().join("work");
    std::fs::create_dir_all(&work).unwrap();
    let run = |cache: &Path| {
        let mut cmd = campaign(Path::new(&file), Path::new(&out));
        server.env(&mut cmd);
        in_the_store(cmd, cache, &work)
    };
    let cache = dir.path().join("cache");
    let stdout = run(&cache);
    assert!(stdout.contains("4 ran, 0 up to date, 0 failed"), "{stdout}");
    assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0);
    // Read back by another client: two recordings and two checks, a log and a stamp per
    // task, and the plan.
    let got = dir.path().join("got");
    let blobs = server.get(container, "out", &got);
    let theirs = outputs(&got);
    assert_eq!(theirs.len(), 4);
    assert_eq!(blobs, 4 + 4 + 4 + 1);
    let stamp = std::fs::read_to_string(got.join("campaign/done/check/rep-01.json")).unwrap();
    assert!(
        stamp.contains(&format!("\"{out}/rec/rep-01.mcap\"")),
        "{stamp}"
    );
    let again = run(&dir.path().join("another-cache"));
    assert!(again.contains("0 ran, 4 up to date"), "{again}");
    // The local executor on the copies the container's tasks read, into the same paths (a
    // recording quotes its capture's path): the same files.
    let mirror = cache.join("objects/az").join(container);
    std::fs::remove_dir_all(mirror.join("out")).unwrap();
    let local = campaign(
        &mirror.join("fixtures/parking/campaign-az.toml"),
        &mirror.join("out"),
    )
    .output()
    .unwrap();
    assert!(
        local.status.success(),
        "{}",
        String::from_utf8_lossy(&local.stdout)
    );
    let ours = outputs(&mirror.join("out"));
    assert_eq!(
        ours.keys().collect::<Vec<_>>(),
        theirs.keys().collect::<Vec<_>>()
    );
    for (rel, bytes) in &ours {
        assert!(theirs[rel] == *bytes, "{} differs", rel.display());
    }
}

/// Runs the campaign command `cmd` (its store's environment set) with `cache` as its cache and
/// `work` as its working folder; asserts it succeeded and returns its standard output.
fn in_the_store(mut cmd: Command, cache: &Path, work: &Path) -> String {
    cmd.env("HILRIG_CACHE", cache).current_dir(work);
    let o = cmd.output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    stdout
}

/// DuckDB over the campaign's Parquet tables agrees with its JSON.
fn duckdb_agrees(out: &Path) {
    let got: serde_json::Value = serde_json::from_slice(&common::interop_script(
        "campaign_duckdb.py",
        &[out.as_os_str()],
    ))
    .unwrap();
    // compare_scans 4, check_epochs 2, check_runs 2, validate_cells 2.
    assert_eq!(got["files"], 10, "{got}");
    assert_eq!(got["runs"], serde_json::json!([2, 2]), "{got}");
    for (k, (model, _)) in MODELS.iter().enumerate() {
        let ocr: Vec<f64> = REPS
            .iter()
            .flat_map(|rep| {
                let c: hilrig::metrics::report::Comparison =
                    hilrig::output::read(&out.join(format!("compare/{model}/{rep}.json"))).unwrap();
                c.scans
                    .iter()
                    .filter_map(|s| s.grid.and_then(|g| g.ocr))
                    .collect::<Vec<_>>()
            })
            .collect();
        let mean = ocr.iter().sum::<f64>() / ocr.len() as f64;
        let row = &got["ocr"][k];
        assert_eq!(row[0], *model, "{got}");
        assert!(
            (row[1].as_f64().unwrap() - mean).abs() < 1e-12,
            "{model}: {} vs {mean}",
            row[1]
        );
        assert_eq!(row[2], ocr.len(), "{got}");
        assert_eq!(row[3], REPS.len(), "{got}");
    }
    // The report's OCR^K over distance, pooled over all drives (from the comparisons' JSON),
    // is what DuckDB finds in the tables, bin by bin.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let ours = report["fleet"].as_array().unwrap();
    let theirs = got["fleet"].as_array().unwrap();
    assert!(theirs.len() >= 4, "{got}");
    assert_eq!(ours.len(), theirs.len(), "{}", report["fleet"]);
    for (o, t) in ours.iter().zip(theirs) {
        assert_eq!(o["group"], format!("compare/{}", t[0].as_str().unwrap()));
        assert_eq!(o["from_m"].as_f64(), Some(5.0 * t[1].as_f64().unwrap()));
        assert_eq!(o["scans"], t[2]);
        assert_eq!(o["drives"], t[3]);
        assert!((o["ocr_mean"].as_f64().unwrap() - t[4].as_f64().unwrap()).abs() < 1e-12);
        match (o["ocr_sd"].as_f64(), t[5].as_f64()) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-9, "{o} {t:?}"),
            (a, b) => assert_eq!(a, b, "{o} {t:?}"),
        }
    }
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(page.contains("id=\"section-fleet\""));
}

/// The campaign's plan run on a Ray cluster of two worker nodes; once the run has finished three
/// more tasks, a node that has finished one is killed while it runs another. The executor's
/// summary (every task's outcome).
fn on_ray(file: &Path, out: &Path, dir: &Path) -> serde_json::Value {
    let plan_path = dir.join("plan.json");
    let plan = Command::new(common::hilrig_bin())
        .args(["campaign", "plan"])
        .arg(file)
        .arg("--out")
        .arg(out)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        plan.status.success(),
        "{}",
        String::from_utf8_lossy(&plan.stderr)
    );
    std::fs::write(&plan_path, &plan.stdout).unwrap();
    let before = finished(out).len();

    let cluster = common::ray::Cluster::start();
    let mut exec = Command::new(common::python())
        .args(["-m", "hilrig_ray"])
        .arg(&plan_path)
        .args(["--address", &cluster.address, "--hilrig"])
        .arg(common::hilrig_bin())
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("python"))
        .env("RAY_USAGE_STATS_ENABLED", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while finished(out).len() < before + 3 {
        assert!(
            exec.try_wait().unwrap().is_none(),
            "the campaign ended before a worker was killed"
        );
        assert!(
            started.elapsed() < Duration::from_secs(600),
            "no progress on Ray"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let killed = cluster.kill_a_worker_node_mid_task(&common::hilrig_bin(), &mut || {
        exec.try_wait().unwrap().is_none()
    });
    let result = exec.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&result.stdout);
    assert!(
        result.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    // Both worker nodes took tasks, the one killed among them: it had finished a task before
    // (with one CPU a node, its next task started only once that outcome had reached the
    // driver, which holds it), so an outcome names it. Every task that ended counts, whether
    // it ran or found its outputs current: either ran `hilrig campaign task` on its node.
    let nodes: BTreeSet<&str> = summary["outcomes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|o| o["node"].as_str())
        .collect();
    assert!(nodes.len() >= 2, "{nodes:?}");
    assert!(nodes.contains(killed.as_str()), "{killed} not in {nodes:?}");
    drop(cluster);
    summary
}

/// Every file under `dir` (relative path -> bytes), without the logs (their timings differ).
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(d: &Path, base: &Path, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(d).unwrap().flatten() {
            let p = e.path();
            let rel = p.strip_prefix(base).unwrap().to_owned();
            // Logs hold timings; the local executor keeps its plan beside its outputs.
            if rel.starts_with("logs") || rel == Path::new("campaign/plan.json") {
                continue;
            }
            if p.is_dir() {
                walk(&p, base, out);
            } else {
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

#[test]
fn the_executors_own_tests_pass() {
    let out = Command::new(common::python())
        .args(["-m", "unittest", "discover", "-s"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("python/tests"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("Ran 9 tests") && stderr.contains("OK"),
        "{stderr}"
    );
}

/// Runs a campaign that cannot run: exit 2, the reason on stderr, and no task started.
fn refused(text: &str, dir: &Path) -> String {
    let file = dir.join("bad.toml");
    std::fs::write(&file, text).unwrap();
    let out = dir.join("bad-out");
    let o = campaign(&file, &out).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(2),
        "{stderr}\n{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert!(!out.join("logs").exists(), "a task ran: {stderr}");
    assert!(
        !out.join("campaign").exists(),
        "a plan was written: {stderr}"
    );
    stderr
}

#[test]
fn a_campaign_that_cannot_run_says_why_before_any_task_runs() {
    let dir = tempfile::tempdir().unwrap();
    let parking = common::fixture("parking");
    let p = parking.display();
    let models = format!("[[model]]\nname = \"idealized\"\nfile = \"{p}/idealized.toml\"\n");
    // A campaign's first lines, and a [[drive]] of `pattern` with the scenes beside the drives.
    let head = |steps: &str| format!("name = \"x\"\nsteps = [{steps}]\n");
    let drive = |pattern: &str| {
        format!("[[drive]]\nrecordings = \"{pattern}\"\nscene = \"{{dir}}/scene.toml\"\n")
    };
    let rep01 = format!("{p}/rep-01/drive.pcapng.zst");
    // A drive that is not there.
    let e = refused(
        &(head("\"check\"") + &drive(&format!("{p}/rep-09/*.mcap"))),
        dir.path(),
    );
    assert!(e.contains("no file matches") && e.contains("rep-09"), "{e}");
    // An unknown step, named.
    let e = refused(
        &(head("\"check\", \"resimulate\"") + &drive(&rep01) + &models),
        dir.path(),
    );
    assert!(e.contains("resimulate"), "{e}");
    // A design's step in a campaign: a plan of its own.
    let e = refused(
        &(head("\"check\", \"efast\"") + &drive(&rep01) + &models),
        dir.path(),
    );
    assert!(e.contains("\"efast\" is not a step of a campaign"), "{e}");
    // A capture without the record step.
    let e = refused(&(head("\"check\"") + &drive(&rep01)), dir.path());
    assert!(e.contains("is a capture") && e.contains("record"), "{e}");
    // A cycle: the drives are the campaign's own re-simulations.
    let sims = dir.path().join("bad-out/sim/idealized");
    std::fs::create_dir_all(&sims).unwrap();
    std::fs::write(sims.join("rep-01.mcap"), b"not read by the planner").unwrap();
    for f in ["scene.toml", "pedestrian.csv"] {
        std::fs::copy(parking.join("rep-01").join(f), sims.join(f)).unwrap();
    }
    let e = refused(
        &(head("\"resim\"") + &drive("bad-out/sim/idealized/*.mcap") + &models),
        dir.path(),
    );
    assert!(
        e.contains("circle") && e.contains("resim/idealized/rep-01"),
        "{e}"
    );
    std::fs::remove_dir_all(dir.path().join("bad-out")).unwrap();
    // A scene whose pedestrian's trajectory is missing (a file the scene names).
    let lone = dir.path().join("lone");
    std::fs::create_dir_all(&lone).unwrap();
    std::fs::write(lone.join("run.mcap"), b"not read by the planner").unwrap();
    std::fs::copy(parking.join("rep-01/scene.toml"), lone.join("scene.toml")).unwrap();
    let e = refused(&(head("\"check\"") + &drive("lone/*.mcap")), dir.path());
    assert!(
        e.contains("lone/scene.toml names") && e.contains("pedestrian.csv does not exist"),
        "{e}"
    );
    // Two drives that would write the same outputs.
    let e = refused(
        &(head("\"check\"") + &drive(&rep01) + &drive(&rep01)),
        dir.path(),
    );
    assert!(e.contains("matched by two"), "{e}");
    // A model file that is not there.
    let e = refused(
        &(head("\"record\", \"resim\"")
            + &format!("rig = \"{}\"\n", common::demo_rig().display())
            + &drive(&format!("{p}/rep-0[12]/drive.pcapng.zst"))
            + "[[model]]\nname = \"m\"\nfile = \"nowhere.toml\"\n"),
        dir.path(),
    );
    assert!(e.contains("model 'm'") && e.contains("nowhere.toml"), "{e}");
    // Where the gap step's re-simulations run: one place, a number of tasks, a command.
    let gap = head("\"record\", \"check\", \"resim\", \"gap\"")
        + &format!("rig = \"{}\"\n", common::demo_rig().display())
        + &drive(&format!("{p}/rep-0[12]/drive.pcapng.zst"))
        + &models;
    for (table, says) in [
        ("jobs = 2\nengine = \"ray-run\"", "both `jobs` and `engine`"),
        ("jobs = 0", "jobs = 0"),
        ("engine = \"run 'plan\"", "unbalanced quotes"),
        ("engine = \"  \"", "not a command"),
        ("workers = 2", "workers"),
        ("", "neither"),
    ] {
        let e = refused(&format!("{gap}[gap]\n{table}\n"), dir.path());
        assert!(e.contains(says), "[gap] {table}: {e}");
    }
    // A bucket without credentials, for the outputs or for the drives: refused before anything
    // is asked of the network, and nothing written here.
    let work = dir.path().join("work");
    std::fs::create_dir_all(&work).unwrap();
    let runnable = head("\"record\", \"check\"")
        + &format!("rig = \"{}\"\n", common::demo_rig().display())
        + &drive(&rep01);
    let in_bucket = head("\"check\"") + &drive("s3://hilrig-drives/rep-*/run.mcap");
    for (text, out) in [
        (runnable.as_str(), "s3://hilrig-out/campaign"),
        (in_bucket.as_str(), "out"),
    ] {
        let file = dir.path().join("bucket.toml");
        std::fs::write(&file, text).unwrap();
        let mut cmd = campaign(&file, Path::new(out));
        for (k, _) in std::env::vars_os() {
            if k.to_string_lossy().starts_with("AWS_") {
                cmd.env_remove(k);
            }
        }
        let o = cmd
            .env("HILRIG_CACHE", dir.path().join("cache"))
            .current_dir(&work)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(
            e.contains("no credentials for S3") && e.contains("AWS_ACCESS_KEY_ID"),
            "{e}"
        );
        assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0);
        assert!(!dir.path().join("cache/objects").exists());
    }
}

#[test]
fn a_drive_that_fails_its_check_gets_its_tables_and_its_report_but_is_not_re_simulated() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let parking = common::fixture("parking");
    // Two recordings, one cut after its first 300 kB: no GNSS fixes, no ego motion in it.
    for (rep, cut) in [("rep-01", false), ("rep-02", true)] {
        std::fs::create_dir_all(d.join(rep)).unwrap();
        let rec = d.join(rep).join("run.mcap");
        let out = common::record_from(
            &common::demo_rig(),
            &[&parking.join(rep).join("drive.pcapng.zst")],
            &rec,
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        if cut {
            let bytes = std::fs::read(&rec).unwrap();
            std::fs::write(&rec, &bytes[..300_000]).unwrap();
        }
    }
    let file = d.join("c.toml");
    std::fs::write(
        &file,
        format!(
            "name = \"x\"\nsteps = [\"check\", \"resim\", \"compare\", \"tables\", \"report\"]\n[[drive]]\nrecordings = \"*/run.mcap\"\nscene = \"{p}/scene.toml\"\n[[model]]\nname = \"idealized\"\nfile = \"{p}/idealized.toml\"\n",
            p = parking.display()
        ),
    )
    .unwrap();
    let run = campaign(&file, &d.join("out")).output().unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    // A failed check is a result the user must see: exit 1, named.
    assert_eq!(run.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("1 drive(s) failed check"), "{stdout}");
    assert!(
        stdout.contains("not run  resim/idealized/rep-02: waits for check/rep-02: exit 1"),
        "{stdout}"
    );
    let out = d.join("out");
    assert!(out.join("sim/idealized/rep-01.mcap").is_file());
    assert!(!out.join("sim/idealized/rep-02.mcap").exists());
    // Its check's tables are made all the same: the fleet's verdicts include the failed one.
    for t in ["check_runs", "check_epochs"] {
        assert!(
            out.join(format!("tables/{t}/rep-02.parquet")).is_file(),
            "{stdout}"
        );
    }
    // So is the report: over what exists, with the comparison that could not be made named
    // as not produced (the report's exit 1 is a result, not a failure of the task).
    assert!(
        !stdout.contains("not run  report") && !stdout.contains("failed   report"),
        "{stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let absent: Vec<&str> = report["absent"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap())
        .collect();
    let missing = out.join("compare/idealized/rep-02.json");
    assert_eq!(absent, [missing.to_str().unwrap()], "{report}");
    let verdicts: Vec<(&str, &str)> = report["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|i| i["kind"] == "check")
        .map(|i| {
            (
                i["name"].as_str().unwrap(),
                i["value"]["verdict"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(verdicts.len(), 2, "{verdicts:?}");
    assert!(
        verdicts.contains(&("check/rep-02.json", "fail")),
        "{verdicts:?}"
    );
    // Named by their path below the campaign's folder, so the model stays in the name.
    assert!(
        report["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .any(|i| i["name"] == "compare/idealized/rep-01.json"),
        "{report}"
    );
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(page.contains("Not produced"), "no absent section");
    assert!(page.contains(missing.to_str().unwrap()));
    // Run again: nothing changed, so nothing runs, the report with its absent input included.
    let again = campaign(&file, &d.join("out")).output().unwrap();
    let stdout = String::from_utf8_lossy(&again.stdout);
    assert_eq!(again.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains(": 0 ran, "), "{stdout}");
    // The first drive's recording is replaced by one that cannot be read: its check fails
    // (exit 2, no JSON) and nothing after it runs. What they made of the earlier recording is
    // gone, so the report lists it as not produced instead of showing it as this run's.
    std::fs::write(d.join("rep-01/run.mcap"), b"not an MCAP file").unwrap();
    let third = campaign(&file, &d.join("out")).output().unwrap();
    let stdout = String::from_utf8_lossy(&third.stdout);
    assert_eq!(third.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("FAILED   check/rep-01: exit 2"), "{stdout}");
    for gone in [
        "check/rep-01.json",
        "sim/idealized/rep-01.mcap",
        "compare/idealized/rep-01.json",
        "tables/check_runs/rep-01.parquet",
    ] {
        assert!(!out.join(gone).exists(), "{gone} left: {stdout}");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let absent = report["absent"].to_string();
    for name in ["check/rep-01.json", "compare/idealized/rep-01.json"] {
        assert!(absent.contains(name), "{name} not absent: {report}");
    }
    assert!(
        !report["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .any(|i| i["name"] == "compare/idealized/rep-01.json"),
        "{report}"
    );
}

#[test]
fn the_plan_is_json_that_names_every_command_and_what_it_waits_for() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(common::hilrig_bin())
        .args(["campaign", "plan"])
        .arg(common::fixture("parking/campaign.toml"))
        .arg("--out")
        .arg(dir.path().join("out"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let plan: hilrig::campaign::plan::Plan =
        hilrig::output::from_slice(Path::new("stdout"), &out.stdout).unwrap();
    // The bundled campaign: 5 x (record, check), 2 x 5 x (resim, compare), 2 validate, gap,
    // report, and the tables of the 5 + 10 + 2 + 1 JSON files.
    assert_eq!(plan.tasks.len(), 10 + 20 + 2 + 1 + 1 + 18);
    let mut seen = BTreeSet::new();
    for t in &plan.tasks {
        for a in &t.after {
            assert!(
                seen.contains(a),
                "{} waits for {a}, which comes later",
                t.id
            );
        }
        seen.insert(t.id.clone());
        assert_eq!(t.args[0], t.step.command());
    }
    let resim = plan.task("resim/truth/rep-03").unwrap();
    let after: BTreeSet<&str> = resim.after.iter().map(String::as_str).collect();
    assert_eq!(after, BTreeSet::from(["check/rep-03", "record/rep-03"]));
    let gap = plan.task("gap/parking").unwrap();
    assert!(gap.args.iter().any(|a| a == "--reference-model"));
    assert_eq!(plan.files.len(), 1);
    // The study the gap task reads fits on the first three repetitions and validates on two.
    let study = &plan.files[0].text;
    assert_eq!(study.matches("role = \"fit\"").count(), 3, "{study}");
    assert_eq!(study.matches("role = \"validate\"").count(), 2, "{study}");
    assert!(plan.task("report").unwrap().after.len() >= 18);
    // Nothing was run or written by planning.
    assert!(!dir.path().join("out").exists());
    // A `[gap]` table hands the study's full re-simulations to local tasks or to an engine:
    // the gap task's command line says so, and no other task's changes.
    let text = with_gap_step();
    let engine = "python -m hilrig_ray --address 'auto'";
    let plan_of = |key: &str, table: &str, out: &OsStr| {
        let file = dir.path().join(format!("gap-{key}.toml"));
        std::fs::write(&file, format!("{text}\n{table}")).unwrap();
        Command::new(common::hilrig_bin())
            .args(["campaign", "plan"])
            .arg(&file)
            .arg("--out")
            .arg(out)
            .arg("--json")
            .output()
            .unwrap()
    };
    let mut args_of = BTreeMap::new();
    for (key, table) in [
        ("none", String::new()),
        ("jobs", "[gap]\njobs = 2\n".into()),
        ("engine", format!("[gap]\nengine = \"{engine}\"\n")),
    ] {
        let out = plan_of(key, &table, dir.path().join("out").as_os_str());
        assert!(
            out.status.success(),
            "[gap] {key}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let plan: hilrig::campaign::plan::Plan =
            hilrig::output::from_slice(Path::new("stdout"), &out.stdout).unwrap();
        let args: BTreeMap<String, Vec<String>> = plan
            .tasks
            .iter()
            .map(|t| (t.id.clone(), t.args.clone()))
            .collect();
        args_of.insert(key, args);
    }
    // `hilrig gap STUDY -o DIR [--jobs N | --engine C] --reference-model M`.
    let gap_args = |key: &str| args_of[key]["gap/parking"].clone();
    let plain = gap_args("none");
    assert!(!plain.iter().any(|a| a == "--jobs" || a == "--engine"));
    assert_eq!(plain[4], "--reference-model", "{plain:?}");
    let with = |extra: [&str; 2]| [&plain[..4], &extra.map(String::from), &plain[4..]].concat();
    assert_eq!(gap_args("jobs"), with(["--jobs", "2"]));
    assert_eq!(gap_args("engine"), with(["--engine", engine]));
    for key in ["jobs", "engine"] {
        let mut others = args_of[key].clone();
        others.remove("gap/parking");
        let mut plain = args_of["none"].clone();
        plain.remove("gap/parking");
        assert_eq!(others, plain, "[gap] {key} changed another task");
    }
    assert!(!dir.path().join("out").exists());
}

/// Every file under `dir` but the executor's own (logs, plan, stamps), by relative path.
fn outputs(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    tree(dir)
        .into_iter()
        .filter(|(rel, _)| !rel.starts_with("logs") && !rel.starts_with("campaign"))
        .collect()
}

/// The parking campaign from a bucket of an S3 server into it: the fixture and the rig put there
/// as in this repository, the campaign beside them with paths relative to itself. Asserts that
/// it writes nothing but the bucket and `cache`, that its stamps name the objects, and that a
/// worker with an empty cache finds every task done. Returns the campaign file and output
/// folder in the cache (where the tasks read and wrote), after reading the bucket's outputs back
/// into `got` with boto3 and removing the cache's copies of them.
fn in_a_bucket(server: &common::s3::Server, d: &Path, got: &Path) -> (PathBuf, PathBuf) {
    let bucket = "hilrig-drives";
    server.put(bucket, "fixtures/parking", &common::fixture("parking"));
    server.put(bucket, "rigs", common::demo_rig().parent().unwrap());
    let upload = d.join("upload");
    std::fs::create_dir_all(&upload).unwrap();
    std::fs::write(
        upload.join("campaign-test.toml"),
        campaign_text(".", "../../rigs/demo.toml"),
    )
    .unwrap();
    server.put(bucket, "fixtures/parking", &upload);
    let file = format!("s3://{bucket}/fixtures/parking/campaign-test.toml");
    let out = format!("s3://{bucket}/out");
    let cache = d.join("cache");
    // Run where nothing is on disk: whatever it writes outside the cache shows up here.
    let work = d.join("work");
    std::fs::create_dir_all(&work).unwrap();
    let run = |cache: &Path| {
        let mut cmd = campaign(Path::new(&file), Path::new(&out));
        server.env(&mut cmd);
        in_the_store(cmd, cache, &work)
    };
    let stdout = run(&cache);
    assert!(
        stdout.contains(&format!("{TASKS} ran, 0 up to date, 0 failed")),
        "{stdout}"
    );
    assert_eq!(std::fs::read_dir(&work).unwrap().count(), 0);
    // Read back by another client: every output, log and stamp, and the plan.
    let objects = server.get(bucket, "out", got);
    assert_eq!(objects, outputs(got).len() + TASKS + TASKS + 1);
    // The stamps name the objects, not this machine's copies of them.
    let stamp = std::fs::read_to_string(got.join("campaign/done/check/rep-01.json")).unwrap();
    assert!(
        stamp.contains(&format!("\"{out}/rec/rep-01.mcap\""))
            && !stamp.contains(&*cache.to_string_lossy()),
        "{stamp}"
    );
    // A worker that shares no disk with this one (an empty cache) finds every task done.
    let again = run(&d.join("another-cache"));
    assert!(
        again.contains(&format!("0 ran, {TASKS} up to date")),
        "{again}"
    );
    let mirror = cache.join("objects/s3").join(bucket);
    std::fs::remove_dir_all(mirror.join("out")).unwrap();
    (
        mirror.join("fixtures/parking/campaign-test.toml"),
        mirror.join("out"),
    )
}
