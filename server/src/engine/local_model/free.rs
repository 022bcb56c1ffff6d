//! Where each surface vertex was when last free: the reference of the indentation.

use nalgebra::Point3;

use crate::engine::contact::Instrument;
use crate::engine::mesh::Surface;

/// For every surface vertex, its position at the end of the last tick in which no
/// instrument held it.
///
/// A vertex an instrument takes keeps the position it had just before: the surface as
/// the liver had it without that instrument — sagging under gravity, dented by other
/// instruments — so that `F_i − x_i` is the push of the instrument alone. Vertices
/// never held sit where they are; before the first tick, at rest.
#[derive(Debug)]
pub struct FreeSurface {
    position: Vec<Point3<f64>>,
    held: Vec<bool>,
}

impl FreeSurface {
    /// At rest: `rest` holds every mesh vertex.
    pub fn new(rest: &[Point3<f64>]) -> Self {
        FreeSurface {
            position: rest.to_vec(),
            held: vec![false; rest.len()],
        }
    }

    /// Where vertex `v` was when last free, m.
    pub fn position(&self, v: u32) -> Point3<f64> {
        self.position[v as usize]
    }

    /// At the end of a tick: every surface vertex no instrument holds is free where it
    /// is now.
    pub fn update(&mut self, instruments: &[Instrument], surface: &Surface, x: &[Point3<f64>]) {
        for ins in instruments {
            for &v in &ins.held {
                self.held[v as usize] = true;
            }
        }
        for &v in &surface.vertices {
            let v = v as usize;
            if !self.held[v] {
                self.position[v] = x[v];
            }
        }
        for ins in instruments {
            for &v in &ins.held {
                self.held[v as usize] = false;
            }
        }
    }
}
