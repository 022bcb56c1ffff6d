//! A scene's mesh: read from a built-in or a file, renumbered for locality when it
//! is large, scaled to metres and centred.

use std::path::PathBuf;

use crate::engine::elastic::part_count;
use crate::engine::mesh::{MeshError, MeshErrorKind, TetMesh, read_gmsh, reverse_cuthill_mckee};
use crate::engine::scene::{
    BUILTIN_MESHES, FileError, MAX_MESH_BYTES, MAX_REFINED_TETS, Scene, SceneError, read_bounded,
};

/// Meshes with at least this many vertices are renumbered by reverse Cuthill–McKee
/// when loaded ([`crate::engine::mesh::reverse_cuthill_mckee`]). Their files number
/// vertices with no locality, so every sweep of the elastic model and every product
/// of the solver gathers from across arrays of tens of megabytes. Measured
/// (corotational bench, contact, kept tangent): on liver-80k (16k vertices, its
/// `K̂` about 9 MB, within this machine's 32 MB cache) the tick is unchanged; on
/// liver-300k (60k vertices, `K̂` about 33 MB) it is shorter. Below the threshold
/// the file's numbering is kept, so that the surface of a smaller scene, and every
/// recording made of it, keeps its vertex order, unless the scene splits the mesh
/// among threads: they share it by ranges of vertex indices
/// ([`crate::engine::elastic::parts`]), which need the locality.
pub const RENUMBER_VERTICES: usize = 32_768;

/// The scene's mesh in metres: `mesh.file` read, refined `mesh.refine` times,
/// renumbered from
/// [`RENUMBER_VERTICES`] vertices up or when split among threads, scaled by
/// `mesh.scale`, and with `mesh.center` its bounding-box centre moved to the
/// origin; its extent checked against the scene
/// limits.
pub(super) fn load(scene: &Scene) -> Result<TetMesh, SceneError> {
    let mut mesh = read(scene)?;
    let refine = scene.mesh.refine;
    let tets = (mesh.tets.len() as u64).saturating_mul(8u64.saturating_pow(refine));
    if tets > MAX_REFINED_TETS as u64 {
        return Err(scene.invalid(
            "mesh.refine",
            format!(
                "{} tetrahedra refined {refine} times would be {tets}, more than {MAX_REFINED_TETS}",
                mesh.tets.len()
            ),
        ));
    }
    for pass in 1..=refine {
        mesh = mesh.refined().map_err(|source| {
            let what = match source.kind {
                MeshErrorKind::DegenerateTet { element, .. } => format!(
                    "its tetrahedron {element} (in the order of the mesh it refined) is so \
                     nearly flat that its children are flat ({})",
                    source.kind
                ),
                _ => source.to_string(),
            };
            scene.invalid(
                "mesh.refine",
                format!(
                    "refinement {pass} of {refine} cannot be simulated: {what}; refine fewer \
                     times or mend the mesh"
                ),
            )
        })?;
    }
    let n = mesh.vertex_count();
    if n >= RENUMBER_VERTICES || part_count(n, scene.mechanics.threads) > 1 {
        mesh = mesh.renumbered(&reverse_cuthill_mckee(mesh.vertex_count(), &mesh.edges));
    }
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

/// The file `scene.mesh.file` names, relative to the scene's folder when it is
/// relative; `None` for a mesh embedded in the binary (`builtin:NAME`).
pub fn mesh_path(scene: &Scene) -> Option<PathBuf> {
    if scene.mesh.file.starts_with("builtin:") {
        return None;
    }
    let path = PathBuf::from(&scene.mesh.file);
    Some(match &scene.base_dir {
        Some(dir) if path.is_relative() => dir.join(path),
        _ => path,
    })
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
    let path = mesh_path(scene).expect("not a built-in mesh");
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
