//! The commands' JSON outputs as tables (`hilrig table`): a row per scan of a comparison, per
//! GNSS epoch and per run of a check, per cell of a validation, per candidate tried in a gap
//! round. Every table starts with the columns `drive`, `scenario` and `model` (null where they
//! do not apply), so that the files of a whole campaign can be read as one table:
//!
//! ```sql
//! SELECT model, avg(ocr) FROM read_parquet('DIR/tables/compare_scans/*.parquet') GROUP BY model
//! ```
//!
//! Each output is read through the type that wrote it; a table is one of [`TableKind`].

use super::parquet::{Column, Table};
use crate::output::OutputKind;
use crate::report::Document;
use serde::Serialize;
use std::iter::once as one;

/// The tables there are, by what one row is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TableKind {
    /// `compare`: one row per scan pair.
    CompareScans,
    /// `check`: one row per GNSS epoch (its RTK state and stated sigma).
    CheckEpochs,
    /// `check`: one row per run (verdict and accuracy budget).
    CheckRuns,
    /// `validate`: one row per phase and metric.
    ValidateCells,
    /// `gap`: one row per candidate tried on the validation runs, per round.
    GapTrials,
}

impl TableKind {
    /// Its name: the folder its files go in.
    pub fn name(self) -> &'static str {
        match self {
            TableKind::CompareScans => "compare_scans",
            TableKind::CheckEpochs => "check_epochs",
            TableKind::CheckRuns => "check_runs",
            TableKind::ValidateCells => "validate_cells",
            TableKind::GapTrials => "gap_trials",
        }
    }

    /// The tables an output of `kind` gives.
    pub fn of(kind: OutputKind) -> &'static [TableKind] {
        match kind {
            OutputKind::Compare => &[TableKind::CompareScans],
            OutputKind::Check => &[TableKind::CheckEpochs, TableKind::CheckRuns],
            OutputKind::Validate => &[TableKind::ValidateCells],
            OutputKind::Gap => &[TableKind::GapTrials],
            OutputKind::Recording
            | OutputKind::CampaignPlan
            | OutputKind::CampaignTask
            | OutputKind::GapTrial => &[],
        }
    }
}

/// Which drive, scenario and model a file's rows are of.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Labels {
    /// The drive.
    pub drive: Option<String>,
    /// The scenario.
    pub scenario: Option<String>,
    /// The model.
    pub model: Option<String>,
}

/// An enum's spelling in the JSON outputs (snake_case).
fn word<T: Serialize>(v: &T) -> Option<String> {
    match serde_json::to_value(v) {
        Ok(serde_json::Value::String(s)) => Some(s),
        Ok(other) => Some(other.to_string()),
        Err(_) => None,
    }
}

/// Builds a table row by row: the label columns first, then the named values.
struct Rows {
    table: Table,
}

impl Rows {
    fn new(labels: &Labels, n: usize) -> Rows {
        let mut table = Table::default();
        for (name, v) in [
            ("drive", &labels.drive),
            ("scenario", &labels.scenario),
            ("model", &labels.model),
        ] {
            table.push(name, Column::Text(vec![v.clone(); n]));
        }
        Rows { table }
    }
    fn text(&mut self, name: &str, v: impl Iterator<Item = Option<String>>) -> &mut Self {
        self.table.push(name, Column::Text(v.collect()));
        self
    }
    fn int(&mut self, name: &str, v: impl Iterator<Item = Option<i64>>) -> &mut Self {
        self.table.push(name, Column::Int(v.collect()));
        self
    }
    fn real(&mut self, name: &str, v: impl Iterator<Item = Option<f64>>) -> &mut Self {
        self.table.push(name, Column::Real(v.collect()));
        self
    }
    fn flag(&mut self, name: &str, v: impl Iterator<Item = Option<bool>>) -> &mut Self {
        self.table.push(name, Column::Flag(v.collect()));
        self
    }
    fn done(self) -> Table {
        self.table
    }
}

fn int(x: usize) -> Option<i64> {
    i64::try_from(x).ok()
}

