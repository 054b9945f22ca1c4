//! The report's plots, drawn in Rust as SVG text with plotters: no browser script draws them,
//! so the HTML holds the figures themselves and opens anywhere, offline.
//!
//! Each function takes the JSON a command wrote (read as [`serde_json::Value`], so that a
//! report can be built from older or newer files with missing fields shown as gaps) and
//! returns one `<svg>` element, or `None` when the input has nothing to draw.

use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::Value;

/// Measured data (a dark blue).
pub const REAL: RGBColor = RGBColor(31, 86, 160);
/// Simulated data (an orange).
pub const SIM: RGBColor = RGBColor(222, 119, 26);
pub(super) const GREY: RGBColor = RGBColor(150, 150, 150);
pub(super) const PASS: RGBColor = RGBColor(60, 160, 80);
pub(super) const FAIL: RGBColor = RGBColor(200, 50, 40);
const FLOAT: RGBColor = RGBColor(235, 180, 40);

/// A number at `path`, if it is one.
pub fn num(v: &Value, path: &[&str]) -> Option<f64> {
    let mut cur = v;
    for k in path {
        cur = cur.get(k)?;
    }
    cur.as_f64()
}

/// The string at `key`, or "".
pub(super) fn text<'a>(v: &'a Value, key: &str) -> &'a str {
    v.get(key).and_then(Value::as_str).unwrap_or("")
}

/// `x` with `d` decimals, or a dash where there is no finite number.
pub(super) fn fixed(x: Option<f64>, d: usize) -> String {
    x.filter(|x| x.is_finite())
        .map_or_else(|| "–".into(), |x| format!("{x:.d$}"))
}

/// The share of a checked run that its segments call usable, %: marked and failing stretches
/// are left out of the metrics, so this is what the run contributes.
pub(super) fn usable_percent(check: &Value) -> Option<f64> {
    let usable: f64 = arr(check, "segments")
        .iter()
        .filter(|g| text(g, "verdict") == "pass")
        .filter_map(|g| Some(num(g, &["to_s"])? - num(g, &["from_s"])?))
        .sum();
    num(check, &["duration_s"])
        .filter(|&d| d > 0.0)
        .map(|d| 100.0 * usable / d)
}

/// Where a checked run's heading came from: the track (RTK and CAN), or the rig's heading
/// source with the offset `check` found for it.
pub(super) fn heading_from(check: &Value) -> String {
    match check.get("heading_source").filter(|h| !h.is_null()) {
        None => "track (RTK, CAN)".into(),
        Some(h) => format!(
            "{}: {} reports, offset {}° ± {}°",
            text(h, "source"),
            fixed(num(h, &["used"]), 0),
            fixed(num(h, &["offset_deg"]), 3),
            fixed(num(h, &["offset_sigma_deg"]), 3)
        ),
    }
}

/// Counts of green, yellow, red and black cells in a `validate` JSON.
pub fn lights(v: &Value) -> [usize; 4] {
    let mut n = [0; 4];
    for c in arr(v, "cells") {
        match text(c, "light") {
            "green" => n[0] += 1,
            "yellow" => n[1] += 1,
            "red" => n[2] += 1,
            "black" => n[3] += 1,
            _ => {}
        }
    }
    n
}

pub(super) fn arr<'a>(v: &'a Value, key: &str) -> &'a [Value] {
    v.get(key)
        .and_then(Value::as_array)
        .map_or(&[], Vec::as_slice)
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
pub(super) fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    c: &mut ChartContext<'a, DB, CT>,
    pos: SeriesLabelPosition,
) -> Result<(), String> {
    c.configure_series_labels()
        .position(pos)
        .border_style(GREY)
        .background_style(WHITE.mix(0.9))
        .draw()
        .map_err(e)
}

