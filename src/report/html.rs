//! The report page: a first table of outcomes ([`super::glance`]), then sections in the order of
//! the method (what was recorded, whether the
//! reference data hold, what the simulation gets wrong and where, whether it is valid, and what
//! the gap workflow found), each figure an inline SVG and each table plain HTML.

use super::gap_section::gap_section;
use super::markup::{esc, figure, table};
use super::plots::{self, fixed, heading_from, usable_percent, Named};
use super::Document;
use super::Input;
use crate::bag::info::Info;
use crate::metrics::report::Comparison;
use crate::reference::check::{Report, Verdict};
use crate::stats::avm::Light;
use crate::stats::repetitions::Validation;
use std::fmt::Write;

const STYLE: &str = "body{font-family:sans-serif;max-width:1060px;margin:24px auto;color:#222;line-height:1.4}\
h1{font-size:24px}h2{font-size:19px;margin-top:34px;border-bottom:1px solid #ccc}h3{font-size:15px}\
table{border-collapse:collapse;margin:10px 0;font-size:13px}td,th{border:1px solid #ccc;padding:3px 7px;text-align:left}\
th{background:#f3f3f3}figure{margin:12px 0}figcaption{font-size:13px;color:#555}\
.light{display:inline-block;min-width:62px;text-align:center;border-radius:3px;padding:1px 4px}\
.green{background:#8fd19e}.yellow{background:#ffe08a}.red{background:#f1948a}.black{background:#333;color:#fff}\
.pass{color:#2d7d3a;font-weight:bold}.fail{color:#b03a2e;font-weight:bold}.missing{color:#999}\
.note{font-size:13px;color:#555}";

/// Records each figure's and table's rendered size in `data-rendered` (width x height in CSS
/// pixels), so that a headless browser's DOM shows what was laid out.
const LAYOUT_SCRIPT: &str = "document.querySelectorAll('figure.plot,table').forEach(function(e){\
var r=e.getBoundingClientRect();var g=e.querySelector('svg');\
var k=g?g.getBoundingClientRect():r;\
e.setAttribute('data-rendered',Math.round(k.width)+'x'+Math.round(k.height));});";

/// The whole page.
pub fn page(
    inputs: &[Input],
    absent: &[std::path::PathBuf],
    fleet: &[super::fleet::FleetBin],
) -> String {
    let (mut recs, mut checks, mut cmps, mut vals, mut gaps) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in inputs {
        let name = i.name.as_str();
        match &i.value {
            Document::Recording(v) => recs.push((name, v.as_ref())),
            Document::Check(v) => checks.push((name, v.as_ref())),
            Document::Compare(v) => cmps.push((name, v.as_ref())),
            Document::Validate(v) => vals.push((name, v.as_ref())),
            Document::Gap(v) => gaps.push((name, v.as_ref())),
        }
    }
    let mut out = String::with_capacity(1 << 20);
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'; script-src 'unsafe-inline'; img-src data:\">\
<title>hilrig validation report</title><style>{STYLE}</style></head><body>\n\
<h1>Lidar sensor model validation report</h1>\n<p class=\"note\">Built by hilrig {} from {} input files (listed with their SHA-256 at the end). \
The method is that of Rosenberger et al. 2019: reference data checked before re-simulation (§6), grid metrics at a cell the \
reference supports (§5), statistical validation over repetitions (§8, Fig. 7).</p>\n",
        env!("CARGO_PKG_VERSION"),
        inputs.len()
    );
    let glance = super::glance::rows(&checks, &cmps, &vals, &gaps, &esc);
    if !glance.is_empty() {
        out.push_str("<h2 id=\"section-glance\">At a glance</h2>\n<p class=\"note\">One line per step of the method; the sections below hold the evidence.</p>\n");
        table(&mut out, "glance", &["step", "result"], &glance);
    }
    absent_section(&mut out, absent);
    recording(&mut out, &recs, &checks);
    check_section(&mut out, &checks);
    compare_section(&mut out, &cmps);
    super::fleet::section(&mut out, cmps.len(), fleet);
    validate_section(&mut out, &vals);
    gap_section(&mut out, &gaps);
    inputs_section(&mut out, inputs);
    let _ = writeln!(out, "<script>{LAYOUT_SCRIPT}</script></body></html>");
    out
}

