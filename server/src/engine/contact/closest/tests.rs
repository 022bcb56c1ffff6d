use super::*;
use proptest::prelude::*;

fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
    Point3::new(x, y, z)
}

fn z_pose() -> InstrumentPose {
    InstrumentPose::new(Point3::origin(), Vector3::z_axis())
}

/// Distance from the edge to the axis segment by an independent method: for a
/// fixed β the best α is the clamped projection, and the resulting distance is a
/// convex function of β (a partial minimum of a convex function), minimised by
/// ternary search.
fn independent_edge_axis(a: &Point3<f64>, b: &Point3<f64>, pose: &InstrumentPose, l: f64) -> f64 {
    let e = b - a;
    let g = |beta: f64| {
        let q = pose.point_at(beta);
        let s = if e.norm_squared() > 0.0 {
            ((q - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        ((a + e * s) - q).norm()
    };
    let (mut lo, mut hi) = (0.0, l);
    for _ in 0..200 {
        let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if g(m1) <= g(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    g(0.5 * (lo + hi))
}

/// The smallest distance over a grid of both parameters (an upper bound).
fn sampled_edge_axis(a: &Point3<f64>, b: &Point3<f64>, pose: &InstrumentPose, l: f64) -> f64 {
    let n = 100;
    let mut best = f64::INFINITY;
    for i in 0..=n {
        for j in 0..=n {
            let (s, beta) = (i as f64 / n as f64, l * j as f64 / n as f64);
            best = best.min(((a + (b - a) * s) - pose.point_at(beta)).norm());
        }
    }
    best
}

fn arb_point(r: f64) -> impl Strategy<Value = Point3<f64>> {
    prop::array::uniform3(-r..r).prop_map(Point3::from)
}

fn arb_pose() -> impl Strategy<Value = InstrumentPose> {
    (arb_point(0.2), prop::array::uniform3(-1.0..1.0f64))
        .prop_filter("axis", |(_, z)| Vector3::from(*z).norm() > 0.1)
        .prop_map(|(p, z)| InstrumentPose::new(p, Unit::new_normalize(Vector3::from(z))))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn edge_axis_matches_brute_force(pose in arb_pose(), a in arb_point(0.5), b in arb_point(0.5), l in 0.0..0.6f64) {
        let c = closest_edge_axis(&a, &b, &pose, l);
        prop_assert!((0.0..=1.0).contains(&c.alpha) && (0.0..=l).contains(&c.beta));
        prop_assert!((c.on_edge - (a + (b - a) * c.alpha)).norm() < 1e-15);
        prop_assert!((c.on_axis - pose.point_at(c.beta)).norm() < 1e-15);
        let sampled = sampled_edge_axis(&a, &b, &pose, l);
        prop_assert!(c.distance() <= sampled + 1e-15, "{} > sampled {}", c.distance(), sampled);
        let independent = independent_edge_axis(&a, &b, &pose, l);
        prop_assert!((c.distance() - independent).abs() <= 1e-12, "{} vs {}", c.distance(), independent);
    }

    /// Nearly parallel edges: the exact minimum is known (the edge is a tilted copy
    /// of a parallel one at distance 0.1), and stays accurate as the tilt vanishes.
    #[test]
    fn nearly_parallel_edge_stays_accurate(tilt_exp in 3.0..15.0f64, lo in -0.3..0.3f64, len in 0.05..0.5f64) {
        let tilt = 10f64.powf(-tilt_exp);
        let pose = z_pose();
        // Edge along z at x = 0.1 (± tilt), heights [lo, lo + len], shaft [0, 0.2].
        let a = p(0.1, 0.0, lo);
        let b = p(0.1 + tilt * len, 0.0, lo + len);
        let c = closest_edge_axis(&a, &b, &pose, 0.2);
        let overlaps = lo <= 0.2 && lo + len >= 0.0;
        if overlaps {
            prop_assert!((c.distance() - 0.1).abs() <= tilt * len + 1e-15, "{}", c.distance());
        }
        prop_assert!(c.distance() <= sampled_edge_axis(&a, &b, &pose, 0.2) + 1e-15);
        prop_assert!((c.distance() - independent_edge_axis(&a, &b, &pose, 0.2)).abs() <= 1e-12);
    }

    #[test]
    fn point_axis_matches_sampling(pose in arb_pose(), x in arb_point(0.5), l in 0.0..0.6f64) {
        let c = closest_point_axis(&x, &pose, l);
        prop_assert!((0.0..=l).contains(&c.beta));
        prop_assert!((c.on_axis + c.offset - x).norm() < 1e-15);
        let best = (0..=10_000)
            .map(|i| (x - pose.point_at(l * i as f64 / 10_000.0)).norm())
            .fold(f64::INFINITY, f64::min);
        prop_assert!(c.distance() <= best + 1e-15 && c.distance() >= best - l * 1e-4);
        // Within the shaft the offset is radial.
        if c.beta > 0.0 && c.beta < l {
            prop_assert!(c.offset.dot(&pose.axis).abs() < 1e-14);
        }
    }

    #[test]
    fn closest_point_triangle_matches_sampling(x in arb_point(1.0), t in prop::array::uniform3(arb_point(0.5))) {
        let c = closest_point_triangle(&x, &t);
        let sum: f64 = c.barycentric.iter().sum();
        prop_assert!((sum - 1.0).abs() < 1e-12 && c.barycentric.iter().all(|w| (-1e-12..=1.0 + 1e-12).contains(w)));
        let n = 300;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (v, w) = (i as f64 / n as f64, j as f64 / n as f64);
                let q = Point3::from(t[0].coords * (1.0 - v - w) + t[1].coords * v + t[2].coords * w);
                best = best.min((q - x).norm());
            }
        }
        let d = (c.point - x).norm();
        prop_assert!(d <= best + 1e-12 && d >= best - 1e-2, "{d} vs sampled {best}");
    }

    /// The segment–triangle distance against an independent method: the distance from
    /// the axis point at `β` to the triangle is convex in `β`, minimised by ternary
    /// search, each point's distance taken by sampling the triangle finely.
    #[test]
    fn triangle_axis_matches_ternary_search(pose in arb_pose(), t in prop::array::uniform3(arb_point(0.3)), l in 0.0..0.5f64) {
        let c = closest_triangle_axis(&t, &pose, l);
        let sum: f64 = c.barycentric.iter().sum();
        prop_assert!((sum - 1.0).abs() < 1e-9 && c.barycentric.iter().all(|w| (-1e-9..=1.0 + 1e-9).contains(w)));
        let from_bary = Point3::from(t[0].coords * c.barycentric[0] + t[1].coords * c.barycentric[1] + t[2].coords * c.barycentric[2]);
        prop_assert!((from_bary - c.on_triangle).norm() < 1e-9);
        prop_assert!((pose.point_at(c.beta) - c.on_axis).norm() < 1e-12 && (0.0..=l).contains(&c.beta));
        let to_triangle = |q: Point3<f64>| {
            // The closest point of the plane, then the edges if it falls outside.
            let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
            let mut best = f64::INFINITY;
            if n.norm() > 1e-12 {
                let n = n.normalize();
                let f = q - n * (q - t[0]).dot(&n);
                let inside = (0..3).all(|i| (t[(i + 1) % 3] - t[i]).cross(&(f - t[i])).dot(&n) >= 0.0);
                if inside {
                    best = (q - f).norm();
                }
            }
            for i in 0..3 {
                let (a, e) = (t[i], t[(i + 1) % 3] - t[i]);
                let s = if e.norm_squared() > 0.0 { ((q - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0) } else { 0.0 };
                best = best.min((a + e * s - q).norm());
            }
            best
        };
        let (mut lo, mut hi) = (0.0, l);
        for _ in 0..200 {
            let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
            if to_triangle(pose.point_at(m1)) <= to_triangle(pose.point_at(m2)) {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        let expected = to_triangle(pose.point_at(0.5 * (lo + hi)));
        prop_assert!((c.distance() - expected).abs() < 1e-9, "{} vs {expected}", c.distance());
    }

    /// Rays through random points of the fan's shared edges, and through its
    /// centre, from random origins above: at least one triangle is hit, and every
    /// hit is consistent (point from t = point from barycentrics).
    #[test]
    fn rays_through_shared_edges_and_vertices_hit_the_fan(
        origin in (-1.0..1.0f64, -1.0..1.0f64, 1.5..3.0f64), k in 0usize..7, f in 0.0..1.0f64, through_centre in any::<bool>(),
    ) {
        let (centre, ring) = fan();
        let origin = p(origin.0, origin.1, origin.2);
        let target = if through_centre { centre } else { centre + (ring[k] - centre) * f };
        let dir = target - origin;
        let mut hits = 0;
        for i in 0..ring.len() {
            let tri = [centre, ring[i], ring[(i + 1) % ring.len()]];
            if let Some(h) = ray_triangle(&origin, &dir, &tri) {
                hits += 1;
                let from_t = origin + dir * h.t;
                let from_bary = Point3::from(tri[0].coords * h.barycentric[0] + tri[1].coords * h.barycentric[1] + tri[2].coords * h.barycentric[2]);
                prop_assert!((from_t - from_bary).norm() < 1e-12);
                prop_assert!((from_t - target).norm() < 1e-12);
                prop_assert!(h.front, "the fan faces up, the ray comes from above");
            }
        }
        prop_assert!(hits >= 1, "the ray through {target:?} slipped through the fan");
    }
}

/// A non-planar fan of 7 triangles around an awkwardly placed centre, counter-
/// clockwise seen from above (+z).
fn fan() -> (Point3<f64>, [Point3<f64>; 7]) {
    let centre = p(0.1, 0.2, 0.05);
    let angles = [0.1, 0.9, 1.7, 2.9, 3.6, 4.7, 5.5];
    let radii = [0.7, 1.1, 0.9, 1.3, 0.8, 1.0, 1.2];
    let heights = [0.1, -0.05, 0.2, 0.0, -0.1, 0.15, 0.03];
    let ring = std::array::from_fn(|i| {
        let (s, c) = f64::sin_cos(angles[i]);
        centre + Vector3::new(radii[i] * c, radii[i] * s, heights[i])
    });
    (centre, ring)
}

#[test]
fn ray_through_a_shared_edge_exactly_hits_both_sides() {
    // Two triangles in z = 0 sharing the edge (0,0)–(2,1); the ray comes straight
    // down onto (1, 0.5), exactly on it (the shear is trivial, arithmetic exact).
    let (a, b) = (p(0.0, 0.0, 0.0), p(2.0, 1.0, 0.0));
    let left = [a, b, p(0.0, 1.0, 0.0)];
    let right = [b, a, p(2.0, 0.0, 0.0)];
    let origin = p(1.0, 0.5, 1.0);
    let down = Vector3::new(0.0, 0.0, -1.0);
    for tri in [left, right] {
        let h = ray_triangle(&origin, &down, &tri).expect("closed test includes the edge");
        assert_eq!(h.t, 1.0);
        assert_eq!(
            h.barycentric[2], 0.0,
            "on the edge opposite the third vertex"
        );
    }
    // Seen from below it hits the back.
    let up = ray_triangle(&p(1.0, 0.5, -1.0), &Vector3::z(), &left).unwrap();
    assert!(!up.front);
}

#[test]
fn ray_triangle_known_hit_and_misses() {
    let tri = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)];
    let h = ray_triangle(&p(0.25, 0.5, 2.0), &Vector3::new(0.0, 0.0, -0.5), &tri).unwrap();
    assert!((h.t - 4.0).abs() < 1e-15);
    let expected = [0.25, 0.25, 0.5];
    for (w, e) in h.barycentric.iter().zip(expected) {
        assert!((w - e).abs() < 1e-15, "{:?}", h.barycentric);
    }
    assert!(h.front);
    // Outside the triangle, behind the origin, parallel to its plane, zero direction.
    assert_eq!(ray_triangle(&p(0.8, 0.8, 2.0), &-Vector3::z(), &tri), None);
    assert_eq!(ray_triangle(&p(0.25, 0.25, 2.0), &Vector3::z(), &tri), None);
    assert_eq!(ray_triangle(&p(-1.0, 0.25, 0.0), &Vector3::x(), &tri), None);
    assert_eq!(
        ray_triangle(&p(0.25, 0.25, 2.0), &Vector3::zeros(), &tri),
        None
    );
    // An oblique ray along a negative dominant axis (the winding swap).
    let origin = p(3.0, 0.3, 0.2);
    let target = p(0.0, 0.2, 0.3);
    let tri = [p(0.0, 0.0, 0.0), p(0.0, 0.0, 1.0), p(0.0, 1.0, 0.0)];
    let h = ray_triangle(&origin, &(target - origin), &tri).unwrap();
    assert!((h.t - 1.0).abs() < 1e-15);
    let point = Point3::from(
        tri[0].coords * h.barycentric[0]
            + tri[1].coords * h.barycentric[1]
            + tri[2].coords * h.barycentric[2],
    );
    assert!((point - target).norm() < 1e-15);
    // The normal (0,0,1)×(0,1,0) = −x faces away from an origin at +x.
    assert!(!h.front);
}

#[test]
fn axis_through_a_closed_surface_always_hits() {
    // An octahedron (closed, counter-clockwise from outside); rays from inside
    // through its vertices and edge midpoints must hit, from outside they enter
    // through a front face.
    let v = [
        p(1.0, 0.0, 0.0),
        p(-1.0, 0.0, 0.0),
        p(0.0, 1.0, 0.0),
        p(0.0, -1.0, 0.0),
        p(0.0, 0.0, 1.0),
        p(0.0, 0.0, -1.0),
    ];
    let faces = [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let inside = p(0.013, -0.021, 0.007);
    let mut targets: Vec<Point3<f64>> = v.to_vec();
    for f in faces {
        for k in 0..3 {
            targets.push(Point3::from(
                (v[f[k]].coords + v[f[(k + 1) % 3]].coords) * 0.5,
            ));
        }
    }
    for target in targets {
        let dir = target - inside;
        let hits = faces
            .iter()
            .filter_map(|f| ray_triangle(&inside, &dir, &f.map(|i| v[i])))
            .count();
        assert!(hits >= 1, "ray to {target:?} escaped");
        let outside = inside + dir * 3.0;
        let front = faces
            .iter()
            .filter_map(|f| ray_triangle(&outside, &-dir, &f.map(|i| v[i])))
            .any(|h| h.front);
        assert!(
            front,
            "ray from outside toward {target:?} did not enter through a front face"
        );
    }
}

/// A case where a grid-and-refine brute force was not tight (a long, thin valley
/// in (α, β)); kept as a fixed check against the independent method.
#[test]
fn closest_edge_axis_thin_valley() {
    let pose = InstrumentPose::new(
        p(
            -0.02175169314796016,
            -0.14733911897277052,
            -0.1985129048335177,
        ),
        Unit::new_normalize(Vector3::new(-0.8476800203914905, 0.5305078538806778, 0.0)),
    );
    let a = p(
        0.10732865525128586,
        -0.27801970840425067,
        -0.4817891603737015,
    );
    let b = p(
        -0.30537972521042117,
        -0.021290007250598143,
        0.2756271764393244,
    );
    let l = 0.027026193558014815;
    let c = closest_edge_axis(&a, &b, &pose, l);
    assert!((c.distance() - independent_edge_axis(&a, &b, &pose, l)).abs() <= 1e-12);
    assert!(c.distance() <= sampled_edge_axis(&a, &b, &pose, l));
}

#[test]
fn closest_edge_axis_special_cases() {
    let pose = z_pose();
    // Crossing the axis: distance 0 at the crossing point.
    let c = closest_edge_axis(&p(-1.0, 0.0, 0.5), &p(1.0, 0.0, 0.5), &pose, 1.0);
    assert!(c.distance() < 1e-16 && (c.alpha - 0.5).abs() < 1e-16 && (c.beta - 0.5).abs() < 1e-16);
    // Skew, closest interior to both.
    let c = closest_edge_axis(&p(-1.0, 0.3, 0.5), &p(1.0, 0.3, 0.5), &pose, 1.0);
    assert!((c.distance() - 0.3).abs() < 1e-16 && (c.beta - 0.5).abs() < 1e-16);
    // Beyond the tip: the tip is the closest axis point.
    let c = closest_edge_axis(&p(-1.0, 0.3, -0.5), &p(1.0, 0.3, -0.5), &pose, 1.0);
    assert_eq!(c.beta, 0.0);
    assert!((c.distance() - (0.3f64.powi(2) + 0.25).sqrt()).abs() < 1e-15);
    // Parallel, overlapping [0.2, 0.6] with [0, 0.5]: middle of [0.2, 0.5].
    let c = closest_edge_axis(&p(0.1, 0.0, 0.2), &p(0.1, 0.0, 0.6), &pose, 0.5);
    assert!((c.beta - 0.35).abs() < 1e-15 && (c.distance() - 0.1).abs() < 1e-15);
    // Parallel, not overlapping: nearest ends.
    let c = closest_edge_axis(&p(0.1, 0.0, 0.8), &p(0.1, 0.0, 0.6), &pose, 0.5);
    assert!((c.beta - 0.5).abs() < 1e-15 && (c.alpha - 1.0).abs() < 1e-15);
    // A point edge, and a point axis (l = 0).
    let c = closest_edge_axis(&p(0.3, 0.4, 0.2), &p(0.3, 0.4, 0.2), &pose, 1.0);
    assert!((c.distance() - 0.5).abs() < 1e-15);
    let c = closest_edge_axis(&p(-1.0, 0.3, 0.5), &p(1.0, 0.3, 0.5), &pose, 0.0);
    assert_eq!(c.beta, 0.0);
    assert!((c.distance() - (0.09f64 + 0.25).sqrt()).abs() < 1e-15);
}

#[test]
fn interpolated_normal_eq7() {
    let n = [Vector3::x(), Vector3::y(), Vector3::z()];
    assert_eq!(
        interpolated_normal(&[1.0, 0.0, 0.0], &n)
            .unwrap()
            .into_inner(),
        Vector3::x()
    );
    let mid = interpolated_normal(&[0.5, 0.5, 0.0], &n).unwrap();
    assert!((mid.into_inner() - Vector3::new(1.0, 1.0, 0.0).normalize()).norm() < 1e-15);
    let any = interpolated_normal(&[0.2, 0.3, 0.5], &n).unwrap();
    assert!((any.into_inner() - Vector3::new(0.2, 0.3, 0.5).normalize()).norm() < 1e-15);
    // A knife edge: opposite normals cancel at the middle.
    let knife = [Vector3::z(), -Vector3::z(), Vector3::z()];
    assert_eq!(interpolated_normal(&[0.5, 0.5, 0.0], &knife), None);
    assert_eq!(
        interpolated_normal(&[1.0, 0.0, 0.0], &[Vector3::zeros(); 3]),
        None
    );
}

#[test]
fn closest_point_triangle_regions_and_degenerate() {
    let tri = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(0.0, 1.0, 0.0)];
    let c = closest_point_triangle(&p(0.2, 0.3, 1.0), &tri);
    assert!((c.point - p(0.2, 0.3, 0.0)).norm() < 1e-16);
    assert!((c.barycentric[1] - 0.2).abs() < 1e-16 && (c.barycentric[2] - 0.3).abs() < 1e-16);
    assert_eq!(
        closest_point_triangle(&p(-1.0, -1.0, 0.0), &tri).barycentric,
        [1.0, 0.0, 0.0]
    );
    let c = closest_point_triangle(&p(1.0, 1.0, 0.5), &tri);
    assert!((c.point - p(0.5, 0.5, 0.0)).norm() < 1e-16);
    // Zero area (collinear): the closest point on the segment.
    let flat = [p(0.0, 0.0, 0.0), p(1.0, 0.0, 0.0), p(2.0, 0.0, 0.0)];
    let c = closest_point_triangle(&p(1.5, 1.0, 0.0), &flat);
    assert!((c.point - p(1.5, 0.0, 0.0)).norm() < 1e-15, "{c:?}");
    let sum: f64 = c.barycentric.iter().sum();
    assert!((sum - 1.0).abs() < 1e-15);
}
