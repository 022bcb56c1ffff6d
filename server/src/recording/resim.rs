//! Re-simulation: the recorded poses run through a fresh build of the recorded
//! scene, tick by tick, and the result compared with what was recorded.
//!
//! Each recorded tick `k` holds every instrument's state after the `k`-th step,
//! including the pose that step used (`InstrumentState.pose`, doubles, absent when
//! the instrument was out of the body). Setting exactly those poses before step `k`
//! and stepping gives the recorded tick again if the engine is deterministic: it is
//! — fixed time step, no clocks or threads or randomness in a stage, every
//! reduction in a fixed order — so with the same build and scene the deviation is
//! exactly zero, and anything else points at a change in the physics.
//!
//! The surface is compared as recorded, f32 per coordinate: a deviation below
//! f32's resolution at the liver's size (~4e-9 m at 0.1 m) cannot be seen, but
//! "zero" means bit for bit equal. Forces are compared in f64, as the contract
//! carries them.
//!
//! A recorder that fell behind left ticks out ([`super::Report::Lagging`]); the
//! poses of a missing tick are not known, so the step holds the previous ones and
//! the ticks are counted in [`ResimReport::missing_ticks`]: from the first gap on,
//! a deviation is expected and says nothing about determinism.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use laparo_proto::v1;
use nalgebra::{Point3, Unit, Vector3};

use super::reader::{ReadError, Recorded, Recording, RecordingMeta};
use crate::engine::contact::InstrumentPose;
use crate::engine::scene::{Scene, SceneError};
use crate::engine::simulation::{Simulation, mesh_path};
use crate::frame::state::surface_positions;
use crate::frame::{Frame, Holder, TickOutputs};

#[derive(Debug, thiserror::Error)]
pub enum ResimError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error("the recorded scene does not build: {0}")]
    Scene(#[from] SceneError),
    #[error(
        "the scene to re-simulate has {built} surface coordinates where the recording \
         has {recorded}: its mesh is not the recorded one{hint}"
    )]
    MeshSize {
        built: usize,
        recorded: usize,
        hint: String,
    },
    #[error(
        "the scene to re-simulate does not rest where the recorded one did \
         (surface vertex {vertex} is {distance_m:e} m away): its mesh or scene is not the \
         recorded one{hint}"
    )]
    MeshMoved {
        vertex: usize,
        distance_m: f64,
        hint: String,
    },
    #[error("tick {tick}: instrument `{name}` is not in the recorded scene")]
    UnknownInstrument { tick: u64, name: String },
    #[error("tick {tick}: instrument `{name}` has a non-finite recorded pose")]
    BadPose { tick: u64, name: String },
    #[error(
        "its mesh is a file, and this server offers no scene directory to read one \
         from: it re-simulates only scenes on the meshes built into it"
    )]
    MeshNotServed,
    #[error("the recording's ticks go backwards: tick {tick} after tick {after}")]
    OutOfOrder { tick: u64, after: u64 },
    #[error(
        "tick {tick} is recorded at {at_s} s, where the scene's step of {dt_s} s puts \
         tick {expected:.0}: the file's ticks and times disagree"
    )]
    TickTime {
        tick: u64,
        at_s: f64,
        dt_s: f64,
        expected: f64,
    },
}

/// How far, in ticks, a recorded frame's tick may lie from its time over the
/// scene's step, `1 + 10⁻⁶ · tick`: a session's time is the sum of its steps, whose
/// round-off after `n` ticks is below `n² ε / 2` ticks (half a tick after 10⁸ ticks,
/// 19 days at 60 Hz). A tick further from its time is a damaged or forged file:
/// stepped to, a tick of 10⁶ among a few seconds of frames ran for minutes.
fn tick_slack(tick: u64) -> f64 {
    1.0 + 1e-6 * tick as f64
}

