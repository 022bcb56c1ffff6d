//! Shared by the benchmarks: meshes and scene variants.
#![allow(dead_code)]

use std::path::PathBuf;
use std::time::Instant;

use laparo_server::engine::integrate::IntegratorKind;
use laparo_server::engine::scene::Scene;
use laparo_server::engine::scene::limits::max_cg_iterations;
use laparo_server::engine::simulation::Simulation;

/// A mesh of the scaling series: its label, where to find it, and how many times
/// the scene refines it when loaded (`mesh.refine`).
pub struct MeshCase {
    pub label: &'static str,
    pub file: String,
    pub refine: u32,
}

/// Where the large livers live: `LAPARO_MESH_DIR`, or `shared/data/liver` beside the
/// repository (they are too large to ship in it).
pub fn shared_mesh_dir() -> PathBuf {
    std::env::var_os("LAPARO_MESH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../shared/data/liver"
            ))
        })
}

/// The mesh labels named on the command line (arguments not starting with `-`), or
/// `default` when none is.
pub fn requested_labels(default: &[&'static str]) -> Vec<&'static str> {
    let wanted: Vec<&'static str> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .map(|a| &*a.leak())
        .collect();
    if wanted.is_empty() {
        default.to_vec()
    } else {
        wanted
    }
}

/// The meshes named, in order; those not found are reported and skipped.
pub fn meshes(labels: &[&'static str]) -> Vec<MeshCase> {
    let mut out = Vec::new();
    for &label in labels {
        // SOFA's liver refined once and twice: 4,768 and 38,144 tetrahedra on the
        // same faceted surface (`mesh.refine`).
        let refine = match label {
            "sofa-liver-r1" => 1,
            "sofa-liver-r2" => 2,
            _ => 0,
        };
        let file = match label {
            "sofa-liver" | "sofa-liver-r1" | "sofa-liver-r2" => "builtin:liver.msh".to_string(),
            "liver-5k" => concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/liver-5k.msh").to_string(),
            other => {
                let path = shared_mesh_dir().join(format!("{other}.msh"));
                if !path.exists() {
                    eprintln!(
                        "skipping {other}: {} not found (set LAPARO_MESH_DIR)",
                        path.display()
                    );
                    continue;
                }
                path.display().to_string()
            }
        };
        out.push(MeshCase {
            label,
            file,
            refine,
        });
    }
    out
}

/// The default scene on another mesh (its file and refinement), with another
/// integrator and CG tolerance.
pub fn scene(mesh: &MeshCase, integrator: IntegratorKind, cg_tolerance: f64) -> Scene {
    let mut scene = Scene::default_scene();
    scene.mesh.file = mesh.file.clone();
    scene.mesh.refine = mesh.refine;
    scene.mechanics.integrator = integrator;
    scene.mechanics.cg_tolerance = cg_tolerance;
    scene.mechanics.cg_max_iterations = 20_000;
    scene
}

/// Builds `scene`, its CG cap lowered to what the tick-work bound allows on its mesh
/// (the benchmarks' tolerances converge long before either cap).
pub fn build(scene: &Scene) -> Simulation {
    let mut scene = scene.clone();
    let mesh = scene.load_mesh().expect("the mesh loads");
    let cap = &mut scene.mechanics.cg_max_iterations;
    *cap = (*cap).min(max_cg_iterations(mesh.vertex_count()));
    scene.build_on(mesh).expect("variant builds")
}

/// Median of a sample.
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Seconds since `t`.
pub fn since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// Largest vertex distance between two position sets, m.
pub fn max_distance(a: &[nalgebra::Point3<f64>], b: &[nalgebra::Point3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}
