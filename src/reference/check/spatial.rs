//! Spatial accuracy as the receiver reports it: RTK state per epoch, its sigmas (GST or UBX),
//! the age of the corrections, and where they exceed the rig's limits. What the GNSS positions
//! say against CAN motion is in [`super::consistency`].

use super::faults::{iso, FaultLog};
use super::names::FaultName;
use super::report::{RtkEpoch, Spatial, Stats};
use crate::rig::Thresholds;
use hilrig_gnss::{Fix, RtkState};
use hilrig_stamp::UtcNanos;

/// RTK states, sigmas and correction ages of `epochs`, with the faults they raise (float and
/// no-RTK stretches, sigma spikes, old corrections, too few fixed epochs). The run starts at
/// `start`; GNSS epochs come every `gnss_period` ns.
pub(super) fn receiver(
    epochs: &[(UtcNanos, &Fix)],
    th: &Thresholds,
    start: UtcNanos,
    gnss_period: i64,
    log: &mut FaultLog,
) -> Spatial {
    let mut sp = Spatial {
        epochs: epochs.len(),
        ..Spatial::default()
    };
    let (mut float_epochs, mut none_epochs, mut spikes, mut old) = (vec![], vec![], vec![], vec![]);
    let (mut sig_h, mut sig_v, mut ages) = (vec![], vec![], vec![]);
    for &(t, f) in epochs {
        match f.rtk {
            RtkState::Fixed => sp.rtk_fixed += 1,
            RtkState::Float => {
                sp.rtk_float += 1;
                float_epochs.push((t, f64::from(f.quality)));
            }
            RtkState::None => {
                sp.rtk_none += 1;
                none_epochs.push((t, f64::from(f.quality)));
            }
        }
        let h = f.sigma_lat_m.zip(f.sigma_lon_m).map(|(a, b)| a.max(b));
        if let Some(h) = h {
            sig_h.push(h);
        }
        if let Some(v) = f.sigma_alt_m {
            sig_v.push(v);
        }
        if f.rtk == RtkState::Fixed
            && (h.is_some_and(|h| h > th.max_sigma_horizontal_m)
                || f.sigma_alt_m.is_some_and(|v| v > th.max_sigma_vertical_m))
        {
            spikes.push((t, h.unwrap_or(0.0)));
        }
        if let Some(a) = f.correction_age_s {
            ages.push(a);
            if a > th.max_correction_age_s {
                old.push((t, a));
            }
        }
    }
    sp.rtk_fixed_share = sp.rtk_fixed as f64 / epochs.len() as f64;
    sp.sigma_horizontal_m = Stats::of(sig_h);
    sp.worst_sigma_windows = worst_sigma_windows(epochs, start);
    sp.sigma_vertical_m = Stats::of(sig_v);
    sp.correction_age_s = Stats::of(ages);
    log.runs(FaultName::RtkFloat, &float_epochs, gnss_period, |n, _| {
        format!("{n} epochs with an RTK float solution (GGA quality 5)")
    });
    log.runs(FaultName::RtkNone, &none_epochs, gnss_period, |n, q| {
        format!("{n} epochs without an RTK solution (GGA quality {q:.0})")
    });
    log.runs(FaultName::SigmaSpike, &spikes, gnss_period, |n, worst| {
        format!(
            "{n} fixed epochs with sigma above {:.3} m (horizontal) or {:.3} m (vertical); worst horizontal {worst:.3} m",
            th.max_sigma_horizontal_m, th.max_sigma_vertical_m
        )
    });
    log.runs(FaultName::CorrectionAge, &old, gnss_period, |n, worst| {
        format!(
            "{n} epochs with corrections older than {:.1} s (worst {worst:.1} s)",
            th.max_correction_age_s
        )
    });
    if sp.rtk_fixed_share < th.min_rtk_fixed_share {
        // Located by the float/none faults above; this one states the share.
        let (a, b) = (epochs[0].0, epochs[epochs.len() - 1].0);
        log.fault(
            FaultName::RtkFixedShare,
            a,
            b,
            format!(
                "{:.1} % of epochs RTK-fixed, below {:.1} %",
                sp.rtk_fixed_share * 100.0,
                th.min_rtk_fixed_share * 100.0
            ),
        );
    }
    sp.rtk_epochs = epochs
        .iter()
        .map(|(t, f)| RtkEpoch {
            time: iso(*t),
            state: f.rtk.name(),
            t_s: (t.0 - start.0) as f64 * 1e-9,
            sigma_horizontal_m: f.sigma_lat_m.zip(f.sigma_lon_m).map(|(a, b)| a.max(b)),
        })
        .collect();
    sp
}

/// The three one-second windows with the largest horizontal sigma: (from s, to s, sigma m).
fn worst_sigma_windows(epochs: &[(UtcNanos, &Fix)], start: UtcNanos) -> Vec<(f64, f64, f64)> {
    let mut windows: std::collections::BTreeMap<i64, f64> = std::collections::BTreeMap::new();
    for &(t, f) in epochs {
        if let Some(h) = f.sigma_lat_m.zip(f.sigma_lon_m).map(|(a, b)| a.max(b)) {
            let w = windows
                .entry((t.0 - start.0).div_euclid(1_000_000_000))
                .or_insert(0.0);
            *w = w.max(h);
        }
    }
    let mut worst: Vec<(i64, f64)> = windows.into_iter().collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    worst
        .iter()
        .take(3)
        .map(|&(k, h)| (k as f64, k as f64 + 1.0, h))
        .collect()
}
