//! Where each surface vertex was when last free: the reference of the indentation.

use nalgebra::Point3;

use crate::engine::contact::Instrument;
use crate::engine::mesh::Surface;

/// How long a vertex must have been free before where it is counts as where it is
/// free, s.
///
/// Tissue let go springs back over tens of milliseconds (the default scene's mass
/// damping, 10/s, has a time constant of 0.1 s), and a contact on a coarse mesh lets
/// go of one triangle and takes the next a few ticks later: on the force-error
/// bench's probe, withdrawing from SOFA's liver, the tip let go of the triangle it
/// held while the tissue still pressed it with 0.69 N and caught the tissue again
/// 10–30 ms later. Counted from where it sprang back to, the indentation `δ` of
/// the vertices taken again was a fraction of a millimetre where the dimple was
/// several, so the calibrated `λ = R·n / δ` rose toward its upper bound and the
/// rendered force fell to zero within that fraction of a millimetre of withdrawal,
/// while the tissue still pushed with 0.3 N for 40 ms. Taken again within this
/// time, a vertex keeps the free position it had before it was first taken: it is
/// the same contact.
pub const FREE_AFTER_S: f64 = 0.1;

// `update` relies on it: a vertex held this tick is not free.
const _: () = assert!(FREE_AFTER_S > 0.0);

/// For every surface vertex, its position at the end of the last tick in which no
/// instrument held it, once it has been free for [`FREE_AFTER_S`].
///
/// A vertex an instrument takes keeps the position it had just before: the surface as
/// the liver had it without that instrument — sagging under gravity, dented by other
/// instruments — so that `F_i − x_i` is the push of the instrument alone. A vertex let
/// go keeps that position for [`FREE_AFTER_S`] more, while it springs back. Vertices
/// never held sit where they are; before the first tick, at rest.
#[derive(Debug)]
pub struct FreeSurface {
    position: Vec<Point3<f64>>,
    /// The simulated time of the last tick each vertex was held at, s (−∞: never).
    last_held: Vec<f64>,
}

impl FreeSurface {
    /// At rest: `rest` holds every mesh vertex.
    pub fn new(rest: &[Point3<f64>]) -> Self {
        FreeSurface {
            position: rest.to_vec(),
            last_held: vec![f64::NEG_INFINITY; rest.len()],
        }
    }

    /// Where vertex `v` was when last free, m.
    pub fn position(&self, v: u32) -> Point3<f64> {
        self.position[v as usize]
    }

    /// At the end of the tick at simulated time `time` (s): every surface vertex no
    /// instrument holds, and none has held for [`FREE_AFTER_S`], is free where it is
    /// now.
    pub fn update(
        &mut self,
        instruments: &[Instrument],
        surface: &Surface,
        x: &[Point3<f64>],
        time: f64,
    ) {
        for ins in instruments {
            for &v in &ins.held {
                self.last_held[v as usize] = time;
            }
        }
        // A vertex held this tick has been free for 0 s, less than FREE_AFTER_S (> 0).
        for &v in &surface.vertices {
            let v = v as usize;
            if time - self.last_held[v] >= FREE_AFTER_S {
                self.position[v] = x[v];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};

    use super::{FREE_AFTER_S, FreeSurface};
    use crate::engine::contact::Instrument;
    use crate::engine::mesh::read_gmsh;

    /// A vertex held, let go and taken again within [`FREE_AFTER_S`] keeps the free
    /// position it had before it was first taken; once free that long it is free
    /// where it is; a vertex never held follows the surface every tick.
    #[test]
    fn a_vertex_let_go_is_free_again_only_after_springing_back() {
        let mesh = read_gmsh(include_str!("../../../meshes/liver.msh"), "liver.msh").unwrap();
        let surface = &mesh.surface;
        let (v, w) = (surface.vertices[0], surface.vertices[1]);
        let mut free = FreeSurface::new(&mesh.positions);
        let mut ins = Instrument::new("probe", 5e-3, 0.3, Point3::origin(), mesh.positions.len());
        let mut x = mesh.positions.clone();
        let dt = 1.0 / 60.0;
        let moved = |x: &mut [Point3<f64>], k: f64| {
            x[v as usize] = mesh.positions[v as usize] + Vector3::new(0.0, 0.0, -1e-3 * k);
            x[w as usize] = mesh.positions[w as usize] + Vector3::new(1e-3 * k, 0.0, 0.0);
        };
        // Where the vertex is free before it is first taken (set at tick 0).
        let mut before = mesh.positions[v as usize];
        // Taken at tick 1, let go at tick 3 (sprung back part of the way), taken again
        // at tick 4, let go at tick 5 for good.
        let held_at = [false, true, true, false, true, false];
        let mut t = 0.0;
        let mut last_held = f64::NEG_INFINITY;
        for (k, &held) in held_at.iter().enumerate() {
            ins.held.clear();
            if held {
                ins.held.push(v);
                last_held = t;
            }
            moved(&mut x, k as f64 + 1.0);
            free.update(std::slice::from_ref(&ins), surface, &x, t);
            assert_eq!(
                free.position(w),
                x[w as usize],
                "the free vertex at tick {k}"
            );
            if k == 0 {
                before = x[v as usize];
            }
            assert_eq!(free.position(v), before, "the taken vertex at tick {k}");
            t += dt;
        }
        // Free, but not yet for FREE_AFTER_S (several ticks): still where it was before
        // it was taken; then where it is.
        assert!(last_held + FREE_AFTER_S - t > dt);
        ins.held.clear();
        while t - last_held < FREE_AFTER_S {
            free.update(std::slice::from_ref(&ins), surface, &x, t);
            assert_eq!(free.position(v), before, "free for {:.3} s", t - last_held);
            t += dt;
        }
        free.update(std::slice::from_ref(&ins), surface, &x, t);
        assert_eq!(free.position(v), x[v as usize]);
    }
}
