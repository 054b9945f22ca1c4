//! The report's first table: one line per step of the method with its outcome, linked to the
//! section that holds the evidence. A reviewer reads the verdicts first and the tables that
//! support them after; without this, the page opened on the recordings' topic list.

use super::plots::{fixed, lights, Named};
use crate::gap::report::GapReport;
use crate::metrics::report::Comparison;
use crate::reference::check::{Report, Verdict};
use crate::stats::repetitions::Validation;

/// The check line: runs passing, the worst ego accuracy, the admissible cells, faults named.
fn checks_line(checks: &[Named<Report>]) -> String {
    let pass = checks
        .iter()
        .filter(|(_, c)| c.verdict == Verdict::Pass)
        .count();
    let values = |f: &dyn Fn(&Report) -> f64| -> Vec<f64> {
        checks
            .iter()
            .map(|(_, c)| f(c))
            .filter(|x| x.is_finite())
            .collect()
    };
    let ego = values(&|c| c.accuracy.ego_m);
    let cells = values(&|c| c.accuracy.grid_cell_m);
    let mut faults: Vec<&str> = checks
        .iter()
        .flat_map(|(_, c)| &c.faults)
        .map(|f| f.name.as_str())
        .collect();
    faults.sort_unstable();
    faults.dedup();
    let mut line = format!("{pass} of {} runs pass", checks.len());
    if let Some(worst) = ego.iter().copied().reduce(f64::max) {
        line.push_str(&format!("; ego accuracy at most {worst:.3} m"));
    }
    let lo = cells.iter().copied().reduce(f64::min);
    let hi = cells.iter().copied().reduce(f64::max);
    if let (Some(lo), Some(hi)) = (lo, hi) {
        if hi - lo < 0.005 {
            line.push_str(&format!("; admissible cell {lo:.2} m"));
        } else {
            line.push_str(&format!("; admissible cell {lo:.2}–{hi:.2} m"));
        }
    }
    if !faults.is_empty() {
        line.push_str(&format!("; faults: {}", faults.join(", ")));
    }
    line
}

/// The gap line: the effects added in order, and why the workflow stopped.
fn gap_line(name: &str, v: &GapReport) -> String {
    let added: Vec<&str> = v
        .rounds
        .iter()
        .filter_map(|r| r.chosen.map(|c| c.name()))
        .collect();
    let mut line = format!(
        "{name}: {}",
        if added.is_empty() {
            "no effect added".to_owned()
        } else {
            format!("effects added: {}", added.join(", "))
        }
    );
    // Why the rounds ended: no effect missing, or the round limit.
    if let Some(ended) = &v.ended {
        line.push_str(&format!("; {ended}"));
    }
    line
}

