//! The report page: a first table of outcomes ([`super::glance`]), then sections in the order of
//! the method (what was recorded, whether the
//! reference data hold, what the simulation gets wrong and where, whether it is valid, and what
//! the gap workflow found), each figure an inline SVG and each table plain HTML.

use super::plots::{self, arr, fixed, heading_from, num, text, usable_percent};
use super::{Input, Kind};
use serde_json::Value;
use std::fmt::Write;

/// HTML-escapes text.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A figure: the SVG or a note why it is missing.
fn figure(out: &mut String, id: &str, svg: Option<String>, caption: &str) {
    let _ = write!(out, "<figure class=\"plot\" id=\"{id}\">");
    match svg {
        Some(svg) => out.push_str(&svg),
        None => out.push_str("<p class=\"missing\">nothing to draw in the inputs</p>"),
    }
    let _ = writeln!(out, "<figcaption>{caption}</figcaption></figure>");
}

/// A table with a header row.
fn table(out: &mut String, id: &str, head: &[&str], rows: &[Vec<String>]) {
    let _ = write!(out, "<table id=\"{id}\"><thead><tr>");
    for h in head {
        let _ = write!(out, "<th>{}</th>", esc(h));
    }
    out.push_str("</tr></thead><tbody>");
    for r in rows {
        out.push_str("<tr>");
        for c in r {
            // Cells are escaped by the caller where they hold text from the inputs (some
            // carry markup of their own: the traffic lights).
            let _ = write!(out, "<td>{c}</td>");
        }
        out.push_str("</tr>");
    }
    out.push_str("</tbody></table>\n");
}

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
pub fn page(inputs: &[Input]) -> String {
    let of = |k: Kind| -> Vec<&Input> { inputs.iter().filter(|i| i.kind == k).collect() };
    let (recs, checks, cmps, vals, gaps) = (
        of(Kind::Recording),
        of(Kind::Check),
        of(Kind::Compare),
        of(Kind::Validate),
        of(Kind::Gap),
    );
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
    recording(&mut out, &recs, &checks);
    check_section(&mut out, &checks);
    compare_section(&mut out, &cmps);
    validate_section(&mut out, &vals);
    gap_section(&mut out, &gaps);
    inputs_section(&mut out, inputs);
    let _ = writeln!(out, "<script>{LAYOUT_SCRIPT}</script></body></html>");
    out
}

