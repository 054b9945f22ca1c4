//! Spatial accuracy as the receiver reports it: RTK state per epoch, its sigmas (GST or UBX),
//! the age of the corrections, and where they exceed the rig's limits. What the GNSS positions
//! say against CAN motion is in [`super::consistency`].

use super::faults::{iso, FaultLog};
use super::names::FaultName;
use super::report::{RtkEpoch, SigmaWindow, Spatial, Stats};
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
            state: f.rtk,
            t_s: (t.0 - start.0) as f64 * 1e-9,
            sigma_horizontal_m: f.sigma_lat_m.zip(f.sigma_lon_m).map(|(a, b)| a.max(b)),
        })
        .collect();
    sp
}

/// The three one-second windows with the largest horizontal sigma.
fn worst_sigma_windows(epochs: &[(UtcNanos, &Fix)], start: UtcNanos) -> Vec<SigmaWindow> {
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
        .map(|&(k, h)| SigmaWindow {
            from_s: k as f64,
            to_s: k as f64 + 1.0,
            sigma_m: h,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::test_drive::{fix, T0};
    use super::*;

    #[test]
    fn rtk_states_sigmas_and_correction_ages_are_counted_and_located() {
        // 100 epochs at 10 Hz: float from 2.0 s to 2.9 s, three fixed epochs with a 5 cm sigma
        // from 5.0 s, corrections 8 s old from 7.0 s to 7.4 s, no RTK at 9.0 and 9.1 s; the rest
        // fixed with 1.0 cm / 1.4 cm (lat / lon) sigmas and 1 s old corrections.
        let fixes: Vec<Fix> = (0..100)
            .map(|k| {
                let t = UtcNanos(T0 + k * 100_000_000);
                match k {
                    20..=29 => fix(t, 5, (0.2, 0.25), 1.0),
                    50..=52 => fix(t, 4, (0.05, 0.05), 1.0),
                    70..=74 => fix(t, 4, (0.010, 0.014), 8.0),
                    90..=91 => fix(t, 1, (1.5, 1.5), 1.0),
                    _ => fix(t, 4, (0.010, 0.014), 1.0),
                }
            })
            .collect();
        let epochs: Vec<(UtcNanos, &Fix)> = fixes.iter().map(|f| (f.time.unwrap(), f)).collect();
        let mut log = FaultLog::new(UtcNanos(T0));
        let th = Thresholds::default();
        let sp = receiver(&epochs, &th, UtcNanos(T0), 100_000_000, &mut log);
        assert_eq!(
            (sp.epochs, sp.rtk_fixed, sp.rtk_float, sp.rtk_none),
            (100, 88, 10, 2)
        );
        assert!((sp.rtk_fixed_share - 0.88).abs() < 1e-12);
        // The larger of the two sigmas per epoch: 85 at 1.4 cm, 3 at 5 cm, 10 at 25 cm, 2 at
        // 1.5 m.
        let median = sp.sigma_horizontal_m.median;
        assert!(
            (median - 0.014).abs() < 1e-12,
            "median horizontal sigma {median} m, the larger of 1.0 and 1.4 cm"
        );
        assert!((sp.sigma_horizontal_m.max - 1.5).abs() < 1e-12);
        assert_eq!(sp.sigma_horizontal_m.n, 100);
        assert_eq!(
            sp.worst_sigma_windows
                .iter()
                .map(|w| (w.from_s, w.to_s, w.sigma_m))
                .collect::<Vec<_>>(),
            [(9.0, 10.0, 1.5), (2.0, 3.0, 0.25), (5.0, 6.0, 0.05)]
        );
        assert!((sp.correction_age_s.max - 8.0).abs() < 1e-12);
        // Each fault over its epochs, to one period after the last.
        let at = |name: FaultName| -> Vec<(f64, f64)> {
            log.faults
                .iter()
                .filter(|f| f.name == name)
                .map(|f| (f.from_s, f.to_s))
                .collect()
        };
        assert_eq!(at(FaultName::RtkFloat), [(2.0, 3.0)], "RtkFloat");
        assert_eq!(at(FaultName::SigmaSpike), [(5.0, 5.3)], "SigmaSpike");
        assert_eq!(at(FaultName::CorrectionAge), [(7.0, 7.5)], "CorrectionAge");
        assert_eq!(at(FaultName::RtkNone), [(9.0, 9.2)], "RtkNone");
        assert_eq!(at(FaultName::RtkFixedShare), [(0.0, 9.9)], "RtkFixedShare");
        assert_eq!(log.faults.len(), 5, "{:?}", log.faults);
        let detail = |name: FaultName| {
            log.faults
                .iter()
                .find(|f| f.name == name)
                .map(|f| f.detail.clone())
                .unwrap()
        };
        assert!(detail(FaultName::RtkNone).contains("quality 1"));
        assert!(detail(FaultName::RtkFixedShare).starts_with("88.0 % of epochs RTK-fixed"));
        assert!(detail(FaultName::SigmaSpike).contains("worst horizontal 0.050 m"));
        assert_eq!(sp.rtk_epochs[25].state, hilrig_gnss::RtkState::Float);
        assert!((sp.rtk_epochs[25].t_s - 2.5).abs() < 1e-9);
    }

    #[test]
    fn a_fixed_receiver_within_its_limits_raises_nothing() {
        let fixes: Vec<Fix> = (0..50)
            .map(|k| fix(UtcNanos(T0 + k * 100_000_000), 4, (0.01, 0.01), 1.0))
            .collect();
        let epochs: Vec<(UtcNanos, &Fix)> = fixes.iter().map(|f| (f.time.unwrap(), f)).collect();
        let mut log = FaultLog::new(UtcNanos(T0));
        let sp = receiver(
            &epochs,
            &Thresholds::default(),
            UtcNanos(T0),
            100_000_000,
            &mut log,
        );
        assert!(log.faults.is_empty(), "{:?}", log.faults);
        assert_eq!(sp.rtk_fixed_share, 1.0);
    }
}