/// What a re-simulation found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ResimReport {
    /// Recorded ticks compared.
    pub ticks_compared: u64,
    /// Steps taken (compared ticks plus the missing ones stepped through).
    pub steps: u64,
    /// Ticks the recording does not hold (the recorder fell behind).
    pub missing_ticks: u64,
    /// First missing tick, after which deviations are expected.
    pub first_missing_tick: Option<u64>,
    /// Largest |recorded − re-simulated| over every surface coordinate, m.
    pub max_surface_deviation_m: f64,
    /// Tick of that largest surface deviation.
    pub worst_surface_tick: Option<u64>,
    /// Largest |recorded − re-simulated| force vector, over instruments and ticks, N.
    pub max_force_deviation_n: f64,
    /// Ticks whose held-vertex count or contact state differ, over instruments.
    pub contact_mismatches: u64,
    /// Simulated time covered, s.
    pub sim_time_s: f64,
    /// Wall time the re-simulation took, s.
    pub elapsed_s: f64,
}

impl ResimReport {
    /// Exactly the recorded session again: every tick present and equal.
    pub fn is_exact(&self) -> bool {
        self.missing_ticks == 0
            && self.max_surface_deviation_m == 0.0
            && self.max_force_deviation_n == 0.0
            && self.contact_mismatches == 0
    }
}

/// The recorded scene rebuilt, stepped with recorded poses.
pub struct Resimulator {
    pub sim: Simulation,
}

