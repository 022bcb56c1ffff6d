//! Closest points to the instrument's axis, and the tip's triangle (paper §2.5–2.6).
//!
//! - Pushing out (§2.6): vertices are moved away from the axis segment
//!   `{P + βZ : β ∈ [0, l]}` ([`closest_point_axis`]) and edges by their closest points
//!   to it ([`closest_edge_axis`]).
//! - The tip (§2.5): `P_prox` is where the axis meets the mesh
//!   ([`ray_triangle`], watertight) or, when it does not, the mesh point closest to the
//!   tip ([`closest_point_triangle`]); both give barycentric coordinates `α_i` in the
//!   triangle, and eq. 7 interpolates the vertex normals with them
//!   ([`interpolated_normal`]).
//!
//! Conventions: `P` the tip, `Z` the unit axis toward the handle, `l ≥ 0` the shaft
//! length; barycentric coordinates `[α₀, α₁, α₂]` sum to 1 and weight the triangle's
//! vertices in the order given.

use nalgebra::{Point3, Unit, Vector3};

use super::pose::InstrumentPose;

/// The closest points between an edge `[A, B]` and the axis segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeAxisClosest {
    /// Position on the edge, `α ∈ [0, 1]` (`A + α (B − A)`).
    pub alpha: f64,
    /// Position on the axis, `β ∈ [0, l]` (`P + β Z`).
    pub beta: f64,
    /// The edge's point.
    pub on_edge: Point3<f64>,
    /// The axis' point.
    pub on_axis: Point3<f64>,
}

impl EdgeAxisClosest {
    /// From the axis to the edge, `on_edge − on_axis`: the direction to push the edge.
    pub fn offset(&self) -> Vector3<f64> {
        self.on_edge - self.on_axis
    }

    /// The distance between the edge and the axis segment.
    pub fn distance(&self) -> f64 {
        self.offset().norm()
    }
}

/// A shadow `|e⊥|` (the edge's part ⊥ `Z`) at or below `4ε·|e|` is the rounding of
/// `e − (e·Z)Z` itself: the edge is parallel to the axis to working precision and
/// every point of it is equally far from the axis line.
const PARALLEL: f64 = 4.0 * f64::EPSILON;

