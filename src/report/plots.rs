//! The report's plots, drawn in Rust as SVG text with plotters: no browser script draws them,
//! so the HTML holds the figures themselves and opens anywhere, offline.
//!
//! Each function takes the typed output a command wrote ([`crate::output`]) and returns one
//! `<svg>` element, or `None` when the input has nothing to draw.

use crate::metrics::report::{Comparison, ScanRow, Snapshot};
use crate::reference::check::{Report, Verdict};
use crate::stats::avm::Light;
use crate::stats::repetitions::Validation;
use hilrig_gnss::RtkState;
use plotters::coord::Shift;
use plotters::prelude::*;

/// An input's short name and its content.
pub(super) type Named<'a, T> = (&'a str, &'a T);

/// Measured data (a dark blue).
pub const REAL: RGBColor = RGBColor(31, 86, 160);
/// Simulated data (an orange).
pub const SIM: RGBColor = RGBColor(222, 119, 26);
pub(super) const GREY: RGBColor = RGBColor(150, 150, 150);
pub(super) const PASS: RGBColor = RGBColor(60, 160, 80);
pub(super) const FAIL: RGBColor = RGBColor(200, 50, 40);
const FLOAT: RGBColor = RGBColor(235, 180, 40);

/// `x` with `d` decimals, or a dash where there is no finite number.
pub(super) fn fixed(x: Option<f64>, d: usize) -> String {
    x.filter(|x| x.is_finite())
        .map_or_else(|| "–".into(), |x| format!("{x:.d$}"))
}

/// The share of a checked run that its segments call usable, %: marked and failing stretches
/// are left out of the metrics, so this is what the run contributes.
pub(super) fn usable_percent(check: &Report) -> Option<f64> {
    let usable: f64 = check
        .segments
        .iter()
        .filter(|g| g.verdict == Verdict::Pass)
        .map(|g| g.to_s - g.from_s)
        .sum();
    Some(check.duration_s)
        .filter(|&d| d > 0.0)
        .map(|d| 100.0 * usable / d)
}

/// Where a checked run's heading came from: the track (RTK and CAN), or the rig's heading
/// source with the offset `check` found for it.
pub(super) fn heading_from(check: &Report) -> String {
    match &check.heading_source {
        None => "track (RTK, CAN)".into(),
        Some(h) => format!(
            "{}: {} reports, offset {}° ± {}°",
            h.source.name(),
            h.used,
            fixed(h.offset_deg, 3),
            fixed(h.offset_sigma_deg, 3)
        ),
    }
}

/// Counts of green, yellow, red and black cells of a validation.
pub fn lights(v: &Validation) -> [usize; 4] {
    let mut n = [0; 4];
    for c in &v.cells {
        n[match c.light {
            Light::Green => 0,
            Light::Yellow => 1,
            Light::Red => 2,
            Light::Black => 3,
        }] += 1;
    }
    n
}

pub(super) fn range_of(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    Some((lo - pad, hi + pad))
}

/// Draws a chart's legend at `pos` in the report's one style.
pub(super) fn legend<'a, CT: CoordTranslate>(
    c: &mut ChartContext<'a, SVGBackend<'a>, CT>,
    pos: SeriesLabelPosition,
) -> Result<(), PlotError> {
    c.configure_series_labels()
        .position(pos)
        .border_style(GREY)
        .background_style(WHITE.mix(0.9))
        .draw()
}

/// Draws into an SVG string of `w` x `h` pixels; `None` when drawing fails (it only fails on
/// a plotters error, which the report shows as a missing figure with a note).
pub(super) fn svg(
    w: u32,
    h: u32,
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<(), PlotError>,
) -> Option<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (w, h)).into_drawing_area();
        root.fill(&WHITE).ok()?;
        if let Err(e) = draw(&root) {
            tracing::warn!("report plot: {e}");
            return None;
        }
        root.present().ok()?;
    }
    Some(out)
}

/// Why a plot could not be drawn (plotters' error for an SVG drawn into a string).
pub(super) type PlotError = plotters::drawing::DrawingAreaErrorKind<std::io::Error>;

