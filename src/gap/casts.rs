//! Casts of the parameterization runs kept from one round to the next.
//!
//! A cast ([`evaluate`]) depends on the model only through its deterministic part
//! ([`deterministic`]: the random parts are the likelihood's, added analytically). Adding an
//! effect that is random only (range noise, dropout) leaves that part as it was, and a
//! candidate that re-fits the detection threshold casts without it; so the next round casts
//! many of the very models this one cast (on the real-size study, the 44 footprints of the
//! beam-divergence search twice over). A Lambertian intensity effect, the one the workflow
//! usually adds, changes only the predicted reflectivity, which every cast gives besides
//! ([`Obs::lambertian`]): a model with it is cast as the model without it. The same inputs give
//! the same observations, bit for bit, so a kept cast is the cast; only the time differs.
//!
//! Memory: at most [`BUDGET_BYTES`] of casts, from the round under way and those of the round
//! before that it used again, each the sample's size ([`Obs`] per sampled slot: about 17 MB
//! for the 400 k firings the real-size study's two parameterization minutes sample), whatever
//! the runs' length. When a cast does not fit, the ones quickest to cast again go first (a
//! beam-divergence footprint of 5 × 5 sub-rays takes twice as long as one of 3 × 3, and ten
//! times as long as a time offset's cast).

use super::observe::{deterministic, simulator, slot, Obs, RunData, SLOTS};
use super::GapError;
use crate::sim::lidar::{Firing, HitSlot, SimStats};
use crate::sim::model::{Effect, ModelFile};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

/// Casts every sampled firing of `run` with `model`'s deterministic part and pairs it with
/// the measured return: one [`Obs`] per slot (packet × block × channel). The first cast of the
/// run keeps its centre rays' static hits ([`RunData::sample_hits`]), and every later one
/// whose rays are the same (a model that does not move the beams: every candidate but a time
/// offset and a mount) takes them instead of traversing the scene again, bit for bit the same
/// ([`crate::sim::lidar::HitSlot`]).
pub fn evaluate(run: &RunData, model: &ModelFile) -> Result<Vec<Obs>, GapError> {
    let model = deterministic(model);
    let sim = simulator(run, &model)?;
    let cal = sim.decoder().calibration().clone();
    let kept = run.sample_hits.get();
    let mut hits: Vec<HitSlot> = (0..run.packets.len())
        .map(|i| HitSlot {
            given: kept.and_then(|k| k.get(i).cloned()).into_iter().collect(),
            keep: kept.is_none(),
            ..HitSlot::default()
        })
        .collect();
    let mut out = vec![Obs::default(); run.packets.len() * SLOTS];
    out.par_chunks_mut(SLOTS)
        .zip(run.packets.par_iter())
        .zip(hits.par_iter_mut())
        .enumerate()
        .for_each(|(i, ((slots, s), hit))| {
            let mut stats = SimStats::default();
            sim.simulate_observed_reusing(
                &s.packet,
                s.time,
                &run.trajectory,
                i as u64,
                &mut stats,
                &mut |f: &Firing| {
                    let slot = slot(f.block, f.channel);
                    let ch = s.packet.blocks[usize::from(f.block)].channels[usize::from(f.channel)];
                    let o = &mut slots[slot];
                    o.cast = true;
                    if ch.distance > 0 {
                        o.measured = cal.metres(usize::from(f.laser), ch.distance) as f32;
                        o.intensity = ch.reflectivity;
                    }
                    if let Some(e) = f.reported {
                        o.predicted = e.range as f32;
                        o.power = e.power as f32;
                        o.reflectivity = e.reflectivity as f32;
                        o.lambertian = e.lambertian as f32;
                    }
                },
                hit,
            );
        });
    if kept.is_none() {
        // Another cast of the run at the same time may have kept its own first: either is
        // the run's.
        let _ = run.sample_hits.set(
            hits.into_iter()
                .map(|h| h.kept.unwrap_or_default())
                .collect(),
        );
    }
    Ok(out)
}

/// What decides a cast: the deterministic part of the model, its limits and effects in their
/// order, each number in its exact (round-trip) form. Two models with the same key cast alike;
/// two that differ only in the order of their effects get two keys (a second cast, never a
/// wrong one).
fn key(model: &ModelFile) -> String {
    let m = deterministic(model);
    format!("{:?} {:?}", m.limits, m.effects)
}

