//! `hilrig check` (issue 6): a clean synthesized drive passes with the injected accuracy; each
//! injected fault is detected, named and located; on real receiver logs the RTK states agree with
//! gpsd's.
//!
//! The drives are the parking scenario (fixtures/parking) synthesized here with `[faults]`
//! added to its drive file, recorded with `hilrig record --from`, then checked. They are
//! synthesized without lidar returns (`[lidar] returns = false`: `check` reads the packets'
//! times), but for the tests that compare a run with its re-simulation.

use crate::common;

use common::*;
use serde_json::Value;

use std::process::Command;

/// [`common::synth_and_record_edited`] without lidar returns (`[lidar] returns = false`): `check`
/// reads the lidar packets' times, not what they measured, and casting the returns was about
/// half of these tests' time. The tests that compare a run call the common one.
fn synth_and_record_edited(
    edit: impl Fn(String) -> String,
    extra: &str,
    seed: u64,
    errors: bool,
) -> SynthRun {
    common::synth_and_record_edited(
        |t| {
            let t = edit(t);
            assert!(t.contains("\n[lidar]\n"), "{t}");
            t.replacen("\n[lidar]\n", "\n[lidar]\nreturns = false\n", 1)
        },
        extra,
        seed,
        errors,
    )
}

/// [`synth_and_record_edited`] of the parking drive as it is.
fn synth_and_record(extra: &str, seed: u64, errors: bool) -> SynthRun {
    synth_and_record_edited(|t| t, extra, seed, errors)
}

/// A drive synthesized without returns is the same drive: with the same seed, the two captures
/// hold the same records at the same receive times, byte for byte (GNSS, CAN, position
/// packets, every frame's headers), but for the lidar data packets' channels, which are all
/// empty without returns (with returns, most packets hold some).
#[test]
fn a_drive_synthesized_without_returns_has_the_same_packets_with_empty_channels() {
    use hilrig::capture::CaptureReader;
    use hilrig::velodyne::{Channel, DataPacket, DATA_PACKET_SIZE};
    let records = |d: &SynthRun| {
        let file = std::fs::File::open(d.rep.join("drive.pcapng")).unwrap();
        let mut reader = CaptureReader::new(std::io::BufReader::new(file)).unwrap();
        let mut v = Vec::new();
        while let Some(r) = reader.next_record() {
            let r = r.unwrap();
            v.push((r.interface, r.time, r.data.to_vec()));
        }
        v
    };
    let (with, without) = (
        common::synth_and_record("", 5, true),
        synth_and_record("", 5, true),
    );
    let (a, b) = (records(&with), records(&without));
    assert_eq!(a.len(), b.len());
    let (mut lidar, mut with_returns) = (0, 0);
    for ((ia, ta, x), (ib, tb, y)) in a.iter().zip(&b) {
        assert_eq!((ia, ta), (ib, tb));
        let at = x.len().saturating_sub(DATA_PACKET_SIZE);
        let (Ok(mut p), Ok(q)) = (DataPacket::decode(&x[at..]), DataPacket::decode(&y[at..]))
        else {
            assert_eq!(x, y, "a record other than a lidar data packet at {ta:?}");
            continue;
        };
        lidar += 1;
        assert_eq!(x[..at], y[..at], "a data packet's headers at {ta:?}");
        assert!(q
            .blocks
            .iter()
            .all(|b| b.channels == [Channel::default(); 32]));
        with_returns += usize::from(
            p.blocks
                .iter()
                .any(|b| b.channels.iter().any(|c| c.distance > 0)),
        );
        for b in &mut p.blocks {
            b.channels = [Channel::default(); 32];
        }
        assert_eq!(p.encode(), q.encode(), "a data packet at {ta:?}");
    }
    assert!(lidar > 10_000, "{lidar} data packets");
    assert!(with_returns > lidar / 2, "{with_returns} of {lidar}");
}

/// Synthesizes the parking drive with `faults` (TOML lines of a `[faults]` table), records it
/// and checks it; returns the check's exit code and JSON report.
fn drive_and_check(faults: &str) -> (i32, Value) {
    drive_edited_and_check(|t| t, faults)
}

/// [`drive_and_check`] with the drive file's text passed through `edit` first.
fn drive_edited_and_check(edit: impl Fn(String) -> String, faults: &str) -> (i32, Value) {
    let (code, v, _) = drive_seeded_and_check(edit, faults, 11);
    (code, v)
}

/// [`drive_edited_and_check`] with the synthesizer's seed (its noise and the drive's variation
/// within the fixture's `[variation]`); also returns the synthesized run (its truth, and the
/// smoothed trajectory in `trajectory.csv` beside the run).
fn drive_seeded_and_check(
    edit: impl Fn(String) -> String,
    faults: &str,
    seed: u64,
) -> (i32, Value, SynthRun) {
    let d = synth_and_record_edited(edit, &format!("[faults]\n{faults}"), seed, true);
    let (dir, rep, mcap) = (&d.dir, &d.rep, &d.run);
    let json = dir.path().join("check.json");
    let out = Command::new(hilrig_bin())
        .arg("check")
        .arg(mcap)
        .arg("--scene")
        .arg(rep.join("scene.toml"))
        .arg("--json")
        .arg(&json)
        .arg("--trajectory")
        .arg(dir.path().join("trajectory.csv"))
        .output()
        .unwrap();
    println!("{}", String::from_utf8_lossy(&out.stdout));
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (out.status.code().unwrap_or(-1), v, d)
}

/// `check` of a synthesized run with its surveyed scene (and `rig` when given), writing the JSON
/// report and the smoothed trajectory: exit code, report, trajectory file.
fn check_with_trajectory(
    d: &SynthRun,
    rig: Option<&std::path::Path>,
) -> (Option<i32>, Value, std::path::PathBuf) {
    let (json, traj) = (
        d.dir.path().join("check.json"),
        d.dir.path().join("trajectory.csv"),
    );
    let mut cmd = Command::new(hilrig_bin());
    cmd.arg("check").arg(&d.run);
    if let Some(r) = rig {
        cmd.arg("--rig").arg(r);
    }
    let out = cmd
        .arg("--scene")
        .arg(d.rep.join("scene.toml"))
        .arg("--json")
        .arg(&json)
        .arg("--trajectory")
        .arg(&traj)
        .output()
        .unwrap();
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (out.status.code(), v, traj)
}

fn faults<'a>(v: &'a Value, name: &str) -> Vec<&'a Value> {
    v["faults"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["name"] == name)
        .collect()
}

fn names(v: &Value) -> Vec<String> {
    v["faults"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap().to_owned())
        .collect()
}

/// The estimate `key` of the spatial report lies within three of its own standard
/// uncertainties (`sigma_key`) of `truth`: the bound the check's uncertainty promises, not a
/// tolerance tuned to the data.
fn within_3_sigma(v: &Value, key: &str, sigma_key: &str, truth: f64) {
    let sp = &v["spatial"];
    let (est, sigma) = (
        sp[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} estimated")),
        sp[sigma_key]
            .as_f64()
            .unwrap_or_else(|| panic!("{sigma_key} reported")),
    );
    assert!(sigma > 0.0, "{sigma_key} = {sigma}");
    assert!(
        (est - truth).abs() <= 3.0 * sigma,
        "{key} = {est} ± {sigma} (1 sigma), truth {truth}"
    );
}

/// Seeds of the clean drives that [`the_reported_sigmas_are_the_scatter_of_the_estimates`]
/// holds the uncertainties against.
const SCATTER_SEEDS: [u64; 12] = [41, 42, 43, 44, 45, 46, 47, 48, 49, 50, 51, 52];

/// The central 99 % of a χ² variable with 11 degrees of freedom (`SCATTER_SEEDS` less one, for
/// the sample mean): scipy.stats.chi2.ppf(0.005, 11) and chi2.ppf(0.995, 11).
const CHI2_11_CENTRAL_99: (f64, f64) = (2.603_222, 26.756_849);

