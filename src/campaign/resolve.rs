//! Where a campaign file's paths lead, files or objects (mirror.rs), and the files a
//! configuration names besides itself (a scene's meshes, a rig's DBC and lidar calibration):
//! what the planner checks
//! exists before any task runs and adds to the tasks' inputs.

use super::{mirror, store, CampaignError};
use std::path::{Path, PathBuf};

/// Which configuration [`named_files`] reads.
#[derive(Clone, Copy)]
pub(super) enum Names {
    /// A scene: its meshes and actors' trajectories.
    Scene,
    /// A rig: its DBC and its lidar's calibration file.
    Rig,
}

/// A file's text, fetched first when it is an object.
pub(super) fn read_text(what: &str, path: &Path) -> Result<String, CampaignError> {
    let local = if mirror::is_url(path) {
        let url = path.to_string_lossy();
        store::shared()?
            .fetch(&url)?
            .ok_or_else(|| CampaignError::Missing {
                what: what.into(),
                path: path.to_owned(),
            })?
    } else {
        path.to_owned()
    };
    std::fs::read_to_string(&local).map_err(|source| CampaignError::Io {
        path: path.to_owned(),
        source,
    })
}

/// The directory of a file or object.
pub(super) fn parent_of(p: &Path) -> PathBuf {
    if mirror::is_url(p) {
        PathBuf::from(mirror::parent(&p.to_string_lossy()))
    } else {
        p.parent().unwrap_or(Path::new("/")).to_owned()
    }
}

/// `p` resolved against `base`, lexically for objects.
pub(super) fn joined(base: &Path, p: &Path) -> Result<PathBuf, CampaignError> {
    if mirror::is_url(base) || mirror::is_url(p) {
        Ok(PathBuf::from(mirror::join(
            &base.to_string_lossy(),
            &p.to_string_lossy(),
        )?))
    } else {
        Ok(base.join(p))
    }
}

/// An existing file or object, `p` resolved against `base`: a file by its canonical path (the
/// plan's command lines read plainly, and one file reached two ways is one file).
pub(super) fn existing_in(base: &Path, what: String, p: &Path) -> Result<PathBuf, CampaignError> {
    let p = joined(base, p)?;
    if mirror::is_url(&p) {
        return match store::shared()?.exists(&p.to_string_lossy())? {
            true => Ok(p),
            false => Err(CampaignError::Missing { what, path: p }),
        };
    }
    if p.is_file() {
        Ok(std::fs::canonicalize(&p).unwrap_or(p))
    } else {
        Err(CampaignError::Missing { what, path: p })
    }
}

/// The files the configuration `config` names besides itself, each checked to exist. One
/// that does not parse names none here: the task that reads it says what is wrong.
pub(super) fn named_files(config: &Path, names: Names) -> Result<Vec<PathBuf>, CampaignError> {
    let text = read_text("the file", config)?;
    let dir = parent_of(config);
    let named: Vec<PathBuf> = match names {
        Names::Scene => match toml::from_str::<crate::scene::file::SceneFile>(&text) {
            Ok(f) => {
                let meshes = |parts: &[crate::scene::file::Shape]| -> Vec<PathBuf> {
                    parts
                        .iter()
                        .filter_map(|p| match p {
                            crate::scene::file::Shape::Mesh { file, .. } => Some(file.clone()),
                            _ => None,
                        })
                        .collect()
                };
                f.objects
                    .iter()
                    .flat_map(|o| meshes(&o.parts))
                    .chain(f.actors.iter().flat_map(|a| {
                        let mut v = vec![a.trajectory.clone()];
                        v.extend(meshes(&a.parts));
                        v
                    }))
                    .collect()
            }
            Err(_) => Vec::new(),
        },
        Names::Rig => match crate::rig::Rig::from_toml(&text, &config.display().to_string()) {
            Ok(r) => r
                .can
                .map(|c| c.dbc)
                .into_iter()
                .chain(r.lidar.and_then(|l| l.calibration))
                .collect(),
            Err(_) => Vec::new(),
        },
    };
    let mut files = Vec::new();
    for f in named {
        let p = existing_in(&dir, format!("a file that {} names", config.display()), &f)?;
        if !files.contains(&p) {
            files.push(p);
        }
    }
    Ok(files)
}

/// The files or objects the glob `pattern` matches, sorted; the pattern's error when it is not
/// one.
pub(super) fn matching(pattern: &Path) -> Result<Result<Vec<PathBuf>, String>, CampaignError> {
    let mut files: Vec<PathBuf> = if mirror::is_url(pattern) {
        store::shared()?
            .glob(&pattern.to_string_lossy())?
            .into_iter()
            .map(PathBuf::from)
            .collect()
    } else {
        match glob::glob(&pattern.to_string_lossy()) {
            Ok(matches) => matches
                .filter_map(Result::ok)
                .filter(|p| p.is_file())
                .map(|p| std::fs::canonicalize(&p).unwrap_or(p))
                .collect(),
            Err(e) => return Ok(Err(e.to_string())),
        }
    };
    files.sort();
    Ok(Ok(files))
}