/// `model` without a Lambertian intensity effect (incidence exponent 1), and whether it had
/// one. Such an effect changes nothing in a cast but the reflectivity it predicts, which every
/// cast also gives as the Lambertian one would ([`Obs::lambertian`], bit for bit): so a model
/// with it is cast as the model without it, and its reflectivity read from there. The round
/// after the workflow added the intensity effect (it is Lambertian unless the runs show
/// otherwise) then finds every candidate's casts of the round before, not just the random
/// effects' (on the real-size study, the 28 s of the beam-divergence search).
fn lambertian_apart(model: &ModelFile) -> (ModelFile, bool) {
    let mut m = model.clone();
    let before = m.effects.len();
    m.effects.retain(|e| {
        !matches!(
            e,
            Effect::Intensity {
                incidence_exponent,
                ..
            } if *incidence_exponent == 1.0
        )
    });
    let had = m.effects.len() != before;
    (m, had)
}

/// Observations of a cast without a Lambertian intensity effect as the model with it predicts
/// them: the reflectivity that effect reports ([`Obs::lambertian`]) in place of the bare one.
fn as_lambertian(obs: &mut [Vec<Obs>]) {
    for o in obs.iter_mut().flatten() {
        o.reflectivity = o.lambertian;
    }
}

/// Bytes of casts kept at most: with the workflow's own 0.6 GB on the real-size study, the
/// process stays near half of the 2 GiB it must fit in.
pub const BUDGET_BYTES: usize = 640 << 20;

/// A cast kept: its observations per run, what it took to cast, and whether the round under
/// way asked for it.
struct Kept {
    obs: Arc<Vec<Vec<Obs>>>,
    seconds: f64,
    used: bool,
}

impl Kept {
    fn bytes(&self) -> usize {
        self.obs
            .iter()
            .map(|o| std::mem::size_of_val(o.as_slice()))
            .sum()
    }
}

/// The casts of one set of runs, by [`key`].
#[derive(Default)]
pub struct Casts {
    kept: Mutex<HashMap<String, Kept>>,
}

impl Casts {
    /// Every run of `runs` cast with `model` (see [`evaluate`]), from a cast kept when there is
    /// one. `runs` must be the same set every time: the key does not name them.
    pub fn of(&self, runs: &[RunData], model: &ModelFile) -> Result<Vec<Vec<Obs>>, GapError> {
        let (model, lambertian) = lambertian_apart(model);
        let key = key(&model);
        let lock = || self.kept.lock().unwrap_or_else(PoisonError::into_inner);
        let kept = lock().get_mut(&key).map(|k| {
            k.used = true;
            k.obs.as_ref().clone()
        });
        let mut obs = match kept {
            Some(obs) => obs,
            None => {
                // Cast without the lock: a cast takes seconds, and uses every core itself.
                let started = std::time::Instant::now();
                let obs: Vec<Vec<Obs>> = runs
                    .iter()
                    .map(|r| evaluate(r, &model))
                    .collect::<Result<_, _>>()?;
                let new = Kept {
                    obs: Arc::new(obs.clone()),
                    seconds: started.elapsed().as_secs_f64(),
                    used: true,
                };
                keep(&mut lock(), key, new, BUDGET_BYTES);
                obs
            }
        };
        if lambertian {
            as_lambertian(&mut obs);
        }
        Ok(obs)
    }

    /// A round ends: the casts it did not ask for go (the round before cast them for its
    /// own model), the others are kept for the next one.
    pub fn next_round(&self) {
        let mut kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner);
        kept.retain(|_, k| k.used);
        for k in kept.values_mut() {
            k.used = false;
        }
    }

    /// Casts kept.
    pub fn len(&self) -> usize {
        self.kept
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len()
    }

    /// No cast kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Keeps `new` under `key` within `budget` bytes: the casts quicker to cast again than it make