/// The standard uncertainties `check` reports are the scatter of its estimates: the clean
/// drive synthesized with 12 seeds (other noise, and another drive within the fixture's
/// variation), the sample standard deviation s of each estimate over them against the rms of
/// the sigmas reported. With honest sigmas, 11 s² / σ² is χ² with 11 degrees of freedom, so
/// σ / s lies in [√(11 / χ²₀.₉₉₅), √(11 / χ²₀.₀₀₅)] = [0.64, 2.06] with 99 % probability (the
/// sigmas differ a little from drive to drive; their rms is what the scatter of a mixture has).
/// Fewer seeds widen the band fast (8: 0.59..2.66, 6: 0.55..3.48). An inflated sigma, which
/// [`within_3_sigma`] cannot see, fails here, as does one too small. The same drives hold the
/// budget's heading term against the true heading error (see the bound below). 12 drives,
/// about 15 s on two cores.
#[test]
fn the_reported_sigmas_are_the_scatter_of_the_estimates() {
    // Per drive: the report, and the true heading error's mean square over the usable
    // stretches at the true range of the scene (m²).
    let (reports, heading_ms): (Vec<Value>, Vec<f64>) = std::thread::scope(|s| {
        let jobs: Vec<_> = SCATTER_SEEDS
            .iter()
            .map(|&seed| s.spawn(move || drive_seeded_and_check(|t| t, "", seed)))
            .collect();
        jobs.into_iter()
            .map(|j| {
                let (code, v, d) = j.join().unwrap();
                assert_eq!(code, 0, "faults: {:?}", names(&v));
                let truth = Truth::read(&d);
                let e = usable_heading_errors(&d, &truth, &v);
                let range = truth.object_range_p95(&d).min(30.0);
                let ms = e.iter().map(|x| x.0.to_radians().powi(2)).sum::<f64>() / e.len() as f64;
                (v, ms * range * range)
            })
            .unzip()
    });
    let n = reports.len() as f64;
    let (lo, hi) = (
        ((n - 1.0) / CHI2_11_CENTRAL_99.1).sqrt(),
        ((n - 1.0) / CHI2_11_CENTRAL_99.0).sqrt(),
    );
    for (key, sigma_key) in [
        ("can_speed_scale", "can_speed_scale_sigma"),
        ("gnss_time_offset_ms", "gnss_time_offset_sigma_ms"),
        ("lever_arm_x_measured_m", "lever_arm_x_sigma_m"),
    ] {
        let get = |v: &Value, k: &str| {
            v["spatial"][k]
                .as_f64()
                .unwrap_or_else(|| panic!("{k} reported"))
        };
        let est: Vec<f64> = reports.iter().map(|v| get(v, key)).collect();
        let sig: Vec<f64> = reports.iter().map(|v| get(v, sigma_key)).collect();
        let mean = est.iter().sum::<f64>() / n;
        let scatter = (est.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let sigma = (sig.iter().map(|s| s * s).sum::<f64>() / n).sqrt();
        let ratio = sigma / scatter;
        println!(
            "{key}: scatter {scatter:.3e}, reported sigma (rms) {sigma:.3e}, ratio {ratio:.2}"
        );
        assert!(
            (lo..=hi).contains(&ratio),
            "{sigma_key} (rms {sigma:.3e}) is {ratio:.2} times the scatter of {key} over {} seeds \
             ({scatter:.3e}); honest sigmas give {lo:.2}..{hi:.2} (99 %)",
            est.len()
        );
    }
    // The budget's heading term (the heading sigma at the scene's range) against the true
    // heading error at the true range. Within a drive the error wanders over seconds, so each
    // drive counts as one sample: 12 Σ e² / σ² is χ² with at least 12 degrees of freedom, and
    // rms e / σ ≤ √(χ²₀.₉₉₅(12) / 12) = 1.54 (an optimistic budget fails). The budget takes the
    // 95th percentile of the sigma over the usable stretches, about 1.3 times its rms there
    // (1.28 over these drives), so an honest one also gives at least
    // √(χ²₀.₀₀₅(12) / 12) / 1.3 = 0.39, 0.35 with room; an inflated one fails.
    let phys = (heading_ms.iter().sum::<f64>() / n).sqrt();
    let budget = (reports
        .iter()
        .map(|v| v["accuracy"]["heading_m"].as_f64().unwrap().powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let ratio = phys / budget;
    println!("heading at range: true error (rms) {phys:.4} m, budget (rms) {budget:.4} m, ratio {ratio:.2}");
    assert!(
        (0.35..=1.54).contains(&ratio),
        "the true heading error at the scene's range (rms {phys:.4} m over {} drives) is {ratio:.2} \
         times the budget's heading term (rms {budget:.4} m); an honest budget gives 0.35..1.54",
        reports.len()
    );
}

/// The synthesized CAN frames are received 1 ms after the instant they describe (the parking
/// drive's CAN latency), so GNSS, on UTC, is 1 ms early against CAN.
const CAN_LATENCY_MS: f64 = 1.0;

/// The parking drive's RTK noise per axis (`[gnss] sigma_horizontal_m`), m.
const RTK_SIGMA_M: f64 = 0.010;

/// The parking drive's survey accuracy of the static objects (`[survey] sigma_m`), m.
const SURVEY_SIGMA_M: f64 = 0.10;

/// The synthesizer's truth of a drive (`truth.csv`: the rear axle's t (s), x, y, z (m) and yaw
/// (deg), every 10 ms), for the budget terms computed from the drive's physics.
struct Truth(Vec<[f64; 5]>);

impl Truth {
    fn read(d: &SynthRun) -> Truth {
        let text = std::fs::read_to_string(d.rep.join("truth.csv")).unwrap();
        Truth(
            text.lines()
                .skip(1)
                .map(|l| {
                    let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                    [v[0], v[1], v[2], v[3], v[4]]
                })
                .collect(),
        )
    }

    /// First and last instant, s.
    fn span(&self) -> (f64, f64) {
        (self.0[0][0], self.0[self.0.len() - 1][0])
    }

    /// Position (x, y) and yaw (deg) at `t`, interpolated linearly.
    fn at(&self, t: f64) -> Option<([f64; 2], f64)> {
        let k = self.0.partition_point(|r| r[0] < t);
        if k == 0 {
            return (t == self.0[0][0]).then(|| ([self.0[0][1], self.0[0][2]], self.0[0][4]));
        }
        let (a, b) = (self.0[k - 1], *self.0.get(k)?);
        let w = (t - a[0]) / (b[0] - a[0]);
        let dyaw = (b[4] - a[4] + 180.0).rem_euclid(360.0) - 180.0;
        Some((
            [a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])],
            a[4] + w * dyaw,
        ))
    }

    /// The 95th percentile, over GNSS epochs `period` s apart (on whole multiples of it, as a
    /// receiver reports), of the distance between the true position halfway between two epochs
    /// and the midpoint of the chord joining them: what linear interpolation between epochs
    /// misses (the sagitta of a turn, the lag of an acceleration), m.
    fn interpolation_p95(&self, period: f64) -> f64 {
        let (t0, t1) = self.span();
        let first = (t0 / period).ceil() as i64;
        let mut e = Vec::new();
        for k in first.. {
            let a = k as f64 * period;
            let (Some((pa, _)), Some((pm, _)), Some((pb, _))) =
                (self.at(a), self.at(a + period / 2.0), self.at(a + period))
            else {
                if a > t1 {
                    break;
                }
                continue;
            };
            e.push((pm[0] - (pa[0] + pb[0]) / 2.0).hypot(pm[1] - (pa[1] + pb[1]) / 2.0));
        }
        quantile(e, 0.95)
    }

    /// The 95th percentile of the distances from the true position, every second from the
    /// start, to the objects of the run's surveyed scene, m.
    fn object_range_p95(&self, d: &SynthRun) -> f64 {
        let scene: toml::Value =
            toml::from_str(&std::fs::read_to_string(d.rep.join("scene.toml")).unwrap()).unwrap();
        let objects: Vec<(f64, f64)> = scene["object"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| {
                let p = &o["pose"];
                (p["x"].as_float().unwrap(), p["y"].as_float().unwrap())
            })
            .collect();
        let (t0, t1) = self.span();
        let mut dist = Vec::new();
        let mut t = t0;
        while t <= t1 {
            let (p, _) = self.at(t).unwrap();
            dist.extend(objects.iter().map(|o| (o.0 - p[0]).hypot(o.1 - p[1])));
            t += 1.0;
        }
        quantile(dist, 0.95)
    }

    /// The speed between consecutive samples, m/s.
    fn speeds(&self) -> Vec<f64> {
        self.0
            .windows(2)
            .map(|w| (w[1][1] - w[0][1]).hypot(w[1][2] - w[0][2]) / (w[1][0] - w[0][0]))
            .collect()
    }
}

/// The numbers of a CSV file of numbers (`truth.csv`, `trajectory.csv`), row by row, without
/// its header.
fn csv_rows(path: &std::path::Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// The smoothed heading's error against the truth (deg) and the smoother's own 1-sigma (deg)
/// at every sample of `trajectory.csv` (written beside the run by [`drive_seeded_and_check`])
/// that lies in a usable segment of the report `v`.
fn usable_heading_errors(d: &SynthRun, truth: &Truth, v: &Value) -> Vec<(f64, f64)> {
    let rows = csv_rows(&d.dir.path().join("trajectory.csv"));
    // The segments are counted from the run's start (to the millisecond).
    let run_start = rows[0][0].min(truth.span().0);
    let segments = v["segments"].as_array().unwrap();
    let usable_at = |t: f64| {
        let rel = t - run_start;
        segments.iter().any(|s| {
            s["verdict"] == "pass"
                && s["from_s"].as_f64().unwrap() - 0.01 <= rel
                && rel <= s["to_s"].as_f64().unwrap() + 0.01
        })
    };
    // trajectory.csv: t, x, y, yaw_deg, sigma_xy, sigma_yaw.
    rows.iter()
        .filter(|r| usable_at(r[0]))
        .filter_map(|r| {
            let (_, yaw) = truth.at(r[0])?;
            Some(((r[3] - yaw + 180.0).rem_euclid(360.0) - 180.0, r[5]))
        })
        .collect()
}

/// The `p` quantile of `v` (the sample at rank round((n − 1) p) of the sorted values).
fn quantile(mut v: Vec<f64>, p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// The fault lies within `slack` seconds of the injected window.
fn located(f: &Value, from: f64, to: f64, slack: f64) {
    let (a, b) = (f["from_s"].as_f64().unwrap(), f["to_s"].as_f64().unwrap());
    assert!(
        (a - from).abs() <= slack && (b - to).abs() <= slack,
        "{}: {a:.2}..{b:.2} s, injected {from}..{to} s",
        f["name"]
    );
}

/// The budget of a clean drive against the drive's physics, each term computed here from what
/// was injected and from the synthesizer's truth, not from `check`'s formulas: RTK noise 1 cm
/// per axis, objects surveyed to 10 cm, the antenna where the rig file says, the truth's own
/// interpolation error between GNSS epochs, the scene's range from the true track, a timing
/// error no larger than what speed times the true offset (CAN's 1 ms latency) and the offset's
/// resolution give. The heading term is the reported heading sigma at the true range; the
/// sigma itself is held against the true heading errors over twelve drives in
/// [`the_reported_sigmas_are_the_scatter_of_the_estimates`].
#[test]
fn a_clean_drive_passes_with_the_injected_accuracy() {
    let (code, v, d) = drive_seeded_and_check(|t| t, "", 11);
    assert_eq!(code, 0, "faults: {:?}", names(&v));
    assert_eq!(v["verdict"], "pass");
    let truth = Truth::read(&d);
    let acc = &v["accuracy"];
    let part = |k: &str| acc[k].as_f64().unwrap_or_else(|| panic!("accuracy {k}"));
    let sp = |k: &str| v["spatial"][k].as_f64().unwrap_or_else(|| panic!("{k}"));
    // Each term as a range [lo, hi] from the physics and its tolerance.
    // RTK: the receiver's 1 cm, unless its residuals say it is optimistic; the drive's 20 s
    // of noise wandering over 2 s hold about ten independent samples per axis, whose spread
    // is within 30 % of the injected sigma.
    let rtk = (0.7 * RTK_SIGMA_M, 1.3 * RTK_SIGMA_M);
    // Timing: what the true offset gives at the drive's speed, and no more than the offset's
    // resolution (3 sigma) would let pass.
    let v95 = quantile(truth.speeds(), 0.95);
    let timing = (
        0.0,
        v95 * (CAN_LATENCY_MS + 3.0 * sp("gnss_time_offset_sigma_ms")) * 1e-3,
    );
    // Interpolation: the true track's departure from the chord between GNSS epochs. The
    // smoothed track follows the truth's curvature and acceleration to a few per cent (at
    // most 4.4 % over 13 seeds), so 10 %.
    let interp = truth.interpolation_p95(0.1);
    let interp = (0.9 * interp, 1.1 * interp);
    // Lever arm: the antenna is where the rig file says; nothing beyond the estimate's
    // resolution may count.
    let lever = (0.0, 3.0 * sp("lever_arm_x_sigma_m"));
    // Heading: the angle in radians times the true 95th-percentile range of the surveyed
    // objects (the rig's 30 m at most); the range to the ego's position error (1 cm) and the
    // instants sampled (every second, within 20 ms: 5 cm at 2.5 m/s).
    let range = truth.object_range_p95(&d).min(30.0);
    let heading_rad = part("heading_sigma_deg").to_radians();
    let heading = (heading_rad * (range - 0.05), heading_rad * (range + 0.05));
    let check = |k: &str, (lo, hi): (f64, f64)| {
        let x = part(k);
        assert!(
            lo - 1e-12 <= x && x <= hi + 1e-12,
            "accuracy {k} = {x:.5} m, the drive's physics give {lo:.5}..{hi:.5} m"
        );
    };
    check("trajectory_m", rtk);
    check("temporal_m", timing);
    check("interpolation_m", interp);
    check("lever_arm_m", lever);
    check("heading_m", heading);
    let (hr, r) = (part("heading_range_m"), range);
    assert!((hr - r).abs() <= 0.05, "heading range {hr} m, true {r} m");
    // The ego budget is the root sum of squares of its parts; the survey is 10 cm (every
    // object's accuracy in the surveyed scene); the grid cell is ten times the reference
    // accuracy and at least 10 cm (Rosenberger et al. 2019, §6).
    let rss = |parts: &[f64]| parts.iter().map(|p| p * p).sum::<f64>().sqrt();
    let ego = (
        rss(&[rtk.0, timing.0, interp.0, lever.0, heading.0]),
        rss(&[rtk.1, timing.1, interp.1, lever.1, heading.1]),
    );
    check("ego_m", ego);
    check("scene_m", (SURVEY_SIGMA_M, SURVEY_SIGMA_M));
    let reference = (rss(&[ego.0, SURVEY_SIGMA_M]), rss(&[ego.1, SURVEY_SIGMA_M]));
    check("reference_m", reference);
    check(
        "grid_cell_m",
        ((10.0 * reference.0).max(0.1), (10.0 * reference.1).max(0.1)),
    );
    // The data-driven estimates agree with the truth within their own uncertainty.
    within_3_sigma(&v, "can_speed_scale", "can_speed_scale_sigma", 1.0);
    within_3_sigma(
        &v,
        "gnss_time_offset_ms",
        "gnss_time_offset_sigma_ms",
        -CAN_LATENCY_MS,
    );
    within_3_sigma(&v, "lever_arm_x_measured_m", "lever_arm_x_sigma_m", 0.60);
    // Segments are usable, or marked for their heading only (no fault anywhere).
    for s in v["segments"].as_array().unwrap() {
        assert!(
            s["verdict"] == "pass"
                || (s["verdict"] == "unusable"
                    && s["reasons"] == serde_json::json!(["heading_uncertain"])),
            "{s}"
        );
    }
}

/// The smoothed heading (`check --trajectory`) against the synthesizer's truth, on drives that
/// start standing, already moving, and in a turn: the smoother's heading sigma is honest (over
/// the three drives the errors, in its units, have an rms near 1: neither far above, which
/// would make the marks meaningless, nor far below), at most 5 % of the usable samples lie
/// beyond three sigma, and no usable sample is off by more than three times the rig's limit.
#[test]
fn the_heading_is_as_good_as_its_sigma_says() {
    let cases: [(&str, u64); 3] = [("standing", 21), ("moving", 22), ("turning", 23)];
    let (mut z2, mut n, mut outside, mut usable) = (0.0, 0usize, 0usize, 0usize);
    for (start, seed) in cases {
        let edit = |t: String| match start {
            "standing" => t,
            "moving" => t.replace("lead_in_s = 0.8", "lead_in_s = 0.8\nstart_speed_mps = 2.2"),
            _ => t
                .replace("lead_in_s = 0.8", "lead_in_s = 0.8\nstart_speed_mps = 2.2")
                .replace(
                    "waypoints = [[-16.0, 0.0],",
                    "waypoints = [[-21.0, -5.0], [-19.0, -1.5], [-16.0, 0.0],",
                ),
        };
        let d = synth_and_record_edited(edit, "", seed, true);
        let (code, v, traj) = check_with_trajectory(&d, None);
        assert_eq!(code, Some(0), "{start}: faults {:?}", names(&v));
        // truth.csv: t, x, y, z, yaw_deg; trajectory.csv: t, x, y, yaw_deg, sigma_xy, sigma_yaw.
        let truth = csv_rows(&d.rep.join("truth.csv"));
        let est = csv_rows(&traj);
        let run_start = est[0][0].min(truth[0][0]);
        let segments = v["segments"].as_array().unwrap();
        let usable_at = |t: f64| {
            // The segments are counted from the run's start (`start`, to the millisecond).
            let rel = t - run_start;
            segments.iter().any(|s| {
                s["verdict"] == "pass"
                    && s["from_s"].as_f64().unwrap() - 0.01 <= rel
                    && rel <= s["to_s"].as_f64().unwrap() + 0.01
            })
        };
        let limit = 0.2;
        for r in &est {
            let k = truth.partition_point(|x| x[0] < r[0]);
            if k == 0 || k >= truth.len() {
                continue;
            }
            let (a, b) = (&truth[k - 1], &truth[k]);
            let w = (r[0] - a[0]) / (b[0] - a[0]);
            let yaw = a[4] + w * ((b[4] - a[4] + 180.0).rem_euclid(360.0) - 180.0);
            let e = (r[3] - yaw + 180.0).rem_euclid(360.0) - 180.0;
            z2 += (e / r[5]).powi(2);
            n += 1;
            if usable_at(r[0]) {
                usable += 1;
                assert!(
                    e.abs() <= 3.0 * limit,
                    "{start}: heading error {e}° at {}",
                    r[0]
                );
                if e.abs() > 3.0 * r[5] {
                    outside += 1;
                }
            }
        }
    }
    let rms = (z2 / n as f64).sqrt();
    assert!((0.3..=1.5).contains(&rms), "rms error/sigma {rms}");
    assert!(usable > n / 2, "{usable} of {n} samples usable");
    assert!(
        outside * 20 <= usable,
        "{outside} of {usable} beyond 3 sigma"
    );
}

/// A slalom (±40° of heading) at 6.5 m/s from standstill, without the pedestrian, with a
/// receiver of 5 mm white noise at 5 Hz and a CAN yaw rate measured only while moving (the car
/// stands 0.8 s: too short to read the sensor's noise there). The filter starts on the course
/// of the first metre, which lies in the first bend: the smoothed heading must still be right
/// from the first instant, within 3 of its own sigmas.
/// Smoothed a second time from the first pass's start only, the start erred by 0.9° against a
/// sigma of 0.03° (benches/check_campaign.py --paths mixed, slalom seed 118).
#[test]
fn a_slalom_from_standstill_starts_on_the_true_heading() {
    let edit = |t: String| {
        let (a, b) = (
            t.find("[[walker]]").unwrap(),
            t.find("[variation]").unwrap(),
        );
        let t = format!("{}{}", &t[..a], &t[b..]);
        let from = t.find("waypoints = [").unwrap();
        let to = from + t[from..].find('\n').unwrap();
        format!(
            "{}waypoints = [[-60.0, 0.0], [-40.0, 6.0], [-20.0, -6.0], [0.0, 6.0], [20.0, -6.0], [40.0, 6.0]]{}",
            &t[..from],
            &t[to..]
        )
        .replace("cruise_speed_mps = 2.2", "cruise_speed_mps = 6.5")
        .replace("acceleration_mps2 = 0.8", "acceleration_mps2 = 1.5")
        .replace("rate_hz = 10\n", "rate_hz = 5\n")
        .replace("sigma_horizontal_m = 0.010", "sigma_horizontal_m = 0.005")
        .replace("correlation_s = 2.0", "correlation_s = 0.0")
    };
    let d = synth_and_record_edited(edit, "", 118, true);
    let (code, v, _) = check_with_trajectory(&d, None);
    assert_eq!(code, Some(0), "faults {:?}", names(&v));
    let truth = Truth::read(&d);
    let rows = csv_rows(&d.dir.path().join("trajectory.csv"));
    let (mut z2, mut n) = (0.0, 0);
    for r in &rows {
        let Some((_, yaw)) = truth.at(r[0]) else {
            continue;
        };
        let e = (r[3] - yaw + 180.0).rem_euclid(360.0) - 180.0;
        if r[0] - rows[0][0] < 1.0 {
            assert!(
                e.abs() <= 3.0 * r[5],
                "{:.2} s after the start: heading error {e:.3}° against a sigma of {:.3}°",
                r[0] - rows[0][0],
                r[5]
            );
        }
        z2 += (e / r[5]).powi(2);
        n += 1;
    }
    // Not yet within 1.25 here: the slaloms are where the sigma is least honest (1.64 on
    // this drive; pooled over the benches' slaloms 1.16-1.38, see the closing notes).
    let rms = (z2 / n as f64).sqrt();
    assert!((0.5..=2.0).contains(&rms), "rms error/sigma {rms:.2}");
}

#[test]
fn rtk_float_sigma_spike_lidar_gap_and_free_running_lidar_clock_are_found_and_located() {
    let (code, v) = drive_and_check(
        "rtk = [{ from_s = 12.0, to_s = 13.5, quality = 5 }]\n\
         sigma_spike = [{ from_s = 16.0, to_s = 16.8, sigma_m = 0.08 }]\n\
         lidar_gap = [{ from_s = 3.0, to_s = 3.4 }]\n\
         lidar_free_running = { offset_ms = 7.0, drift_ppm = 60.0 }",
    );
    assert_eq!(code, 1);
    assert_eq!(v["verdict"], "fail");
    let n = names(&v);
    let float = faults(&v, "rtk_float");
    assert_eq!(float.len(), 1, "{n:?}");
    located(float[0], 12.0, 13.5, 0.15);
    // The largest sigmas are reported where they were: the float window (0.2 m), then the spike.
    let worst = v["spatial"]["worst_sigma_windows"].as_array().unwrap();
    let (from, sigma) = (
        worst[0]["from_s"].as_f64().unwrap(),
        worst[0]["sigma_m"].as_f64().unwrap(),
    );
    assert!((11.0..14.0).contains(&from) && sigma > 0.15, "{worst:?}");
    let spike = faults(&v, "sigma_spike");
    assert_eq!(spike.len(), 1, "{n:?}");
    located(spike[0], 16.0, 16.8, 0.15);
    let gap = faults(&v, "lidar_gap");
    assert_eq!(gap.len(), 1, "{n:?}");
    located(gap[0], 3.0, 3.4, 0.05);
    let pps = faults(&v, "lidar_not_pps_locked");
    assert_eq!(pps.len(), 1, "{n:?}");
    assert!(
        pps[0]["detail"].as_str().unwrap().contains("60.")
            && pps[0]["detail"].as_str().unwrap().contains("faster"),
        "{}",
        pps[0]["detail"]
    );
    assert!(pps[0]["to_s"].as_f64().unwrap() - pps[0]["from_s"].as_f64().unwrap() > 15.0);
    // Nothing else is blamed.
    for other in ["can_speed_scale", "gnss_time_offset", "lever_arm", "jump"] {
        assert!(faults(&v, other).is_empty(), "false {other}: {n:?}");
    }
    // The segments say which parts are usable: 5-6 s is (nothing injected there)... only if the
    // whole-run PPS fault did not cover it, which it does; so every segment fails with a reason.
    let segs = v["segments"].as_array().unwrap();
    let at = |t: f64| {
        segs.iter()
            .find(|s| s["from_s"].as_f64().unwrap() <= t && t < s["to_s"].as_f64().unwrap())
            .unwrap()
    };
    assert!(at(12.5)["reasons"]
        .as_array()
        .unwrap()
        .iter()
        .any(|r| r == "rtk_float"));
    assert!(!at(7.5)["reasons"]
        .as_array()
        .unwrap()
        .iter()
        .any(|r| r == "rtk_float"));
}

#[test]
fn a_50_ms_gnss_time_offset_is_found() {
    let (code, v, d) = drive_seeded_and_check(|t| t, "gnss_time_offset_ms = 50.0", 11);
    assert_eq!(code, 1);
    let f = faults(&v, "gnss_time_offset");
    assert_eq!(f.len(), 1, "{:?}", names(&v));
    within_3_sigma(
        &v,
        "gnss_time_offset_ms",
        "gnss_time_offset_sigma_ms",
        50.0 - CAN_LATENCY_MS,
    );
    assert!(faults(&v, "lever_arm").is_empty() && faults(&v, "can_speed_scale").is_empty());
    // The budget counts the offset at the drive's speed: the true offset (the injected 50 ms
    // less CAN's 1 ms latency) times the 95th percentile of the true speed, to the offset's
    // resolution (3 sigma) and the speed's (CAN's 1 cm/s noise moves the percentile of
    // 2.5 m/s by well under 2 %). The lidar is PPS-locked: no time error of its own.
    let v95 = quantile(Truth::read(&d).speeds(), 0.95);
    let offset_s = (50.0 - CAN_LATENCY_MS) * 1e-3;
    let sigma_s = v["spatial"]["gnss_time_offset_sigma_ms"].as_f64().unwrap() * 1e-3;
    let temporal = v["accuracy"]["temporal_m"].as_f64().unwrap();
    let tolerance = v95 * 3.0 * sigma_s + 0.02 * v95 * offset_s;
    assert!(
        (temporal - v95 * offset_s).abs() <= tolerance,
        "temporal term {temporal:.4} m; {offset_s} s at {v95:.3} m/s is {:.4} ± {tolerance:.4} m",
        v95 * offset_s
    );
}

#[test]
fn a_3_percent_can_speed_scale_error_is_found() {
    let (code, v) = drive_and_check("can_speed_scale = 1.03");
    assert_eq!(code, 1);
    let f = faults(&v, "can_speed_scale");
    assert_eq!(f.len(), 1, "{:?}", names(&v));
    within_3_sigma(&v, "can_speed_scale", "can_speed_scale_sigma", 1.03);
    assert!(f[0]["detail"].as_str().unwrap().contains("higher"));
    assert!(faults(&v, "gnss_time_offset").is_empty() && faults(&v, "lever_arm").is_empty());
}

#[test]
fn an_antenna_lever_arm_wrong_by_half_a_metre_is_found() {
    let (code, v) = drive_and_check("antenna_error_m = [0.5, 0.0, 0.0]");
    assert_eq!(code, 1);
    let f = faults(&v, "lever_arm");
    assert_eq!(f.len(), 1, "{:?}", names(&v));
    // True antenna x: the rig's 0.60 m plus the 0.5 m error.
    within_3_sigma(&v, "lever_arm_x_measured_m", "lever_arm_x_sigma_m", 1.10);
    // Located in the turn into the slot (the last part of the drive).
    assert!(f[0]["from_s"].as_f64().unwrap() > 8.0);
    assert!(faults(&v, "gnss_time_offset").is_empty(), "{:?}", names(&v));
    // The budget counts the injected error, to the estimate's resolution (3 sigma).
    let lever = v["accuracy"]["lever_arm_m"].as_f64().unwrap();
    let sigma = v["spatial"]["lever_arm_x_sigma_m"].as_f64().unwrap();
    assert!(
        (lever - 0.5).abs() <= 3.0 * sigma,
        "lever-arm term {lever:.3} m, injected 0.5 m (sigma {sigma:.3} m)"
    );
}

/// A lidar clock that runs free behind a host with 300 µs of receive jitter (a half-normal
/// delay on top of the latency): without PPS the lidar's time is the host clock model's, whose
/// residuals above its lower envelope are that delay. Their 95th percentile is 1.96 × 300 µs
/// (P(|Z| ≤ 1.96) = 0.95), within the 1 ms limit, so the clock is not a residual fault, and
/// the budget counts it at the drive's speed (the 95th percentile of the true speed).
#[test]
fn a_free_running_lidar_clock_counts_its_jitter_at_speed_in_the_budget() {
    let (code, v, d) = drive_seeded_and_check(
        |t| t.replace("jitter_us = 60", "jitter_us = 300"),
        "lidar_free_running = { offset_ms = 3.0, drift_ppm = 20.0 }",
        11,
    );
    assert_eq!(code, 1);
    assert_eq!(names(&v), ["lidar_not_pps_locked"]);
    let v95 = quantile(Truth::read(&d).speeds(), 0.95);
    let error_s = 1.959_964 * 300e-6;
    // Tolerance: the percentile of some 15 000 packet delays (1 % of it, one sigma of the
    // order statistic), the µs resolution of the lidar's stamps, the speed's percentile (2 %).
    let expected = v95 * error_s;
    let temporal = v["accuracy"]["temporal_m"].as_f64().unwrap();
    assert!(
        (temporal - expected).abs() <= 0.05 * expected,
        "temporal term {temporal:.5} m; a {:.0} µs clock residual at {v95:.3} m/s is {expected:.5} m",
        error_s * 1e6
    );
}

/// The faults no other test injects, each in its own stretch of one drive: epochs without RTK,
/// old corrections, a silent receiver, a silent CAN bus and one epoch 15 cm off (15 receiver
/// sigmas) that the receiver still calls fixed. Each is named and located where it was put.
#[test]
fn rtk_none_old_corrections_gaps_and_a_jump_are_found_and_located() {
    let (code, v) = drive_and_check(
        "rtk = [{ from_s = 9.0, to_s = 10.0, quality = 1 }]\n\
         correction_age = [{ from_s = 4.0, to_s = 5.0, age_s = 8.0 }]\n\
         gnss_gap = [{ from_s = 12.0, to_s = 13.0 }]\n\
         can_gap = [{ from_s = 6.0, to_s = 6.5 }]\n\
         position_jump = [{ at_s = 15.0, offset_m = [0.15, 0.0] }]",
    );
    assert_eq!(code, 1);
    let n = names(&v);
    let none = faults(&v, "rtk_none");
    assert_eq!(none.len(), 1, "{n:?}");
    located(none[0], 9.0, 10.0, 0.15);
    assert!(none[0]["detail"].as_str().unwrap().contains("quality 1"));
    let age = faults(&v, "correction_age");
    assert_eq!(age.len(), 1, "{n:?}");
    located(age[0], 4.0, 5.0, 0.15);
    // A gap runs from the last sample before it to the first after it.
    let gnss = faults(&v, "gnss_gap");
    assert_eq!(gnss.len(), 1, "{n:?}");
    located(gnss[0], 12.0, 13.0, 0.15);
    let can = faults(&v, "can_gap");
    assert_eq!(can.len(), 1, "{n:?}");
    located(can[0], 6.0, 6.5, 0.05);
    let jump = faults(&v, "jump");
    assert_eq!(jump.len(), 1, "{n:?}");
    located(jump[0], 15.0, 15.1, 0.15);
    assert!(v["spatial"]["jumps"].as_u64().unwrap() >= 1);
}

/// A lidar clock that runs free behind a busy host (2 ms of receive jitter): without PPS its
/// time is the host clock model's, whose residuals (p95 about 4 ms) exceed the 1 ms limit.
#[test]
fn a_free_running_lidar_clock_behind_a_jittery_host_fails_on_its_residuals() {
    let (code, v) = drive_edited_and_check(
        |t| t.replace("jitter_us = 60", "jitter_us = 2000"),
        "lidar_free_running = { offset_ms = 3.0, drift_ppm = 20.0 }",
    );
    assert_eq!(code, 1);
    let n = names(&v);
    assert_eq!(faults(&v, "lidar_not_pps_locked").len(), 1, "{n:?}");
    let r = faults(&v, "lidar_clock_residual");
    assert_eq!(r.len(), 1, "{n:?}");
    assert!(r[0]["detail"].as_str().unwrap().contains("above 1000 µs"));
}

/// Must-hold 3: the RTK states `check` reports for real receiver logs recorded with `record
/// --from` are gpsd's (TPV status 3 fixed, 4 float, else none), epoch by epoch.
fn gpsd_states(name: &str) {
    let log = real_data().join("gnss").join(name);
    let chk = std::fs::read_to_string(log.with_file_name(format!("{name}.chk"))).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("run.mcap");
    let rec = record_from(&demo_rig(), &[&log], &mcap);
    assert!(
        rec.status.success(),
        "{}",
        String::from_utf8_lossy(&rec.stderr)
    );
    let json = dir.path().join("check.json");
    let out = Command::new(hilrig_bin())
        .arg("check")
        .arg(&mcap)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    // No CAN and no lidar in a receiver log: the run fails for the two missing sources, and
    // the GNSS part is reported (with the receiver's own faults).
    assert_eq!(out.status.code(), Some(1));
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(names(&v)[..2], ["no_lidar_data", "no_ego_motion"]);
    let ours: std::collections::BTreeMap<String, String> = v["spatial"]["rtk_epochs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["time"].as_str().unwrap().to_owned(),
                e["state"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    let (mut matched, mut untimed) = (0, 0);
    for l in chk.lines().filter(|l| l.starts_with('{')) {
        let t: Value = serde_json::from_str(l).unwrap();
        if t["class"] != "TPV" || !t["lat"].is_number() {
            continue;
        }
        let Some(time) = t["time"].as_str() else {
            untimed += 1;
            continue;
        };
        let state = match t["status"].as_i64() {
            Some(3) => "fixed",
            Some(4) => "float",
            _ => "none",
        };
        assert_eq!(
            ours.get(time).map(String::as_str),
            Some(state),
            "{name}: epoch {time}"
        );
        matched += 1;
    }
    println!("{name}: {matched} gpsd epochs with the same RTK state ({untimed} TPVs without time)");
    assert!(matched > 0);
}

macro_rules! gpsd_rtk {
    ($($test:ident => $file:literal),*) => {$(
        #[test]
        #[cfg_attr(not(hilrig_real_data), ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run")]
        fn $test() {
            gpsd_states($file);
        }
    )*};
}

gpsd_rtk!(
    gpsd_rtk_states_trimble => "nmea-rtk.log",
    gpsd_rtk_states_f9p_rtk => "ublox-zed-f9p-rtk.log",
    gpsd_rtk_states_f9p_hp => "ublox-zed-f9p-hp.log",
    gpsd_rtk_states_f9r => "ublox-zed-f9r.log"
);

/// A recording cut anywhere or with bytes flipped still gives a report, never a panic (what a
/// crash or a failing disk leaves behind), and a recording cut early is judged on what it holds.
#[test]
fn damaged_recordings_give_a_report_not_a_panic() {
    use proptest::prelude::*;
    let d = synth_and_record("", 1, true);
    let mcap = &d.run;
    let bytes = std::fs::read(mcap).unwrap();
    let rig = hilrig::rig::Rig::load(&demo_rig()).unwrap();
    let whole = hilrig::reference::check::check(
        &hilrig::reference::run::Run::from_bytes(&bytes),
        &rig,
        None,
    );
    assert_eq!(whole.verdict, hilrig::reference::check::Verdict::Pass);
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig::with_cases(24));
    runner
        .run(
            &(
                0.0f64..1.0,
                proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..8),
            ),
            |(cut, flips)| {
                let mut b = bytes[..(bytes.len() as f64 * cut) as usize].to_vec();
                for &(at, v) in &flips {
                    if !b.is_empty() {
                        let i = (b.len() as f64 * at) as usize % b.len();
                        b[i] ^= v;
                    }
                }
                let cut_short = b.len() < bytes.len();
                let run = hilrig::reference::run::Run::from_bytes(&b);
                let report = hilrig::reference::check::check(&run, &rig, None);
                // A cut-off file is reported as damaged, in the report and its text, and judged
                // on what it holds: never more epochs or a longer run than the whole file.
                if cut_short {
                    prop_assert!(
                        report.damage.is_some()
                            || report.verdict == hilrig::reference::check::Verdict::Unusable,
                        "cut at {cut}: neither damage nor unusable"
                    );
                    let text = report.text();
                    prop_assert!(
                        report.verdict == hilrig::reference::check::Verdict::Unusable
                            || text.contains("recording damaged"),
                        "{text}"
                    );
                }
                prop_assert!(report.spatial.epochs <= whole.spatial.epochs);
                // A cut file spans no longer than the whole; a flipped byte may move a log time
                // (MCAP chunks carry no checksum here), and the run is then judged on that.
                if flips.is_empty() {
                    prop_assert!(report.duration_s <= whole.duration_s + 1e-9);
                }
                Ok(())
            },
        )
        .unwrap();
}

/// With a heading limit between the best and the worst heading sigma of the drive, the
/// stretches whose sigma exceeds it are marked `heading_uncertain`: not usable, yet no fault
/// (exit 0); every trajectory sample above the limit lies in a mark, and none in a usable
/// segment.
#[test]
fn stretches_with_an_uncertain_heading_are_marked_not_usable_without_a_fault() {
    // With returns: the run is compared with its re-simulation below.
    let d = common::synth_and_record_edited(|t| t, "", 21, true);
    let rig_text = std::fs::read_to_string(demo_rig()).unwrap();
    let dbc = demo_rig().with_file_name("hilrig-ego.dbc");
    // The limit halfway between the drive's best and worst heading sigma at the default rig.
    let (_, _, traj) = check_with_trajectory(&d, None);
    let sigmas: Vec<f64> = std::fs::read_to_string(&traj)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(5).unwrap().parse().unwrap())
        .collect();
    let (lo, hi) = sigmas
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(
        hi - lo > 0.01,
        "heading sigma {lo}..{hi}°: too flat to test"
    );
    let limit = ((lo + hi) / 2.0 * 1000.0).round() / 1000.0;
    let tight = rig_text
        .replace(
            "max_heading_sigma_deg = 0.2",
            &format!("max_heading_sigma_deg = {limit}"),
        )
        .replace(
            "\"hilrig-ego.dbc\"",
            &format!("{:?}", dbc.display().to_string()),
        );
    assert!(tight.contains(&format!("max_heading_sigma_deg = {limit}")));
    let rig = d.dir.path().join("tight.toml");
    std::fs::write(&rig, tight).unwrap();
    let (code, v, traj) = check_with_trajectory(&d, Some(&rig));
    assert_eq!(code, Some(0), "faults {:?}", names(&v));
    let marks = v["marks"].as_array().unwrap();
    assert!(!marks.is_empty(), "no marks at a {limit}° limit");
    let t0 = std::fs::read_to_string(d.rep.join("truth.csv"))
        .unwrap()
        .lines()
        .nth(1)
        .and_then(|l| l.split(',').next().map(|x| x.parse::<f64>().unwrap()))
        .unwrap();
    let within = |list: &[Value], rel: f64, pad: f64| {
        list.iter().any(|m| {
            m["from_s"].as_f64().unwrap() - pad <= rel && rel <= m["to_s"].as_f64().unwrap() + pad
        })
    };
    let usable: Vec<Value> = v["segments"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["verdict"] == "pass")
        .cloned()
        .collect();
    let (mut above, mut seen) = (0, 0);
    for l in std::fs::read_to_string(&traj).unwrap().lines().skip(1) {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        let rel = f[0] - t0;
        seen += 1;
        if f[5] > limit + 0.002 {
            above += 1;
            assert!(
                within(marks, rel, 0.15),
                "sigma {}° at {rel:.2} s not marked",
                f[5]
            );
            assert!(
                !within(&usable, rel, -0.15),
                "sigma {}° at {rel:.2} s usable",
                f[5]
            );
        }
    }
    assert!(
        above > 0 && above < seen,
        "{above} of {seen} samples above the limit"
    );

    // Downstream, the marked stretches are left out: the run passes, so `resim` casts all of
    // it, and `compare` (with the same rig) leaves out exactly the scans that touch a mark.
    let sim = d.dir.path().join("sim.mcap");
    hilrig_ok(&[
        "resim".as_ref(),
        d.run.as_os_str(),
        "--rig".as_ref(),
        rig.as_os_str(),
        "--scene".as_ref(),
        d.rep.join("scene.toml").as_os_str(),
        "--model".as_ref(),
        fixture("parking/idealized.toml").as_os_str(),
        "-o".as_ref(),
        sim.as_os_str(),
    ]);
    let (scene, json) = (d.rep.join("scene.toml"), d.dir.path().join("compare.json"));
    let compare = |rig: Option<&std::path::Path>| {
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "compare".as_ref(),
            d.run.as_os_str(),
            sim.as_os_str(),
            "--scene".as_ref(),
            scene.as_os_str(),
            "--json".as_ref(),
            json.as_os_str(),
        ];
        if let Some(r) = rig {
            args.extend(["--rig".as_ref(), r.as_os_str()]);
        }
        let out = hilrig_ok(&args);
        let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (String::from_utf8_lossy(&out.stdout).into_owned(), v)
    };
    let (_, all) = compare(None);
    assert_eq!(all["left_out"], serde_json::json!([]));
    let (text, kept) = compare(Some(&rig));
    let left: u64 = kept["left_out"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["scans"].as_u64().unwrap())
        .sum();
    assert!(left > 0, "nothing left out: {text}");
    assert!(text.contains("left out"), "{text}");
    assert_eq!(
        kept["summary"]["scans"].as_u64().unwrap() + left,
        all["summary"]["scans"].as_u64().unwrap()
    );
    // Every scan compared lies clear of the marks (a scan's packets span 0.1 s from its
    // stamp).
    let start = iso_ns(v["start"].as_str().unwrap());
    for row in kept["scans"].as_array().unwrap() {
        let rel = (row["stamp_ns"].as_i64().unwrap() - start) as f64 * 1e-9;
        assert!(
            !marks
                .iter()
                .any(|m| m["from_s"].as_f64().unwrap() - 0.09 <= rel
                    && rel <= m["to_s"].as_f64().unwrap()),
            "scan at {rel:.2} s compared inside a mark"
        );
    }

    // The gap workflow samples no firing from a marked stretch, and says what it left out.
    let load = |part: Option<(usize, usize)>, firings: usize| {
        hilrig::gap::observe::load_run(
            &d.run,
            hilrig::scene::Scene::load(&scene).unwrap(),
            &scene,
            Some(&hilrig::rig::Rig::load(&rig).unwrap()),
            hilrig::gap::study::Role::Fit,
            part,
            firings,
            false,
        )
        .unwrap()
    };
    let run = load(None, 100_000);
    assert_eq!(run.left_out.len(), marks.len());
    assert!(!run.packets.is_empty());
    // A part of the run (here its first two scans) lists only the marks within it.
    let part = load(Some((0, 2)), 1_000);
    // (The two scans span the run's first 0.2 s or so: marks from before 0.15 s are in, marks
    // from after 0.3 s are not.)
    assert!(
        marks.iter().any(|m| m["from_s"].as_f64().unwrap() < 0.15),
        "no mark at the start to test the part with"
    );
    let starts: Vec<f64> = part.left_out.iter().map(|l| l.from_s).collect();
    println!(
        "marks from {:?} s; in the first two scans {starts:?}",
        marks.iter().map(|m| &m["from_s"]).collect::<Vec<_>>()
    );
    for m in marks {
        let from = m["from_s"].as_f64().unwrap();
        if from < 0.15 {
            assert!(starts.contains(&from), "{from} missing from {starts:?}");
        }
    }
    assert!(starts.iter().all(|&f| f <= 0.3), "{starts:?}");
    for p in &run.packets {
        let rel = (p.time.first_firing.0 - start) as f64 * 1e-9;
        assert!(
            !marks
                .iter()
                .any(|m| m["from_s"].as_f64().unwrap() - 0.002 <= rel
                    && rel <= m["to_s"].as_f64().unwrap() + 0.002),
            "a packet at {rel:.3} s sampled inside a mark"
        );
    }
}

/// UTC nanoseconds of an ISO 8601 time as `check` writes it (`2026-11-21T10:00:00.002Z`).
fn iso_ns(iso: &str) -> i64 {
    let (date, time) = iso.trim_end_matches('Z').split_once('T').unwrap();
    let d: Vec<i64> = date.split('-').map(|x| x.parse().unwrap()).collect();
    let days = hilrig_stamp::civil::days_from_civil(d[0], d[1] as u32, d[2] as u32).unwrap();
    days * 86_400_000_000_000 + hilrig_stamp::civil::parse_hms(&time.replace(':', "")).unwrap()
}

/// A heading limit below the drive's best heading sigma marks every stretch: nothing is left to
/// measure a model against, so the run fails (`nothing_usable`, exit 1) and `resim` refuses it.
#[test]
fn a_run_marked_not_usable_throughout_fails() {
    let d = synth_and_record_edited(|t| t, "", 22, true);
    let dbc = demo_rig().with_file_name("hilrig-ego.dbc");
    let rig_text = std::fs::read_to_string(demo_rig())
        .unwrap()
        .replace(
            "max_heading_sigma_deg = 0.2",
            "max_heading_sigma_deg = 0.0001",
        )
        .replace(
            "\"hilrig-ego.dbc\"",
            &format!("{:?}", dbc.display().to_string()),
        );
    assert!(rig_text.contains("max_heading_sigma_deg = 0.0001"));
    let rig = d.dir.path().join("tight.toml");
    std::fs::write(&rig, rig_text).unwrap();
    let (code, v, _) = check_with_trajectory(&d, Some(&rig));
    assert_eq!(code, Some(1));
    assert_eq!(names(&v), ["nothing_usable"]);
    assert!(
        faults(&v, "nothing_usable")[0]["detail"]
            .as_str()
            .unwrap()
            .contains("heading_uncertain"),
        "{v}"
    );
    assert!(v["segments"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s["verdict"] == "fail"));
    let out = std::process::Command::new(hilrig_bin())
        .arg("resim")
        .arg(&d.run)
        .arg("--rig")
        .arg(&rig)
        .arg("--scene")
        .arg(d.rep.join("scene.toml"))
        .arg("--model")
        .arg(fixture("parking/idealized.toml"))
        .arg("-o")
        .arg(d.dir.path().join("sim.mcap"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("nothing_usable") && err.contains("--force"),
        "{err}"
    );
    assert!(!d.dir.path().join("sim.mcap").exists());
}

/// Copies the capture `src` to `out`, each record's data passed through `edit`, which keeps
/// the record (possibly changed) or drops it (false).
fn rewrite_capture(
    src: &std::path::Path,
    out: &std::path::Path,
    mut edit: impl FnMut(
        hilrig::capture::LinkType,
        &mut hilrig::capture::UtcNanos,
        &mut Vec<u8>,
    ) -> bool,
) {
    use hilrig::capture::{CaptureReader, PcapngWriter};
    let mut r =
        CaptureReader::new(std::io::BufReader::new(std::fs::File::open(src).unwrap())).unwrap();
    let mut w = PcapngWriter::new(Vec::new(), "tests/check.rs").unwrap();
    let mut declared = 0usize;
    while let Some(rec) = r.next_record() {
        let rec = rec.unwrap();
        let (interface, link, mut time, mut data) =
            (rec.interface, rec.link, rec.time, rec.data.to_vec());
        while declared <= interface as usize {
            let i = r.interfaces()[declared].clone();
            w.add_interface(i.link, i.name.as_deref().unwrap_or(""))
                .unwrap();
            declared += 1;
        }
        if edit(link, &mut time, &mut data) {
            w.write_packet(interface, time, &data).unwrap();
        }
    }
    std::fs::write(out, w.finish().unwrap()).unwrap();
}

/// A logger whose clock is not on UTC (no NTP or PTP on the vehicle, or not yet settled)
/// stamps every record of its capture off GNSS time: the lidar's own stamps and the fixes'
/// UTC stay, and the CAN frames, which carry no clock, carry the logger's. The PPS-locked
/// lidar's clock model tells how far off. Beyond what the lidar's own timing could be off
/// (100 ms), and with the GNSS receiver's clock model agreeing, the run's logger times are
/// put on GNSS time with it: the drive checks as with the clock on time (a drive of another
/// generator, the logger 2.5 s ahead, raised jumps at every epoch and a lever arm 2 m off),
/// and `compare` pairs and leaves out the same scans (the files keep the logger's clock).
/// Within 100 ms, a logger 50 ms ahead cannot be told from a lidar 50 ms late; with the GNSS
/// model 600 ms later than the lidar's, the two disagree: in both the times stay, and the GNSS
/// time offset fault says which it was.
#[test]
fn a_logger_clock_off_gnss_time_is_put_right_or_named() {
    // With returns: `compare` pairs the scans below.
    let d = common::synth_and_record("", 12, true);
    // A heading limit halfway between the drive's best and worst heading sigma, so that some
    // stretches are marked and `compare` leaves their scans out.
    let (_, _, traj) = check_with_trajectory(&d, None);
    let sigmas: Vec<f64> = csv_rows(&traj).iter().map(|r| r[5]).collect();
    let (lo, hi) = sigmas
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    let limit = ((lo + hi) / 2.0 * 1000.0).round() / 1000.0;
    let rig = d.dir.path().join("tight.toml");
    std::fs::write(
        &rig,
        std::fs::read_to_string(demo_rig())
            .unwrap()
            .replace(
                "max_heading_sigma_deg = 0.2",
                &format!("max_heading_sigma_deg = {limit}"),
            )
            .replace(
                "\"hilrig-ego.dbc\"",
                &format!(
                    "{:?}",
                    demo_rig()
                        .with_file_name("hilrig-ego.dbc")
                        .display()
                        .to_string()
                ),
            ),
    )
    .unwrap();
    let check_json =
        |d: &SynthRun, run: &std::path::Path, name: &str| check_json_with(d, run, Some(&rig), name);
    let (code, text, on_time) = check_json(&d, &d.run, "on-time");
    assert_eq!(code, Some(0), "{text}");
    let on_time_ahead = on_time["temporal"]["logger_ahead_of_gnss_ms"]
        .as_f64()
        .unwrap_or_else(|| panic!("no PPS-locked lidar clock: {}", on_time["temporal"]));
    assert_eq!(on_time["temporal"]["can_on_gnss_time"], false);
    assert_eq!(on_time["temporal"]["logger_clock"], "within_lidar_timing");
    let marks = on_time["marks"].as_array().unwrap().len();
    assert!(marks > 0, "no marks at a {limit}° limit");
    let on_time_cmp = resim_and_compare(&d, &d.run, &rig, "on-time");
    // The stamps of the scans `compare` kept, ns, on the clock of the drive on time.
    let kept = |c: &Value, off_ns: i64| -> Vec<i64> {
        c["scans"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["stamp_ns"].as_i64().unwrap() - off_ns)
            .collect()
    };
    let left_out = |c: &Value| -> Vec<(String, u64)> {
        c["left_out"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| {
                (
                    l["name"].as_str().unwrap().to_owned(),
                    l["scans"].as_u64().unwrap(),
                )
            })
            .collect()
    };
    assert!(
        !left_out(&on_time_cmp).is_empty(),
        "{}",
        on_time_cmp["left_out"]
    );
    let detail = |v: &Value| -> String {
        faults(v, "gnss_time_offset")[0]["detail"]
            .as_str()
            .unwrap()
            .to_owned()
    };
    for (off_ms, gnss_later_ms) in [(-2500i64, 0i64), (400, 0), (50, 0), (400, 600)] {
        let name = format!("logger{off_ms:+}ms-gnss{gnss_later_ms:+}ms");
        let edited = d.dir.path().join(format!("{name}.pcapng"));
        rewrite_capture(&d.rep.join("drive.pcapng"), &edited, |link, t, _| {
            t.0 += off_ms * 1_000_000;
            if link == hilrig::capture::LinkType::USER0 {
                t.0 += gnss_later_ms * 1_000_000;
            }
            true
        });
        let run = d.dir.path().join(format!("{name}.mcap"));
        let rec = record_from(&demo_rig(), &[&edited], &run);
        assert!(
            rec.status.success(),
            "{}",
            String::from_utf8_lossy(&rec.stderr)
        );
        let (code, text, v) = check_json(&d, &run, &name);
        let ahead = v["temporal"]["logger_ahead_of_gnss_ms"].as_f64().unwrap();
        assert!(
            (ahead - on_time_ahead - off_ms as f64).abs() < 1e-6,
            "{name}: {ahead} ms ahead, on time {on_time_ahead}"
        );
        let says = format!(
            "the PPS-locked lidar's clock model puts the logger's clock {:.1} ms {} GNSS time",
            ahead.abs(),
            if ahead < 0.0 { "behind" } else { "ahead of" }
        );
        if off_ms.abs() < 100 || gnss_later_ms > 0 {
            assert_eq!(code, Some(1), "{name}: {text}");
            assert_eq!(v["temporal"]["can_on_gnss_time"], false);
            assert!(
                names(&v).contains(&"gnss_time_offset".to_owned()),
                "{name}: {text}"
            );
            let (state, why) = if gnss_later_ms > 0 {
                (
                    "gnss_model_disagrees",
                    "CAN stays on the logger's clock: the GNSS receiver's clock model puts it",
                )
            } else {
                (
                    "within_lidar_timing",
                    "CAN stays on the logger's clock: within 100 ms",
                )
            };
            assert_eq!(v["temporal"]["logger_clock"], state, "{name}");
            let detail = detail(&v);
            assert!(
                detail.contains(&says) && detail.contains(why),
                "{name}: {detail}"
            );
            if gnss_later_ms == 0 {
                assert_eq!(names(&v), ["gnss_time_offset"], "{name}: {text}");
            }
            continue;
        }
        assert_eq!(code, Some(0), "{name}: {:?}\n{text}", names(&v));
        assert_eq!(v["temporal"]["can_on_gnss_time"], true);
        assert_eq!(v["temporal"]["logger_clock"], "put_on_gnss_time");
        assert!(
            text.contains(&format!("logger clock: {says}"))
                && text.contains("was put on GNSS time with that model"),
            "{text}"
        );
        // The CAN times went off with the logger's clock and came back, and then by the
        // lidar's transport latency too (the drive on time keeps its logger times: its model's
        // offset is that latency alone): the GNSS time offset moves by it, the other estimates
        // by a fraction of their sigma; the faults, marks, sources and span are the same.
        assert_eq!(v["faults"], on_time["faults"], "{name}");
        assert_eq!(
            v["marks"].as_array().unwrap().len(),
            on_time["marks"].as_array().unwrap().len(),
            "{name}"
        );
        let start_ms = |v: &Value| iso_ns(v["start"].as_str().unwrap()) as f64 * 1e-6;
        assert!(
            (start_ms(&v) - start_ms(&on_time)).abs() < 5.0
                && (v["duration_s"].as_f64().unwrap() - on_time["duration_s"].as_f64().unwrap())
                    .abs()
                    < 0.005,
            "{name}: starts {} for {} s, on time {} for {} s",
            v["start"],
            v["duration_s"],
            on_time["start"],
            on_time["duration_s"]
        );
        let sources = |v: &Value| -> Vec<(String, u64, f64)> {
            v["temporal"]["sources"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| {
                    (
                        s["source"].as_str().unwrap().to_owned(),
                        s["gaps"].as_u64().unwrap(),
                        s["rate_hz"].as_f64().unwrap(),
                    )
                })
                .collect()
        };
        for (a, b) in sources(&v).iter().zip(sources(&on_time).iter()) {
            assert!(
                a.0 == b.0 && a.1 == b.1 && (a.2 - b.2).abs() < 0.01 * b.2,
                "{name}: {a:?} against {b:?} on time"
            );
        }
        assert_eq!(sources(&v).len(), sources(&on_time).len());
        let sp = |v: &Value, k: &str| v["spatial"][k].as_f64().unwrap();
        let moved = sp(&v, "gnss_time_offset_ms") - sp(&on_time, "gnss_time_offset_ms");
        assert!(
            (moved - on_time_ahead).abs() < 0.3,
            "{name}: the GNSS time offset moved {moved} ms, the latency is {on_time_ahead} ms"
        );
        for (k, sigma) in [
            ("can_speed_scale", "can_speed_scale_sigma"),
            ("lever_arm_x_measured_m", "lever_arm_x_sigma_m"),
        ] {
            let by = (sp(&v, k) - sp(&on_time, k)).abs() / sp(&on_time, sigma);
            assert!(by < 0.25, "{name}: {k} moved {by} sigma");
        }
        // Compared with its own re-simulation: every scan paired, the same scans left out
        // for the same marks (their ends sampled every 100 ms from a start the latency moves:
        // a scan either side; put off by the logger's offset, 4 or more), the same figures
        // within the CAN's shift by the latency.
        let cmp = resim_and_compare(&d, &run, &rig, &name);
        let (a, b) = (kept(&cmp, off_ms * 1_000_000), kept(&on_time_cmp, 0));
        let near = |x: i64, ys: &[i64]| ys.iter().any(|y| (x - y).abs() < 1_000);
        let differ = a.iter().filter(|x| !near(**x, &b)).count()
            + b.iter().filter(|x| !near(**x, &a)).count();
        assert!(
            differ <= 2 * marks,
            "{name}: {differ} scans kept in one comparison only ({marks} marks)"
        );
        let summary = |c: &Value, k: &str| c["summary"][k].as_f64().unwrap();
        assert!(
            (summary(&cmp, "scans") - summary(&on_time_cmp, "scans")).abs() <= 1.0,
            "{name}: {} scans paired, {} on time",
            cmp["summary"]["scans"],
            on_time_cmp["summary"]["scans"]
        );
        assert_eq!(cmp["summary"]["unpaired_run_scans"], 0, "{name}");
        let (l, l0) = (left_out(&cmp), left_out(&on_time_cmp));
        assert!(
            l.len() == l0.len()
                && l.iter()
                    .zip(&l0)
                    .all(|(x, y)| x.0 == y.0 && x.1.abs_diff(y.1) <= 2),
            "{name}: left out {l:?}, on time {l0:?}"
        );
        for k in ["ocr_mean", "precision_mean", "range_diff_rms_m"] {
            assert!(
                (summary(&cmp, k) - summary(&on_time_cmp, k)).abs()
                    <= 0.02 * summary(&on_time_cmp, k).abs(),
                "{name}: {k} {} against {} on time",
                summary(&cmp, k),
                summary(&on_time_cmp, k)
            );
        }
    }
}

/// `compare`'s JSON of `run` against its re-simulation with the idealized model, checked
/// with `rig`.
fn resim_and_compare(
    d: &SynthRun,
    run: &std::path::Path,
    rig: &std::path::Path,
    name: &str,
) -> Value {
    let sim = d.dir.path().join(format!("{name}-sim.mcap"));
    let json = d.dir.path().join(format!("{name}-compare.json"));
    let resim = Command::new(hilrig_bin())
        .arg("resim")
        .arg(run)
        .arg("--scene")
        .arg(d.rep.join("scene.toml"))
        .arg("--model")
        .arg(fixture("parking/idealized.toml"))
        .arg("--no-clouds")
        .arg("-o")
        .arg(&sim)
        .output()
        .unwrap();
    assert!(
        resim.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&resim.stderr)
    );
    let cmp = Command::new(hilrig_bin())
        .arg("compare")
        .arg(run)
        .arg(&sim)
        .arg("--rig")
        .arg(rig)
        .arg("--scene")
        .arg(d.rep.join("scene.toml"))
        .arg("--no-point-metrics")
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert_eq!(
        cmp.status.code(),
        Some(0),
        "{name}: {}",
        String::from_utf8_lossy(&cmp.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// The capture `src` without the packets of its interfaces of link type `drop` (the interface
/// itself stays declared): what a silent serial line or CAN bus leaves in a capture. Returns
/// how many were dropped.
fn capture_without(
    src: &std::path::Path,
    drop: hilrig::capture::LinkType,
    out: &std::path::Path,
) -> usize {
    let mut dropped = 0;
    rewrite_capture(src, out, |link, _, _| {
        dropped += usize::from(link == drop);
        link != drop
    });
    dropped
}

/// `check` of `run` with the surveyed scene: exit code, stdout, JSON report.
fn check_json(d: &SynthRun, run: &std::path::Path, name: &str) -> (Option<i32>, String, Value) {
    check_json_with(d, run, None, name)
}

/// [`check_json`] with the rig file `rig` instead of the recording's own.
fn check_json_with(
    d: &SynthRun,
    run: &std::path::Path,
    rig: Option<&std::path::Path>,
    name: &str,
) -> (Option<i32>, String, Value) {
    let json = d.dir.path().join(format!("{name}.json"));
    let mut cmd = Command::new(hilrig_bin());
    cmd.arg("check").arg(run);
    if let Some(r) = rig {
        cmd.arg("--rig").arg(r);
    }
    let out = cmd
        .arg("--scene")
        .arg(d.rep.join("scene.toml"))
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        v,
    )
}

/// `hilrig resim` and `hilrig gap` on `run`, without and with `--force`: exit codes and
/// standard errors.
fn resim_and_gap(d: &SynthRun, run: &std::path::Path) -> [(Option<i32>, String, bool); 4] {
    let scene = d.rep.join("scene.toml");
    let model = fixture("parking/idealized.toml");
    let go = |args: &[&std::ffi::OsStr], out: &std::path::Path| {
        let o = Command::new(hilrig_bin()).args(args).output().unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
            out.exists(),
        )
    };
    let sim = d.dir.path().join("sim.mcap");
    let gap_out = d.dir.path().join("gap");
    let resim = |force: bool| {
        let mut a: Vec<&std::ffi::OsStr> = vec![
            "resim".as_ref(),
            run.as_os_str(),
            "--scene".as_ref(),
            scene.as_os_str(),
            "--model".as_ref(),
            model.as_os_str(),
            "-o".as_ref(),
            sim.as_os_str(),
        ];
        if force {
            a.push("--force".as_ref());
        }
        go(&a, &sim)
    };
    let gap = |force: bool| {
        let mut a: Vec<&std::ffi::OsStr> = vec![
            "gap".as_ref(),
            "--real".as_ref(),
            run.as_os_str(),
            "--scene".as_ref(),
            scene.as_os_str(),
            "--model".as_ref(),
            model.as_os_str(),
            "--no-full-metrics".as_ref(),
            "-o".as_ref(),
            gap_out.as_os_str(),
        ];
        if force {
            a.push("--force".as_ref());
        }
        go(&a, &gap_out.join("gap.json"))
    };
    [resim(false), resim(true), gap(false), gap(true)]
}

/// A recording made with the wrong lidar data port in the rig (the user's case: `record` said
/// so and exited 1, `check` then passed it): `check` fails it with `no_lidar_data`, naming
/// /velodyne_packets in the fault, its JSON and the report page; `resim` and `gap` refuse it,
/// and with `--force` still stop, saying there are no /velodyne_packets.
#[test]
fn a_run_without_lidar_data_fails_and_is_not_re_simulated() {
    let d = synth_and_record("", 31, true);
    let dbc = demo_rig().with_file_name("hilrig-ego.dbc");
    let rig_text = std::fs::read_to_string(demo_rig())
        .unwrap()
        .replace("data_port = 2368", "data_port = 2369")
        .replace(
            "\"hilrig-ego.dbc\"",
            &format!("{:?}", dbc.display().to_string()),
        );
    assert!(rig_text.contains("data_port = 2369"));
    let rig = d.dir.path().join("wrong-port.toml");
    std::fs::write(&rig, rig_text).unwrap();
    let run = d.dir.path().join("no-lidar.mcap");
    let rec = record_from(&rig, &[&d.rep.join("drive.pcapng")], &run);
    assert_eq!(
        rec.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&rec.stderr)
    );
    assert!(run.exists());

    let (code, text, v) = check_json(&d, &run, "no-lidar");
    assert_eq!(code, Some(1), "{text}");
    assert_eq!(v["verdict"], "fail");
    // The reference itself is fine: the missing lidar is the only fault.
    assert_eq!(names(&v), ["no_lidar_data"], "{text}");
    let f = faults(&v, "no_lidar_data")[0];
    assert_eq!(f["topics"], serde_json::json!(["/velodyne_packets"]));
    let detail = f["detail"].as_str().unwrap();
    assert!(
        detail.contains("/velodyne_packets") && detail.contains("2369"),
        "{detail}"
    );
    // It spans the run, and so fails every segment.
    assert_eq!(f["from_s"], 0.0);
    assert_eq!(
        f["to_s"].as_f64(),
        v["duration_s"].as_f64().map(|x| (x * 1e3).round() / 1e3)
    );
    assert!(v["segments"]
        .as_array()
        .unwrap()
        .iter()
        .all(|s| s["verdict"] == "fail" && s["reasons"] == serde_json::json!(["no_lidar_data"])));
    assert!(
        text.contains("verdict: FAIL") && text.contains("no_lidar_data"),
        "{text}"
    );

    // The report shows it: in the first table's check line and on the check timeline.
    let html = d.dir.path().join("report.html");
    hilrig_ok(&[
        "report".as_ref(),
        d.dir.path().join("no-lidar.json").as_os_str(),
        "-o".as_ref(),
        html.as_os_str(),
    ]);
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("faults: no_lidar_data"), "glance line");
    assert!(
        page.matches("no_lidar_data").count() >= 2,
        "the timeline names it too"
    );

    let [resim, resim_forced, gap, gap_forced] = resim_and_gap(&d, &run);
    assert_eq!(resim.0, Some(1), "{}", resim.1);
    assert!(
        resim.1.contains("no_lidar_data") && resim.1.contains("--force"),
        "{}",
        resim.1
    );
    assert!(resim_forced.0.is_some_and(|c| c != 0), "{}", resim_forced.1);
    assert!(
        resim_forced.1.contains("no /velodyne_packets"),
        "{}",
        resim_forced.1
    );
    assert_eq!(gap.0, Some(2), "{}", gap.1);
    assert!(gap.1.contains("no_lidar_data"), "{}", gap.1);
    assert!(gap_forced.0.is_some_and(|c| c != 0), "{}", gap_forced.1);
    assert!(
        gap_forced.1.contains("no /velodyne_packets"),
        "{}",
        gap_forced.1
    );
    for (code, err, written) in [resim, resim_forced, gap, gap_forced] {
        assert!(!written, "{code:?}: output written: {err}");
    }
}

