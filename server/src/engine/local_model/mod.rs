//! Reaction forces (paper §3): per instrument and per tick, the two-plane local model a
//! force loop extrapolates from, and the force it gives at the tick's pose.
//!
//! The local model ([`laparo_proto::force::LocalModel`]) is two planes:
//! - the **tip plane**, normal `n_prox` (eq. 7, from the contact stage), while the axis
//!   meets the surface;
//! - the **shaft plane**, containing the axis, normal the average of `Z × ê` over the
//!   shaft's neighbouring edges (each oriented from the tissue toward the axis), while
//!   the shaft holds vertices.
//!
//! # Anchors: penetration depth that survives a steady push
//!
//! Eq. 8 takes the force from the depth of the instrument in the plane's half-space.
//! A plane through the tissue as the instrument has pushed it (`P_prox`, or the axis
//! itself for the shaft plane) gives zero depth at the pose the model was made for: a
//! trainee holding the instrument still inside the liver would feel nothing. So each
//! plane is moved out of the tissue, along its normal, by the **indentation** `δ` the
//! instrument has made:
//!
//! `δ = max(0, max_i (F_i − x_i)·n)` over the vertices `i` the plane's contact holds,
//!
//! where `x_i` is where the vertex is now and `F_i` where it was when last free: the
//! surface before the instrument took it, with the sag under gravity and the dents of
//! other instruments already in it ([`free`]; a vertex let go and taken again within
//! [`free::FREE_AFTER_S`] keeps where it was before it was first taken, not where it
//! sprang back to). The anchor is `A = X + δ n` with `X` the
//! tip `P` (tip plane) or the point of the axis level with the held vertices (shaft
//! plane). At the model's pose the depth is then `δ`; pushing deeper by `h` makes it
//! `δ + h`, withdrawing lowers it until the force vanishes; holding still keeps it, and
//! the force, steady.
//!
//! # Stiffness
//!
//! - `geometric` (the paper): `λ` proportional to the average Young's modulus near the
//!   contact ([`stiffness::geometric_tip`], [`stiffness::geometric_shaft`]);
//! - `calibrated`: `λ` and the anchor fitted so that the model reproduces, at the
//!   tick's pose, the elastic model's reaction on the vertices each plane holds
//!   ([`stiffness::Fit`]): its push along the plane's normal by the plane, and its
//!   part along the plane, the drag of tissue that sticks to the instrument, as the
//!   plane's `drag`, where the geometric planes give only the push.
//!
//! # Drag, rendered at haptic rate
//!
//! The drag is sent apart from the plane, with its own stiffness: a force loop
//! renders it plus the held tissue's pull back toward where the contact point was
//! when the model was made, `κ λ (X₀ − X)` along the plane, fading with the depth
//! ([`laparo_proto::force::LocalModel::force`]; `κ = 1.5`, the stuck tissue being
//! stiffer sideways than `λ`, see [`laparo_proto::force::LATERAL_STIFFNESS_RATIO`]).
//! Rendered instead by tilting the
//! plane along the whole reaction, the drag did not change as the instrument moved
//! sideways, and only each new model (60 Hz) stepped it to what the tissue dragged
//! along gave: a lateral spring of the held tissue's stiffness sampled at the
//! mechanics rate. A 0.15 kg hand resting on 1 MPa tissue with it gained energy at
//! every target from 2 to 8 mm past the surface, the fitted `λ` swinging from 10² to
//! 10⁶ N/m from tick to tick as the tip bounced; with the drag apart it comes to rest
//! at all of them, `λ` steady within 10% (`tests/tests/haptics.rs`). With the pull at
//! `λ` rather than `κ λ`, softer than the stuck tissue, it still gained energy on
//! 0.1–0.8 MPa tissue, at 49 of 84 targets of the grid that test runs.
//!
//! Which held vertices belong to which plane: with a tip contact, those within one
//! radius of the tip along the axis (`(x_i − P)·Z ≤ r`) are the tip's; the others are
//! the shaft's.

pub mod free;
pub mod planes;
pub mod stiffness;

use laparo_proto::force::{DeviceForce, ForceModel, LocalModel, Plane, split};
use nalgebra::{Point3, Unit, Vector3};
use serde::Deserialize;

use crate::engine::contact::{Instrument, InstrumentPose};
use crate::engine::elastic::ElasticModel;
use crate::engine::mesh::{Surface, TetMesh};
use free::FreeSurface;
use stiffness::{Calibration, VertexMaterial};