/// The check's timeline: the RTK state and horizontal sigma per GNSS epoch, the verdict of
/// each one-second segment, and the located faults.
pub fn check_timeline(check: &Report) -> Option<String> {
    let epochs = &check.spatial.rtk_epochs;
    if epochs.is_empty() && check.segments.is_empty() {
        return None;
    }
    let duration = Some(check.duration_s).filter(|d| d.is_finite())?.max(1e-3);
    let sigmas: Vec<(f64, f64)> = epochs
        .iter()
        .filter_map(|e| Some((e.t_s, e.sigma_horizontal_m?)))
        .collect();
    let trajectory = Some(check.accuracy.trajectory_m).filter(|x| x.is_finite());
    let top = sigmas
        .iter()
        .map(|s| s.1)
        .fold(0.0f64, f64::max)
        .max(trajectory.unwrap_or(0.01))
        * 1.3;
    svg(1000, 330, |root| {
        let (upper, lower) = root.split_vertically(200);
        let mut c = ChartBuilder::on(&upper)
            .margin(8)
            .x_label_area_size(22)
            .y_label_area_size(60)
            .caption(
                "GNSS horizontal sigma (1σ) and RTK state per epoch",
                ("sans-serif", 15),
            )
            .build_cartesian_2d(0.0..duration, 0.0..top)?;
        c.configure_mesh()
            .y_desc("sigma, m")
            .x_labels(12)
            .light_line_style(WHITE)
            .draw()?;
        // RTK state as a band along the bottom of the sigma panel.
        let band = top * 0.06;
        c.draw_series(epochs.iter().map(|ep| {
            let t = ep.t_s;
            let color = match ep.state {
                RtkState::Fixed => PASS,
                RtkState::Float => FLOAT,
                RtkState::None => FAIL,
            };
            Rectangle::new([(t, 0.0), (t + 0.1, band)], color.filled())
        }))?
        .label("RTK fixed / float / none (band)")
        .legend(|(x, y)| Rectangle::new([(x, y - 4), (x + 12, y + 4)], PASS.filled()));
        c.draw_series(LineSeries::new(
            sigmas.iter().copied(),
            REAL.stroke_width(2),
        ))?
        .label("horizontal sigma")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], REAL.stroke_width(2)));
        legend(&mut c, SeriesLabelPosition::MiddleRight)?;

        let mut s = ChartBuilder::on(&lower)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .caption(
                "verdict per segment (top row) and located faults",
                ("sans-serif", 15),
            )
            .build_cartesian_2d(0.0..duration, 0.0..2.0)?;
        s.configure_mesh()
            .x_desc("seconds after the run's start")
            .y_labels(0)
            .light_line_style(WHITE)
            .draw()?;
        s.draw_series(check.segments.iter().map(|seg| {
            let color = match seg.verdict {
                Verdict::Pass => PASS,
                Verdict::Fail => FAIL,
                Verdict::Unusable => GREY,
            };
            Rectangle::new([(seg.from_s, 1.15), (seg.to_s, 1.85)], color.filled())
        }))?;
        for f in &check.faults {
            let (a, b) = (f.from_s, f.to_s);
            let b = b.max(a + duration * 0.004);
            s.draw_series(std::iter::once(Rectangle::new(
                [(a, 0.15), (b, 0.85)],
                FAIL.mix(0.8).filled(),
            )))?;
            s.draw_series(std::iter::once(Text::new(
                f.name.as_str().to_owned(),
                (a, 0.95),
                ("sans-serif", 12),
            )))?;
        }
        if check.faults.is_empty() {
            s.draw_series(std::iter::once(Text::new(
                "no faults".to_owned(),
                (duration * 0.01, 0.6),
                ("sans-serif", 12),
            )))?;
        }
        Ok(())
    })
}

/// A named curve and the admissible cell it was computed against.
type Curve<'a> = (&'a str, Vec<(f64, f64)>, f64);