fn recording(out: &mut String, recs: &[Named<Info>], checks: &[Named<Report>]) {
    out.push_str("<h2 id=\"section-recording\">What the recordings hold</h2>\n");
    let mut rows = Vec::new();
    for (name, r) in recs {
        let span = r
            .span
            .map(|s| s.last_ns.saturating_sub(s.first_ns) as f64 * 1e-9);
        for c in &r.channels {
            let count = c.count as f64;
            rows.push(vec![
                esc(name),
                esc(&c.topic),
                esc(&c.message_type),
                fixed(Some(count), 0),
                fixed(span.map(|s| count / s.max(1e-9)), 2),
            ]);
        }
    }
    table(
        out,
        "topics",
        &["recording", "topic", "type", "messages", "rate, Hz"],
        &rows,
    );
    // Clock models and per-source rates, from the checks.
    let mut rows = Vec::new();
    for (name, c) in checks {
        for src in &c.temporal.sources {
            rows.push(vec![
                esc(name),
                esc(&src.source),
                fixed(Some(src.rate_hz), 2),
                fixed(Some(src.jitter_ms), 2),
                src.gaps.to_string(),
                fixed(Some(src.max_interval_ms), 1),
            ]);
        }
    }
    table(
        out,
        "rates",
        &[
            "run",
            "source",
            "rate, Hz",
            "jitter, ms",
            "gaps",
            "longest interval, ms",
        ],
        &rows,
    );
    let mut rows = Vec::new();
    for (name, c) in checks {
        for (source, model) in &c.temporal.clock_sync {
            rows.push(vec![
                esc(name),
                esc(source),
                fixed(Some(model.drift_ppm), 3),
                fixed(Some(model.offset_ns as f64 * 1e-6), 3),
                fixed(Some(model.residual_p95_ns as f64 * 1e-3), 1),
                esc(&model.pps.map_or(String::new(), |p| format!("{p:?}"))),
            ]);
        }
    }
    table(
        out,
        "clocks",
        &[
            "run",
            "clock",
            "drift, ppm",
            "offset, ms",
            "residual p95, µs",
            "PPS",
        ],
        &rows,
    );
}

/// A verdict, in the colour of passing or not.
fn verdict(v: &str, pass: bool) -> String {
    let class = if pass { "pass" } else { "fail" };
    format!("<span class=\"{class}\">{}</span>", esc(v))
}

fn check_verdict(v: Verdict) -> &'static str {
    match v {
        Verdict::Pass => "pass",
        Verdict::Fail => "fail",
        Verdict::Unusable => "unusable",
    }
}

fn check_section(out: &mut String, checks: &[Named<Report>]) {
    out.push_str("<h2 id=\"section-check\">Reference data (Rosenberger et al. 2019, §6)</h2>\n<p class=\"note\">Each run's trajectory and timing are checked before anything is re-simulated; the grid cell of the metrics follows from the accuracy found (at least ten times the reference accuracy).</p>\n");
    let rows: Vec<Vec<String>> = checks
        .iter()
        .map(|(name, v)| {
            vec![
                esc(name),
                verdict(check_verdict(v.verdict), v.verdict == Verdict::Pass),
                fixed(Some(v.duration_s), 1),
                fixed(usable_percent(v), 0),
                fixed(Some(v.spatial.rtk_fixed_share * 100.0), 1),
                fixed(Some(v.accuracy.ego_m), 3),
                fixed(Some(v.accuracy.heading_sigma_deg), 3),
                esc(&heading_from(v)),
                fixed(Some(v.accuracy.reference_m), 3),
                fixed(Some(v.accuracy.grid_cell_m), 2),
                v.faults.len().to_string(),
            ]
        })
        .collect();
    table(
        out,
        "check-runs",
        &[
            "run",
            "verdict",
            "duration, s",
            "usable, %",
            "RTK fixed, %",
            "ego accuracy, m",
            "heading σ, °",
            "heading from",
            "reference accuracy, m",
            "admissible cell, m",
            "faults",
        ],
        &rows,
    );
    for (k, (name, c)) in checks.iter().enumerate() {
        figure(
            out,
            &format!("check-timeline-{k}"),
            plots::check_timeline(c),
            &format!("Check timeline of {}: RTK state, horizontal sigma, verdict per segment, located faults.", esc(name)),
        );
    }
}

