//! A scene's mesh: read from a built-in or a file, scaled to metres and centred.

use std::path::PathBuf;

use crate::engine::mesh::{TetMesh, read_gmsh, read_gmsh_file};
use crate::engine::scene::{BUILTIN_MESHES, Scene, SceneError};

/// The scene's mesh in metres: `mesh.file` read, scaled by `mesh.scale`, and with
/// `mesh.center` its bounding-box centre moved to the origin.
pub(super) fn load(scene: &Scene) -> Result<TetMesh, SceneError> {
    let mut mesh = read(scene)?;
    mesh.scale(scene.mesh.scale);
    if scene.mesh.center {
        let (lo, hi) = mesh.bounding_box();
        let c = (lo.coords + hi.coords) / 2.0;
        for p in &mut mesh.positions {
            *p -= c;
        }
    }
    Ok(mesh)
}

/// Reads `mesh.file`: `builtin:NAME` from the meshes embedded in the binary, else a
/// path, relative to the scene's folder when it is relative.
fn read(scene: &Scene) -> Result<TetMesh, SceneError> {
    let wrap = |source| SceneError::Mesh {
        scene: scene.source.clone(),
        source,
    };
    if let Some(name) = scene.mesh.file.strip_prefix("builtin:") {
        let (_, text) = BUILTIN_MESHES
            .iter()
            .find(|(n, _)| *n == name)
            .ok_or_else(|| scene.invalid("mesh.file", format!("no built-in mesh `{name}`")))?;
        return read_gmsh(text, &scene.mesh.file).map_err(wrap);
    }
    let mut path = PathBuf::from(&scene.mesh.file);
    if path.is_relative()
        && let Some(dir) = &scene.base_dir
    {
        path = dir.join(path);
    }
    read_gmsh_file(&path).map_err(wrap)
}