/// Recordings whose capture lost its GNSS serial stream, or its CAN frames: `check` fails
/// each with one fault that names the missing source's topics (exit 1, in the JSON and the
/// text), measures what it still can (the receiver's RTK states without CAN), and `resim`
/// and `gap` refuse the run, forced or not.
#[test]
fn runs_without_gnss_fixes_or_ego_motion_fail_naming_the_topic() {
    use hilrig::capture::LinkType;
    let d = synth_and_record("", 32, true);
    let cases = [
        (
            LinkType::USER0,
            "no_gnss_fixes",
            vec!["/gnss/nmea", "/gnss/ubx"],
            "no RTK+CAN trajectory",
        ),
        (
            LinkType::CAN_SOCKETCAN,
            "no_ego_motion",
            vec!["/ego/twist"],
            "no RTK+CAN trajectory",
        ),
    ];
    for (link, name, topics, forced_reason) in cases {
        let capture = d.dir.path().join(format!("{name}.pcapng"));
        let dropped = capture_without(&d.rep.join("drive.pcapng"), link, &capture);
        assert!(dropped > 100, "{name}: {dropped} packets dropped");
        let run = d.dir.path().join(format!("{name}.mcap"));
        // `record` takes what there is (its exit says nothing about a silent serial line).
        record_from(&demo_rig(), &[&capture], &run);
        assert!(run.exists());
        let (code, text, v) = check_json(&d, &run, name);
        assert_eq!(code, Some(1), "{name}: {text}");
        assert_eq!(v["verdict"], "fail");
        assert_eq!(names(&v), [name], "{text}");
        let f = faults(&v, name)[0];
        assert_eq!(f["topics"], serde_json::json!(topics), "{name}");
        for t in &topics {
            assert!(f["detail"].as_str().unwrap().contains(t), "{name}: {f}");
        }
        assert!(
            text.contains("verdict: FAIL") && text.contains(name),
            "{text}"
        );
        assert!(text.contains("no reference trajectory"), "{text}");
        // The fault spans what the run holds: the other sources' 20-odd seconds.
        assert!(v["duration_s"].as_f64().unwrap() > 15.0, "{name}");
        assert!(f["to_s"].as_f64().unwrap() > 15.0, "{name}: {f}");
        if name == "no_ego_motion" {
            // The receiver's own accuracy is still measured.
            assert!(v["spatial"]["epochs"].as_u64().unwrap() > 100, "{name}");
        }
        let [resim, resim_forced, gap, gap_forced] = resim_and_gap(&d, &run);
        assert_eq!(resim.0, Some(1), "{name}: {}", resim.1);
        assert!(
            resim.1.contains(name) && resim.1.contains("--force"),
            "{name}: {}",
            resim.1
        );
        assert!(
            resim_forced.0.is_some_and(|c| c != 0),
            "{name}: {}",
            resim_forced.1
        );
        assert!(
            resim_forced.1.contains(forced_reason),
            "{name}: {}",
            resim_forced.1
        );
        assert_eq!(gap.0, Some(2), "{name}: {}", gap.1);
        assert!(gap.1.contains(name), "{name}: {}", gap.1);
        assert!(
            gap_forced.0.is_some_and(|c| c != 0),
            "{name}: {}",
            gap_forced.1
        );
        assert!(
            gap_forced.1.contains(forced_reason),
            "{name}: {}",
            gap_forced.1
        );
        for (code, err, written) in [resim, resim_forced, gap, gap_forced] {
            assert!(!written, "{name} {code:?}: output written: {err}");
        }
    }
}