/// Bird's-eye view of one scan: measured and simulated points over the scene's objects, and
/// the cells occupied by only one of them at the comparison's cell size.
pub fn birds_eye(snapshot: &Snapshot) -> Option<String> {
    let thin = |p: &[[f32; 2]]| -> Vec<(f64, f64)> {
        p.iter()
            .map(|q| (f64::from(q[0]), f64::from(q[1])))
            .collect()
    };
    let cells = |p: &[[f64; 2]]| -> Vec<(f64, f64)> { p.iter().map(|q| (q[0], q[1])).collect() };
    let (real, sim) = (thin(&snapshot.real), thin(&snapshot.sim));
    let (only_r, only_s) = (
        cells(&snapshot.only_real_cells),
        cells(&snapshot.only_sim_cells),
    );
    let cell = snapshot.cell_m;
    let all = real.iter().chain(&sim).chain(&only_r).chain(&only_s);
    let (x0, x1) = range_of(all.clone().map(|p| p.0))?;
    let (y0, y1) = range_of(all.map(|p| p.1))?;
    // Equal scales: widen the shorter side.
    let (w, h) = (x1 - x0, y1 - y0);
    let (px, py) = (900.0, 620.0);
    let scale = (w / px).max(h / py);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (x0, x1) = (cx - scale * px / 2.0, cx + scale * px / 2.0);
    let (y0, y1) = (cy - scale * py / 2.0, cy + scale * py / 2.0);
    svg(1000, 700, |root| {
        let mut c = ChartBuilder::on(root)
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .caption(
                format!(
                    "scan at {:.1} s from above: cells of {cell:.2} m occupied by only one cloud",
                    snapshot.t_s
                ),
                ("sans-serif", 15),
            )
            .build_cartesian_2d(x0..x1, y0..y1)?;
        c.configure_mesh()
            .x_desc("east, m")
            .y_desc("north, m")
            .light_line_style(WHITE)
            .draw()?;
        c.draw_series(only_r.iter().map(|&(x, y)| {
            Rectangle::new([(x, y), (x + cell, y + cell)], REAL.mix(0.25).filled())
        }))?
        .label("cell: measured only")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], REAL.mix(0.25).filled()));
        c.draw_series(
            only_s.iter().map(|&(x, y)| {
                Rectangle::new([(x, y), (x + cell, y + cell)], SIM.mix(0.3).filled())
            }),
        )?
        .label("cell: simulated only")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], SIM.mix(0.3).filled()));
        for o in &snapshot.objects {
            let (a, b) = ((o.min[0], o.min[1]), (o.max[0], o.max[1]));
            c.draw_series(std::iter::once(Rectangle::new(
                [a, b],
                BLACK.stroke_width(1),
            )))?;
            c.draw_series(std::iter::once(Text::new(
                o.name.clone(),
                (a.0, b.1 + scale * 4.0),
                ("sans-serif", 11),
            )))?;
        }
        c.draw_series(real.iter().map(|&p| Circle::new(p, 1, REAL.filled())))?
            .label("measured points")
            .legend(|(x, y)| Circle::new((x + 5, y), 3, REAL.filled()));
        c.draw_series(sim.iter().map(|&p| Circle::new(p, 1, SIM.filled())))?
            .label("simulated points")
            .legend(|(x, y)| Circle::new((x + 5, y), 3, SIM.filled()));
        if let Some([x, y]) = snapshot.sensor {
            c.draw_series(std::iter::once(TriangleMarker::new(
                (x, y),
                7,
                BLACK.filled(),
            )))?
            .label("sensor")
            .legend(|(x, y)| TriangleMarker::new((x + 5, y), 5, BLACK.filled()));
        }
        legend(&mut c, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// One panel of a stacked series plot: its label and (x, y) points.
type Panel = (&'static str, Vec<(f64, f64)>);

/// Rosenberger et al. 2019, Fig. 5: OCR, objects in view, ego speed and mean distance to the
/// objects along the drive, one panel each over a common time axis.
pub fn fig5(compare: &Comparison) -> Option<String> {
    let scans = &compare.scans;
    let series = |f: &dyn Fn(&ScanRow) -> Option<f64>| -> Vec<(f64, f64)> {
        scans
            .iter()
            .filter_map(|s| Some((s.t_s, f(s)?)))
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect()
    };
    let panels: [Panel; 4] = [
        ("OCR^K", series(&|s| s.grid.as_ref()?.ocr)),
        (
            "objects in view",
            series(&|s| Some(s.objects_in_view as f64)),
        ),
        ("ego speed, m/s", series(&|s| Some(s.ego_speed_mps))),
        (
            "mean distance to objects, m",
            series(&|s| s.mean_distance_m),
        ),
    ];
    let t1 = scans
        .iter()
        .map(|s| s.t_s)
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max);
    if t1 <= 0.0 {
        return None;
    }
    svg(1000, 640, |root| {
        let areas = root.split_evenly((4, 1));
        for (k, ((label, pts), area)) in panels.iter().zip(&areas).enumerate() {
            let (lo, hi) = range_of(pts.iter().map(|p| p.1)).unwrap_or((0.0, 1.0));
            let lo = if k == 0 {
                lo.clamp(-0.05, 0.0)
            } else {
                lo.min(0.0)
            };
            let mut c = ChartBuilder::on(area)
                .margin(6)
                .x_label_area_size(if k == 3 { 28 } else { 14 })
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..t1, lo..hi)?;
            let mut mesh = c.configure_mesh();
            mesh.y_desc(*label).y_labels(4).light_line_style(WHITE);
            if k == 3 {
                mesh.x_desc("seconds after the first scan");
            }
            mesh.draw()?;
            let color = if k == 0 { REAL } else { BLACK };
            c.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))?;
        }
        Ok(())
    })
}