fn compare_section(out: &mut String, cmps: &[Named<Comparison>]) {
    out.push_str("<h2 id=\"section-compare\">Measurement against re-simulation (Rosenberger et al. 2019, §5)</h2>\n");
    let rows: Vec<Vec<String>> = cmps
        .iter()
        .map(|(name, v)| {
            let left_out: usize = v.left_out.iter().map(|l| l.scans).sum();
            let s = &v.summary;
            let rho = s.ocr_vs_distance.as_ref();
            vec![
                esc(name),
                format!("{} ({left_out})", s.scans),
                fixed(Some(v.cell_m), 2),
                fixed(s.ocr_mean, 3),
                fixed(s.precision_mean, 3),
                fixed(s.iou_mean, 3),
                fixed(s.chamfer_mean_m, 3),
                fixed(s.range_diff_rms_m, 3),
                fixed(s.only_sim_share.map(|x| x * 100.0), 1),
                format!(
                    "{} [{}, {}]",
                    fixed(rho.map(|r| r.rho), 2),
                    fixed(rho.map(|r| r.low), 2),
                    fixed(rho.map(|r| r.high), 2)
                ),
            ]
        })
        .collect();
    table(
        out,
        "compare-summary",
        &[
            "comparison",
            "scans (left out: reference not usable)",
            "cell, m",
            "OCR^K",
            "precision",
            "IoU",
            "Chamfer, m",
            "range residual rms, m",
            "simulated-only returns, %",
            "Spearman(OCR, distance) [95 %]",
        ],
        &rows,
    );
    // At the admissible cell if there is such a comparison (the cells that disagree there are
    // the ones the metrics count).
    let at_admissible = |c: &Comparison| (c.cell_m - c.admissible_cell_m).abs() < 1e-9;
    let pick = cmps
        .iter()
        .find(|(_, c)| c.snapshot.is_some() && at_admissible(c))
        .or_else(|| cmps.iter().find(|(_, c)| c.snapshot.is_some()));
    if let Some((name, c)) = pick {
        figure(
            out,
            "birds-eye",
            c.snapshot.as_ref().and_then(plots::birds_eye),
            &format!("One scan of {} from above, over the scene's objects; shaded cells are occupied by one cloud only.", esc(name)),
        );
    }
    for (k, (name, c)) in cmps.iter().enumerate() {
        figure(
            out,
            &format!("fig5-{k}"),
            plots::fig5(c),
            &format!(
                "Rosenberger et al. 2019, Fig. 5, for {} at a {} m cell: OCR, objects in view, ego speed and mean distance to the objects along the drive.",
                esc(name),
                fixed(Some(c.cell_m), 2)
            ),
        );
    }
    figure(
        out,
        "calibration-curve",
        plots::calibration_curve(cmps),
        "The calibration curve: OCR^K over cell sizes from 0.05 m to 2 m. Cells left of the red line are smaller than the reference data support.",
    );
}

fn light(l: Light) -> String {
    let l = match l {
        Light::Green => "green",
        Light::Yellow => "yellow",
        Light::Red => "red",
        Light::Black => "black",
    };
    format!("<span class=\"light {l}\">{l}</span>")
}

