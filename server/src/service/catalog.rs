//! The scenes a server offers: the embedded default and the `.toml` files of a
//! directory, and the files of that directory it cannot offer, with why.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use laparo_proto::v1;

use crate::engine::scene::Scene;

/// Why the scenes a server offers could not be loaded at all: only the directory
/// itself failing does that (a broken file is reported, see [`SceneCatalog::load`]).
#[derive(Debug, thiserror::Error)]
pub enum CatalogError {
    #[error("{}: {source}", dir.display())]
    ReadDir {
        dir: PathBuf,
        source: std::io::Error,
    },
}

/// The embedded default scene and the `.toml` files of a directory, by name.
#[derive(Debug, Default)]
pub struct SceneCatalog {
    pub scenes: BTreeMap<String, Scene>,
    /// Files of the directory that are not offered, and why: they do not read or
    /// parse (regular files of at most `MAX_SCENE_BYTES`, inside the directory), or
    /// repeat a name already offered. `ListScenes` reports them beside the scenes.
    pub unavailable: Vec<v1::SceneProblem>,
}

impl SceneCatalog {
    /// The default scene, and every `*.toml` in `dir`, in file-name order. A file that
    /// does not load is left out, logged and kept in [`unavailable`](Self::unavailable),
    /// so that one broken file neither hides the others nor stops the server; a name
    /// already offered (by the default scene or an earlier file) keeps the first, with
    /// a warning naming both files. Only an unreadable directory is an error.
    pub fn load(dir: Option<&Path>) -> Result<Self, CatalogError> {
        let mut catalog = SceneCatalog::default();
        let default = Scene::default_scene();
        catalog.scenes.insert(default.name.clone(), default);
        let Some(dir) = dir else {
            return Ok(catalog);
        };
        let entries = std::fs::read_dir(dir).map_err(|source| CatalogError::ReadDir {
            dir: dir.to_path_buf(),
            source,
        })?;
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        for f in files {
            let file = f
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
            let problem = match Scene::load_served(&f, dir) {
                Ok(scene) => match catalog.scenes.get(&scene.name) {
                    None => {
                        catalog.scenes.insert(scene.name.clone(), scene);
                        continue;
                    }
                    Some(first) => v1::SceneProblem {
                        error: format!(
                            "a scene named `{}` is already offered by {}; keeping that one",
                            scene.name, first.source
                        ),
                        name: scene.name,
                        file,
                    },
                },
                Err(e) => v1::SceneProblem {
                    name: String::new(),
                    file,
                    error: e.to_string(),
                },
            };
            tracing::warn!(file = %f.display(), "scene not offered: {}", problem.error);
            catalog.unavailable.push(problem);
        }
        Ok(catalog)
    }
}
