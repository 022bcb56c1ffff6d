//! One tick's state read off the simulation: the surface and each instrument.

use laparo_proto::force::wire::{to_pose, to_vec3};
use laparo_proto::v1;

use crate::engine::simulation::Simulation;

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
        held_surface_vertices: held_surface_vertices(sim, k),
        local_model: model.as_ref().map(v1::LocalModel::from),
        force: force.map(|f| v1::Force {
            force: Some(to_vec3(&f.force)),
            axial_n: f.axial,
            magnitude_n: f.force.norm(),
            torque: Some(to_vec3(&f.torque)),
        }),
    }
}

/// The vertices instrument `k` holds, as surface vertex numbers (their slots in
/// the surface, the order of [`surface_positions`]). The contact stage pushes and
/// holds surface vertices only; an interior vertex, which it never holds, would
/// have no number and is left out.
pub fn held_surface_vertices(sim: &Simulation, k: usize) -> Vec<u32> {
    let slot = &sim.mesh.surface.surface_index;
    sim.instruments[k]
        .held
        .iter()
        .map(|&v| slot[v as usize])
        .filter(|&s| s != u32::MAX)
        .collect()
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