fn recording(out: &mut String, recs: &[&Input], checks: &[&Input]) {
    out.push_str("<h2 id=\"section-recording\">What the recordings hold</h2>\n");
    let mut rows = Vec::new();
    for r in recs {
        let v = &r.value;
        let span = v
            .get("span")
            .and_then(Value::as_array)
            .and_then(|a| Some((a.first()?.as_f64()?, a.get(1)?.as_f64()?)))
            .map(|(a, b)| (b - a) * 1e-9);
        for c in arr(v, "channels") {
            let count = num(c, &["count"]);
            rows.push(vec![
                esc(&r.name),
                esc(text(c, "topic")),
                esc(text(c, "message_type")),
                fixed(count, 0),
                fixed(count.zip(span).map(|(c, s)| c / s.max(1e-9)), 2),
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
    for c in checks {
        let t = c.value.get("temporal").cloned().unwrap_or(Value::Null);
        for src in arr(&t, "sources") {
            rows.push(vec![
                esc(&c.name),
                esc(text(src, "source")),
                fixed(num(src, &["rate_hz"]), 2),
                fixed(num(src, &["jitter_ms"]), 2),
                fixed(num(src, &["gaps"]), 0),
                fixed(num(src, &["max_interval_ms"]), 1),
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
    for c in checks {
        if let Some(m) = c
            .value
            .pointer("/temporal/clock_sync")
            .and_then(Value::as_object)
        {
            for (source, model) in m {
                rows.push(vec![
                    esc(&c.name),
                    esc(source),
                    fixed(num(model, &["drift_ppm"]), 3),
                    fixed(num(model, &["offset_ns"]).map(|x| x * 1e-6), 3),
                    fixed(num(model, &["residual_p95_ns"]).map(|x| x * 1e-3), 1),
                    esc(model.get("pps").and_then(Value::as_str).unwrap_or("")),
                ]);
            }
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

fn verdict(v: &str) -> String {
    let class = if v == "pass" { "pass" } else { "fail" };
    format!("<span class=\"{class}\">{}</span>", esc(v))
}

fn check_section(out: &mut String, checks: &[&Input]) {
    out.push_str("<h2 id=\"section-check\">Reference data (Rosenberger et al. 2019, §6)</h2>\n<p class=\"note\">Each run's trajectory and timing are checked before anything is re-simulated; the grid cell of the metrics follows from the accuracy found (at least ten times the reference accuracy).</p>\n");
    let rows: Vec<Vec<String>> = checks
        .iter()
        .map(|c| {
            let v = &c.value;
            vec![
                esc(&c.name),
                verdict(text(v, "verdict")),
                fixed(num(v, &["duration_s"]), 1),
                fixed(usable_percent(v), 0),
                fixed(
                    num(v, &["spatial", "rtk_fixed_share"]).map(|x| x * 100.0),
                    1,
                ),
                fixed(num(v, &["accuracy", "ego_m"]), 3),
                fixed(num(v, &["accuracy", "heading_sigma_deg"]), 3),
                esc(&heading_from(v)),
                fixed(num(v, &["accuracy", "reference_m"]), 3),
                fixed(num(v, &["accuracy", "grid_cell_m"]), 2),
                arr(v, "faults").len().to_string(),
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
    for (k, c) in checks.iter().enumerate() {
        figure(
            out,
            &format!("check-timeline-{k}"),
            plots::check_timeline(&c.value),
            &format!("Check timeline of {}: RTK state, horizontal sigma, verdict per segment, located faults.", esc(&c.name)),
        );
    }
}

fn compare_section(out: &mut String, cmps: &[&Input]) {
    out.push_str("<h2 id=\"section-compare\">Measurement against re-simulation (Rosenberger et al. 2019, §5)</h2>\n");
    let rows: Vec<Vec<String>> = cmps
        .iter()
        .map(|c| {
            let v = &c.value;
            let left_out: f64 = arr(v, "left_out")
                .iter()
                .filter_map(|l| num(l, &["scans"]))
                .sum();
            vec![
                esc(&c.name),
                format!(
                    "{} ({left_out:.0})",
                    fixed(num(v, &["summary", "scans"]), 0)
                ),
                fixed(num(v, &["cell_m"]), 2),
                fixed(num(v, &["summary", "ocr_mean"]), 3),
                fixed(num(v, &["summary", "precision_mean"]), 3),
                fixed(num(v, &["summary", "iou_mean"]), 3),
                fixed(num(v, &["summary", "chamfer_mean_m"]), 3),
                fixed(num(v, &["summary", "range_diff_rms_m"]), 3),
                fixed(num(v, &["summary", "only_sim_share"]).map(|x| x * 100.0), 1),
                format!(
                    "{} [{}, {}]",
                    fixed(num(v, &["summary", "ocr_vs_distance", "rho"]), 2),
                    fixed(num(v, &["summary", "ocr_vs_distance", "low"]), 2),
                    fixed(num(v, &["summary", "ocr_vs_distance", "high"]), 2)
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
    let at_admissible = |c: &&&Input| {
        num(&c.value, &["cell_m"])
            .zip(num(&c.value, &["admissible_cell_m"]))
            .is_some_and(|(a, b)| (a - b).abs() < 1e-9)
    };
    let has_snapshot = |c: &&&Input| c.value.get("snapshot").is_some_and(|s| !s.is_null());
    let pick = cmps
        .iter()
        .find(|c| has_snapshot(c) && at_admissible(c))
        .or_else(|| cmps.iter().find(|c| has_snapshot(c)));
    if let Some(c) = pick {
        figure(
            out,
            "birds-eye",
            c.value.get("snapshot").and_then(plots::birds_eye),
            &format!("One scan of {} from above, over the scene's objects; shaded cells are occupied by one cloud only.", esc(&c.name)),
        );
    }
    for (k, c) in cmps.iter().enumerate() {
        figure(
            out,
            &format!("fig5-{k}"),
            plots::fig5(&c.value),
            &format!(
                "Rosenberger et al. 2019, Fig. 5, for {} at a {} m cell: OCR, objects in view, ego speed and mean distance to the objects along the drive.",
                esc(&c.name),
                fixed(num(&c.value, &["cell_m"]), 2)
            ),
        );
    }
    let named: Vec<(&str, &Value)> = cmps.iter().map(|c| (c.name.as_str(), &c.value)).collect();
    figure(
        out,
        "calibration-curve",
        plots::calibration_curve(&named),
        "The calibration curve: OCR^K over cell sizes from 0.05 m to 2 m. Cells left of the red line are smaller than the reference data support.",
    );
}

fn light(l: &str) -> String {
    format!("<span class=\"light {l}\">{l}</span>", l = esc(l))
}

fn validate_section(out: &mut String, vals: &[&Input]) {
    out.push_str("<h2 id=\"section-validate\">Statistical validation (Rosenberger et al. 2019, §8, Fig. 7)</h2>\n<p class=\"note\">Per scenario sample (phase) and metric, the interval over the real repetitions against the interval over the simulated ones: green inside, yellow overlapping, red disjoint, black not evaluable. AVM: the area validation metric (area between the two empirical CDFs), in the metric's unit.</p>\n");
    for (k, v) in vals.iter().enumerate() {
        let val = &v.value;
        let _ = write!(
            out,
            "<h3>{}: verdict {}</h3>\n<p class=\"note\">1. Measurement validation: {}. 2. Scenario validation: {}. 3. Model validation: the matrix below.</p>\n",
            esc(&v.name),
            verdict(text(val, "verdict")),
            if val.get("measurement_pass").and_then(Value::as_bool).unwrap_or(false) {
                "every simulation has its real twin".to_string()
            } else {
                "a simulation lacks its real twin".to_string()
            },
            {
                let p: Vec<String> = arr(val, "scenario_problems")
                    .iter()
                    .filter_map(|p| p.as_str().map(esc))
                    .collect();
                if p.is_empty() {
                    "no problem found".to_string()
                } else {
                    p.join("; ")
                }
            }
        );
        let cells = arr(val, "cells");
        let mut samples: Vec<&str> = Vec::new();
        let mut metrics: Vec<&str> = Vec::new();
        for c in cells {
            if !samples.contains(&text(c, "sample")) {
                samples.push(text(c, "sample"));
            }
            if !metrics.contains(&text(c, "metric")) {
                metrics.push(text(c, "metric"));
            }
        }
        let rows: Vec<Vec<String>> = samples
            .iter()
            .map(|sample| {
                let mut row = vec![esc(sample)];
                for m in &metrics {
                    let cell = cells
                        .iter()
                        .find(|c| text(c, "sample") == *sample && text(c, "metric") == *m);
                    row.push(match cell {
                        Some(c) => format!(
                            "{} AVM {}{}",
                            light(text(c, "light")),
                            fixed(num(c, &["avm"]), 3),
                            c.get("why_black")
                                .and_then(Value::as_str)
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

fn gap_section(out: &mut String, gaps: &[&Input]) {
    out.push_str("<h2 id=\"section-gap\">The gap workflow</h2>\n<p class=\"note\">Per round: every effect of the catalogue fitted to the parameterization runs and scored by the likelihood gain on the measured firings; the best one is kept only if the validation runs improve.</p>\n");
    for (g, input) in gaps.iter().enumerate() {
        let v = &input.value;
        let _ = write!(out, "<h3>{}</h3>\n<ul>", esc(&input.name));
        for line in arr(v, "summary") {
            let _ = write!(out, "<li>{}</li>", esc(line.as_str().unwrap_or("")));
        }
        out.push_str("</ul>\n");
        let rounds = arr(v, "rounds");
        for (k, r) in rounds.iter().enumerate() {
            let round = num(r, &["round"]).unwrap_or(k as f64 + 1.0);
            let chosen = text(r, "chosen");
            let _ = writeln!(
                out,
                "<h3>Round {round:.0}: {}</h3>",
                if chosen.is_empty() {
                    "nothing added".to_string()
                } else {
                    format!("{} added", esc(chosen))
                }
            );
            figure(
                out,
                &format!("gap-{g}-round-{k}-candidates"),
                super::gap_plots::gap_candidates(r),
                "Candidates' likelihood gain with bootstrap intervals (the chosen one in blue).",
            );
            // The feature this round's effect settled most: the largest drop in disagreeing
            // bins to the next round (else the one disagreeing most now).
            let disagreeing = |round: &Value, feature: &str| -> usize {
                arr(round, "bins")
                    .iter()
                    .filter(|b| text(b, "feature") == feature)
                    .flat_map(|b| arr(b, "bins"))
                    .filter(|x| x.get("disagrees").and_then(Value::as_bool) == Some(true))
                    .count()
            };
            let next = rounds.get(k + 1);
            let feature = arr(r, "bins")
                .iter()
                .map(|b| text(b, "feature"))
                .max_by_key(|f| {
                    let now = disagreeing(r, f);
                    let drop = next.map_or(0, |x| now.saturating_sub(disagreeing(x, f)));
                    (drop, now)
                })
                .unwrap_or_default()
                .to_owned();
            let of = |round: &Value| {
                arr(round, "bins")
                    .iter()
                    .find(|b| text(b, "feature") == feature)
                    .cloned()
            };
            if let Some(before) = of(r) {
                let after = rounds.get(k + 1).and_then(of);
                figure(
                    out,
                    &format!("gap-{g}-round-{k}-bins"),
                    super::gap_plots::gap_bins(&feature, &before, after.as_ref()),
                    &format!(
                        "Binned disagreement against {} before and after this round.",
                        esc(&feature)
                    ),
                );
            }
            let params: Vec<Vec<String>> = arr(r, "parameters")
                .iter()
                .map(|p| {
                    let iv = p.get("interval").and_then(Value::as_array);
                    vec![
                        esc(chosen),
                        esc(text(p, "name")),
                        fixed(num(p, &["value"]), 5),
                        format!(
                            "[{}, {}]",
                            fixed(iv.and_then(|a| a.first()?.as_f64()), 5),
                            fixed(iv.and_then(|a| a.get(1)?.as_f64()), 5)
                        ),
                    ]
                })
                .collect();
            if !params.is_empty() {
                table(
                    out,
                    &format!("gap-{g}-round-{k}-parameters"),
                    &["effect", "parameter", "fitted", "95 % interval"],
                    &params,
                );
            }
            let (b, a) = (r.get("metrics_before"), r.get("metrics_after"));
            if let (Some(b), Some(a)) = (b.filter(|x| !x.is_null()), a.filter(|x| !x.is_null())) {
                let mut rows = Vec::new();
                for m in ["ocr", "precision", "iou"] {
                    rows.push(vec![
                        m.to_uppercase(),
                        fixed(num(b, &[m]), 3),
                        fixed(num(a, &[m]), 3),
                    ]);
                }
                let avm = |x: &Value, name: &str| {
                    arr(x, "avm")
                        .iter()
                        .find(|p| p.get(0).and_then(Value::as_str) == Some(name))
                        .and_then(|p| p.get(1)?.as_f64())
                };
                for p in arr(b, "avm") {
                    let name = p.get(0).and_then(Value::as_str).unwrap_or("");
                    rows.push(vec![
                        format!("AVM {}", esc(name)),
                        fixed(avm(b, name), 3),
                        fixed(avm(a, name), 3),
                    ]);
                }
                rows.push(vec![
                    "verdict".into(),
                    esc(text(b, "verdict")),
                    esc(text(a, "verdict")),
                ]);
                table(
                    out,
                    &format!("gap-{g}-round-{k}-metrics"),
                    &["metric on the validation runs", "before", "after"],
                    &rows,
                );
            }
        }
    }
}

fn inputs_section(out: &mut String, inputs: &[Input]) {
    out.push_str("<h2 id=\"section-inputs\">Inputs</h2>\n<p class=\"note\">Every number above comes from these files (and is in report.json beside this page).</p>\n");
    let mut rows: Vec<Vec<String>> = inputs
        .iter()
        .map(|i| {
            vec![
                esc(&i.name),
                format!("{:?}", i.kind).to_lowercase(),
                i.bytes.to_string(),
                format!("<code>{}</code>", i.sha256),
            ]
        })
        .collect();
    // What produced the recordings, from their metadata.
    for i in inputs.iter().filter(|i| i.kind == Kind::Recording) {
        if let Some(m) = i
            .value
            .pointer("/metadata/hilrig")
            .and_then(Value::as_object)
        {
            let kv: Vec<String> = m
                .iter()
                .map(|(k, v)| format!("{}={}", esc(k), esc(v.as_str().unwrap_or(""))))
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
