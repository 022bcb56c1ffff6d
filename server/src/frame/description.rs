//! What a session tells its clients about its scene before any tick.

use laparo_proto::force::wire::to_vec3;
use laparo_proto::v1;

use super::state::surface_positions;
use crate::engine::integrate::IntegratorKind;
use crate::engine::local_model::ForceModelKind;
use crate::engine::scene::Scene;
use crate::engine::simulation::Simulation;

/// The scene's summary: sizes, rate, integrator, instruments, force model.
pub fn summary(scene: &Scene, sim: &Simulation) -> v1::SceneSummary {
    let m = &sim.mesh;
    v1::SceneSummary {
        name: scene.name.clone(),
        description: scene.description.clone(),
        vertex_count: m.vertex_count() as u32,
        tetrahedron_count: m.tets.len() as u32,
        surface_vertex_count: m.surface.vertices.len() as u32,
        surface_triangle_count: m.surface.triangles.len() as u32,
        mechanics_rate_hz: scene.mechanics.rate_hz,
        integrator: match scene.mechanics.integrator {
            IntegratorKind::Explicit => "explicit",
            IntegratorKind::Implicit => "implicit",
            IntegratorKind::Static => "static",
        }
        .to_string(),
        instruments: scene.instruments.iter().map(|i| i.name.clone()).collect(),
        force_model: match scene.force_model.kind {
            ForceModelKind::Geometric => v1::ForceModelKind::Geometric,
            ForceModelKind::Calibrated => v1::ForceModelKind::Calibrated,
        } as i32,
    }
}

/// The scene as a station first sees it: the summary, the rest surface (surface
/// vertices in `Surface::vertices` order, triangles indexed into that list), the
/// instruments and gravity.
pub fn description(scene: &Scene, sim: &Simulation) -> v1::SceneDescription {
    let s = &sim.mesh.surface;
    let triangles = s
        .triangles
        .iter()
        .flat_map(|t| t.map(|v| s.surface_index[v as usize]))
        .collect();
    v1::SceneDescription {
        summary: Some(summary(scene, sim)),
        rest_surface: Some(v1::SurfaceMesh {
            positions: surface_positions(sim),
            triangles,
        }),
        instruments: sim
            .instruments
            .iter()
            .map(|i| v1::InstrumentDescription {
                name: i.name.clone(),
                radius_m: i.radius,
                length_m: i.length,
                trocar: Some(to_vec3(&i.trocar.coords)),
                tip_contact: i.tip_contact,
                shaft_contact: i.shaft_contact,
            })
            .collect(),
        gravity: Some(to_vec3(&sim.gravity)),
    }
}