/// The reaction-force model.
///
/// `Calibrated` is the default: it renders the contact's own reaction (the elastic
/// force on the held tissue, scaled to the instrument's footprint unless the scene
/// turns that off), which is what a press gives on every mesh alike. The paper's
/// `Geometric` model stays as the scene's option: mesh-independent by construction
/// but not the tissue's force. On the force-error bench's probe of the default
/// liver at 60 Hz it is 97.4% RMS off the 1 kHz reaction, the calibrated model
/// 14.0%; pressed 8 mm it renders the flat punch's 0.45 N where the footprint's
/// reaction is 0.20–0.29 N on every liver (`cargo bench --bench convergence`).
/// Most of the calibrated model's error is not the model's: it lies where the
/// reaction itself steps within a tick, which a model a tick old cannot foresee. On
/// that probe the 1 kHz engine drops 0.68 N to nothing in one tick of the
/// withdrawal, when the tissue laid on the tip plane beside the shaft has slid
/// 1.05 r from the tip and is let go (the bench's let-go table). The vertex that
/// carries it, three radii off the axis, slides on the friction cone (`|T| / N` =
/// 1.01 at μ = 1) and takes its triangles off the tip: for 51 ms before the let-go
/// the tip touches none of them, yet the vertex, held, rides with the instrument
/// and keeps its load. What that points to is contact on the face under the tip,
/// its load shared among the triangle's vertices as the contact point moves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ForceModelKind {
    /// The paper's: apparent stiffness proportional to the local Young's modulus.
    Geometric,
    /// Stiffness and anchors fitted to the elastic model's reaction each tick.
    #[default]
    Calibrated,
}

/// The force stage of a scene with instruments: builds every instrument's local model
/// and force after the contact stage. Allocates nothing per tick.
#[derive(Debug)]
pub struct LocalModelStage {
    kind: ForceModel,
    material: VertexMaterial,
    free: FreeSurface,
    calibration: Vec<Calibration>,
    /// The last local model of each instrument, in scene order.
    pub models: Vec<LocalModel>,
    /// The force of each instrument's model at its pose, split for the device.
    pub forces: Vec<DeviceForce>,
}

/// What one plane's contact holds: the inputs of its anchor and stiffness.
#[derive(Clone, Copy, Debug, Default)]
struct Held {
    /// Vertices counted.
    count: u32,
    /// Indentation `δ`, m (≥ 0).
    indentation: f64,
    /// The tissue's force on the instrument through these vertices, N.
    reaction: Vector3<f64>,
    /// Sum of the vertices' Young's moduli and Poisson ratios (for averages).
    young: f64,
    poisson: f64,
    /// Sums over the vertices of `w`, `w s` and `w s²`, with `s = (x_i − P)·Z` their
    /// place along the axis and `w = max(0, depth)` their indentation.
    along: [f64; 3],
}

impl Held {
    fn new() -> Self {
        Held {
            along: [0.0; 3],
            ..Held::default()
        }
    }

    fn add(&mut self, depth: f64, reaction: Vector3<f64>, material: (f64, f64), s: f64) {
        self.count += 1;
        self.indentation = self.indentation.max(depth);
        self.reaction += reaction;
        self.young += material.0;
        self.poisson += material.1;
        let w = depth.max(0.0);
        self.along = [
            self.along[0] + w,
            self.along[1] + w * s,
            self.along[2] + w * s * s,
        ];
    }
}

impl LocalModelStage {
    /// A stage for `instruments` instruments on `mesh` with `model`'s materials.
    pub fn new(
        kind: ForceModelKind,
        mesh: &TetMesh,
        model: &ElasticModel,
        instruments: &[Instrument],
    ) -> Self {
        let kind = match kind {
            ForceModelKind::Geometric => ForceModel::Geometric,
            ForceModelKind::Calibrated => ForceModel::Calibrated,
        };
        let axis = Unit::new_unchecked(Vector3::z());
        LocalModelStage {
            kind,
            material: VertexMaterial::new(mesh, model),
            free: FreeSurface::new(&mesh.positions),
            calibration: vec![Calibration::default(); instruments.len()],
            models: vec![LocalModel::free(0, 0.0, Point3::origin(), axis); instruments.len()],
            forces: vec![
                DeviceForce {
                    force: Vector3::zeros(),
                    axial: 0.0,
                    torque: Vector3::zeros(),
                };
                instruments.len()
            ],
        }
    }