/// OCR against the cell size (the calibration curve), the admissible cell marked.
pub fn calibration_curve(compares: &[(&str, &Comparison)]) -> Option<String> {
    let curves: Vec<Curve> = compares
        .iter()
        .filter_map(|(name, c)| {
            let pts: Vec<(f64, f64)> = c
                .calibration
                .iter()
                .filter_map(|p| Some((p.cell_m, p.ocr_mean?)))
                .collect();
            (!pts.is_empty()).then_some((*name, pts, c.admissible_cell_m))
        })
        .collect();
    let x1 = curves
        .iter()
        .flat_map(|c| c.1.iter().map(|p| p.0))
        .fold(0.0, f64::max)
        * 1.05;
    let adm = curves.first()?.2;
    let curves: Vec<(&str, Vec<(f64, f64)>)> = curves
        .into_iter()
        .map(|(name, pts, _)| (name, pts))
        .collect();
    ocr_lines(
        Some("mean OCR^K over the scans against the cell size"),
        "cell size, m",
        &curves,
        x1,
        SeriesLabelPosition::LowerRight,
        |c| {
            c.draw_series(std::iter::once(PathElement::new(
                vec![(adm, 0.0), (adm, 1.0)],
                FAIL.stroke_width(2),
            )))?
            .label(format!("admissible cell {adm:.2} m (smaller: refused)"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], FAIL.stroke_width(2)));
            Ok(())
        },
    )
}

