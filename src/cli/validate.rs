//! `hilrig validate`: statistical validation over repetitions (Rosenberger et al. 2019, §8,
//! Fig. 6 stage 5 and Fig. 7): real repetitions against their re-simulations, per phase and
//! metric, as traffic lights with the area validation metric. Exit 0 valid, 1 partly valid or
//! invalid, 2 not evaluable or bad input.

use anyhow::{Context, Result};
use hilrig::stats::avm::Light;
use hilrig::stats::repetitions::validate;
use hilrig::stats::validate::{Phase, Verdict};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct ValidateArgs {
    /// A real repetition (.mcap); give one per repetition.
    #[arg(long = "real", required = true)]
    real: Vec<PathBuf>,
    /// A re-simulation of one of them; give one per repetition.
    #[arg(long = "sim", required = true)]
    sim: Vec<PathBuf>,
    /// Named phases (TOML `[[phase]]` with name, from_s, to_s after each run's first scan);
    /// default: the whole run is one sample.
    #[arg(long)]
    phases: Option<PathBuf>,
    /// The rig file; default: the one attached to the first real run.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Also write everything as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PhaseFile {
    phase: Vec<Phase>,
}

pub fn run(args: ValidateArgs) -> Result<ExitCode> {
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("error: {e}");
        Ok(ExitCode::from(2))
    };
    let phases = match &args.phases {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            if let Err(e) = hilrig::config::check_finite(&text) {
                return fail(&format!("{}: {e}", p.display()));
            }
            match toml::from_str::<PhaseFile>(&text) {
                Ok(f) => f.phase,
                Err(e) => return fail(&format!("{}: {e}", p.display())),
            }
        }
        None => Vec::new(),
    };
    let rig = args
        .rig
        .as_ref()
        .map(|p| hilrig::rig::Rig::load(p))
        .transpose()?;
    let v = match validate(&args.real, &args.sim, rig.as_ref(), &phases) {
        Ok(v) => v,
        Err(e) => return fail(&e),
    };
    for d in &v.damage {
        eprintln!("warning: {d}");
    }
    println!("1 measurement validation: each simulation against its real twin");
    for p in &v.measurement {
        println!(
            "  {} <- {} ({} scans shared, simulated mean range {} the measured by {} m)",
            p.sim,
            p.real.as_deref().unwrap_or("NO REAL RUN"),
            p.shared_scans,
            if p.mean_range_difference_m.unwrap_or(0.0) >= 0.0 {
                "above"
            } else {
                "below"
            },
            p.mean_range_difference_m
                .map_or("n/a".into(), |d| format!("{:.3}", d.abs()))
        );
    }
    println!(
        "2 scenario validation: {}",
        if v.scenario_problems.is_empty() {
            "every repetition covers every sample".to_owned()
        } else {
            v.scenario_problems.join("; ")
        }
    );
    println!("3 model validation (1 green: simulated interval inside the real one, 2 yellow: overlapping, 3 red: disjoint):");
    println!(
        "  {:<12} {:<18} {:>21} {:>21} {:>7} {:>10}",
        "sample", "metric", "real", "simulated", "light", "AVM"
    );
    let iv = |i: Option<(f64, f64)>| i.map_or("n/a".into(), |(a, b)| format!("{a:.3} .. {b:.3}"));
    for c in &v.cells {
        let light = match c.light {
            Light::Green => "1 green",
            Light::Yellow => "2 yellow",
            Light::Red => "3 red",
            Light::Black => "black",
        };
        println!(
            "  {:<12} {:<18} {:>21} {:>21} {:>7} {:>10}{}",
            c.sample,
            c.metric,
            iv(c.real_interval),
            iv(c.sim_interval),
            light,
            c.avm.map_or("n/a".into(), |a| format!("{a:.4}")),
            c.why_black
                .as_ref()
                .map_or(String::new(), |w| format!("  ({w})"))
        );
    }
    println!("verdict: {:?}", v.verdict);
    if let Some(j) = &args.json {
        hilrig::output::write(j, &v)?;
    }
    Ok(ExitCode::from(match v.verdict {
        Verdict::Valid => 0,
        Verdict::PartlyValid | Verdict::Invalid => 1,
        Verdict::NotEvaluable => 2,
    }))
}
