//! The scenes a server offers: the embedded default and the `.toml` files of a
//! directory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::engine::scene::{Scene, SceneError};

/// Why the scenes a server offers could not be loaded; each names the file or
/// directory at fault.
#[derive(Debug, thiserror::Error)]
pub enum CatalogError {
    #[error("{}: {source}", dir.display())]
    ReadDir {
        dir: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("{}: a scene named `{name}` is already loaded", file.display())]
    Duplicate { file: PathBuf, name: String },
}

/// The embedded default scene and the `.toml` files of a directory, by name.
#[derive(Debug, Default)]
pub struct SceneCatalog {
    pub scenes: BTreeMap<String, Scene>,
}

impl SceneCatalog {
    /// The default scene, and every `*.toml` in `dir` (each must parse; a broken file
    /// is an error naming it, so a typo does not silently hide a scene).
    pub fn load(dir: Option<&Path>) -> Result<Self, CatalogError> {
        let mut scenes = BTreeMap::new();
        let default = Scene::default_scene();
        scenes.insert(default.name.clone(), default);
        if let Some(dir) = dir {
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
                let scene = Scene::load(&f)?;
                if scenes.contains_key(&scene.name) {
                    return Err(CatalogError::Duplicate {
                        file: f,
                        name: scene.name,
                    });
                }
                scenes.insert(scene.name.clone(), scene);
            }
        }
        Ok(SceneCatalog { scenes })
    }
}
