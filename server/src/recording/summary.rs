//! What a reviewer wants first from a recording: how long, how far each instrument
//! travelled, how long it touched the liver, how hard and how abruptly it pushed,
//! and what happened.

use std::collections::BTreeMap;

use laparo_proto::v1;

use super::reader::{ReadError, Recorded, Recording};

/// One instrument over a recording.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct InstrumentSummary {
    /// Ticks at which the instrument had a pose.
    pub ticks_with_pose: u64,
    /// Length of the tip's path, m: the sum of the distances between the tip
    /// positions of consecutive ticks.
    pub path_length_m: f64,
    /// Ticks in contact (tip, shaft or both).
    pub contact_ticks: u64,
    /// Simulated time in contact, s (contact ticks / mechanics rate).
    pub time_in_contact_s: f64,
    /// Largest |force|, N.
    pub max_force_n: f64,
    /// Mean |force| over every tick, N.
    pub mean_force_n: f64,
    /// Mean |force| over the ticks in contact, N (0 without contact).
    pub mean_contact_force_n: f64,
    /// Largest |F(t) − F(t−1)| between consecutive ticks, N.
    pub max_force_jump_n: f64,
}

/// A recording in numbers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordingSummary {
    /// Simulated time of the last tick, s since the session started.
    pub duration_s: f64,
    /// Ticks recorded (surface frames).
    pub ticks: u64,
    /// Poses recorded.
    pub poses: u64,
    /// Per instrument, by name.
    pub instruments: BTreeMap<String, InstrumentSummary>,
    /// Events counted by kind (`EVENT_KIND_…` names).
    pub events: BTreeMap<String, u64>,
}

#[derive(Default)]
struct Running {
    summary: InstrumentSummary,
    ticks: u64,
    force_sum: f64,
    contact_force_sum: f64,
    last_tip: Option<[f64; 3]>,
    last_force: Option<[f64; 3]>,
}

fn vec3(v: &Option<v1::Vec3>) -> Option<[f64; 3]> {
    v.as_ref().map(|v| [v.x, v.y, v.z])
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Reads the whole recording once and sums it up.
pub fn summarize(recording: &Recording) -> Result<RecordingSummary, ReadError> {
    let mut out = RecordingSummary::default();
    let mut rate = 0.0;
    let mut running: BTreeMap<String, Running> = BTreeMap::new();
    for m in recording.messages() {
        match m?.message {
            Recorded::Scene(scene) => {
                rate = scene.summary.map_or(0.0, |s| s.mechanics_rate_hz);
            }
            Recorded::Pose(_) => out.poses += 1,
            Recorded::Surface(frame) => {
                out.ticks += 1;
                out.duration_s = out.duration_s.max(frame.sim_time_s);
            }
            Recorded::Event(event) => {
                let kind = v1::EventKind::try_from(event.kind).map_or_else(
                    |_| format!("EVENT_KIND_{}", event.kind),
                    |k| k.as_str_name().to_string(),
                );
                *out.events.entry(kind).or_default() += 1;
            }
            Recorded::Instrument(state) => {
                let r = running.entry(state.instrument.clone()).or_default();
                r.ticks += 1;
                let tip = state.pose.as_ref().and_then(|p| vec3(&p.tip));
                if let Some(tip) = tip {
                    r.summary.ticks_with_pose += 1;
                    if let Some(last) = r.last_tip {
                        r.summary.path_length_m += distance(tip, last);
                    }
                }
                r.last_tip = tip.or(r.last_tip);
                let in_contact = !matches!(
                    v1::ContactState::try_from(state.contact),
                    Ok(v1::ContactState::None | v1::ContactState::Unspecified) | Err(_)
                );
                let force = state
                    .force
                    .as_ref()
                    .and_then(|f| vec3(&f.force))
                    .unwrap_or([0.0; 3]);
                let magnitude = distance(force, [0.0; 3]);
                r.summary.max_force_n = r.summary.max_force_n.max(magnitude);
                r.force_sum += magnitude;
                if in_contact {
                    r.summary.contact_ticks += 1;
                    r.contact_force_sum += magnitude;
                }
                if let Some(last) = r.last_force {
                    r.summary.max_force_jump_n =
                        r.summary.max_force_jump_n.max(distance(force, last));
                }
                r.last_force = Some(force);
            }
        }
    }
    for (name, r) in running {
        let mut s = r.summary;
        s.mean_force_n = r.force_sum / r.ticks.max(1) as f64;
        if s.contact_ticks > 0 {
            s.mean_contact_force_n = r.contact_force_sum / s.contact_ticks as f64;
        }
        if rate > 0.0 {
            s.time_in_contact_s = s.contact_ticks as f64 / rate;
        }
        out.instruments.insert(name, s);
    }
    Ok(out)
}