fn validate_section(out: &mut String, vals: &[Named<Validation>]) {
    out.push_str("<h2 id=\"section-validate\">Statistical validation (Rosenberger et al. 2019, §8, Fig. 7)</h2>\n<p class=\"note\">Per scenario sample (phase) and metric, the interval over the real repetitions against the interval over the simulated ones: green inside, yellow overlapping, red disjoint, black not evaluable. AVM: the area validation metric (area between the two empirical CDFs), in the metric's unit.</p>\n");
    for (k, (name, val)) in vals.iter().enumerate() {
        let _ = write!(
            out,
            "<h3>{}: verdict {}</h3>\n<p class=\"note\">1. Measurement validation: {}. 2. Scenario validation: {}. 3. Model validation: the matrix below.</p>\n",
            esc(name),
            verdict(
                val.verdict.name(),
                val.verdict == crate::stats::validate::Verdict::Valid
            ),
            if val.measurement_pass {
                "every simulation has its real twin".to_string()
            } else {
                "a simulation lacks its real twin".to_string()
            },
            {
                let p: Vec<String> = val.scenario_problems.iter().map(|p| esc(p)).collect();
                if p.is_empty() {
                    "no problem found".to_string()
                } else {
                    p.join("; ")
                }
            }
        );
        let cells = &val.cells;
        let mut samples: Vec<&str> = Vec::new();
        let mut metrics: Vec<&str> = Vec::new();
        for c in cells {
            if !samples.contains(&c.sample.as_str()) {
                samples.push(&c.sample);
            }
            if !metrics.contains(&c.metric.as_str()) {
                metrics.push(&c.metric);
            }
        }
        let rows: Vec<Vec<String>> = samples
            .iter()
            .map(|sample| {
                let mut row = vec![esc(sample)];
                for m in &metrics {
                    let cell = cells.iter().find(|c| c.sample == *sample && c.metric == *m);
                    row.push(match cell {
                        Some(c) => format!(
                            "{} AVM {}{}",
                            light(c.light),
                            fixed(c.avm, 3),
                            c.why_black
                                .as_deref()
                                .map(|w| format!("<br><span class=\"note\">{}</span>", esc(w)))
                                .unwrap_or_default()
                        ),
                        None => "–".into(),
                    });
                }
                row
            })
            .collect();
        let mut head = vec!["phase"];
        head.extend(metrics.iter().copied());
        table(out, &format!("traffic-light-{k}"), &head, &rows);
    }
}

/// The outputs the report was to read that were not written: first on the page, because a
/// result that is not there (a drive whose check failed has no comparison) is the first thing
/// a reader of a fleet's report must not overlook.
fn absent_section(out: &mut String, absent: &[std::path::PathBuf]) {
    if absent.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "<h2 id=\"section-absent\">Not produced</h2>\n<p class=\"fail\">{} of the files this report was to read do not exist: the steps that write them did not run or failed (the campaign's summary and logs say why).</p>",
        absent.len()
    );
    let rows: Vec<Vec<String>> = absent
        .iter()
        .map(|p| vec![esc(&p.display().to_string())])
        .collect();
    table(out, "absent", &["file"], &rows);
}

fn inputs_section(out: &mut String, inputs: &[Input]) {
    out.push_str("<h2 id=\"section-inputs\">Inputs</h2>\n<p class=\"note\">Every number above comes from these files (and is in report.json beside this page).</p>\n");
    let mut rows: Vec<Vec<String>> = inputs
        .iter()
        .map(|i| {
            vec![
                esc(&i.name),
                i.kind.name().to_owned(),
                i.bytes.to_string(),
                format!("<code>{}</code>", i.sha256),
            ]
        })
        .collect();
    // What produced the recordings, from their metadata.
    for i in inputs {
        let Document::Recording(r) = &i.value else {
            continue;
        };
        if let Some(m) = r.metadata.get("hilrig") {
            let kv: Vec<String> = m
                .iter()
                .map(|(k, v)| format!("{}={}", esc(k), esc(v)))
                .collect();
            rows.push(vec![
                esc(&i.name),
                "recorded by".into(),
                String::new(),
                kv.join(", "),
            ]);
        }
    }
    table(out, "inputs", &["file", "kind", "bytes", "SHA-256"], &rows);
}