/// Where a re-simulated scene's mesh file may come from.
#[derive(Clone, Copy, Debug)]
pub enum MeshFiles<'a> {
    /// A re-simulation on the operator's own machine: relative paths resolve against
    /// the folder given, else the one the recording names; any file may be read.
    Local(Option<&'a Path>),
    /// A server's: a recording's scene is the file's word, so its mesh is read only
    /// inside the server's own scene directory, relative paths resolving against it
    /// (as the scenes it offers read theirs); without one, only the meshes embedded in
    /// the binary. Otherwise a forged recording naming `/etc/passwd` as its mesh had
    /// the server read it and quote its first line back.
    Served(Option<&'a Path>),
}

impl Resimulator {
    /// Builds the scene the recording names, its mesh from where `meshes` allows
    /// (see [`MeshFiles`]); the built
    /// rest surface must be the recorded one to the bit (`rest`, f32 triples), so a
    /// moved or edited mesh is an error rather than a meaningless deviation.
    pub fn new(
        meta: &RecordingMeta,
        rest: &[f32],
        meshes: MeshFiles<'_>,
    ) -> Result<Self, ResimError> {
        let (dir, root): (Option<PathBuf>, Option<&Path>) = match meshes {
            MeshFiles::Local(dir) => (
                dir.map(Path::to_path_buf)
                    .or_else(|| meta.scene_dir.clone()),
                None,
            ),
            MeshFiles::Served(dir) => (dir.map(Path::to_path_buf), dir),
        };
        let hint = match &dir {
            Some(d) => format!(" (its mesh was looked for from {})", d.display()),
            None => String::new(),
        };
        let mut scene = Scene::parse(&meta.scene_toml, &meta.scene, dir.as_deref())?;
        if let MeshFiles::Served(served) = meshes {
            if served.is_none() && mesh_path(&scene).is_some() {
                return Err(ResimError::MeshNotServed);
            }
            scene.mesh_root = root.map(Path::to_path_buf);
        }
        let sim = scene.build()?;
        let built = surface_positions(&sim);
        if built.len() != rest.len() {
            return Err(ResimError::MeshSize {
                built: built.len(),
                recorded: rest.len(),
                hint,
            });
        }
        if let Some((vertex, distance_m)) = largest_gap(&built, rest).filter(|&(_, d)| d != 0.0) {
            return Err(ResimError::MeshMoved {
                vertex,
                distance_m,
                hint,
            });
        }
        Ok(Resimulator { sim })
    }

    /// Index of an instrument by name.
    pub fn instrument(&self, name: &str) -> Option<usize> {
        self.sim.instruments.iter().position(|i| i.name == name)
    }

    /// Sets the poses recorded for the next tick (instruments not named keep theirs)
    /// and steps once. The recorded doubles are used as they are: the axis was unit
    /// when the server stepped with it, and normalising again could move its last bit.
    pub fn step(&mut self, states: &[v1::InstrumentState]) -> Result<(), ResimError> {
        let tick = self.sim.tick + 1;
        for s in states {
            let k =
                self.instrument(&s.instrument)
                    .ok_or_else(|| ResimError::UnknownInstrument {
                        tick,
                        name: s.instrument.clone(),
                    })?;
            let pose = match &s.pose {
                None => None,
                Some(p) => {
                    let v = |v: &Option<v1::Vec3>| v.as_ref().map(|v| Vector3::new(v.x, v.y, v.z));
                    match (v(&p.tip), v(&p.axis)) {
                        (Some(tip), Some(axis))
                            if tip.iter().chain(axis.iter()).all(|c| c.is_finite()) =>
                        {
                            Some(InstrumentPose::new(
                                Point3::from(tip),
                                Unit::new_unchecked(axis),
                            ))
                        }
                        _ => {
                            return Err(ResimError::BadPose {
                                tick,
                                name: s.instrument.clone(),
                            });
                        }
                    }
                }
            };
            self.sim.set_pose(k, pose);
        }
        self.sim.tick();
        Ok(())
    }
}

/// The coordinate triple where `a` and `b` differ most, and by how much (m).
fn largest_gap(a: &[f32], b: &[f32]) -> Option<(usize, f64)> {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .enumerate()
        .map(|(i, (p, q))| {
            let d = p
                .iter()
                .zip(q)
                .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            (i, d)
        })
        .max_by(|x, y| x.1.total_cmp(&y.1))
}

/// Largest coordinate difference, m.
fn max_abs_diff(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .fold(0.0, f64::max)
}

/// Re-runs the recording's physics and compares every recorded tick (see the module
/// documentation). `progress` is called after each compared tick with its number.
pub fn resimulate(
    recording: &Recording,
    scene_dir: Option<&Path>,
    progress: impl FnMut(u64),
) -> Result<ResimReport, ResimError> {
    resimulate_as(recording, recording.meta(), scene_dir, progress)
}

/// [`resimulate`] with the scene `meta` describes (its `scene_toml`, `scene` and
/// `scene_dir`) in place of the recorded one: the same hands on another material or
/// force model. The mesh must be the recorded one.
pub fn resimulate_as(
    recording: &Recording,
    meta: &RecordingMeta,
    scene_dir: Option<&Path>,
    mut progress: impl FnMut(u64),
) -> Result<ResimReport, ResimError> {
    let started = Instant::now();
    let mut run = Resimulation::new(recording, meta, MeshFiles::Local(scene_dir))?;
    let mut report = ResimReport::default();
    for m in recording.messages() {
        let Recorded::Surface(surface) = m?.message else {
            continue;
        };
        run.run_to(surface.tick, surface.sim_time_s, |stepped| {
            report.steps += 1;
            if stepped.recorded.is_empty() {
                report.missing_ticks += 1;
                report.first_missing_tick.get_or_insert(stepped.frame.tick);
            }
            if stepped.frame.tick == surface.tick {
                compare(&stepped, &surface, &mut report);
            }
            true
        })?;
        progress(surface.tick);
    }
    report.sim_time_s = run.sim().time;
    report.elapsed_s = started.elapsed().as_secs_f64();
    Ok(report)
}

/// A recording's poses by tick, and the scene rebuilt to step with them: what
/// [`resimulate`] and a re-simulated replay both drive.
pub struct Resimulation {
    resim: Resimulator,
    /// The recorded instrument states by tick. They are small (a pose, a model and
    /// a force per instrument and tick); the surfaces are not, and callers stream
    /// them.
    states: BTreeMap<u64, Vec<v1::InstrumentState>>,
    /// Each step's events and frame, made as the live session made them.
    outputs: TickOutputs,
}

/// One re-simulated tick: the states recorded for it (empty for a tick the recorder
/// lost), then what the step gives, made as a live session makes it
/// ([`TickOutputs::produce`]): its contact events and its frame, with each
/// instrument's holder as recorded.
pub struct Stepped<'a> {
    pub recorded: &'a [v1::InstrumentState],
    pub events: Vec<v1::Event>,
    pub frame: Frame,
}

