//! Meshes and scenes for tests.

use super::mesh::generate::kuhn_box;
use super::mesh::{TetMesh, read_gmsh};

/// SOFA's liver (181 nodes, 596 tetrahedra), in SOFA units.
pub const LIVER_MSH: &str = include_str!("../../meshes/liver.msh");

/// A box `[0, sx] × [0, sy] × [0, sz]` of Kuhn-split cubes ([`kuhn_box`]) as Gmsh 2.2
/// text, so that tests go through the reader and its orientation repair too.
pub fn box_msh(n: [usize; 3], size: [f64; 3]) -> String {
    let (positions, tets) = kuhn_box(n, size, [0.0; 3]);
    let mut out = format!(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{}\n",
        positions.len()
    );
    for (i, p) in positions.iter().enumerate() {
        out += &format!("{} {} {} {}\n", i + 1, p.x, p.y, p.z);
    }
    out += &format!("$EndNodes\n$Elements\n{}\n", tets.len());
    for (e, t) in tets.iter().enumerate() {
        out += &format!(
            "{} 4 2 1 1 {} {} {} {}\n",
            e + 1,
            t[0] + 1,
            t[1] + 1,
            t[2] + 1,
            t[3] + 1
        );
    }
    out + "$EndElements\n"
}

/// A box mesh, loaded.
pub fn box_mesh(n: [usize; 3], size: [f64; 3]) -> TetMesh {
    read_gmsh(&box_msh(n, size), "box.msh").expect("generated box mesh is valid")
}

/// SOFA's liver, loaded, in SOFA units.
pub fn liver_mesh() -> TetMesh {
    read_gmsh(LIVER_MSH, "liver.msh").expect("liver.msh loads")
}
