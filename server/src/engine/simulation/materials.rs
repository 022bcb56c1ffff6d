//! A scene's materials: the base material and one per tagged region.

use std::collections::HashMap;

use crate::engine::material::Material;
use crate::engine::mesh::TetMesh;
use crate::engine::scene::{Scene, SceneError};

/// The distinct materials and each tetrahedron's material index: index 0 is the
/// scene's `material`, then one per `material.regions` entry in order, whose unset
/// fields take the base material's. A region whose tag no tetrahedron has is an error.
pub(super) fn materials(
    scene: &Scene,
    mesh: &TetMesh,
) -> Result<(Vec<Material>, Vec<u16>), SceneError> {
    let spec = &scene.material;
    let base = Material {
        young_modulus: spec.young_modulus,
        poisson_ratio: spec.poisson_ratio,
        density: spec.density,
    };
    let mut materials = vec![base];
    let mut by_tag = HashMap::new();
    for (k, r) in spec.regions.iter().enumerate() {
        if !mesh.tet_tags.contains(&r.tag) {
            return Err(scene.invalid(
                format!("material.regions[{k}].tag"),
                format!("no tetrahedron of the mesh has tag {}", r.tag),
            ));
        }
        by_tag.insert(r.tag, materials.len() as u16);
        materials.push(Material {
            young_modulus: r.young_modulus.unwrap_or(base.young_modulus),
            poisson_ratio: r.poisson_ratio.unwrap_or(base.poisson_ratio),
            density: r.density.unwrap_or(base.density),
        });
    }
    let tet_material = mesh
        .tet_tags
        .iter()
        .map(|t| by_tag.get(t).copied().unwrap_or(0))
        .collect();
    Ok((materials, tet_material))
}
