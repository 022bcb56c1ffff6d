//! What a session tells its clients about its scene, and each tick's frame.

use laparo_proto::force::wire::{to_pose, to_vec3};
use laparo_proto::v1;

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

/// The surface vertices' current positions, packed as f32 triples.
pub fn surface_positions(sim: &Simulation) -> Vec<f32> {
    let mut out = Vec::with_capacity(3 * sim.mesh.surface.vertices.len());
    for &v in &sim.mesh.surface.vertices {
        let p = sim.state.x[v as usize];
        out.extend([p.x as f32, p.y as f32, p.z as f32]);
    }
    out
}

/// Instrument `k`'s state after the tick: pose, contact, held vertices, local model
/// and force.
pub fn instrument_state(
    sim: &Simulation,
    k: usize,
    station: Option<u64>,
    pose_sequence: Option<u64>,
) -> v1::InstrumentState {
    let ins = &sim.instruments[k];
    let forces = sim.forces.as_ref();
    let model = forces.map(|f| f.models[k]);
    let force = forces.map(|f| f.forces[k]);
    v1::InstrumentState {
        tick: sim.tick,
        sim_time_s: sim.time,
        instrument: ins.name.clone(),
        station_id: station,
        pose: ins.current.map(|p| to_pose(&p.tip, &p.axis)),
        pose_sequence,
        contact: contact_state(sim, k) as i32,
        held_vertex_count: ins.held.len() as u32,
        local_model: model.as_ref().map(v1::LocalModel::from),
        force: force.map(|f| v1::Force {
            force: Some(to_vec3(&f.force)),
            axial_n: f.axial,
            magnitude_n: f.force.norm(),
            torque: Some(to_vec3(&f.torque)),
        }),
    }
}

/// Which parts of instrument `k` push tissue: the tip while its plane has depth
/// (the tip holds tissue, or the axis met the surface), the shaft while its plane is
/// in use.
pub fn contact_state(sim: &Simulation, k: usize) -> v1::ContactState {
    let Some(model) = sim.forces.as_ref().map(|f| f.models[k]) else {
        return v1::ContactState::None;
    };
    let tip = model
        .tip_plane
        .is_some_and(|p| (p.anchor - model.tip).dot(&p.normal) > 0.0);
    match (tip, model.shaft_plane.is_some()) {
        (false, false) => v1::ContactState::None,
        (true, false) => v1::ContactState::Tip,
        (false, true) => v1::ContactState::Shaft,
        (true, true) => v1::ContactState::TipAndShaft,
    }
}

/// Watches each instrument's contact state from tick to tick and turns its changes
/// into `CONTACT_BEGAN` / `CONTACT_ENDED` events: for the live session and for a
/// re-simulated replay alike.
#[derive(Clone, Debug)]
pub struct ContactWatch {
    states: Vec<v1::ContactState>,
}

impl ContactWatch {
    /// No instrument in contact yet.
    pub fn new(instruments: usize) -> Self {
        ContactWatch {
            states: vec![v1::ContactState::None; instruments],
        }
    }

    /// After a tick: an event for each instrument that came into or out of contact;
    /// `station(k)` is who holds instrument `k`.
    pub fn update(
        &mut self,
        sim: &Simulation,
        station: impl Fn(usize) -> Option<u64>,
        mut emit: impl FnMut(v1::Event),
    ) {
        for (k, was) in self.states.iter_mut().enumerate() {
            let now = contact_state(sim, k);
            let (was_in, is_in) = (
                *was != v1::ContactState::None,
                now != v1::ContactState::None,
            );
            if was_in != is_in {
                let kind = if is_in {
                    v1::EventKind::ContactBegan
                } else {
                    v1::EventKind::ContactEnded
                };
                emit(v1::Event {
                    tick: sim.tick,
                    sim_time_s: sim.time,
                    kind: kind as i32,
                    station_id: station(k),
                    instrument: Some(sim.instruments[k].name.clone()),
                    detail: format!("{now:?}"),
                });
            }
            *was = now;
        }
    }
}
