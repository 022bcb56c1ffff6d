//! The apparent stiffness `λ` of the local-model planes (paper §3, eq. 8).

use crate::engine::elastic::ElasticModel;
use crate::engine::mesh::TetMesh;

/// Young's modulus and Poisson's ratio at each vertex: the averages over the
/// tetrahedra around it, weighted by their volumes. What "the tetrahedra located in
/// the neighbourhood of the instrument" average to (the paper's λ follows E there).
#[derive(Debug)]
pub struct VertexMaterial {
    young: Vec<f64>,
    poisson: Vec<f64>,
}

impl VertexMaterial {
    pub fn new(mesh: &TetMesh, model: &ElasticModel) -> Self {
        let n = mesh.vertex_count();
        let (mut young, mut poisson, mut volume) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for (t, &tet) in mesh.tets.iter().enumerate() {
            let v = TetMesh::six_volume(&mesh.positions, tet).abs() / 6.0;
            let m = &model.materials[model.tet_material[t] as usize];
            for &i in &tet {
                young[i as usize] += v * m.young_modulus;
                poisson[i as usize] += v * m.poisson_ratio;
                volume[i as usize] += v;
            }
        }
        for ((e, nu), v) in young.iter_mut().zip(&mut poisson).zip(&volume) {
            if *v > 0.0 {
                *e /= v;
                *nu /= v;
            }
        }
        VertexMaterial { young, poisson }
    }

    /// `(E, ν)` at vertex `v`.
    pub fn at(&self, v: u32) -> (f64, f64) {
        (self.young[v as usize], self.poisson[v as usize])
    }

    /// `(E, ν)` averaged over a triangle's vertices.
    pub fn triangle(&self, t: [u32; 3]) -> (f64, f64) {
        let sum = t.iter().fold((0.0, 0.0), |(e, nu), &v| {
            let (ev, nuv) = self.at(v);
            (e + ev, nu + nuv)
        });
        (sum.0 / 3.0, sum.1 / 3.0)
    }
}

/// Geometric `λ` of the tip plane, N/m: a rigid flat circular punch of radius `r`
/// pressed into an elastic half-space (Boussinesq), `λ = 2 r E / (1 − ν²)`.
///
/// The paper asks only that `λ` be proportional to the average `E` near the contact;
/// the punch gives the factor, so that the geometric model's forces have the right
/// order for the instrument's size (56 N/m for r = 5 mm, E = 4.5 kPa, ν = 0.45). It
/// is a half-space law: a thin part of the liver, or a contact near a support, is
/// stiffer than it says — what the calibrated model corrects.
pub fn geometric_tip(radius: f64, (e, nu): (f64, f64)) -> f64 {
    2.0 * radius * e / (1.0 - nu * nu)
}

/// Geometric `λ` of the shaft plane, N/m: the shaft presses a strip `2r` wide and
/// `L + 2r` long (`L` the extent of the held vertices along the axis); the punch law of
/// [`geometric_tip`] with the radius of the circle of the same area,
/// `a = √(2r (L + 2r) / π)`.
pub fn geometric_shaft(radius: f64, length: f64, material: (f64, f64)) -> f64 {
    let area = 2.0 * radius * (length.max(0.0) + 2.0 * radius);
    geometric_tip((area / std::f64::consts::PI).sqrt(), material)
}

/// What one plane's contact gives for calibration: the indentation and the push,
/// both along the plane's normal `n` (the surface's). The reaction's part along the
/// plane, the drag, is no stiffness against pressing and is rendered apart (the
/// plane's `drag`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Indentation `δ` of the held vertices along `n`, m.
    pub indentation: f64,
    /// The elastic model's reaction on them along `n`, `R·n`, N.
    pub push: f64,
}

/// Calibration state of an instrument's two planes, kept from tick to tick while the
/// contact lasts.
#[derive(Clone, Copy, Debug, Default)]
pub struct Calibration {
    pub tip: Fit,
    pub shaft: Fit,
}

/// The calibrated stiffness of one plane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Fit {
    lambda: Option<f64>,
}

/// The indentation below which `R / δ` is not trusted, m: 0.1 mm. Below it both are small differences of positions that the
/// elastic solve only knows to its tolerance (a few µm for the default scene), and the
/// previous stiffness (or the geometric one) is kept.
pub const MIN_INDENTATION: f64 = 1e-4;

/// How far the calibrated `λ` may stray from the geometric one, either way: a factor
/// of 100 covers a thin lobe over a support and a soft region at the edge of the mesh,
/// and keeps a glitch of one tick from producing a wall.
pub const RANGE: f64 = 100.0;

impl Fit {
    /// `(λ, depth)` such that `λ · depth` is the push `max(0, R·n)` exactly: with the
    /// drag rendered apart, the model reproduces the elastic force at the tick's pose.
    ///
    /// `λ` is the secant stiffness `(R·n) / δ` of the elastic model at this contact
    /// (the tangent too for the linear model; for the corotational one, whose reaction
    /// the contact stage reports with fresh rotations, the secant of the turned
    /// tissue): push and indentation along the same
    /// normal, within [`RANGE`] of `geometric`; while `δ < MIN_INDENTATION` the last
    /// fitted `λ` (or `geometric`) is kept. The depth `(R·n) / λ` then sets the anchor.
    ///
    /// Why not `|R| / δ`: the drag of tissue stuck to the instrument is no stiffness
    /// against pressing. A single vertex under the tip, dragged sideways by a hand
    /// that slid 2 mm on 1 MPa tissue, carried 70 N of drag for 0.2 mm of indentation;
    /// counted as stiffness it made a wall of 100–200 kN/m (`RANGE` times the
    /// geometric one) that a 0.15 kg hand at 1 kHz bounced on, kicked to the device's
    /// limit at every return by the approach plane that keeps the last `λ`.
    pub fn fit(&mut self, sample: Sample, geometric: f64) -> (f64, f64) {
        let push = sample.push;
        if sample.indentation >= MIN_INDENTATION && push > 0.0 {
            let lambda = (push / sample.indentation).clamp(geometric / RANGE, geometric * RANGE);
            self.lambda = Some(lambda);
        }
        let lambda = self.lambda.unwrap_or(geometric);
        (lambda, push.max(0.0) / lambda)
    }
}