    /// After the contact stage of tick `tick` (simulated time `time`): each
    /// instrument's local model and force, from the positions `x`.
    pub fn compute_models_and_forces(
        &mut self,
        tick: u64,
        time: f64,
        instruments: &[Instrument],
        surface: &Surface,
        x: &[Point3<f64>],
    ) {
        for (k, ins) in instruments.iter().enumerate() {
            let model = match ins.current {
                Some(pose) => self.model_of(k, ins, &pose, surface, x, tick, time),
                None => {
                    self.calibration[k] = Calibration::default();
                    let last = &self.models[k];
                    LocalModel::free(tick, time, last.tip, last.axis)
                }
            };
            let applied = model.force(&model.tip, &model.axis);
            self.forces[k] = split(&applied.force, &applied.point, &model.axis, &ins.trocar);
            self.models[k] = model;
        }
        self.free.update(instruments, surface, x, time);
    }

    #[allow(clippy::too_many_arguments)]
    fn model_of(
        &mut self,
        k: usize,
        ins: &Instrument,
        pose: &InstrumentPose,
        surface: &Surface,
        x: &[Point3<f64>],
        tick: u64,
        time: f64,
    ) -> LocalModel {
        let mut model = LocalModel::free(tick, time, pose.tip, pose.axis);
        model.kind = self.kind;
        let (p, z, r) = (pose.tip, pose.axis, ins.radius);
        let tip_contact = tip_contact(ins, pose, surface, x);
        // Held vertices go to the tip plane only when the tip touches.
        let tip_normal = tip_contact.filter(|t| t.touching).map(|t| t.normal);
        let shaft_normal = planes::shaft_normal(ins, surface, x);
        let (mut tip, mut shaft) = (Held::new(), Held::new());
        for (i, &v) in ins.held.iter().enumerate() {
            let vi = v as usize;
            let s = (x[vi] - p).dot(&z);
            let (held, n) = match (tip_normal, shaft_normal) {
                (Some(n), _) if s <= r => (&mut tip, n),
                (_, Some(n)) => (&mut shaft, n),
                (Some(n), None) => (&mut tip, n),
                (None, None) => continue,
            };
            let pushed = self.free.position(v) - x[vi];
            let reaction = ins.report.held_reactions.get(i).copied();
            let reaction = reaction.unwrap_or_else(Vector3::zeros);
            held.add(pushed.dot(&n), reaction, self.material.at(v), s);
        }
        let calibration = &mut self.calibration[k];
        model.tip_plane = match tip_contact {
            Some(TipTouch {
                normal: n,
                triangle,
                surface: q,
                ..
            }) => {
                // Nothing held yet: the material under the tip.
                let material = match tip.count {
                    0 => self.material.triangle(surface.triangles[triangle as usize]),
                    _ => tip.material(),
                };
                let k_geo = stiffness::geometric_tip(r, material);
                let (lambda, depth, drag) = match self.kind {
                    ForceModel::Geometric => (k_geo, tip.indentation, Vector3::zeros()),
                    ForceModel::Calibrated => {
                        let (lambda, depth) = calibration.tip.fit(tip.sample(&n), k_geo);
                        (lambda, depth, tip.drag(&n))
                    }
                };
                model.young_modulus = Some(material.0);
                // Holding tissue: out by the indentation. Holding nothing (touching
                // or approaching): on the surface ahead, offset by the tip's radius,
                // where the tip meets it — negative depth, no force, until it does.
                let anchor = match (tip.count, q) {
                    (0, Some(q)) => q + n.into_inner() * r,
                    _ => p + n.into_inner() * depth,
                };
                Some(Plane {
                    normal: n,
                    anchor,
                    stiffness: lambda,
                    drag,
                })
            }
            _ => {
                calibration.tip = Default::default();
                None
            }
        };
        model.shaft_plane = match shaft_normal {
            Some(n) if shaft.count > 0 => {
                let material = shaft.material();
                let (level, contact_length) = shaft.footprint();
                let k_geo = stiffness::geometric_shaft(r, contact_length, material);
                let (lambda, depth, drag) = match self.kind {
                    ForceModel::Geometric => (k_geo, shaft.indentation, Vector3::zeros()),
                    ForceModel::Calibrated => {
                        let (lambda, depth) = calibration.shaft.fit(shaft.sample(&n), k_geo);
                        (lambda, depth, shaft.drag(&n))
                    }
                };
                let level = level.clamp(0.0, ins.length);
                let e = if tip.count > 0 {
                    (tip.young + shaft.young) / f64::from(tip.count + shaft.count)
                } else {
                    material.0
                };
                model.young_modulus = Some(e);
                Some(Plane {
                    normal: n,
                    anchor: p + z.into_inner() * level + n.into_inner() * depth,
                    stiffness: lambda,
                    drag,
                })
            }
            _ => {
                calibration.shaft = Default::default();
                None
            }
        };
        model
    }
}

