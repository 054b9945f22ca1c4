//! The report's section on the gap workflow: per study its summary lines, and per round the
//! candidates, the disagreement they settled, the parameters fitted and re-fitted, the trials on
//! the validation runs with the keep rule's decision on each, and the metrics before and after.

use super::markup::{esc, figure, table};
use super::plots::{fixed, Named};
use crate::gap::limits::DetectionLimit;
use crate::gap::report::{GapReport, Round, RunMetrics};
use std::fmt::Write;

pub(super) fn gap_section<'a>(out: &mut String, gaps: &[Named<'a, GapReport>]) {
    out.push_str("<h2 id=\"section-gap\">The gap workflow</h2>\n<p class=\"note\">Per round: every effect of the catalogue fitted to the parameterization runs and scored by the likelihood gain on the measured firings; the best one is kept only if the validation runs improve.</p>\n");
    for (g, (name, v)) in gaps.iter().enumerate() {
        let _ = write!(out, "<h3>{}</h3>\n<ul>", esc(name));
        for line in &v.summary {
            let _ = write!(out, "<li>{}</li>", esc(line));
        }
        out.push_str("</ul>\n");
        limits_table(out, &format!("gap-{g}-limits"), &v.limits);
        if let Some(r) = &v.reference {
            let _ = writeln!(
                out,
                "<p class=\"note\">The fitted model beside the model known to have made the data ({}), on the validation runs; \"worse beyond noise\" as the keep rule judges a trial.</p>",
                esc(&r.path)
            );
            metrics_table_with(
                out,
                &format!("gap-{g}-reference"),
                (&r.metrics, &r.fitted),
                [&format!("generating model '{}'", r.name), "fitted model"],
            );
            let worse: Vec<Vec<String>> =
                r.worse.iter().map(|w| vec![esc(&w.to_string())]).collect();
            if !worse.is_empty() {
                table(
                    out,
                    &format!("gap-{g}-reference-worse"),
                    &["the fitted model worse beyond the generating model's noise"],
                    &worse,
                );
            }
        }
        let rounds = &v.rounds;
        for (k, r) in rounds.iter().enumerate() {
            let chosen = r.chosen.map_or("", |c| c.name());
            let _ = writeln!(
                out,
                "<h3>Round {}: {}</h3>",
                r.round,
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
            let disagreeing = |round: &Round, feature: &str| -> usize {
                round
                    .bins
                    .iter()
                    .filter(|b| b.feature == feature)
                    .flat_map(|b| &b.bins)
                    .filter(|x| x.disagrees)
                    .count()
            };
            let next = rounds.get(k + 1);
            let feature = r
                .bins
                .iter()
                .map(|b| b.feature.as_ref())
                .max_by_key(|f| {
                    let now = disagreeing(r, f);
                    let drop = next.map_or(0, |x| now.saturating_sub(disagreeing(x, f)));
                    (drop, now)
                })
                .unwrap_or_default()
                .to_owned();
            let of = |round: &'a Round| round.bins.iter().find(|b| b.feature == feature.as_str());
            if let Some(before) = of(r) {
                let after = next.and_then(of);
                figure(
                    out,
                    &format!("gap-{g}-round-{k}-bins"),
                    super::gap_plots::gap_bins(&feature, before, after),
                    &format!(
                        "Binned disagreement against {} before and after this round.",
                        esc(&feature)
                    ),
                );
            }
            let params: Vec<Vec<String>> = r
                .parameters
                .iter()
                .map(|p| {
                    vec![
                        esc(chosen),
                        esc(&p.name),
                        fixed(Some(p.value), 5),
                        format!(
                            "[{}, {}]",
                            fixed(p.interval.map(|i| i.0), 5),
                            fixed(p.interval.map(|i| i.1), 5)
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
            // The effects added before, re-fitted together with this one.
            let refits: Vec<Vec<String>> = r
                .refits
                .iter()
                .flat_map(|f| {
                    f.after.iter().map(move |p| {
                        let before = f.before.iter().find(|b| b.name == p.name);
                        vec![
                            esc(f.effect.name()),
                            esc(&p.name),
                            fixed(before.map(|b| b.value), 5),
                            fixed(Some(p.value), 5),
                            if f.below_floor {
                                "below its floor now".to_owned()
                            } else {
                                String::new()
                            },
                        ]
                    })
                })
                .collect();
            if !refits.is_empty() {
                table(
                    out,
                    &format!("gap-{g}-round-{k}-refits"),
                    &["re-fitted with it", "parameter", "before", "after", ""],
                    &refits,
                );
            }
            trials_table(out, &format!("gap-{g}-round-{k}-trials"), r);
            if let (Some(b), Some(a)) = (&r.metrics_before, &r.metrics_after) {
                metrics_table(out, &format!("gap-{g}-round-{k}-metrics"), b, a);
            }
        }
    }
}

/// The candidates tried on the validation runs and the keep rule's decision on each: the
/// likelihood gain's interval, then the metrics judged and those made worse.
/// The detection limits of the effects not added: the smallest size of each the runs would
/// have shown, the size missed below it, and every size injected.
fn limits_table(out: &mut String, id: &str, limits: &[DetectionLimit]) {
    if limits.is_empty() {
        return;
    }
    out.push_str("<p class=\"note\">What was not found, and what would have been: each effect injected into the runs' own measured ranges at growing sizes, and the workflow's test run on each (Rosenberger et al. 2019, §6: the reference data's accuracy bounds what the data can show).</p>\n");
    let rows: Vec<Vec<String>> = limits
        .iter()
        .map(|l| {
            let sign = if l.at_most { "≤" } else { "≥" };
            let cell = |x: Option<f64>| x.map_or_else(String::new, |x| format!("{x:.3}"));
            let tried: Vec<String> = l
                .tries
                .iter()
                .map(|t| format!("{:.3}{}", t.size, if t.seen { " seen" } else { "" }))
                .collect();
            match &l.note {
                Some(n) => vec![
                    esc(l.effect.name()),
                    String::new(),
                    esc(n),
                    String::new(),
                    String::new(),
                ],
                None => vec![
                    esc(l.effect.name()),
                    esc(&format!("{} ({})", l.parameter, l.unit)),
                    l.seen_at.map_or_else(
                        || "not seen at any size tried".to_owned(),
                        |s| format!("{sign} {}", cell(Some(s))),
                    ),
                    cell(l.missed_at),
                    esc(&tried.join(", ")),
                ],
            }
        })
        .collect();
    table(
        out,
        id,
        &[
            "effect not added",
            "size",
            "would have been seen at",
            "missed at",
            "sizes injected",
        ],
        &rows,
    );
}

fn trials_table(out: &mut String, id: &str, r: &Round) {
    use crate::gap::keep::GridBasis;
    let rows: Vec<Vec<String>> = r
        .trials
        .iter()
        .map(|t| {
            let (judged, worse) = match &t.metrics {
                None => ("likelihood only".to_owned(), String::new()),
                Some(m) => (
                    format!(
                        "{} at {:.4} each{}",
                        m.judged,
                        m.level,
                        match m.grid {
                            GridBasis::Models => "",
                            GridBasis::DeterministicParts => "; grid on deterministic parts",
                            GridBasis::Unchanged => "; grid unchanged",
                        }
                    ),
                    m.worse
                        .iter()
                        .map(ToString::to_string)
                        .collect::<Vec<_>>()
                        .join("; "),
                ),
            };
            let trade_off = t
                .metrics
                .as_ref()
                .is_some_and(|m| m.decision == crate::gap::keep::Decision::TradeOff);
            let decision = if t.kept && trade_off {
                "kept: a trade-off (a grid metric better, a run-level one worse)"
            } else if t.kept {
                "kept"
            } else if t.confounded() {
                "confounded: a metric worse"
            } else {
                "no clear likelihood gain"
            };
            vec![
                esc(t.effect.name()),
                format!(
                    "{:.1} [{}, {}]",
                    t.gain,
                    fixed(t.gain_interval.map(|i| i.0), 1),
                    fixed(t.gain_interval.map(|i| i.1), 1)
                ),
                esc(&judged),
                esc(&worse),
                decision.to_owned(),
            ]
        })
        .collect();
    if !rows.is_empty() {
        table(
            out,
            id,
            &[
                "tried on the validation runs",
                "likelihood gain, nats [95 %]",
                "metrics judged",
                "worse beyond noise",
                "decision",
            ],
            &rows,
        );
    }
}

/// The validation runs' metrics before and after a round.
fn metrics_table(out: &mut String, id: &str, b: &RunMetrics, a: &RunMetrics) {
    metrics_table_with(out, id, (b, a), ["before", "after"]);
}

/// The validation runs' metrics of two models, under the given column heads.
fn metrics_table_with(
    out: &mut String,
    id: &str,
    (b, a): (&RunMetrics, &RunMetrics),
    heads: [&str; 2],
) {
    let mut rows = Vec::new();
    for (m, x, y) in [
        ("OCR", b.ocr, a.ocr),
        ("PRECISION", b.precision, a.precision),
        ("IOU", b.iou, a.iou),
    ] {
        rows.push(vec![m.to_owned(), fixed(x, 3), fixed(y, 3)]);
    }
    let avm =
        |x: &RunMetrics, name: &str| x.avm.iter().find(|p| p.metric == name).and_then(|p| p.avm);
    for p in &b.avm {
        rows.push(vec![
            format!("AVM {}", esc(&p.metric)),
            fixed(avm(b, &p.metric), 3),
            fixed(avm(a, &p.metric), 3),
        ]);
    }
    rows.push(vec![
        "verdict".into(),
        esc(b.verdict.name()),
        esc(a.verdict.name()),
    ]);
    table(
        out,
        id,
        &["metric on the validation runs", heads[0], heads[1]],
        &rows,
    );
}