/// Draws into an SVG string of `w` x `h` pixels; `None` when drawing fails (it only fails on
/// a plotters error, which the report shows as a missing figure with a note).
pub(super) fn svg(
    w: u32,
    h: u32,
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<(), String>,
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

pub(super) fn e<E: std::fmt::Debug>(x: E) -> String {
    format!("{x:?}")
}

/// The check's timeline: the RTK state and horizontal sigma per GNSS epoch, the verdict of
/// each one-second segment, and the located faults.
pub fn check_timeline(check: &Value) -> Option<String> {
    let epochs = arr(check.get("spatial")?, "rtk_epochs");
    let duration = num(check, &["duration_s"])?.max(1e-3);
    let sigmas: Vec<(f64, f64)> = epochs
        .iter()
        .filter_map(|e| Some((num(e, &["t_s"])?, num(e, &["sigma_horizontal_m"])?)))
        .collect();
    let top = sigmas
        .iter()
        .map(|s| s.1)
        .fold(0.0f64, f64::max)
        .max(num(check, &["accuracy", "trajectory_m"]).unwrap_or(0.01))
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
            .build_cartesian_2d(0.0..duration, 0.0..top)
            .map_err(e)?;
        c.configure_mesh()
            .y_desc("sigma, m")
            .x_labels(12)
            .light_line_style(WHITE)
            .draw()
            .map_err(e)?;
        // RTK state as a band along the bottom of the sigma panel.
        let band = top * 0.06;
        c.draw_series(epochs.iter().filter_map(|ep| {
            let t = num(ep, &["t_s"])?;
            let color = match ep.get("state")?.as_str()? {
                "fixed" => PASS,
                "float" => FLOAT,
                _ => FAIL,
            };
            Some(Rectangle::new([(t, 0.0), (t + 0.1, band)], color.filled()))
        }))
        .map_err(e)?
        .label("RTK fixed / float / none (band)")
        .legend(|(x, y)| Rectangle::new([(x, y - 4), (x + 12, y + 4)], PASS.filled()));
        c.draw_series(LineSeries::new(
            sigmas.iter().copied(),
            REAL.stroke_width(2),
        ))
        .map_err(e)?
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
            .build_cartesian_2d(0.0..duration, 0.0..2.0)
            .map_err(e)?;
        s.configure_mesh()
            .x_desc("seconds after the run's start")
            .y_labels(0)
            .light_line_style(WHITE)
            .draw()
            .map_err(e)?;
        s.draw_series(arr(check, "segments").iter().filter_map(|seg| {
            let (a, b) = (num(seg, &["from_s"])?, num(seg, &["to_s"])?);
            let color = match seg.get("verdict")?.as_str()? {
                "pass" => PASS,
                "fail" => FAIL,
                _ => GREY,
            };
            Some(Rectangle::new([(a, 1.15), (b, 1.85)], color.filled()))
        }))
        .map_err(e)?;
        for f in arr(check, "faults") {
            let (Some(a), Some(b)) = (num(f, &["from_s"]), num(f, &["to_s"])) else {
                continue;
            };
            let b = b.max(a + duration * 0.004);
            s.draw_series(std::iter::once(Rectangle::new(
                [(a, 0.15), (b, 0.85)],
                FAIL.mix(0.8).filled(),
            )))
            .map_err(e)?;
            let name = f.get("name").and_then(Value::as_str).unwrap_or("fault");
            s.draw_series(std::iter::once(Text::new(
                name.to_owned(),
                (a, 0.95),
                ("sans-serif", 12),
            )))
            .map_err(e)?;
        }
        if arr(check, "faults").is_empty() {
            s.draw_series(std::iter::once(Text::new(
                "no faults".to_owned(),
                (duration * 0.01, 0.6),
                ("sans-serif", 12),
            )))
            .map_err(e)?;
        }
        Ok(())
    })
}

/// An object's name and footprint (two corners, east and north).
type Footprint = (String, (f64, f64), (f64, f64));

/// A named curve and the admissible cell it was computed against.
type Curve<'a> = (&'a str, Vec<(f64, f64)>, f64);

