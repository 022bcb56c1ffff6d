//! Contact changes from tick to tick, as `CONTACT_BEGAN` / `CONTACT_ENDED` events.

use laparo_proto::v1;

use super::state::contact_state;
use crate::engine::simulation::Simulation;

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
                    detail: what_touches(now).to_owned(),
                });
            }
            *was = now;
        }
    }
}

/// What touches the liver in contact state `state`, in the words of a
/// `CONTACT_BEGAN` event's detail: `tip`, `shaft` or `tip and shaft`; nothing for
/// no contact (a `CONTACT_ENDED`'s detail is empty).
pub fn what_touches(state: v1::ContactState) -> &'static str {
    match state {
        v1::ContactState::Tip => "tip",
        v1::ContactState::Shaft => "shaft",
        v1::ContactState::TipAndShaft => "tip and shaft",
        v1::ContactState::None | v1::ContactState::Unspecified => "",
    }
}