/// The demo rig with a heading source (`[gnss.heading]`: a dual-antenna THS whose baseline
/// The demo rig's text with its DBC at an absolute path, for a rig file written elsewhere.
fn demo_rig_text() -> String {
    let dbc = demo_rig().parent().unwrap().join("hilrig-ego.dbc");
    std::fs::read_to_string(demo_rig()).unwrap().replace(
        "dbc = \"hilrig-ego.dbc\"",
        &format!("dbc = {:?}", dbc.display().to_string()),
    )
}

/// lies across the car, 90° off its axis, 0.05° at 20 Hz), written into `dir`.
fn heading_rig(dir: &std::path::Path, source: &str) -> std::path::PathBuf {
    let text = demo_rig_text();
    let path = dir.join("heading-rig.toml");
    std::fs::write(
        &path,
        format!("{text}\n[gnss.heading]\nsource = \"{source}\"\nyaw_offset_deg = 90.0\nsigma_deg = 0.05\n"),
    )
    .unwrap();
    path
}

/// The parking drive synthesized with the heading rig and `heading` (lines of the drive's
/// `[heading]` table), recorded, and checked with the heading rig: exit code, report, run.
fn heading_drive(
    source: &str,
    heading: &str,
    seed: u64,
) -> (Option<i32>, Value, SynthRun, tempfile::TempDir) {
    let rigs = tempfile::tempdir().unwrap();
    let rig = heading_rig(rigs.path(), source);
    let d = synth_and_record_edited(
        |t| {
            t.replace(
                "rig = \"../../rigs/demo.toml\"",
                &format!("rig = {:?}", rig.display().to_string()),
            )
        },
        &format!("[heading]\n{heading}"),
        seed,
        true,
    );
    let (code, v, _) = check_with_trajectory(&d, Some(&rig));
    (code, v, d, rigs)
}

