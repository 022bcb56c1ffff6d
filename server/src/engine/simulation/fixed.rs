//! A scene's supports: the vertices held in place.

use crate::engine::mesh::TetMesh;
use crate::engine::scene::{Scene, SceneError};

/// Fixed vertices from `fixed.nodes` and `fixed.boxes` (surface vertices only with
/// `fixed.surface_only`), sorted and unique. A node the mesh does not have, or a box
/// with no vertex in it, is an error naming its key.
pub(super) fn fixed_vertices(scene: &Scene, mesh: &TetMesh) -> Result<Vec<u32>, SceneError> {
    let spec = &scene.fixed;
    let n = mesh.vertex_count();
    let mut fixed = Vec::new();
    // `fixed.nodes` counts in file order; the mesh may have been renumbered.
    let mut vertex_of = vec![0u32; n];
    for (v, &i) in mesh.file_index.iter().enumerate() {
        vertex_of[i as usize] = v as u32;
    }
    for (k, &i) in spec.nodes.iter().enumerate() {
        if i as usize >= n {
            return Err(scene.invalid(
                format!("fixed.nodes[{k}]"),
                format!(
                    "vertex {i} does not exist (the mesh has {n}, numbered from 0 in file order)"
                ),
            ));
        }
        fixed.push(vertex_of[i as usize]);
    }
    for (k, b) in spec.boxes.iter().enumerate() {
        let before = fixed.len();
        let candidates: Box<dyn Iterator<Item = u32>> = if spec.surface_only {
            Box::new(mesh.surface.vertices.iter().copied())
        } else {
            Box::new(0..n as u32)
        };
        for i in candidates {
            let p = mesh.positions[i as usize];
            if (0..3).all(|a| b.min[a] <= p[a] && p[a] <= b.max[a]) {
                fixed.push(i);
            }
        }
        if fixed.len() == before {
            return Err(scene.invalid(
                format!("fixed.boxes[{k}]"),
                "contains no vertex of the mesh",
            ));
        }
    }
    fixed.sort_unstable();
    fixed.dedup();
    Ok(fixed)
}