/// The chart an OCR^K plot is drawn on: x from 0, OCR^K from 0 to 1.
pub(super) type OcrChart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// OCR^K against `x` (0 to `x1`), one line with its points per named series in the report's
/// colours; `more` draws after them, before the legend. `None` without series.
pub(super) fn ocr_lines(
    caption: Option<&str>,
    x_desc: &str,
    series: &[(&str, Vec<(f64, f64)>)],
    x1: f64,
    legend_at: SeriesLabelPosition,
    more: impl FnOnce(&mut OcrChart) -> Result<(), PlotError>,
) -> Option<String> {
    if series.is_empty() {
        return None;
    }
    let colors = [REAL, SIM, PASS, BLACK];
    svg(1000, 380, |root| {
        let mut b = ChartBuilder::on(root);
        b.margin(10).x_label_area_size(32).y_label_area_size(55);
        if let Some(text) = caption {
            b.caption(text, ("sans-serif", 15));
        }
        let mut c = b.build_cartesian_2d(0.0..x1, 0.0..1.0)?;
        c.configure_mesh()
            .x_desc(x_desc)
            .y_desc("OCR^K")
            .light_line_style(WHITE)
            .draw()?;
        for (k, (name, pts)) in series.iter().enumerate() {
            let color = colors[k % colors.len()];
            c.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 14, y)], color.stroke_width(2))
                });
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        }
        more(&mut c)?;
        legend(&mut c, legend_at)?;
        Ok(())
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::reference::check::{Fault, FaultName, RtkEpoch, Segment};
    use hilrig_stamp::UtcNanos;

    /// A check report as `check` builds it, with the segments, epochs and faults given.
    pub(crate) fn report(duration_s: f64, segments: &[(f64, f64, Verdict)]) -> Report {
        Report {
            verdict: Verdict::Pass,
            unusable: None,
            start: String::new(),
            duration_s,
            spatial: Default::default(),
            temporal: Default::default(),
            accuracy: Default::default(),
            faults: Vec::new(),
            marks: Vec::new(),
            warnings: Vec::new(),
            segments: segments
                .iter()
                .map(|&(from_s, to_s, verdict)| Segment {
                    from_s,
                    to_s,
                    verdict,
                    reasons: Vec::new(),
                })
                .collect(),
            damage: None,
            heading_source: None,
            travel: Default::default(),
        }
    }

    /// Usable is the passing segments' share of the run: 2 s marked and 1 s failing of 10 s
    /// leave 70 %; a run without duration has none.
    #[test]
    fn the_usable_share_counts_passing_segments_only() {
        let check = report(
            10.0,
            &[
                (0.0, 2.0, Verdict::Unusable),
                (2.0, 6.0, Verdict::Pass),
                (6.0, 7.0, Verdict::Fail),
                (7.0, 10.0, Verdict::Pass),
            ],
        );
        assert!((usable_percent(&check).unwrap() - 70.0).abs() < 1e-9);
        assert_eq!(usable_percent(&report(0.0, &[])), None);
    }

    /// A run without a heading source took its heading from the track; one with names the
    /// message, the reports used and the offset found.
    #[test]
    fn the_heading_column_names_its_source() {
        let mut check = report(10.0, &[]);
        assert_eq!(heading_from(&check), "track (RTK, CAN)");
        check.heading_source = Some(crate::reference::check::report::HeadingReport {
            source: crate::rig::HeadingSource::Ths,
            used: 412,
            not_measured: 0,
            untimed: 0,
            invalid: 0,
            malformed_gnss: 0,
            sigma_deg: 0.05,
            yaw_offset_rig_deg: 0.0,
            yaw_offset_sigma_rig_deg: None,
            offset_deg: Some(1.2034),
            offset_sigma_deg: Some(0.0051),
            rms_normalized: None,
            beyond_3_sigma: 0,
        });
        assert_eq!(
            heading_from(&check),
            "THS: 412 reports, offset 1.203° ± 0.005°"
        );
    }

    #[test]
    fn a_plot_is_an_svg_with_its_labels_as_text() {
        let mut check = report(
            10.0,
            &[(0.0, 4.0, Verdict::Pass), (4.0, 6.0, Verdict::Fail)],
        );
        let epoch = |t_s, state, sigma| RtkEpoch {
            time: String::new(),
            state,
            t_s,
            sigma_horizontal_m: Some(sigma),
        };
        check.spatial.rtk_epochs = vec![
            epoch(0.0, RtkState::Fixed, 0.01),
            epoch(5.0, RtkState::Float, 0.2),
            epoch(9.9, RtkState::Fixed, 0.01),
        ];
        check.accuracy.trajectory_m = 0.01;
        check.faults = vec![Fault {
            name: FaultName::RtkFloat,
            topics: Vec::new(),
            from: String::new(),
            to: String::new(),
            from_s: 4.9,
            to_s: 5.1,
            detail: String::new(),
            from_ns: UtcNanos(0),
            to_ns: UtcNanos(0),
        }];
        let s = check_timeline(&check).expect("drawn");
        assert!(s.starts_with("<svg"), "{}", &s[..40]);
        assert!(s.contains("rtk_float") && s.contains("sigma, m"));
        // Nothing to draw: no figure, not an empty one.
        assert!(check_timeline(&report(10.0, &[])).is_none());
    }
}
