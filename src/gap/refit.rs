//! The joint re-fit: when the workflow adds an effect, the effects it added before are fitted
//! again with the new one in the model, in turn, until no parameter moves. Two effects that
//! explain one disagreement (a detection threshold and random dropout both remove returns)
//! share it out only when they are fitted together; the one fitted first would otherwise keep
//! what it took before the other came.

use super::candidates::{with_effect, Candidate, Fitting, Param};
use super::report::Refit;
use super::runset::RunSet;
use super::GapError;
use crate::sim::model::{EffectKind, ModelFile};

/// An effect the workflow added, with its parameters as they stand.
#[derive(Clone, Debug)]
pub(super) struct Added {
    pub(super) kind: EffectKind,
    pub(super) params: Vec<Param>,
}

/// Passes of the joint re-fit at most: each re-fits every added effect in turn. Two effects
/// that share a disagreement settle in two or three.
const REFIT_PASSES: usize = 3;

/// A parameter has settled when a pass moves it by less than this share of its value.
const REFIT_TOLERANCE: f64 = 0.01;

/// Whether two fits of one effect differ beyond [`REFIT_TOLERANCE`] in any parameter.
fn moved(a: &[Param], b: &[Param]) -> bool {
    a.len() != b.len()
        || a.iter().zip(b).any(|(x, y)| {
            (x.value - y.value).abs() > REFIT_TOLERANCE * x.value.abs().max(y.value.abs()).max(1e-9)
        })
}

/// `model` without the effect `kind`.
fn without(model: &ModelFile, kind: EffectKind) -> ModelFile {
    let mut m = model.clone();
    m.effects.retain(|e| e.kind() != kind);
    m
}

/// The joint re-fit (Rosenberger et al. 2019, §7: a model's parameters are identified
/// together): `model` holds the new candidate's effect; every effect the workflow `added`
/// before, and then the new one, is fitted again on the parameterization runs with all the
/// others in the model, in turn, until no parameter moves (or [`REFIT_PASSES`]). Motion
/// distortion, a switch, has nothing to re-fit. Returns the jointly fitted model, the new
/// effect's parameters and what changed for the others.
pub(super) fn joint_refit(
    fit: &RunSet,
    model: ModelFile,
    new: &Candidate,
    added: &[Added],
) -> Result<(ModelFile, Vec<Param>, Vec<Refit>), GapError> {
    let others: Vec<&Added> = added
        .iter()
        .filter(|a| a.kind != new.effect && a.kind != EffectKind::MotionDistortion)
        .collect();
    let mut params: Vec<(EffectKind, Vec<Param>, bool)> = others
        .iter()
        .map(|a| (a.kind, a.params.clone(), true))
        .chain([(new.effect, new.params.clone(), true)])
        .collect();
    let mut model = model;
    if others.is_empty() {
        return Ok((model, new.params.clone(), Vec::new()));
    }
    for pass in 0..REFIT_PASSES {
        let mut any_moved = false;
        for (kind, now, above) in &mut params {
            let rest = without(&model, *kind);
            let e = fit.evaluate(&rest, None)?;
            let fitting = Fitting::of(fit, &rest, &e);
            let Some(c) = fitting.fit(*kind)? else {
                continue;
            };
            let Some(effect) = c.fitted.clone() else {
                continue;
            };
            any_moved |= moved(now, &c.params);
            model = c.refitted.iter().fold(with_effect(&rest, effect), |m, r| {
                with_effect(&m, r.clone())
            });
            *now = c.params;
            *above = c.above_floor;
        }
        tracing::debug!(
            "joint re-fit with {}: pass {} moved: {any_moved}",
            new.effect,
            pass + 1
        );
        if !any_moved {
            break;
        }
    }
    let new_params = params.last().map(|p| p.1.clone()).unwrap_or_default();
    let refits = others
        .iter()
        .zip(&params)
        .map(|(a, (kind, after, above))| Refit {
            effect: *kind,
            before: a.params.clone(),
            after: after.clone(),
            below_floor: !above,
        })
        .collect();
    Ok((model, new_params, refits))
}