/// Bird's-eye view of one scan: measured and simulated points over the scene's objects, and
/// the cells occupied by only one of them at the comparison's cell size.
pub fn birds_eye(snapshot: &Value) -> Option<String> {
    let pts = |k: &str| -> Vec<(f64, f64)> {
        arr(snapshot, k)
            .iter()
            .filter_map(|p| Some((p.get(0)?.as_f64()?, p.get(1)?.as_f64()?)))
            .collect()
    };
    let (real, sim) = (pts("real"), pts("sim"));
    let (only_r, only_s) = (pts("only_real_cells"), pts("only_sim_cells"));
    let cell = num(snapshot, &["cell_m"])?;
    let objects: Vec<Footprint> = arr(snapshot, "objects")
        .iter()
        .filter_map(|o| {
            let n = o.get(0)?.as_str()?.to_owned();
            let a = o.get(1)?;
            let b = o.get(2)?;
            Some((
                n,
                (a.get(0)?.as_f64()?, a.get(1)?.as_f64()?),
                (b.get(0)?.as_f64()?, b.get(1)?.as_f64()?),
            ))
        })
        .collect();
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
                    num(snapshot, &["t_s"]).unwrap_or(0.0)
                ),
                ("sans-serif", 15),
            )
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        c.configure_mesh()
            .x_desc("east, m")
            .y_desc("north, m")
            .light_line_style(WHITE)
            .draw()
            .map_err(e)?;
        c.draw_series(only_r.iter().map(|&(x, y)| {
            Rectangle::new([(x, y), (x + cell, y + cell)], REAL.mix(0.25).filled())
        }))
        .map_err(e)?
        .label("cell: measured only")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], REAL.mix(0.25).filled()));
        c.draw_series(
            only_s.iter().map(|&(x, y)| {
                Rectangle::new([(x, y), (x + cell, y + cell)], SIM.mix(0.3).filled())
            }),
        )
        .map_err(e)?
        .label("cell: simulated only")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], SIM.mix(0.3).filled()));
        for (name, a, b) in &objects {
            c.draw_series(std::iter::once(Rectangle::new(
                [*a, *b],
                BLACK.stroke_width(1),
            )))
            .map_err(e)?;
            c.draw_series(std::iter::once(Text::new(
                name.clone(),
                (a.0, b.1 + scale * 4.0),
                ("sans-serif", 11),
            )))
            .map_err(e)?;
        }
        c.draw_series(real.iter().map(|&p| Circle::new(p, 1, REAL.filled())))
            .map_err(e)?
            .label("measured points")
            .legend(|(x, y)| Circle::new((x + 5, y), 3, REAL.filled()));
        c.draw_series(sim.iter().map(|&p| Circle::new(p, 1, SIM.filled())))
            .map_err(e)?
            .label("simulated points")
            .legend(|(x, y)| Circle::new((x + 5, y), 3, SIM.filled()));
        if let Some(s) = snapshot.get("sensor").and_then(Value::as_array) {
            if let (Some(x), Some(y)) = (
                s.first().and_then(Value::as_f64),
                s.get(1).and_then(Value::as_f64),
            ) {
                c.draw_series(std::iter::once(TriangleMarker::new(
                    (x, y),
                    7,
                    BLACK.filled(),
                )))
                .map_err(e)?
                .label("sensor")
                .legend(|(x, y)| TriangleMarker::new((x + 5, y), 5, BLACK.filled()));
            }
        }
        legend(&mut c, SeriesLabelPosition::UpperRight)?;
        Ok(())
    })
}

/// One panel of a stacked series plot: its label and (x, y) points.
type Panel = (&'static str, Vec<(f64, f64)>);

/// Rosenberger et al. 2019, Fig. 5: OCR, objects in view, ego speed and mean distance to the
/// objects along the drive, one panel each over a common time axis.
pub fn fig5(compare: &Value) -> Option<String> {
    let scans = arr(compare, "scans");
    let series = |f: &dyn Fn(&Value) -> Option<f64>| -> Vec<(f64, f64)> {
        scans
            .iter()
            .filter_map(|s| Some((num(s, &["t_s"])?, f(s)?)))
            .collect()
    };
    let panels: [Panel; 4] = [
        ("OCR^K", series(&|s| num(s, &["grid", "ocr"]))),
        ("objects in view", series(&|s| num(s, &["objects_in_view"]))),
        ("ego speed, m/s", series(&|s| num(s, &["ego_speed_mps"]))),
        (
            "mean distance to objects, m",
            series(&|s| num(s, &["mean_distance_m"])),
        ),
    ];
    let t1 = scans
        .iter()
        .filter_map(|s| num(s, &["t_s"]))
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
                .build_cartesian_2d(0.0..t1, lo..hi)
                .map_err(e)?;
            let mut mesh = c.configure_mesh();
            mesh.y_desc(*label).y_labels(4).light_line_style(WHITE);
            if k == 3 {
                mesh.x_desc("seconds after the first scan");
            }
            mesh.draw().map_err(e)?;
            let color = if k == 0 { REAL } else { BLACK };
            c.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
                .map_err(e)?;
        }
        Ok(())
    })
}