impl Resimulation {
    /// Builds the scene `meta` describes against `recording`'s rest surface, its
    /// mesh from where `meshes` allows (see [`Resimulator::new`]), and gathers its
    /// recorded states.
    pub fn new(
        recording: &Recording,
        meta: &RecordingMeta,
        meshes: MeshFiles<'_>,
    ) -> Result<Self, ResimError> {
        let rest = recording
            .scene()?
            .rest_surface
            .map(|s| s.positions)
            .unwrap_or_default();
        let resim = Resimulator::new(meta, &rest, meshes)?;
        let mut states: BTreeMap<u64, Vec<v1::InstrumentState>> = BTreeMap::new();
        for s in recording.instrument_states()? {
            states.entry(s.message.tick).or_default().push(s.message);
        }
        let outputs = TickOutputs::new(resim.sim.instruments.len());
        Ok(Resimulation {
            resim,
            states,
            outputs,
        })
    }

    pub fn sim(&self) -> &Simulation {
        &self.resim.sim
    }

    /// Steps up to and including tick `tick`, recorded at `at_s` s, each step with
    /// the poses recorded for it; a tick the recorder lost (no states) holds the
    /// previous poses. `each` sees every step's outputs ([`Stepped`]), and stops the
    /// run by answering `false`, which this then returns (calling again with the same
    /// tick goes on). A tick at or before the current one is an error (the file's
    /// ticks go backwards), and so is one that its time does not put within
    /// [`tick_slack`] of it.
    pub fn run_to(
        &mut self,
        tick: u64,
        at_s: f64,
        mut each: impl FnMut(Stepped<'_>) -> bool,
    ) -> Result<bool, ResimError> {
        let dt_s = self.resim.sim.dt;
        let expected = at_s / dt_s;
        let off = (tick as f64 - expected).abs();
        if off.is_nan() || off > tick_slack(tick) {
            return Err(ResimError::TickTime {
                tick,
                at_s,
                dt_s,
                expected,
            });
        }
        if tick <= self.resim.sim.tick {
            return Err(ResimError::OutOfOrder {
                tick,
                after: self.resim.sim.tick,
            });
        }
        while self.resim.sim.tick < tick {
            let next = self.resim.sim.tick + 1;
            let recorded = self.states.remove(&next).unwrap_or_default();
            self.resim.step(&recorded)?;
            let sim = &self.resim.sim;
            let holder = |k: usize| {
                let name = &sim.instruments[k].name;
                recorded
                    .iter()
                    .find(|s| &s.instrument == name)
                    .map_or_else(Holder::default, |s| Holder {
                        station: s.station_id,
                        pose_sequence: s.pose_sequence,
                    })
            };
            let mut events = Vec::new();
            let frame = self.outputs.produce(sim, holder, |e| events.push(e));
            let stepped = Stepped {
                recorded: &recorded,
                events,
                frame,
            };
            if !each(stepped) {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// Adds one tick's differences to the report: the recorded `surface` and the
/// states recorded for the tick against the re-simulated frame.
fn compare(stepped: &Stepped<'_>, surface: &v1::SurfaceFrame, report: &mut ResimReport) {
    report.ticks_compared += 1;
    let now = &stepped.frame.surface;
    let d = if now.len() == surface.positions.len() {
        max_abs_diff(now, &surface.positions)
    } else {
        f64::INFINITY
    };
    if d > report.max_surface_deviation_m {
        report.max_surface_deviation_m = d;
        report.worst_surface_tick = Some(surface.tick);
    }
    for s in stepped.recorded {
        let instruments = &stepped.frame.instruments;
        let Some(again) = instruments.iter().find(|i| i.instrument == s.instrument) else {
            continue;
        };
        let f = |s: &v1::InstrumentState| {
            s.force
                .as_ref()
                .and_then(|f| f.force.as_ref())
                .map(|v| Vector3::new(v.x, v.y, v.z))
                .unwrap_or_else(Vector3::zeros)
        };
        let df = (f(s) - f(again)).norm();
        report.max_force_deviation_n = report.max_force_deviation_n.max(df);
        if s.held_vertex_count != again.held_vertex_count || s.contact != again.contact {
            report.contact_mismatches += 1;
        }
    }
}