/// The rows (step with its section link, outcome) of the inputs at hand; the caller escapes
/// nothing: names and lines are escaped here with `esc`.
pub(super) fn rows(
    checks: &[Named<Report>],
    cmps: &[Named<Comparison>],
    vals: &[Named<Validation>],
    gaps: &[Named<GapReport>],
    esc: &dyn Fn(&str) -> String,
) -> Vec<Vec<String>> {
    let step = |id: &str, title: &str| format!("<a href=\"#section-{id}\">{title}</a>");
    let mut rows = Vec::new();
    if !checks.is_empty() {
        rows.push(vec![
            step("check", "Reference data (§6)"),
            esc(&checks_line(checks)),
        ]);
    }
    // One row per kind of input present: its step and a line per input.
    let mut section = |id: &str, title: &str, lines: Vec<String>| {
        if !lines.is_empty() {
            let lines: Vec<String> = lines.iter().map(|l| esc(l)).collect();
            rows.push(vec![step(id, title), lines.join("<br>")]);
        }
    };
    section(
        "compare",
        "Measurement against re-simulation (§5)",
        cmps.iter()
            .map(|(name, c)| {
                format!(
                    "{name}: OCR^K {} at a {} m cell",
                    fixed(c.summary.ocr_mean, 3),
                    fixed(Some(c.cell_m), 2)
                )
            })
            .collect(),
    );
    section(
        "validate",
        "Statistical validation (§8, Fig. 7)",
        vals.iter()
            .map(|(name, v)| {
                let [g, y, r, b] = lights(v);
                format!(
                    "{name}: {} ({g} green, {y} yellow, {r} red, {b} black)",
                    v.verdict.name()
                )
            })
            .collect(),
    );
    section(
        "gap",
        "The gap workflow",
        gaps.iter().map(|(name, g)| gap_line(name, g)).collect(),
    );
    rows
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::gap::report::Round;
    use crate::reference::check::{Fault, FaultName};
    use crate::sim::model::EffectKind;
    use crate::stats::avm::Light;
    use crate::stats::validate::Cell;

    /// A comparison at a 1.05 m cell with the scans and summary given, nothing else in it.
    pub(crate) fn comparison(
        scans: Vec<crate::metrics::report::ScanRow>,
        summary: crate::metrics::report::Summary,
    ) -> Comparison {
        Comparison {
            cell_m: 1.05,
            admissible_cell_m: 1.05,
            k: 3,
            grid_phases: 1,
            curve_every: 0,
            point_metrics: false,
            dims: crate::metrics::grid::Dims::Voxel,
            region: String::new(),
            damage: Vec::new(),
            left_out: Vec::new(),
            ground_excluded: false,
            frame: crate::metrics::report::ComparisonFrame::Scene,
            scans,
            calibration: Vec::new(),
            snapshot: None,
            summary,
        }
    }

    fn check(verdict: Verdict, faults: &[FaultName], ego_m: f64, grid_cell_m: f64) -> Report {
        let mut r = crate::report::plots::tests::report(10.0, &[]);
        r.verdict = verdict;
        r.accuracy.ego_m = ego_m;
        r.accuracy.grid_cell_m = grid_cell_m;
        r.faults = faults
            .iter()
            .map(|&name| Fault {
                name,
                topics: Vec::new(),
                from: String::new(),
                to: String::new(),
                from_s: 0.0,
                to_s: 1.0,
                detail: String::new(),
                from_ns: hilrig_stamp::UtcNanos(0),
                to_ns: hilrig_stamp::UtcNanos(0),
            })
            .collect();
        r
    }

    fn round(chosen: Option<EffectKind>) -> Round {
        Round {
            round: 1,
            disagreeing_bins: Vec::new(),
            bins: Vec::new(),
            candidates: Vec::new(),
            trials: Vec::new(),
            chosen,
            parameters: Vec::new(),
            refits: Vec::new(),
            metrics_before: None,
            metrics_after: None,
        }
    }

    #[test]
    fn one_line_per_step_with_what_decides_it() {
        let checks = [
            check(Verdict::Pass, &[], 0.031, 1.05),
            check(
                Verdict::Fail,
                &[FaultName::RtkFloat, FaultName::Jump],
                0.052,
                1.20,
            ),
        ];
        let cell = |light| Cell {
            sample: "whole run".into(),
            metric: "ocr".into(),
            real: Vec::new(),
            sim: Vec::new(),
            real_interval: None,
            sim_interval: None,
            light,
            why_black: None,
            avm: None,
        };
        let val = Validation {
            measurement: Vec::new(),
            measurement_pass: true,
            damage: Vec::new(),
            scenario_problems: Vec::new(),
            cells: vec![
                cell(Light::Green),
                cell(Light::Yellow),
                cell(Light::Yellow),
                cell(Light::Black),
            ],
            verdict: crate::stats::validate::Verdict::PartlyValid,
        };
        let gap = GapReport {
            start_model: String::new(),
            runs: Vec::new(),
            split: None,
            floors: Vec::new(),
            rounds: vec![round(Some(EffectKind::RangeNoise)), round(None)],
            finished: true,
            summary: vec![
                "found: range_noise ...".into(),
                "no missing effect found in round 2: x".into(),
            ],
            ended: Some("no missing effect found in round 2: x".into()),
            reference: None,
            limits: Vec::new(),
        };
        let summary = crate::metrics::report::Summary {
            ocr_mean: Some(0.8734),
            ..Default::default()
        };
        let cmp = comparison(Vec::new(), summary);
        let esc = |s: &str| s.replace('<', "&lt;");
        let rows = rows(
            &[("check/a.json", &checks[0]), ("check/b.json", &checks[1])],
            &[("compare/c.json", &cmp)],
            &[("validate/m.json", &val)],
            &[("gap/gap.json", &gap)],
            &esc,
        );
        assert_eq!(rows.len(), 4);
        assert!(rows[0][0].contains("#section-check"));
        assert_eq!(
            rows[0][1],
            "1 of 2 runs pass; ego accuracy at most 0.052 m; admissible cell 1.05–1.20 m; faults: jump, rtk_float"
        );
        assert_eq!(rows[1][1], "compare/c.json: OCR^K 0.873 at a 1.05 m cell");
        assert_eq!(
            rows[2][1],
            "validate/m.json: partly_valid (1 green, 2 yellow, 0 red, 1 black)"
        );
        assert_eq!(
            rows[3][1],
            "gap/gap.json: effects added: range_noise; no missing effect found in round 2: x"
        );
        // Stopped by the round limit after a round that added an effect: said so.
        let limited = GapReport {
            rounds: vec![round(Some(EffectKind::RangeNoise))],
            ended: Some("stopped after 1 rounds (--max-rounds)".into()),
            ..gap.clone()
        };
        let rows = super::rows(&[], &[], &[], &[("gap.json", &limited)], &esc);
        assert_eq!(
            rows[0][1],
            "gap.json: effects added: range_noise; stopped after 1 rounds (--max-rounds)"
        );
        // Nothing of a kind, no line for it.
        assert!(rows_of_nothing().is_empty());
    }

    fn rows_of_nothing() -> Vec<Vec<String>> {
        rows(&[], &[], &[], &[], &|s| s.to_owned())
    }
}
