//! The scenes a server offers: the embedded default and the `.toml` files of a
//! directory, and the files of that directory it cannot offer, with why.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

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
    /// The directory the scenes were read from (`--scene-dir`), if any: the only
    /// place a re-simulated recording's mesh may be read from.
    pub dir: Option<PathBuf>,
    /// Files of the directory that are not offered, and why: they do not read or
    /// parse (regular files of at most `MAX_SCENE_BYTES`, inside the directory), or
    /// repeat a name already offered. `ListScenes` reports them beside the scenes.
    pub unavailable: Vec<v1::SceneProblem>,
    /// Each scene's description once built, or why it does not build: scenes do
    /// not change while the server runs, and describing one builds its mesh (a
    /// second or more for a large liver), so `ListScenes` and `GetScene` build each
    /// scene at most once.
    described: Mutex<HashMap<String, Arc<Described>>>,
}

/// A scene's description, built once.
type Described = OnceLock<Result<v1::SceneDescription, String>>;

impl SceneCatalog {
    /// The description of scene `name` (`None`: no such scene), built by
    /// `describe` on the first call; concurrent first callers wait for one build.
    pub fn described(
        &self,
        name: &str,
        describe: impl FnOnce(&Scene) -> Result<v1::SceneDescription, String>,
    ) -> Option<Result<v1::SceneDescription, String>> {
        let scene = self.scenes.get(name)?;
        let cell = self
            .described
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .entry(name.to_string())
            .or_default()
            .clone();
        Some(cell.get_or_init(|| describe(scene)).clone())
    }

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
        catalog.dir = Some(dir.to_path_buf());
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

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    #[test]
    fn a_scene_is_described_once_however_often_it_is_asked() {
        let catalog = SceneCatalog::load(None).unwrap();
        let name = Scene::default_scene().name;
        let builds = AtomicUsize::new(0);
        let describe = |scene: &Scene| {
            builds.fetch_add(1, Ordering::Relaxed);
            let sim = scene.build().map_err(|e| e.to_string())?;
            Ok(crate::frame::description::description(scene, &sim))
        };
        let first = catalog.described(&name, describe).unwrap().unwrap();
        let again = catalog.described(&name, describe).unwrap().unwrap();
        assert_eq!(first, again);
        assert!(!first.rest_surface.as_ref().unwrap().positions.is_empty());
        assert_eq!(builds.load(Ordering::Relaxed), 1);
        assert!(catalog.described("no-such-scene", describe).is_none());
        assert_eq!(builds.load(Ordering::Relaxed), 1);
    }
}
