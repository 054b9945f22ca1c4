//! The plan's graph from its files: which task waits for which (the writer of a file waits
//! before its readers), in an order that runs each after those, and the two mistakes a campaign
//! file can make that only the graph shows: a cycle, and two tasks writing one file.

use super::task::Task;
use super::CampaignError;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `path` absolute, with its longest existing ancestor canonical: the campaign's inputs are
/// canonical paths, so an output is recognised as an input (a cycle) whichever way it is named.
pub(super) fn canonical(path: &Path) -> std::io::Result<PathBuf> {
    let path = std::path::absolute(path)?;
    let mut rest = Vec::new();
    let mut base = path.as_path();
    loop {
        if let Ok(c) = std::fs::canonicalize(base) {
            return Ok(rest.iter().rev().fold(c, |p: PathBuf, part| p.join(part)));
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_owned());
                base = parent;
            }
            _ => return Ok(path),
        }
    }
}

/// Derives each task's `after` from the files (and `gates`), and sorts the tasks so that each
/// comes after those it waits for; a cycle or two writers of one file is an error.
pub(super) fn order(
    mut tasks: Vec<Task>,
    gates: &BTreeMap<String, Vec<String>>,
) -> Result<Vec<Task>, CampaignError> {
    let mut writer: BTreeMap<&Path, usize> = BTreeMap::new();
    for (i, t) in tasks.iter().enumerate() {
        for o in &t.outputs {
            if let Some(&j) = writer.get(o.as_path()) {
                return Err(CampaignError::TwoWriters {
                    path: o.clone(),
                    first: tasks[j].id.clone(),
                    second: t.id.clone(),
                });
            }
            writer.insert(o, i);
        }
    }
    let index: BTreeMap<String, usize> = tasks
        .iter()
        .enumerate()
        .map(|(i, t)| (t.id.clone(), i))
        .collect();
    let mut deps: Vec<Vec<usize>> = vec![Vec::new(); tasks.len()];
    for (i, t) in tasks.iter().enumerate() {
        let mut d: Vec<usize> = t
            .inputs
            .iter()
            .filter_map(|p| writer.get(p.as_path()).copied())
            .collect();
        if let Some(g) = gates.get(&t.id) {
            d.extend(g.iter().filter_map(|id| index.get(id).copied()));
        }
        d.sort_unstable();
        d.dedup();
        deps[i] = d;
    }
    // Depth-first, in the tasks' own order, so that the plan reads like the method.
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Open,
        Done,
    }
    fn visit(
        i: usize,
        deps: &[Vec<usize>],
        marks: &mut [Mark],
        stack: &mut Vec<usize>,
        sorted: &mut Vec<usize>,
    ) -> Result<(), Vec<usize>> {
        match marks[i] {
            Mark::Done => return Ok(()),
            Mark::Open => {
                let from = stack.iter().position(|&k| k == i).unwrap_or(0);
                let mut cycle = stack[from..].to_vec();
                cycle.push(i);
                return Err(cycle);
            }
            Mark::New => {}
        }
        marks[i] = Mark::Open;
        stack.push(i);
        for &d in &deps[i] {
            visit(d, deps, marks, stack, sorted)?;
        }
        stack.pop();
        marks[i] = Mark::Done;
        sorted.push(i);
        Ok(())
    }
    let mut marks = vec![Mark::New; tasks.len()];
    let mut sorted = Vec::with_capacity(tasks.len());
    for i in 0..tasks.len() {
        let mut stack = Vec::new();
        if let Err(cycle) = visit(i, &deps, &mut marks, &mut stack, &mut sorted) {
            let ids: Vec<String> = cycle.iter().map(|&k| tasks[k].id.clone()).collect();
            // The file that closes the cycle: one the last task but one reads and the last writes.
            let (reader, written_by) = (cycle[cycle.len() - 2], cycle[cycle.len() - 1]);
            let file = tasks[reader]
                .inputs
                .iter()
                .find(|p| writer.get(p.as_path()) == Some(&written_by))
                .cloned()
                .unwrap_or_default();
            return Err(CampaignError::Cycle {
                tasks: ids.join(" -> "),
                file,
            });
        }
    }
    let ids: Vec<String> = tasks.iter().map(|t| t.id.clone()).collect();
    for (t, d) in tasks.iter_mut().zip(&deps) {
        t.after = d.iter().map(|&k| ids[k].clone()).collect();
        t.gates = gates
            .get(&t.id)
            .into_iter()
            .flatten()
            .filter(|g| index.contains_key(*g))
            .cloned()
            .collect();
    }
    let mut slots: Vec<Option<Task>> = tasks.into_iter().map(Some).collect();
    Ok(sorted
        .into_iter()
        .map(|i| slots[i].take().expect("each task once"))
        .collect())
}