/// What lies ahead of the tip.
#[derive(Clone, Copy, Debug)]
struct TipTouch {
    /// `n_prox` (eq. 7).
    normal: Unit<Vector3<f64>>,
    triangle: u32,
    /// The surface point ahead, when the contact stage found it by proximity.
    surface: Option<Point3<f64>>,
    /// Whether the tip touches: held vertices near it are the tip plane's.
    touching: bool,
}

/// The surface ahead of the tip: where the axis met the surface this tick (the
/// contact stage's §2.5, touching), or else the surface point `q` nearest the tip
/// within the approach reach, if it lies ahead, within 60° of `−Z`
/// (`(P − q)·Z ≥ |P − q| / 2`). It touches within `1.5 r`: a pressed tip keeps its
/// triangle at `r` ahead, and 1.5 r is the margin the shaft's neighbouring edges use.
/// A point beside the tip, level with it, is the shaft's.
///
/// Sending the plane ahead before the tip touches is what lets a force loop render
/// the onset of contact at haptic rate: without it, the first force would come one
/// mechanics tick after the tip went in, and a hand would bounce off.
fn tip_contact(
    ins: &Instrument,
    pose: &InstrumentPose,
    surface: &Surface,
    x: &[Point3<f64>],
) -> Option<TipTouch> {
    let (tip, axis) = (&pose.tip, &pose.axis);
    if let Some(t) = ins.report.tip {
        return Some(TipTouch {
            normal: t.n_prox,
            triangle: t.triangle,
            surface: None,
            touching: true,
        });
    }
    let near = ins.report.nearest.and_then(|near| {
        let distance = (near.point - tip).norm();
        let ahead = (tip - near.point).dot(axis);
        (ahead >= 0.5 * distance).then_some(TipTouch {
            normal: near.normal,
            triangle: near.triangle,
            surface: Some(near.point),
            touching: distance <= 1.5 * ins.radius,
        })
    });
    near.or_else(|| held_at_tip(ins, pose, surface, x))
}

/// A tip pressed deep, the tissue wrapped around it: the face pass has cleared
/// every triangle off its axis and the nearest surface lies beside it, not ahead,
/// yet it holds vertices level with its end (`(x_i − P)·Z ≤ r`). Their plane is
/// the tip's, with the axis for the surface's normal (the tissue pushes the tip back
/// along `Z`) and a triangle of the first such vertex for its material. Without it
/// those vertices belonged to no plane, and a tip pressed 15 mm into liver-80k
/// rendered nothing against a reaction of 0.48 N.
fn held_at_tip(
    ins: &Instrument,
    pose: &InstrumentPose,
    surface: &Surface,
    x: &[Point3<f64>],
) -> Option<TipTouch> {
    let v = *ins
        .held
        .iter()
        .find(|&&v| (x[v as usize] - pose.tip).dot(&pose.axis) <= ins.radius)?;
    let slot = *surface.surface_index.get(v as usize)? as usize;
    let first = *surface.vertex_triangle_offsets.get(slot)? as usize;
    Some(TipTouch {
        normal: pose.axis,
        triangle: *surface.vertex_triangles.get(first)?,
        surface: None,
        touching: true,
    })
}

impl Held {
    /// Where the contact is along the axis and how long it is, m: the mean and
    /// `√12 ×` the standard deviation of `s` weighted by indentation (the length of
    /// a uniform contact with that spread). A vertex barely pressed at the end of the
    /// contact moves them a little, not by a whole edge as the extent of the held
    /// vertices did — which made the shaft's λ flicker by 6% as such a vertex came
    /// and went.
    fn footprint(&self) -> (f64, f64) {
        let [w, ws, wss] = self.along;
        if w <= 0.0 {
            return (0.0, 0.0);
        }
        let mean = ws / w;
        (mean, (12.0 * (wss / w - mean * mean).max(0.0)).sqrt())
    }

    /// Average `(E, ν)` of the counted vertices (at least one).
    fn material(&self) -> (f64, f64) {
        let n = f64::from(self.count.max(1));
        (self.young / n, self.poisson / n)
    }

    /// The calibration sample: indentation and push along the plane's normal `n` (the
    /// drag is rendered apart, see [`Held::drag`]).
    fn sample(&self, n: &Unit<Vector3<f64>>) -> stiffness::Sample {
        stiffness::Sample {
            indentation: self.indentation,
            push: self.reaction.dot(n),
        }
    }

    /// The drag: the reaction's part along the plane, orthogonal to `n`, N (zero while
    /// nothing is held).
    fn drag(&self, n: &Unit<Vector3<f64>>) -> Vector3<f64> {
        self.reaction - n.into_inner() * self.reaction.dot(n)
    }
}

#[cfg(test)]
mod tests;
