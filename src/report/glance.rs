//! The report's first table: one line per step of the method with its outcome, linked to the
//! section that holds the evidence. A reviewer reads the verdicts first and the tables that
//! support them after; without this, the page opened on the recordings' topic list.

use super::plots::{arr, fixed, lights, num, text};
use super::Input;
use serde_json::Value;

/// The check line: runs passing, the worst ego accuracy, the admissible cells, faults named.
fn checks_line(checks: &[&Input]) -> String {
    let pass = checks
        .iter()
        .filter(|c| text(&c.value, "verdict") == "pass")
        .count();
    let values = |path: &[&str]| -> Vec<f64> {
        checks
            .iter()
            .filter_map(|c| num(&c.value, path))
            .filter(|x| x.is_finite())
            .collect()
    };
    let ego = values(&["accuracy", "ego_m"]);
    let cells = values(&["accuracy", "grid_cell_m"]);
    let mut faults: Vec<&str> = checks
        .iter()
        .flat_map(|c| arr(&c.value, "faults"))
        .map(|f| text(f, "name"))
        .filter(|f| !f.is_empty())
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
fn gap_line(name: &str, v: &Value) -> String {
    let added: Vec<&str> = arr(v, "rounds")
        .iter()
        .map(|r| text(r, "chosen"))
        .filter(|c| !c.is_empty())
        .collect();
    let mut line = format!(
        "{name}: {}",
        if added.is_empty() {
            "no effect added".to_owned()
        } else {
            format!("effects added: {}", added.join(", "))
        }
    );
    // The last line says why the rounds ended, unless the last round added something.
    if let Some(last) = arr(v, "summary").last().and_then(Value::as_str) {
        if !last.starts_with("found:") {
            line.push_str(&format!("; {last}"));
        }
    }
    line
}

/// The rows (step with its section link, outcome) of the inputs at hand; the caller escapes
/// nothing: names and lines are escaped here with `esc`.
pub(super) fn rows(
    checks: &[&Input],
    cmps: &[&Input],
    vals: &[&Input],
    gaps: &[&Input],
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
    let mut section =
        |id: &str, title: &str, inputs: &[&Input], line: &dyn Fn(&Input) -> String| {
            if !inputs.is_empty() {
                let lines: Vec<String> = inputs.iter().map(|i| esc(&line(i))).collect();
                rows.push(vec![step(id, title), lines.join("<br>")]);
            }
        };
    section(
        "compare",
        "Measurement against re-simulation (§5)",
        cmps,
        &|c| {
            format!(
                "{}: OCR^K {} at a {} m cell",
                c.name,
                fixed(num(&c.value, &["summary", "ocr_mean"]), 3),
                fixed(num(&c.value, &["cell_m"]), 2)
            )
        },
    );
    section(
        "validate",
        "Statistical validation (§8, Fig. 7)",
        vals,
        &|v| {
            let [g, y, r, b] = lights(&v.value);
            format!(
                "{}: {} ({g} green, {y} yellow, {r} red, {b} black)",
                v.name,
                text(&v.value, "verdict")
            )
        },
    );
    section("gap", "The gap workflow", gaps, &|g| {
        gap_line(&g.name, &g.value)
    });
    rows
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Kind;
    use serde_json::json;

    fn input(name: &str, kind: Kind, value: Value) -> Input {
        Input {
            path: name.into(),
            name: name.into(),
            kind,
            value,
            bytes: 0,
            sha256: String::new(),
        }
    }

    #[test]
    fn one_line_per_step_with_what_decides_it() {
        let checks = [
            input(
                "check/a.json",
                Kind::Check,
                json!({"verdict": "pass", "faults": [],
                       "accuracy": {"ego_m": 0.031, "grid_cell_m": 1.05}}),
            ),
            input(
                "check/b.json",
                Kind::Check,
                json!({"verdict": "fail", "faults": [{"name": "rtk_float"}, {"name": "jump"}],
                       "accuracy": {"ego_m": 0.052, "grid_cell_m": 1.20}}),
            ),
        ];
        let val = input(
            "validate/m.json",
            Kind::Validate,
            json!({"verdict": "partly_valid", "cells": [{"light": "green"}, {"light": "yellow"},
                   {"light": "yellow"}, {"light": "black"}]}),
        );
        let gap = input(
            "gap/gap.json",
            Kind::Gap,
            json!({"rounds": [{"chosen": "range_noise"}, {"chosen": null}],
                   "summary": ["found: range_noise ...", "no missing effect found in round 2: x"]}),
        );
        let cmp = input(
            "compare/c.json",
            Kind::Compare,
            json!({"cell_m": 1.05, "summary": {"ocr_mean": 0.8734}}),
        );
        let esc = |s: &str| s.replace('<', "&lt;");
        let rows = rows(
            &checks.iter().collect::<Vec<_>>(),
            &[&cmp],
            &[&val],
            &[&gap],
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
        // Nothing of a kind, no line for it.
        assert!(rows_of_nothing().is_empty());
    }

    fn rows_of_nothing() -> Vec<Vec<String>> {
        rows(&[], &[], &[], &[], &|s| s.to_owned())
    }
}