/// The closest points between the edge `[a, b]` and the axis segment of `pose` of
/// length `length` (minimising `|A + αe − P − βZ|`, `e = B − A`, over
/// `[0, 1] × [0, l]`).
///
/// Method, exact for this convex problem: first ignore `β`'s bounds. The distance to
/// the axis *line* is the length of the shadow `r⊥ + α e⊥` on the plane ⊥ `Z`
/// (`r = A − P`), minimised at `α = clamp(−r⊥·e⊥ / |e⊥|², 0, 1)`, with `β` the height of
/// that point. If that `β` is in `[0, l]`, it is the answer. Otherwise some optimum
/// has `β` on the violated bound (the objective is convex: on the segment from a
/// feasible point to the relaxed optimum it does not increase, and the segment crosses
/// the bound), so fix `β` there and take the best `α` for it. Working with the shadow
/// `e⊥` (computed directly, not as `|e|² − (e·Z)²`) keeps a nearly parallel edge
/// accurate: an error in `α` along the edge costs distance in proportion to `|e⊥|`.
///
/// An edge parallel to the axis (`|e⊥| ≤ 4ε|e|`, including `A = B`) is at one distance
/// from the axis line all along; the closest pair is then not unique and we take the
/// middle of the overlap of the edge's height range with `[0, l]`, or the nearest ends
/// if they do not overlap.
pub fn closest_edge_axis(
    a: &Point3<f64>,
    b: &Point3<f64>,
    pose: &InstrumentPose,
    length: f64,
) -> EdgeAxisClosest {
    let z = pose.axis.into_inner();
    let r = a - pose.tip;
    let e = b - a;
    let r_perp = pose.across(&r);
    let e_perp = pose.across(&e);
    let ee = e_perp.norm_squared();
    let (alpha, beta) = if ee.sqrt() <= PARALLEL * e.norm() || ee == 0.0 {
        let (ha, hb) = (r.dot(&z), (r + e).dot(&z));
        let (lo, hi) = if ha <= hb { (ha, hb) } else { (hb, ha) };
        let beta = 0.5 * (lo.clamp(0.0, length) + hi.clamp(0.0, length));
        let alpha = if hb != ha {
            ((beta - ha) / (hb - ha)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (alpha, r.dot(&z) + alpha * e.dot(&z))
    } else {
        let alpha = (-r_perp.dot(&e_perp) / ee).clamp(0.0, 1.0);
        let beta = (r + e * alpha).dot(&z);
        if (0.0..=length).contains(&beta) {
            (alpha, beta)
        } else {
            let beta = beta.clamp(0.0, length);
            let ee_full = e.norm_squared();
            let alpha = if ee_full > 0.0 {
                (-(r - z * beta).dot(&e) / ee_full).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (alpha, beta)
        }
    };
    let beta = beta.clamp(0.0, length);
    EdgeAxisClosest {
        alpha,
        beta,
        on_edge: a + e * alpha,
        on_axis: pose.point_at(beta),
    }
}

/// The closest point of the axis segment to a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointAxisClosest {
    /// Position on the axis, `β ∈ [0, l]`.
    pub beta: f64,
    /// The axis' point `P + βZ`.
    pub on_axis: Point3<f64>,
    /// From the axis to the point, `X − (P + βZ)`.
    pub offset: Vector3<f64>,
}

impl PointAxisClosest {
    /// The distance from the point to the axis segment.
    pub fn distance(&self) -> f64 {
        self.offset.norm()
    }
}

/// The closest point of the axis segment to `x`: `β = clamp((X − P)·Z, 0, l)`.
/// Within the shaft (`0 < β < l`) the offset is ⊥ `Z`, the direction §2.6 pushes
/// vertices in; beyond the tip it points from the tip.
pub fn closest_point_axis(x: &Point3<f64>, pose: &InstrumentPose, length: f64) -> PointAxisClosest {
    let beta = (x - pose.tip).dot(&pose.axis).clamp(0.0, length);
    let on_axis = pose.point_at(beta);
    PointAxisClosest {
        beta,
        on_axis,
        offset: x - on_axis,
    }
}

/// Where a ray meets a triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    /// Ray parameter, `≥ 0`: the point is `origin + t·direction`.
    pub t: f64,
    /// Barycentric coordinates of the point in the triangle (in `[0, 1]`, sum 1).
    pub barycentric: [f64; 3],
    /// Whether the ray meets the triangle's front: `direction · ((v₁ − v₀) × (v₂ − v₀)) < 0`,
    /// i.e. it comes from outside for a counter-clockwise-from-outside triangle.
    pub front: bool,
}

/// The intersection of the ray `origin + t·direction`, `t ≥ 0`, with a triangle (either
/// side), by the watertight test of Woop, Benthin and Wald (JCGT 2013).
///
/// Why not Möller–Trumbore: it computes each triangle's barycentric coordinates from
/// its own edge vectors, so the two triangles sharing an edge round differently, and a
/// ray through that edge (or through a shared vertex) can fall between them. Here the
/// vertices are moved into a frame where the ray is the `+k_z` axis through the origin
/// (translate by `−origin`, then shear along the dominant axis `k_z` of `direction`:
/// `x' = x_{kx} − S_x x_{kz}`, `y' = x_{ky} − S_y x_{kz}`). Each vertex is transformed
/// on its own, the same way in every triangle, and each edge's 2D edge function
/// `U = x'_c y'_b − y'_c x'_b` is then computed from the two transformed vertices only,
/// so the neighbour across the edge computes exactly `−U` (IEEE products commute and
/// `p − q = −(q − p)` exactly). The inside test is closed (an edge function of 0
/// counts as inside for both signs), so a ray through a shared edge or vertex hits at
/// least one of the triangles around it. Swapping `k_x` and `k_y` when
/// `direction[k_z] < 0` keeps the winding.
///
/// Returns `None` for a miss, a hit behind the origin, or a ray in the triangle's plane
/// (edge functions summing to 0: degenerate, and a grazing ray meets the neighbours
/// instead).
pub fn ray_triangle(
    origin: &Point3<f64>,
    direction: &Vector3<f64>,
    triangle: &[Point3<f64>; 3],
) -> Option<RayHit> {
    let abs = direction.abs();
    let kz = if abs.x >= abs.y && abs.x >= abs.z {
        0
    } else if abs.y >= abs.z {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if direction[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    if direction[kz] == 0.0 {
        return None; // a zero direction
    }
    let sx = direction[kx] / direction[kz];
    let sy = direction[ky] / direction[kz];
    let sz = 1.0 / direction[kz];
    let [a, b, c] = triangle.map(|v| v - origin);
    let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
    let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
    let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let t_scaled = u * (sz * a[kz]) + v * (sz * b[kz]) + w * (sz * c[kz]);
    if (det > 0.0 && t_scaled < 0.0) || (det < 0.0 && t_scaled > 0.0) {
        return None;
    }
    let inv = 1.0 / det;
    let normal = (triangle[1] - triangle[0]).cross(&(triangle[2] - triangle[0]));
    Some(RayHit {
        t: t_scaled * inv,
        barycentric: [u * inv, v * inv, w * inv],
        front: direction.dot(&normal) < 0.0,
    })
}

/// A point of a triangle with its barycentric coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePoint {
    /// Barycentric coordinates (in `[0, 1]`, sum 1).
    pub barycentric: [f64; 3],
    /// The point `Σ α_i v_i`.
    pub point: Point3<f64>,
}

/// The point of a triangle closest to `x` (the fallback for `P_prox` when the axis
/// misses the mesh, §2.5), by Voronoi regions (Ericson, *Real-Time Collision
/// Detection*, §5.1.5): a vertex region, an edge region or the face. A degenerate
/// (zero-area) triangle is treated as its three edges.
pub fn closest_point_triangle(x: &Point3<f64>, triangle: &[Point3<f64>; 3]) -> TrianglePoint {
    let [a, b, c] = *triangle;
    let at = |bary: [f64; 3]| TrianglePoint {
        barycentric: bary,
        point: Point3::from(a.coords * bary[0] + b.coords * bary[1] + c.coords * bary[2]),
    };
    let (ab, ac, ap) = (b - a, c - a, x - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return at([1.0, 0.0, 0.0]);
    }
    let bp = x - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return at([0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 && d1 - d3 > 0.0 {
        let v = d1 / (d1 - d3);
        return at([1.0 - v, v, 0.0]);
    }
    let cp = x - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return at([0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 && d2 - d6 > 0.0 {
        let w = d2 / (d2 - d6);
        return at([1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 && (d4 - d3) + (d5 - d6) > 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return at([0.0, 1.0 - w, w]);
    }
    let sum = va + vb + vc;
    if sum > 0.0 {
        let (v, w) = (vb / sum, vc / sum);
        return at([1.0 - v - w, v, w]);
    }
    // Zero area: the closest of the three edges.
    let on_edge = |i: usize, j: usize| {
        let (p, q) = (triangle[i], triangle[j]);
        let e = q - p;
        let s = if e.norm_squared() > 0.0 {
            ((x - p).dot(&e) / e.norm_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut bary = [0.0; 3];
        bary[i] = 1.0 - s;
        bary[j] += s;
        at(bary)
    };
    [on_edge(0, 1), on_edge(1, 2), on_edge(2, 0)]
        .into_iter()
        .min_by(|p, q| (p.point - x).norm().total_cmp(&(q.point - x).norm()))
        .expect("three edges")
}

/// The closest points between a surface triangle and the axis segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleAxisClosest {
    /// The triangle's point in barycentric coordinates.
    pub barycentric: [f64; 3],
    /// Position on the axis, `β ∈ [0, l]`.
    pub beta: f64,
    /// The triangle's point.
    pub on_triangle: Point3<f64>,
    /// The axis' point `P + βZ`.
    pub on_axis: Point3<f64>,
}

impl TriangleAxisClosest {
    /// From the axis to the triangle: the direction to push the triangle.
    pub fn offset(&self) -> Vector3<f64> {
        self.on_triangle - self.on_axis
    }

    /// The distance between the triangle and the axis segment (0 if the axis meets it).
    pub fn distance(&self) -> f64 {
        self.offset().norm()
    }
}

/// The closest points between a triangle and the axis segment of `pose` of length
/// `length`: its face interior as well as its edges and corners.
///
/// Method, exact for these two convex sets: if the segment meets the triangle
/// ([`ray_triangle`] from the tip along `Z`, hit at `t ≤ l`), the distance is 0 at the
/// hit. Otherwise the closest pair can be taken with a point of the triangle's boundary
/// or an end of the segment: a pair interior to both has its offset ⊥ to the segment
/// and to the triangle's plane, so the segment is parallel to the plane and sliding
/// the pair along the segment keeps its length until an end of the segment or an edge
/// of the triangle is reached. So the answer is the best of the segment's two ends
/// against the triangle ([`closest_point_triangle`]) and the triangle's three edges
/// against the segment ([`closest_edge_axis`]).
pub fn closest_triangle_axis(
    triangle: &[Point3<f64>; 3],
    pose: &InstrumentPose,
    length: f64,
) -> TriangleAxisClosest {
    if let Some(hit) = ray_triangle(&pose.tip, &pose.axis, triangle)
        && hit.t <= length
    {
        let on_axis = pose.point_at(hit.t);
        return TriangleAxisClosest {
            barycentric: hit.barycentric,
            beta: hit.t,
            on_triangle: on_axis,
            on_axis,
        };
    }
    let mut best: Option<(f64, TriangleAxisClosest)> = None;
    let mut consider = |c: TriangleAxisClosest| {
        let d = c.distance();
        if best.is_none_or(|(b, _)| d < b) {
            best = Some((d, c));
        }
    };
    for beta in [0.0, length] {
        let on_axis = pose.point_at(beta);
        let c = closest_point_triangle(&on_axis, triangle);
        consider(TriangleAxisClosest {
            barycentric: c.barycentric,
            beta,
            on_triangle: c.point,
            on_axis,
        });
    }
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        let c = closest_edge_axis(&triangle[i], &triangle[j], pose, length);
        let mut barycentric = [0.0; 3];
        barycentric[i] = 1.0 - c.alpha;
        barycentric[j] = c.alpha;
        consider(TriangleAxisClosest {
            barycentric,
            beta: c.beta,
            on_triangle: c.on_edge,
            on_axis: c.on_axis,
        });
    }
    best.expect("five candidates").1
}

/// Below this fraction of `Σ |α_i| |n_i|`, the interpolated normal is taken as
/// cancelled: the sum carries a rounding error of a few ε times that magnitude, so a
/// remainder of 1e-9 of it still has a direction good to about 1e-6 rad, and a smaller
/// one is a knife edge whose normal is undefined.
const CANCELLED_NORMAL: f64 = 1e-9;

/// Eq. 7: the normal at `P_prox`, `n_prox = α₀n₀ + α₁n₁ + α₂n₂` normalised, from its
/// barycentric coordinates and the triangle's vertex normals. `None` if the weighted
/// normals cancel (opposite normals across a knife edge) or are all zero.
pub fn interpolated_normal(
    barycentric: &[f64; 3],
    normals: &[Vector3<f64>; 3],
) -> Option<Unit<Vector3<f64>>> {
    let mut sum = Vector3::zeros();
    let mut magnitude = 0.0;
    for (w, n) in barycentric.iter().zip(normals) {
        sum += n * *w;
        magnitude += w.abs() * n.norm();
    }
    let length = sum.norm();
    (length.is_finite() && length > CANCELLED_NORMAL * magnitude && length > 0.0)
        .then(|| Unit::new_unchecked(sum / length))
}

#[cfg(test)]
mod tests;
