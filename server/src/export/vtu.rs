//! VTK XML unstructured grid (`.vtu`), the format ParaView opens.
//!
//! The volume mesh is written as ASCII: points at their **rest** positions `X` (m),
//! tetrahedra (VTK cell type 10), point data `displacement` `u = x − X` (m, three
//! components) and cell data `von_mises_stress` (Pa, of the strain the scene's
//! elastic model acts on: `sym ∇u` when linear, `sym(Rᵀ F) − I` when corotational)
//! and `region` (the tetrahedron's physical tag). ParaView's Warp By Vector on
//! `displacement` (scale 1) then draws the deformed shape `X + u`; a file that held
//! the deformed points would be warped twice. The file says so in a comment.

use std::io::{self, Write};
use std::path::Path;

use crate::engine::elastic::von_mises_of_strain;
use crate::engine::simulation::Simulation;
use crate::output::write_whole;

/// VTK's cell type for a linear tetrahedron.
const VTK_TETRA: u8 = 10;

/// Von Mises stress of every tetrahedron in the simulation's current state, Pa, by
/// the scene's elastic model.
pub fn tet_von_mises(sim: &Simulation) -> Vec<f64> {
    let model = &sim.model;
    (0..sim.mesh.tets.len())
        .map(|t| {
            let eps = model.tet_strain(&sim.mesh.tets, &sim.state.x, t);
            von_mises_of_strain(&eps, &model.materials[model.tet_material[t] as usize])
        })
        .collect()
}

/// Writes the simulation's current state to `path`, whole or not at all (see
/// [`output`](crate::output): a failed write leaves an earlier file of that name as
/// it was).
pub fn write_vtu(sim: &Simulation, path: &Path) -> io::Result<()> {
    write_whole(path, |w| write_vtu_to(sim, w))
}

/// Writes the simulation's current state as VTU to any writer.
pub fn write_vtu_to(sim: &Simulation, w: &mut impl Write) -> io::Result<()> {
    let (x, rest) = (&sim.state.x, &sim.model.rest);
    let tets = &sim.mesh.tets;
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    )?;
    writeln!(
        w,
        "  <!-- Points are rest positions; Warp By Vector with `displacement` (scale 1) draws the deformed shape. -->"
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        r#"    <Piece NumberOfPoints="{}" NumberOfCells="{}">"#,
        x.len(),
        tets.len()
    )?;
    writeln!(w, "      <Points>")?;
    writeln!(
        w,
        r#"        <DataArray type="Float64" NumberOfComponents="3" format="ascii">"#
    )?;
    for p in rest {
        writeln!(w, "{:e} {:e} {:e}", p.x, p.y, p.z)?;
    }
    writeln!(w, "        </DataArray>\n      </Points>\n      <Cells>")?;
    writeln!(
        w,
        r#"        <DataArray type="Int64" Name="connectivity" format="ascii">"#
    )?;
    for t in tets {
        writeln!(w, "{} {} {} {}", t[0], t[1], t[2], t[3])?;
    }
    writeln!(w, "        </DataArray>")?;
    writeln!(
        w,
        r#"        <DataArray type="Int64" Name="offsets" format="ascii">"#
    )?;
    for k in 1..=tets.len() {
        writeln!(w, "{}", 4 * k)?;
    }
    writeln!(w, "        </DataArray>")?;
    writeln!(
        w,
        r#"        <DataArray type="UInt8" Name="types" format="ascii">"#
    )?;
    for _ in tets {
        writeln!(w, "{VTK_TETRA}")?;
    }
    writeln!(w, "        </DataArray>\n      </Cells>")?;
    writeln!(w, r#"      <PointData Vectors="displacement">"#)?;
    writeln!(
        w,
        r#"        <DataArray type="Float64" Name="displacement" NumberOfComponents="3" format="ascii">"#
    )?;
    for (p, r) in x.iter().zip(rest) {
        let u = p - r;
        writeln!(w, "{:e} {:e} {:e}", u.x, u.y, u.z)?;
    }
    writeln!(w, "        </DataArray>\n      </PointData>")?;
    writeln!(w, r#"      <CellData Scalars="von_mises_stress">"#)?;
    writeln!(
        w,
        r#"        <DataArray type="Float64" Name="von_mises_stress" format="ascii">"#
    )?;
    for s in tet_von_mises(sim) {
        writeln!(w, "{s:e}")?;
    }
    writeln!(w, "        </DataArray>")?;
    writeln!(
        w,
        r#"        <DataArray type="Int32" Name="region" format="ascii">"#
    )?;
    for tag in &sim.mesh.tet_tags {
        writeln!(w, "{tag}")?;
    }
    writeln!(
        w,
        "        </DataArray>\n      </CellData>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>"
    )?;
    Ok(())
}