/// OCR against the cell size (the calibration curve), the admissible cell marked.
pub fn calibration_curve(compares: &[(&str, &Value)]) -> Option<String> {
    let curves: Vec<Curve> = compares
        .iter()
        .filter_map(|(name, c)| {
            let pts: Vec<(f64, f64)> = arr(c, "calibration")
                .iter()
                .filter_map(|p| Some((num(p, &["cell_m"])?, num(p, &["ocr_mean"])?)))
                .collect();
            (!pts.is_empty()).then(|| (*name, pts, num(c, &["admissible_cell_m"]).unwrap_or(0.0)))
        })
        .collect();
    let x1 = curves
        .iter()
        .flat_map(|c| c.1.iter().map(|p| p.0))
        .fold(0.0, f64::max)
        * 1.05;
    if curves.is_empty() {
        return None;
    }
    let colors = [REAL, SIM, PASS, BLACK];
    svg(1000, 380, |root| {
        let mut c = ChartBuilder::on(root)
            .margin(10)
            .x_label_area_size(32)
            .y_label_area_size(55)
            .caption(
                "mean OCR^K over the scans against the cell size",
                ("sans-serif", 15),
            )
            .build_cartesian_2d(0.0..x1, 0.0..1.0)
            .map_err(e)?;
        c.configure_mesh()
            .x_desc("cell size, m")
            .y_desc("OCR^K")
            .light_line_style(WHITE)
            .draw()
            .map_err(e)?;
        for (k, (name, pts, _)) in curves.iter().enumerate() {
            let color = colors[k % colors.len()];
            c.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
                .map_err(e)?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 14, y)], color.stroke_width(2))
                });
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(e)?;
        }
        let adm = curves[0].2;
        c.draw_series(std::iter::once(PathElement::new(
            vec![(adm, 0.0), (adm, 1.0)],
            FAIL.stroke_width(2),
        )))
        .map_err(e)?
        .label(format!("admissible cell {adm:.2} m (smaller: refused)"))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], FAIL.stroke_width(2)));
        legend(&mut c, SeriesLabelPosition::LowerRight)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Usable is the passing segments' share of the run: 2 s marked and 1 s failing of 10 s
    /// leave 70 %; a run without duration has none.
    #[test]
    fn the_usable_share_counts_passing_segments_only() {
        let check = serde_json::json!({"duration_s": 10.0, "segments": [
            {"from_s": 0.0, "to_s": 2.0, "verdict": "unusable"},
            {"from_s": 2.0, "to_s": 6.0, "verdict": "pass"},
            {"from_s": 6.0, "to_s": 7.0, "verdict": "fail"},
            {"from_s": 7.0, "to_s": 10.0, "verdict": "pass"}]});
        assert!((usable_percent(&check).unwrap() - 70.0).abs() < 1e-9);
        assert_eq!(
            usable_percent(&serde_json::json!({"verdict": "unusable"})),
            None
        );
    }

    /// A run without a heading source took its heading from the track; one with names the
    /// message, the reports used and the offset found.
    #[test]
    fn the_heading_column_names_its_source() {
        use serde_json::json;
        assert_eq!(
            heading_from(&json!({"heading_source": null})),
            "track (RTK, CAN)"
        );
        assert_eq!(heading_from(&json!({})), "track (RTK, CAN)");
        let h = json!({"heading_source": {"source": "THS", "used": 412,
            "offset_deg": 1.2034, "offset_sigma_deg": 0.0051}});
        assert_eq!(heading_from(&h), "THS: 412 reports, offset 1.203° ± 0.005°");
    }

    #[test]
    fn a_plot_is_an_svg_with_its_labels_as_text() {
        let check = serde_json::json!({
            "duration_s": 10.0,
            "spatial": {"rtk_epochs": [
                {"t_s": 0.0, "state": "fixed", "sigma_horizontal_m": 0.01},
                {"t_s": 5.0, "state": "float", "sigma_horizontal_m": 0.2},
                {"t_s": 9.9, "state": "fixed", "sigma_horizontal_m": 0.01}
            ]},
            "accuracy": {"trajectory_m": 0.01},
            "segments": [{"from_s": 0.0, "to_s": 4.0, "verdict": "pass"},
                         {"from_s": 4.0, "to_s": 6.0, "verdict": "fail"}],
            "faults": [{"name": "rtk_float", "from_s": 4.9, "to_s": 5.1}]
        });
        let s = check_timeline(&check).expect("drawn");
        assert!(s.starts_with("<svg"), "{}", &s[..40]);
        assert!(s.contains("rtk_float") && s.contains("sigma, m"));
        // Nothing to draw: no figure, not an empty one.
        assert!(check_timeline(&serde_json::json!({})).is_none());
        assert!(fig5(&serde_json::json!({"scans": []})).is_none());
    }
}