/// The table `kind` of `doc`, labelled; `None` when `doc` does not give that table.
pub fn table(doc: &Document, kind: TableKind, labels: &Labels) -> Option<Table> {
    Some(match (doc, kind) {
        (Document::Compare(c), TableKind::CompareScans) => {
            let s = &c.scans;
            let mut r = Rows::new(labels, s.len());
            r.int("scan", (0..s.len()).map(int))
                .real("t_s", s.iter().map(|x| Some(x.t_s)))
                .int("stamp_ns", s.iter().map(|x| Some(x.stamp_ns)))
                .real("cell_m", s.iter().map(|_| Some(c.cell_m)))
                .real("ego_speed_mps", s.iter().map(|x| Some(x.ego_speed_mps)))
                .int("objects_in_view", s.iter().map(|x| int(x.objects_in_view)))
                .real("mean_distance_m", s.iter().map(|x| x.mean_distance_m))
                .int("real_points", s.iter().map(|x| int(x.real_points)))
                .int("sim_points", s.iter().map(|x| int(x.sim_points)))
                .real("ocr", s.iter().map(|x| x.grid.and_then(|g| g.ocr)))
                .real(
                    "precision",
                    s.iter().map(|x| x.grid.and_then(|g| g.precision)),
                )
                .real("iou", s.iter().map(|x| x.grid.and_then(|g| g.iou)))
                .real("cosine", s.iter().map(|x| x.grid.and_then(|g| g.cosine)))
                .real("chamfer_m", s.iter().map(|x| x.points.map(|p| p.chamfer_m)))
                .real(
                    "hausdorff_m",
                    s.iter().map(|x| x.points.map(|p| p.hausdorff_m)),
                )
                .real("range_diff_mean_m", s.iter().map(|x| x.range_diff_mean_m))
                .real("range_diff_rms_m", s.iter().map(|x| x.range_diff_rms_m))
                .int("only_real", s.iter().map(|x| int(x.only_real)))
                .int("only_sim", s.iter().map(|x| int(x.only_sim)));
            r.done()
        }
        (Document::Check(c), TableKind::CheckEpochs) => {
            let e = &c.spatial.rtk_epochs;
            let mut r = Rows::new(labels, e.len());
            r.real("t_s", e.iter().map(|x| Some(x.t_s)))
                .text("time", e.iter().map(|x| Some(x.time.clone())))
                .text("rtk_state", e.iter().map(|x| word(&x.state)))
                .real("sigma_horizontal_m", e.iter().map(|x| x.sigma_horizontal_m));
            r.done()
        }
        (Document::Check(c), TableKind::CheckRuns) => {
            let a = &c.accuracy;
            let usable: f64 = c
                .segments
                .iter()
                .filter(|s| s.verdict == crate::reference::check::Verdict::Pass)
                .map(|s| s.to_s - s.from_s)
                .sum();
            let mut r = Rows::new(labels, 1);
            r.text("verdict", one(word(&c.verdict)))
                .text("start", one(Some(c.start.clone())))
                .real("duration_s", one(Some(c.duration_s)))
                .real("usable_s", one(Some(usable)))
                .int("epochs", one(int(c.spatial.epochs)))
                .real("rtk_fixed_share", one(Some(c.spatial.rtk_fixed_share)))
                .int("jumps", one(int(c.spatial.jumps)))
                .int("faults", one(int(c.faults.len())))
                .int("marks", one(int(c.marks.len())))
                .real("ego_m", one(Some(a.ego_m)))
                .real("heading_sigma_deg", one(Some(a.heading_sigma_deg)))
                .real("reference_m", one(Some(a.reference_m)))
                .real("grid_cell_m", one(Some(a.grid_cell_m)));
            r.done()
        }
        (Document::Validate(v), TableKind::ValidateCells) => {
            let c = &v.cells;
            let lo = |i: &Option<(f64, f64)>| i.map(|x| x.0);
            let hi = |i: &Option<(f64, f64)>| i.map(|x| x.1);
            let mut r = Rows::new(labels, c.len());
            r.text("sample", c.iter().map(|x| Some(x.sample.clone())))
                .text("metric", c.iter().map(|x| Some(x.metric.clone())))
                .int("repetitions", c.iter().map(|x| int(x.real.len())))
                .real("real_low", c.iter().map(|x| lo(&x.real_interval)))
                .real("real_high", c.iter().map(|x| hi(&x.real_interval)))
                .real("sim_low", c.iter().map(|x| lo(&x.sim_interval)))
                .real("sim_high", c.iter().map(|x| hi(&x.sim_interval)))
                .text("light", c.iter().map(|x| word(&x.light)))
                .real("avm", c.iter().map(|x| x.avm))
                .text("verdict", c.iter().map(|_| word(&v.verdict)));
            r.done()
        }
        (Document::Gap(g), TableKind::GapTrials) => {
            let trials: Vec<(
                usize,
                Option<crate::sim::model::EffectKind>,
                &crate::gap::report::Trial,
            )> = g
                .rounds
                .iter()
                .flat_map(|round| {
                    round
                        .trials
                        .iter()
                        .map(move |t| (round.round, round.chosen, t))
                })
                .collect();
            let mut r = Rows::new(labels, trials.len());
            r.int("round", trials.iter().map(|t| int(t.0)))
                .text(
                    "effect",
                    trials.iter().map(|t| Some(t.2.effect.name().to_owned())),
                )
                .real("gain", trials.iter().map(|t| Some(t.2.gain)))
                .real(
                    "gain_low",
                    trials.iter().map(|t| t.2.gain_interval.map(|i| i.0)),
                )
                .real(
                    "gain_high",
                    trials.iter().map(|t| t.2.gain_interval.map(|i| i.1)),
                )
                .flag("kept", trials.iter().map(|t| Some(t.2.kept)))
                .flag(
                    "chosen",
                    trials.iter().map(|t| Some(t.1 == Some(t.2.effect))),
                );
            r.done()
        }
        _ => return None,
    })
}
