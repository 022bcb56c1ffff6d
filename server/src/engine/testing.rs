//! Meshes and scenes for tests.

use super::mesh::{TetMesh, read_gmsh};

/// SOFA's liver (181 nodes, 596 tetrahedra), in SOFA units.
pub const LIVER_MSH: &str = include_str!("../../meshes/liver.msh");

/// A box `[0, sx] × [0, sy] × [0, sz]` split into `nx·ny·nz` cubes of six tetrahedra
/// each (Kuhn subdivision along the main diagonal, conforming), as Gmsh 2.2 text.
/// Odd permutations are written with two vertices swapped, so that the loader's
/// orientation repair is exercised too.
pub fn box_msh(n: [usize; 3], size: [f64; 3]) -> String {
    let id = |i: usize, j: usize, k: usize| 1 + i + (n[0] + 1) * (j + (n[1] + 1) * k);
    let mut out = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    out += &format!("{}\n", (n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                let p = [i, j, k].map(|v| v as f64);
                out += &format!(
                    "{} {} {} {}\n",
                    id(i, j, k),
                    p[0] * size[0] / n[0] as f64,
                    p[1] * size[1] / n[1] as f64,
                    p[2] * size[2] / n[2] as f64
                );
            }
        }
    }
    out += "$EndNodes\n$Elements\n";
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    out += &format!("{}\n", 6 * n[0] * n[1] * n[2]);
    let mut e = 0;
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                for perm in perms {
                    let mut c = [i, j, k];
                    let mut v = vec![id(c[0], c[1], c[2])];
                    for axis in perm {
                        c[axis] += 1;
                        v.push(id(c[0], c[1], c[2]));
                    }
                    e += 1;
                    out += &format!("{e} 4 2 1 1 {} {} {} {}\n", v[0], v[1], v[2], v[3]);
                }
            }
        }
    }
    out += "$EndElements\n";
    out
}

/// A box mesh, loaded.
pub fn box_mesh(n: [usize; 3], size: [f64; 3]) -> TetMesh {
    read_gmsh(&box_msh(n, size), "box.msh").expect("generated box mesh is valid")
}

/// SOFA's liver, loaded, in SOFA units.
pub fn liver_mesh() -> TetMesh {
    read_gmsh(LIVER_MSH, "liver.msh").expect("liver.msh loads")
}
