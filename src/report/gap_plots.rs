//! The gap workflow's plots: each round's candidates and the binned disagreement before and
//! after the effect it added.

use super::plots::{legend, range_of, svg, GREY, PASS, REAL, SIM};
use crate::gap::bins::{Bin, Table};
use crate::gap::report::Round;
use plotters::prelude::*;

/// One gap round's candidates: each effect's likelihood gain (nats per 1000 firings) with its
/// bootstrap interval; the chosen one in the measured colour.
pub fn gap_candidates(round: &Round) -> Option<String> {
    let cands = &round.candidates;
    if cands.is_empty() {
        return None;
    }
    let rows: Vec<(String, f64, f64, f64, bool)> = cands
        .iter()
        .filter(|c| c.gain.is_finite())
        .map(|c| {
            let (g, per) = (c.gain, c.gain_per_1000_firings);
            let scale = if g.abs() > 0.0 { per / g } else { 0.0 };
            let (lo, hi) = c.gain_interval.unwrap_or((g, g));
            let chosen = round.chosen == Some(c.effect);
            (
                c.effect.name().to_owned(),
                per,
                lo * scale,
                hi * scale,
                chosen,
            )
        })
        .collect();
    let (lo, hi) = range_of(rows.iter().flat_map(|r| [r.1, r.2, r.3, 0.0]))?;
    let n = rows.len();
    svg(1000, 60 + 26 * n as u32, |root| {
        let mut c = ChartBuilder::on(root)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(170)
            .build_cartesian_2d(lo..hi, (0..n).into_segmented())?;
        let names: Vec<String> = rows.iter().map(|r| r.0.clone()).collect();
        c.configure_mesh()
            .x_desc("likelihood gain, nats per 1000 firings (bootstrap 95 % interval)")
            .y_labels(n + 1)
            .y_label_formatter(&|y| match y {
                SegmentValue::CenterOf(i) => names.get(*i).cloned().unwrap_or_default(),
                _ => String::new(),
            })
            .light_line_style(WHITE)
            .draw()?;
        for (i, (_, g, a, b, chosen)) in rows.iter().enumerate() {
            let color = if *chosen { REAL } else { GREY };
            c.draw_series(std::iter::once(Rectangle::new(
                [
                    (0.0f64.min(*g), SegmentValue::Exact(i)),
                    (0.0f64.max(*g), SegmentValue::Exact(i + 1)),
                ],
                color.filled(),
            )))?;
            c.draw_series(std::iter::once(PathElement::new(
                vec![
                    (*a, SegmentValue::CenterOf(i)),
                    (*b, SegmentValue::CenterOf(i)),
                ],
                BLACK.stroke_width(2),
            )))?;
        }
        Ok(())
    })
}

/// A feature's binned disagreement before and after a round: the share of firings with a
/// return, measured against predicted by the model before and after, and the range residual's
/// median and spread per bin.
pub fn gap_bins(feature: &str, before: &Table, after: Option<&Table>) -> Option<String> {
    let series = |table: &Table, value: &dyn Fn(&Bin) -> Option<f64>| -> Vec<(f64, f64)> {
        table
            .bins
            .iter()
            .filter_map(|b| Some(((b.from + b.to) / 2.0, value(b)?)))
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect()
    };
    let measured_share = |b: &Bin| Some(b.measured_share);
    let predicted_share = |b: &Bin| Some(b.predicted_share);
    let sigma = |b: &Bin| b.sigma_m;
    let measured = series(before, &measured_share);
    if measured.is_empty() {
        return None;
    }
    let pred_before = series(before, &predicted_share);
    let pred_after = after
        .map(|a| series(a, &predicted_share))
        .unwrap_or_default();
    // Unchanged by this round's effect (noise does not change whether a firing returns): one
    // line, not "after" drawn over "before".
    let same = |a: &[(f64, f64)], b: &[(f64, f64)]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x.1 - y.1).abs() < 1e-9)
    };
    let pred_after = if same(&pred_after, &pred_before) {
        Vec::new()
    } else {
        pred_after
    };
    let med: Vec<(f64, f64)> = series(before, &|b| b.median_m);
    let sig_b = series(before, &sigma);
    let sig_a = after.map(|a| series(a, &sigma)).unwrap_or_default();
    // The measured residuals' spread changes only when the effect moves the model's ranges
    // (a bias, a misalignment); otherwise "after" would hide "before" under the same line.
    let sig_a = if same(&sig_a, &sig_b) {
        Vec::new()
    } else {
        sig_a
    };
    let (x0, x1) = range_of(measured.iter().map(|p| p.0))?;
    svg(1000, 330, |root| {
        let (left, right) = root.split_horizontally(500);
        let mut c = ChartBuilder::on(&left)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .caption(
                format!("returns per firing against {feature}"),
                ("sans-serif", 14),
            )
            .build_cartesian_2d(x0..x1, 0.0..1.05)?;
        c.configure_mesh()
            .x_desc(feature)
            .light_line_style(WHITE)
            .draw()?;
        c.draw_series(LineSeries::new(
            measured.iter().copied(),
            REAL.stroke_width(2),
        ))?
        .label("measured")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], REAL.stroke_width(2)));
        c.draw_series(LineSeries::new(
            pred_before.iter().copied(),
            SIM.stroke_width(2),
        ))?
        .label(if pred_after.is_empty() {
            "model (unchanged)"
        } else {
            "model before"
        })
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], SIM.stroke_width(2)));
        if !pred_after.is_empty() {
            c.draw_series(LineSeries::new(
                pred_after.iter().copied(),
                PASS.stroke_width(2),
            ))?
            .label("model after")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], PASS.stroke_width(2)));
        }
        legend(&mut c, SeriesLabelPosition::LowerLeft)?;

        let (y0, y1) = range_of(
            med.iter()
                .chain(&sig_b)
                .chain(&sig_a)
                .map(|p| p.1)
                .chain([0.0]),
        )
        .unwrap_or((0.0, 0.1));
        let mut r = ChartBuilder::on(&right)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .caption(
                format!("range residual against {feature}"),
                ("sans-serif", 14),
            )
            .build_cartesian_2d(x0..x1, y0..y1)?;
        r.configure_mesh()
            .x_desc(feature)
            .y_desc("m")
            .light_line_style(WHITE)
            .draw()?;
        r.draw_series(LineSeries::new(med.iter().copied(), BLACK.stroke_width(1)))?
            .label("median (measured - model)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], BLACK.stroke_width(1)));
        r.draw_series(LineSeries::new(sig_b.iter().copied(), SIM.stroke_width(2)))?
            .label(if sig_a.is_empty() {
                "spread"
            } else {
                "spread before"
            })
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], SIM.stroke_width(2)));
        if !sig_a.is_empty() {
            r.draw_series(LineSeries::new(sig_a.iter().copied(), PASS.stroke_width(2)))?
                .label("spread after")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], PASS.stroke_width(2)));
        }
        legend(&mut r, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}
