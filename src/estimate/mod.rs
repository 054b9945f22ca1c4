//! Estimators of one sample that several steps share: the median and a robust standard deviation
//! ([`robust`]), Spearman's rank correlation with its bootstrap interval ([`rank`]).
//!
//! A leaf: it imports nothing of the crate, so `metrics` (per scan), `stats` (over repetitions)
//! and `gap` can all use it without reaching into each other (before, `metrics` took the rank
//! correlation from `stats` while `stats` took the features from `metrics`).

pub mod rank;
pub mod robust;