/// Issue 32, must-holds 2 and 5 on one drive each for three messages: a heading source of
/// 0.05° at 20 Hz whose baseline is misaligned by 1.2° beyond the rig file's 90° is fused;
/// the misalignment is estimated within 2 sigma, its reports fit their stated accuracy, the
/// smoothed heading's error is within 0.05° at the 95th percentile over the usable stretches
/// (against the synthesizer's truth), and the clean drive passes.
#[test]
fn a_heading_source_is_fused_and_its_misalignment_estimated() {
    for (source, seed) in [("THS", 41), ("PASHR", 42), ("PSTI,036", 43)] {
        let (code, v, d, _rigs) = heading_drive(source, "misalignment_deg = 1.2\n", seed);
        let h = &v["heading_source"];
        assert_eq!(code, Some(0), "{source}: {:?} {h}", names(&v));
        assert_eq!(h["source"], source);
        // THS comes with each 10 Hz epoch, the others at 20 Hz over the 21 s drive.
        assert!(h["used"].as_u64().unwrap() > 180, "{h}");
        let (o, so) = (
            h["offset_deg"].as_f64().unwrap(),
            h["offset_sigma_deg"].as_f64().unwrap(),
        );
        assert!(
            (o - 1.2).abs() <= 2.0 * so && so < 0.05,
            "{source}: offset {o} ± {so}"
        );
        let rms = h["rms_normalized"].as_f64().unwrap();
        assert!((0.7..1.4).contains(&rms), "{source}: rms normalised {rms}");
        let errors: Vec<f64> = usable_heading_errors(&d, &Truth::read(&d), &v)
            .into_iter()
            .map(|e| e.0.abs())
            .collect();
        assert!(errors.len() > 100);
        let p95 = quantile(errors, 0.95);
        assert!(p95 <= 0.05, "{source}: heading error p95 {p95:.4}°");
        println!("{source}: offset {o:.3}° ± {so:.3}°, rms normalised {rms:.2}, heading error p95 {p95:.4}°");
    }
}

