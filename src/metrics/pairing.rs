//! Scan pairing: each measured scan with its simulated twin (a re-simulation keeps every
//! measured scan's stamp), less the scans that lie where `check` marked the reference not
//! usable.

use super::report::LeftOut;
use crate::bag::scans::Scan;
use std::collections::HashMap;
use std::path::Path;

/// A measured scan and its simulated twin.
pub(super) type Pair<'a> = (&'a Scan, &'a Scan);

/// The measured scans with their simulated twins (same stamp); an error naming both files and
/// their spans when there are none.
pub(super) fn pair_scans<'a>(
    real_scans: &'a [Scan],
    sim_scans: &'a [Scan],
    run_path: &Path,
    sim_path: &Path,
) -> Result<Vec<Pair<'a>>, String> {
    let by_stamp: HashMap<i64, usize> = sim_scans
        .iter()
        .enumerate()
        .map(|(i, s)| (s.stamp.0, i))
        .collect();
    let pairs: Vec<Pair<'a>> = real_scans
        .iter()
        .filter_map(|r| by_stamp.get(&r.stamp.0).map(|&i| (r, &sim_scans[i])))
        .collect();
    if pairs.is_empty() {
        let span = |s: &[Scan]| {
            format!(
                "{} .. {}",
                hilrig_stamp::civil::iso8601_millis(s[0].stamp),
                hilrig_stamp::civil::iso8601_millis(s[s.len() - 1].stamp)
            )
        };
        return Err(format!(
            "{} and {} share no scan (scan stamps {} and {}): the simulation is not a re-simulation of this run",
            run_path.display(),
            sim_path.display(),
            span(real_scans),
            span(sim_scans)
        ));
    }
    Ok(pairs)
}

/// The pairs whose measured scan lies clear of every mark of `left_out`; each mark's entry
/// counts the pairs it took out.
fn leave_out_marked<'a>(pairs: Vec<Pair<'a>>, left_out: &mut [LeftOut]) -> Vec<Pair<'a>> {
    pairs
        .into_iter()
        .filter(|(r, _)| {
            let (a, b) = r.span();
            let mut keep = true;
            for l in left_out.iter_mut() {
                let w = l.mark.window();
                if a <= w.1 && w.0 <= b {
                    l.scans += 1;
                    keep = false;
                }
            }
            keep
        })
        .collect()
}

/// The measured scans (of the run at the path) with their simulated twins, less those that touch
/// a mark of `left_out` (which counts them per mark), and how many pairs there were before; an
/// error when no scan pairs, or when every pair lies in a marked stretch.
pub(super) fn usable_pairs<'a>(
    (real_scans, run_path): (&'a [Scan], &Path),
    (sim_scans, sim_path): (&'a [Scan], &Path),
    left_out: &mut [LeftOut],
) -> Result<(Vec<Pair<'a>>, usize), String> {
    let paired = pair_scans(real_scans, sim_scans, run_path, sim_path)?;
    let n = paired.len();
    let pairs = leave_out_marked(paired, left_out);
    if pairs.is_empty() {
        return Err(format!(
            "{}: every paired scan lies where `check` marks the reference not usable ({}): nothing is left to compare; see `hilrig check`",
            run_path.display(),
            left_out
                .iter()
                .map(|l| format!("{} {:.1}-{:.1} s", l.mark.name, l.mark.from_s, l.mark.to_s))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok((pairs, n))
}
