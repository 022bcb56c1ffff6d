//! A scene's mesh: read from a built-in or a file, scaled to metres and centred.

use std::path::PathBuf;

use crate::engine::mesh::{MeshError, MeshErrorKind, TetMesh, read_gmsh};
use crate::engine::scene::{
    BUILTIN_MESHES, FileError, MAX_MESH_BYTES, Scene, SceneError, read_bounded,
};

/// The scene's mesh in metres: `mesh.file` read, scaled by `mesh.scale`, and with
/// `mesh.center` its bounding-box centre moved to the origin; its extent checked
/// against the scene limits.
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
    scene.check_mesh_extent(&mesh)?;
    Ok(mesh)
}

/// Reads `mesh.file`: `builtin:NAME` from the meshes embedded in the binary, else a
/// path, relative to the scene's folder when it is relative: a regular file of at
/// most [`MAX_MESH_BYTES`], inside `scene.mesh_root` when that is set (a served
/// scene).
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
    let source = path.display().to_string();
    let bytes = match read_bounded(&path, scene.mesh_root.as_deref(), MAX_MESH_BYTES) {
        Ok(bytes) => bytes,
        Err(FileError::Io(e)) => {
            return Err(wrap(MeshError {
                source,
                line: None,
                kind: MeshErrorKind::Io {
                    kind: e.kind(),
                    message: e.to_string(),
                },
            }));
        }
        Err(e) => return Err(scene.invalid("mesh.file", format!("{source} {e}"))),
    };
    // A binary Gmsh file is not UTF-8 past its header: a lossy conversion keeps the
    // header readable, so the reader can say "binary" rather than "not text".
    read_gmsh(&String::from_utf8_lossy(&bytes), &source).map_err(wrap)
}