/// room for it, quickest first; when they cannot make enough, nothing changes.
fn keep(kept: &mut HashMap<String, Kept>, key: String, new: Kept, budget: usize) {
    let mut total: usize = kept.values().map(Kept::bytes).sum::<usize>() + new.bytes();
    let mut quicker: Vec<(f64, String, usize)> = kept
        .iter()
        .filter(|(_, k)| k.seconds < new.seconds)
        .map(|(name, k)| (k.seconds, name.clone(), k.bytes()))
        .collect();
    if total - quicker.iter().map(|q| q.2).sum::<usize>() > budget {
        return;
    }
    quicker.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (_, name, bytes) in quicker {
        if total <= budget {
            break;
        }
        kept.remove(&name);
        total -= bytes;
    }
    kept.insert(key, new);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(effects: Vec<Effect>) -> ModelFile {
        ModelFile {
            name: "m".into(),
            description: String::new(),
            limits: None,
            effects,
        }
    }

    #[test]
    fn a_cast_is_keyed_by_what_decides_it_only() {
        let threshold = Effect::DetectionThreshold {
            reference_range_m: 57.9,
            reference_reflectivity: 0.1,
        };
        let bare = model(vec![threshold.clone()]);
        // Random parts and the name do not change what a cast gives.
        let mut noisy = model(vec![
            Effect::RangeNoise { sigma_m: 0.013 },
            threshold.clone(),
            Effect::RandomDropout { probability: 0.003 },
        ]);
        noisy.name = "m (gap-fitted)".into();
        assert_eq!(key(&bare), key(&noisy));
        // A deterministic parameter does, to its last digit.
        let moved = model(vec![Effect::DetectionThreshold {
            reference_range_m: 57.900_000_000_000_01,
            reference_reflectivity: 0.1,
        }]);
        assert_ne!(key(&bare), key(&moved));
        assert_ne!(key(&bare), key(&model(Vec::new())));
        let limited = ModelFile {
            limits: Some(crate::sim::model::Limits {
                min_range_m: Some(1.0),
                max_range_m: None,
            }),
            ..bare.clone()
        };
        assert_ne!(key(&bare), key(&limited));
    }

    #[test]
    fn a_lambertian_intensity_effect_is_cast_as_the_model_without_it() {
        let intensity = |k: f64| Effect::Intensity {
            incidence_exponent: k,
            noise_sigma: 2.1,
        };
        let threshold = Effect::DetectionThreshold {
            reference_range_m: 57.9,
            reference_reflectivity: 0.1,
        };
        let bare = model(vec![threshold.clone()]);
        let (m, had) = lambertian_apart(&model(vec![intensity(1.0), threshold.clone()]));
        assert!(had);
        assert_eq!(key(&m), key(&bare));
        // Another exponent is cast as it is.
        let (m, had) = lambertian_apart(&model(vec![intensity(1.000_001), threshold]));
        assert!(!had);
        assert_ne!(key(&m), key(&bare));
        assert_eq!(lambertian_apart(&bare).0.effects, bare.effects);
    }

    #[test]
    fn a_cast_without_the_effect_reads_as_the_model_with_it() {
        let o = |reflectivity: f32, lambertian: f32| Obs {
            reflectivity,
            lambertian,
            predicted: 10.0,
            ..Obs::default()
        };
        let mut obs = vec![vec![o(0.5, 0.25), Obs::default()], vec![o(0.9, 0.9)]];
        as_lambertian(&mut obs);
        assert_eq!(obs[0][0].reflectivity, 0.25);
        assert_eq!(obs[0][0].predicted, 10.0);
        assert!(obs[0][1].reflectivity.is_nan() && obs[0][1].lambertian.is_nan());
        assert_eq!(obs[1][0].reflectivity, 0.9);
    }

    fn kept(n: usize, seconds: f64) -> Kept {
        Kept {
            obs: Arc::new(vec![vec![Obs::default(); n]]),
            seconds,
            used: true,
        }
    }

    #[test]
    fn over_budget_the_casts_quickest_to_redo_go_first() {
        let size = std::mem::size_of::<Obs>();
        let budget = 3 * 100 * size;
        let mut map = HashMap::new();
        keep(&mut map, "a".into(), kept(100, 1.0), budget);
        keep(&mut map, "b".into(), kept(100, 0.2), budget);
        keep(&mut map, "c".into(), kept(100, 0.5), budget);
        assert_eq!(map.len(), 3);
        // A fourth that took longer than the quickest: the quickest (b) makes room.
        keep(&mut map, "d".into(), kept(100, 0.9), budget);
        let mut names: Vec<&String> = map.keys().collect();
        names.sort();
        assert_eq!(names, ["a", "c", "d"]);
        // One quicker than all kept is not kept.
        keep(&mut map, "e".into(), kept(100, 0.1), budget);
        assert!(!map.contains_key("e"));
        // One larger than the whole budget is not kept, and nothing goes for it.
        keep(&mut map, "f".into(), kept(400, 9.0), budget);
        assert!(!map.contains_key("f"));
        assert_eq!(map.len(), 3);
    }

    #[test]
    fn a_round_keeps_what_it_used() {
        let casts = Casts::default();
        {
            let mut map = casts.kept.lock().unwrap();
            map.insert("used".into(), kept(1, 1.0));
            let mut old = kept(1, 1.0);
            old.used = false;
            map.insert("unused".into(), old);
        }
        casts.next_round();
        assert_eq!(casts.len(), 1);
        // Not asked for in the round that follows: gone after it.
        casts.next_round();
        assert!(casts.is_empty());
    }
}