/// Issue 32, must-hold 6: a THS in "invalid" mode, one whose heading is out of its range and
/// one with a checksum that fails, written into the serial stream of a clean drive after its
/// first THS in the middle of the drive: none is used, the invalid one and the one out of range
/// are counted in `check`'s report and text (the one that fails its checksum never frames, so
/// the recorder keeps no message of it), and the drive still passes.
#[test]
fn invalid_and_malformed_heading_messages_are_counted_and_not_used() {
    use hilrig::capture::LinkType;
    let rigs = tempfile::tempdir().unwrap();
    let rig = heading_rig(rigs.path(), "THS");
    let d = synth_and_record_edited(
        |t| {
            t.replace(
                "rig = \"../../rigs/demo.toml\"",
                &format!("rig = {:?}", rig.display().to_string()),
            )
        },
        "[heading]\nmisalignment_deg = 0.5\n",
        44,
        true,
    );
    let (_, clean, _) = check_with_trajectory(&d, Some(&rig));
    let nmea = |body: &str| {
        let sum = body.bytes().fold(0u8, |a, b| a ^ b);
        format!("${body}*{sum:02X}\r\n")
    };
    let bad = format!(
        "{}{}$GNTHS,123.000,A*00\r\n",
        nmea("GNTHS,123.000,V"),
        nmea("GNTHS,400.000,A")
    );
    let edited = d.dir.path().join("edited.pcapng");
    let (mut serial, mut injected) = (0usize, false);
    rewrite_capture(&d.rep.join("drive.pcapng"), &edited, |link, _, data| {
        if link == LinkType::USER0 && data.windows(5).any(|x| x == b"GNTHS") {
            serial += 1;
            if serial == 100 && !injected {
                data.extend_from_slice(bad.as_bytes());
                injected = true;
            }
        }
        true
    });
    assert!(injected, "{serial} serial chunks with a THS");
    let run = d.dir.path().join("edited.mcap");
    let rec = record_from(&rig, &[&edited], &run);
    // The recorder keeps everything that frames and says what it could not: the THS with the
    // wrong checksum is not in the file, counted, named, and the exit status says so.
    let err = String::from_utf8_lossy(&rec.stderr);
    assert_eq!(rec.status.code(), Some(1), "{err}");
    assert!(
        err.contains("1 GNSS serial frames were not recorded")
            && err.contains("NMEA sentence with a wrong checksum: 1 (first: serial interface"),
        "{err}"
    );
    let left_out: hilrig::record::rejects::GnssRejects = common::recorded_rejects(&run);
    assert_eq!(left_out.total(), 1, "{left_out:?}");
    let (code, text, v) = check_json_with(&d, &run, Some(&rig), "edited");
    let h = &v["heading_source"];
    assert_eq!(code, Some(0), "{:?} {h}", names(&v));
    assert_eq!(h["invalid"], 1, "{h}");
    assert_eq!(h["malformed_gnss"], 1, "{h}");
    assert_eq!(clean["heading_source"]["invalid"], 0);
    assert_eq!(clean["heading_source"]["malformed_gnss"], 0);
    // Neither is used: the same reports as the clean drive's.
    assert_eq!(h["used"], clean["heading_source"]["used"], "{h}");
    assert!(
        text.contains("1 flagged invalid; 1 GNSS messages malformed"),
        "{text}"
    );
}

/// Issue 32, must-hold 3: a source that dead-reckons and says so (THS mode E), one whose
/// output freezes while the car turns, and one mounted 6° off what the rig file says are
/// each named and located as a fault.
#[test]
fn a_heading_source_that_estimates_freezes_or_is_misaligned_is_a_fault() {
    let (code, v, _d, _r) =
        heading_drive("THS", "estimated = [{ from_s = 4.0, to_s = 6.0 }]\n", 44);
    assert_eq!(code, Some(1), "{:?}", names(&v));
    let f = faults(&v, "heading_source_not_measured");
    assert_eq!(f.len(), 1, "{:?}", names(&v));
    located(f[0], 4.0, 6.0, 0.2);
    // The parking drive turns into the slot in its last seconds: frozen from 12 s to the end.
    let (code, v, _d, _r) =
        heading_drive("THS", "frozen = [{ from_s = 12.0, to_s = 100.0 }]\n", 45);
    assert_eq!(code, Some(1), "{:?}", names(&v));
    let f = faults(&v, "heading_source_disagrees");
    assert!(!f.is_empty(), "{:?} {}", names(&v), v["heading_source"]);
    // Located from about a second before the freeze: until the run fails, the smoother is
    // pulled by the frozen reports too.
    assert!(
        f.iter().all(|f| f["from_s"].as_f64().unwrap() >= 10.5),
        "{f:?}"
    );
    let (code, v, _d, _r) = heading_drive("THS", "misalignment_deg = 6.0\n", 46);
    assert_eq!(code, Some(1), "{:?}", names(&v));
    assert_eq!(
        faults(&v, "heading_source_offset").len(),
        1,
        "{:?}",
        names(&v)
    );
    let o = v["heading_source"]["offset_deg"].as_f64().unwrap();
    assert!((o - 6.0).abs() < 0.2, "offset {o}");
}

/// A rig that says it has a heading source, on a recording in which that source never
/// reported: the recording is not what the rig describes, and the check says so.
#[test]
fn a_heading_source_the_rig_names_but_the_run_lacks_is_a_fault() {
    let d = synth_and_record_edited(|t| t, "", 47, true);
    let rigs = tempfile::tempdir().unwrap();
    let rig = heading_rig(rigs.path(), "PASHR");
    let (code, v, _) = check_with_trajectory(&d, Some(&rig));
    assert_eq!(code, Some(1), "{:?}", names(&v));
    let f = faults(&v, "heading_source_missing");
    assert_eq!(f.len(), 1, "{:?}", names(&v));
    assert!(
        f[0]["detail"].as_str().unwrap().contains("PASHR"),
        "{}",
        f[0]
    );
    assert_eq!(v["heading_source"]["used"], 0);
    // Without the rig's heading, the same run passes.
    let (code, v, _) = check_with_trajectory(&d, None);
    assert_eq!(code, Some(0), "{:?}", names(&v));
    assert!(v["heading_source"].is_null());
}

/// A 20 m parking manoeuvre tells the heading source's mounting only as well as its track tells
/// the heading (about 0.035° with 1 cm RTK), and the smoothed heading inherits that. A rig that
/// states its mounting as a calibration measured it (`yaw_offset_sigma_deg`) lends the drive the
/// calibration's accuracy: the offset's sigma and the heading's drop below what the track alone
/// gives, the small offset the calibration left is still found within 2 sigma, and the heading
/// stays within its sigma. A sigma that is not positive is refused, naming the key.
#[test]
fn a_calibrated_mounting_carries_a_short_drive() {
    let (code, v, d, rigs) = heading_drive("THS", "misalignment_deg = 1.2\n", 44);
    assert_eq!(code, Some(0), "{:?}", names(&v));
    let alone = v["heading_source"]["offset_sigma_deg"].as_f64().unwrap();
    assert!(alone > 0.02, "the drive alone gives the offset to {alone}°");
    // The calibration left 0.004° of the mounting unknown, and says it is good to 0.01°.
    let plain = std::fs::read_to_string(rigs.path().join("heading-rig.toml")).unwrap();
    let calibrated = |sigma: &str| {
        let path = rigs.path().join(format!("calibrated-{sigma}.toml"));
        let text = plain.replace(
            "yaw_offset_deg = 90.0\n",
            &format!("yaw_offset_deg = 91.204\nyaw_offset_sigma_deg = {sigma}\n"),
        );
        assert_ne!(text, plain);
        std::fs::write(&path, text).unwrap();
        path
    };
    let (code, v, _) = check_with_trajectory(&d, Some(&calibrated("0.01")));
    assert_eq!(code, Some(0), "{:?}", names(&v));
    let h = &v["heading_source"];
    let (o, so) = (
        h["offset_deg"].as_f64().unwrap(),
        h["offset_sigma_deg"].as_f64().unwrap(),
    );
    assert!(
        so < 0.01 && so < alone / 2.0,
        "offset {o} ± {so} (alone ± {alone})"
    );
    assert!(
        (o + 0.004).abs() <= 2.0 * so,
        "offset {o} ± {so}, truth -0.004"
    );
    let e = usable_heading_errors(&d, &Truth::read(&d), &v);
    assert!(e.len() > 100);
    let worst_sigma = e.iter().map(|x| x.1).fold(0.0, f64::max);
    assert!(
        worst_sigma < alone,
        "heading sigma up to {worst_sigma}° with the calibration, the offset alone {alone}°"
    );
    let z = (e.iter().map(|(err, s)| (err / s).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
    assert!(z < 1.5, "rms(error/sigma) {z}");
    let p95 = quantile(e.iter().map(|x| x.0.abs()).collect(), 0.95);
    // Issue 32's bound for a heading source of 0.05°.
    assert!(p95 <= 0.05, "heading error p95 {p95:.4}°");
    println!("alone ± {alone:.4}°; calibrated: offset {o:.4}° ± {so:.4}°, heading sigma up to {worst_sigma:.4}°, error p95 {p95:.4}°, rms z {z:.2}");
    for bad in ["0.0", "-0.01"] {
        let out = Command::new(hilrig_bin())
            .arg("check")
            .arg(&d.run)
            .arg("--rig")
            .arg(calibrated(bad))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("yaw_offset_sigma_deg"), "{bad}: {err}");
    }
}

/// The parking drive made a slow loop of about 250 m (3.5 m/s, entered already moving in the
/// first bend, no pedestrian), with 20 Hz RTK fixes whose error wanders over 2 s.
fn slow_loop_at_20_hz(seed: u64) -> SynthRun {
    synth_and_record_edited(
        |t| {
            let (head, rest) = t.split_at(t.find("[[walker]]").unwrap());
            let tail = &rest[rest.find("[variation]").unwrap()..];
            let text = format!("{head}{tail}")
                .replace(
                    "waypoints = [[-16.0, 0.0], [-6.0, 0.0], [-1.0, 0.4], [1.6, 1.8], [2.5, 3.6], [2.55, 4.8]]",
                    "waypoints = [[-98.64, 38.64], [-93.46, 19.32], [-79.32, 5.18], [-60.0, 0.0], [-40.0, 0.0], [-20.0, 0.0], [10.0, -5.0], [30.0, 10.0], [35.0, 35.0], [15.0, 50.0], [-20.0, 45.0], [-45.0, 30.0]]\nstart_speed_mps = 3.5",
                )
                .replace("cruise_speed_mps = 2.2", "cruise_speed_mps = 3.5")
                .replace("acceleration_mps2 = 0.8", "acceleration_mps2 = 1.5");
            let text = text.replacen("rate_hz = 10\n", "rate_hz = 20\n", 1);
            assert!(text.contains("start_speed_mps = 3.5") && text.contains("rate_hz = 20\n"));
            assert!(!text.contains("[[walker]]") && !text.contains("[yield_to]"));
            text
        },
        "",
        seed,
        true,
    )
}

/// On a slow loop with 20 Hz fixes that wander over 2 s, the drive's GNSS noise fit prefers
/// 4 s, and under that the time offset and lever arm were found 7 sigma off (-30 ± 3.6 ms):
/// clean drives failed. Their uncertainties now carry how much they move under half and twice
/// the fitted wander time: no fault, and the truth within 2 sigma (the time offset's truth is
/// the CAN frames' 1 ms delay: the check measures GNSS time against CAN).
#[test]
fn a_slow_loop_with_wandering_20_hz_fixes_raises_no_timing_or_lever_fault() {
    for seed in [729, 829] {
        let d = slow_loop_at_20_hz(seed);
        let (code, v, _) = check_with_trajectory(&d, None);
        let sp = &v["spatial"];
        let (dt, sdt) = (
            sp["gnss_time_offset_ms"].as_f64().unwrap(),
            sp["gnss_time_offset_sigma_ms"].as_f64().unwrap(),
        );
        let (x, sx) = (
            sp["lever_arm_x_measured_m"].as_f64().unwrap(),
            sp["lever_arm_x_sigma_m"].as_f64().unwrap(),
        );
        println!("seed {seed}: time offset {dt:.1} ± {sdt:.1} ms, lever arm {x:.3} ± {sx:.3} m");
        assert_eq!(code, Some(0), "seed {seed}: {:?}", names(&v));
        assert!(
            (dt + 1.0).abs() <= 2.0 * sdt,
            "seed {seed}: {dt} ± {sdt} ms"
        );
        assert!((x - 0.6).abs() <= 2.0 * sx, "seed {seed}: {x} ± {sx} m");
    }
}

/// The mounting a drive measured, as `check` prints it for the rig file, calibrates the rig for
/// the next drive: the printed value holds the true mounting within 2 sigma, and a second drive
/// checked with it finds its source on that mounting within 2 sigma, with a sigma smaller than
/// the calibration's (the second drive adds what it saw).
#[test]
fn the_printed_mounting_calibrates_the_rig_for_the_next_drive() {
    let (_, _, first, rigs) = heading_drive("THS", "misalignment_deg = 1.2\n", 41);
    let rig = rigs.path().join("heading-rig.toml");
    let (_, text, _) = check_json_with(&first, &first.run, Some(&rig), "first");
    let line = text
        .lines()
        .find(|l| l.contains("for the rig file's [gnss.heading]"))
        .unwrap_or_else(|| panic!("no calibration line in {text}"));
    let value = |key: &str| -> f64 {
        line.split(&format!("{key} = "))
            .nth(1)
            .and_then(|v| v.split([',', ' ']).next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{key} in {line}"))
    };
    let (yaw, sigma) = (value("yaw_offset_deg"), value("yaw_offset_sigma_deg"));
    assert!((yaw - 91.2).abs() <= 2.0 * sigma, "{line}");
    let calibrated = rigs.path().join("calibrated.toml");
    let plain = std::fs::read_to_string(&rig).unwrap();
    let with = plain.replace(
        "yaw_offset_deg = 90.0\n",
        &format!("yaw_offset_deg = {yaw}\nyaw_offset_sigma_deg = {sigma}\n"),
    );
    assert_ne!(with, plain);
    std::fs::write(&calibrated, with).unwrap();
    let (_, _, second, _rigs) = heading_drive("THS", "misalignment_deg = 1.2\n", 45);
    let (code, v, _) = check_with_trajectory(&second, Some(&calibrated));
    assert_eq!(code, Some(0), "{:?}", names(&v));
    let h = &v["heading_source"];
    let (o, so) = (
        h["offset_deg"].as_f64().unwrap(),
        h["offset_sigma_deg"].as_f64().unwrap(),
    );
    println!("calibrated {yaw} ± {sigma}°; second drive: {o:+.4} ± {so:.4}° beyond it");
    assert!((o - (91.2 - yaw)).abs() <= 2.0 * so, "{o} ± {so}");
    assert!(so < sigma, "{so} against the calibration's {sigma}");
}

/// The parking drive's path turned into a reverse park: along the aisle past the slot, a stop,
/// and back into the slot (`[path.reverse]`).
fn backing_into_the_slot(t: String) -> String {
    let from = t.find("waypoints = [").unwrap();
    let to = from + t[from..].find('\n').unwrap();
    format!(
        "{}waypoints = [[-16.0, 0.0], [-6.0, 0.0], [2.0, 0.0], [8.5, 0.0]]{}",
        &t[..from],
        &t[to..]
    )
    .replace(
        "lead_out_s = 0.8\n",
        "lead_out_s = 0.8\n\n[path.reverse]\nwaypoints = [[5.0, 0.8], [3.0, 3.0], [2.6, 5.2]]\nspeed_mps = 1.0\n",
    )
}

/// A drive that backs into its slot, its CAN speed a magnitude (the demo rig's DBC, as most
/// cars send it), with and without a heading source: `check` tells the stretch backed up from
/// the track, where the truth backs up, passes the drive without a fault, and its smoothed
/// heading follows the truth through the turn-around (a dual-antenna source reports the body's
/// heading whichever way it moves). Taken as forward, the leg backed up raised jumps (349
/// epochs up to 4 m off) and a lever-arm fault, as a blind check of another generator's
/// reversing drive did, and the heading there would be turned round.
#[test]
fn a_drive_that_backs_into_its_slot_passes_naming_the_stretch_backed_up() {
    for (source, seed, from) in [
        (None, 41, "lever_arm_swing"),
        (Some("THS"), 42, "heading_source"),
    ] {
        let rigs = tempfile::tempdir().unwrap();
        let rig = source.map(|s| heading_rig(rigs.path(), s));
        let d = synth_and_record_edited(
            |t| {
                let t = backing_into_the_slot(t);
                match &rig {
                    Some(r) => t.replace(
                        "rig = \"../../rigs/demo.toml\"",
                        &format!("rig = {:?}", r.display().to_string()),
                    ),
                    None => t,
                }
            },
            if source.is_some() {
                "[heading]\nmisalignment_deg = 0.8\n"
            } else {
                ""
            },
            seed,
            true,
        );
        let (code, v, traj) = check_with_trajectory(&d, rig.as_deref());
        println!("{}", serde_json::to_string_pretty(&v["travel"]).unwrap());
        assert_eq!(code, Some(0), "{source:?}: faults {:?}", v["faults"]);
        assert_eq!(v["travel"]["direction_from"], from);
        if source.is_none() {
            assert_eq!(v["travel"]["lever_swing"]["outcome"], "confirmed");
        }
        let truth = Truth::read(&d);
        backed_up_once_as_the_truth(&v, &truth, &format!("{source:?}"));
        heading_follows_the_truth(&truth, &traj, &format!("{source:?}"));
    }
}

/// A recording that starts with the car standing and then backs up, turning into its slot
/// (the reverse park's recording from just before it backs up), its CAN speed a magnitude and
/// no heading source: the antenna's sideways swing in the turn tells that the car backed up,
/// not drove forwards turned round. The drive passes, the stretch is named, and the smoothed
/// heading follows the truth. Taken as forward (before the swing was tested), the same
/// recording read as the car turned round, with a lever-arm fault.
#[test]
fn a_recording_that_starts_backing_up_is_told_by_the_antenna_s_swing_in_the_turn() {
    let d = synth_and_record_edited(backing_into_the_slot, "", 43, true);
    let truth = Truth::read(&d);
    let (b0, _) = backed_up(&truth);
    // The whole drive (forward, then backing into the slot) checked with a rig file whose
    // antenna is on the wrong side of the rear axle: the swing then fits only with the drive
    // turned round. That is a drive that could be (it backs up 25 m at parking speed), so it
    // cannot be refused, but it must not pass unremarked: the report names the lever arm.
    let rigs = tempfile::tempdir().unwrap();
    let wrong = rigs.path().join("antenna-behind.toml");
    let text = demo_rig_text().replace("antenna = { x = 0.60,", "antenna = { x = -0.60,");
    assert!(text.contains("x = -0.60,"));
    std::fs::write(&wrong, text).unwrap();
    let (_, w, _) = check_with_trajectory(&d, Some(&wrong));
    println!("antenna behind: {}", w["travel"]);
    let names = |k: &str| -> Vec<String> {
        w[k].as_array()
            .unwrap()
            .iter()
            .map(|x| x["name"].as_str().unwrap().to_owned())
            .collect()
    };
    assert!(
        names("warnings").contains(&"lever_arm".to_owned())
            || names("faults").contains(&"lever_arm".to_owned()),
        "{w}"
    );
    let run = d.dir.path().join("from-the-stop.mcap");
    recording_from(&d.run, &run, ((b0 - 0.7) * 1e9) as u64);
    let d = SynthRun { run, ..d };
    let (code, v, traj) = check_with_trajectory(&d, None);
    println!("{}", serde_json::to_string_pretty(&v["travel"]).unwrap());
    assert_eq!(code, Some(0), "faults {:?}", v["faults"]);
    assert_eq!(v["travel"]["direction_from"], "lever_arm_swing");
    let swing = &v["travel"]["lever_swing"];
    assert_eq!(swing["outcome"], "turned_round", "{swing}");
    let share = swing["lever_share"].as_f64().unwrap();
    assert!((share + 1.0).abs() < 0.3, "{swing}");
    // The turn-round rests on the sign of the rig's lever arm, and the report says so.
    assert!(
        v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w["name"] == "lever_arm"
                && w["detail"].as_str().unwrap().contains("backing up")),
        "{}",
        v["warnings"]
    );
    backed_up_once_as_the_truth(&v, &truth, "from the stop");
    heading_follows_the_truth(&truth, &traj, "from the stop");
}

/// The check report `v` names one stretch backed up, within 0.3 s of where the truth backs up.
fn backed_up_once_as_the_truth(v: &Value, truth: &Truth, case: &str) {
    let (b0, b1) = backed_up(truth);
    let stretches = v["travel"]["reversing"].as_array().unwrap();
    assert_eq!(stretches.len(), 1, "{case}: {stretches:?}");
    let at = |k: &str| iso_ns(stretches[0][k].as_str().unwrap()) as f64 * 1e-9;
    assert!(
        (at("from") - b0).abs() < 0.3 && (at("to") - b1).abs() < 0.3,
        "{case}: backed up {:.2}-{:.2} s, the truth {b0:.2}-{b1:.2}",
        at("from"),
        at("to")
    );
}

/// The smoothed heading of `traj` stays within 3 sigma of the truth over more than 100 samples.
fn heading_follows_the_truth(truth: &Truth, traj: &std::path::Path, case: &str) {
    let (worst, n) = heading_error_sigmas(truth, traj);
    println!("{case}: heading error up to {worst:.2} sigma over {n} samples");
    assert!(n > 100);
    assert!(worst <= 3.0, "{case}: heading error up to {worst:.2} sigma");
}

/// `src` from log time `from_ns` on, into `dst`: its schemas, channels, attachments (the rig
/// file, the DBC) and metadata, and the messages logged from then on; a recording started
/// there.
fn recording_from(src: &std::path::Path, dst: &std::path::Path, from_ns: u64) {
    use mcap::records::Record;
    let bytes = std::fs::read(src).unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(dst).unwrap());
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(file)
        .unwrap();
    let mut kept = 0;
    for r in mcap::read::ChunkFlattener::new(&bytes).unwrap() {
        match r.unwrap() {
            Record::Schema { header, data } => {
                w.add_schema_with_id(header.id, &header.name, &header.encoding, &data)
                    .unwrap();
            }
            Record::Channel(c) => {
                w.add_channel_with_id(
                    c.id,
                    c.schema_id,
                    &c.topic,
                    &c.message_encoding,
                    &c.metadata,
                )
                .unwrap();
            }
            Record::Message { header, data } if header.log_time >= from_ns => {
                w.write_to_known_channel(&header, &data).unwrap();
                kept += 1;
            }
            Record::Attachment { header, data, .. } => w
                .attach(&mcap::Attachment {
                    log_time: header.log_time,
                    create_time: header.create_time,
                    name: header.name,
                    media_type: header.media_type,
                    data,
                })
                .unwrap(),
            Record::Metadata(m) => w.write_metadata(&m).unwrap(),
            _ => {}
        }
    }
    w.finish().unwrap();
    assert!(kept > 1000, "{kept} messages from {from_ns} ns on");
}

/// The truth's stretch backed up, first and last instant (s): where the rear axle moves
/// against its heading.
fn backed_up(truth: &Truth) -> (f64, f64) {
    let back: Vec<f64> = truth
        .0
        .windows(2)
        .filter(|w| {
            let h = w[0][4].to_radians();
            let along = (w[1][1] - w[0][1]) * h.cos() + (w[1][2] - w[0][2]) * h.sin();
            along / (w[1][0] - w[0][0]) < -MOVING
        })
        .map(|w| w[0][0])
        .collect();
    (back[0], back[back.len() - 1])
}

/// The smoothed heading against the truth at every sample of `trajectory.csv` (t, x, y,
/// yaw_deg, sigma_xy, sigma_yaw): the worst error in sigmas (or in 0.01° where the sigma is
/// smaller), and the number of samples compared.
fn heading_error_sigmas(truth: &Truth, traj: &std::path::Path) -> (f64, usize) {
    let rows = csv_rows(traj);
    let (mut n, mut worst) = (0, 0.0f64);
    for r in &rows {
        let Some((_, yaw)) = truth.at(r[0]) else {
            continue;
        };
        let e = (r[3] - yaw + 180.0).rem_euclid(360.0) - 180.0;
        worst = worst.max(e.abs() / r[5].max(0.01));
        n += 1;
    }
    (worst, n)
}

/// The speed (m/s) above which the truth moves.
const MOVING: f64 = 0.1;
