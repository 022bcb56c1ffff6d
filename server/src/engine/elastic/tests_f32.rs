//! The products of the f32 copy of the stiffness: the copy is each block rounded,
//! and its product is the f64 product of those rounded blocks, to the last bit,
//! within the rounding's bound of the f64 product.

use nalgebra::Vector3;

use super::tests_corotational::models;
use super::tests_shared::{liver, product_case};
use super::*;
use crate::engine::workers::Workers;

/// The unit round-off of f32: a block entry rounded to f32 is within this much of
/// itself, relatively.
const F32_ROUNDING: f64 = 1.0 / (1u64 << 24) as f64;

#[test]
fn the_f32_product_is_the_product_of_the_rounded_blocks() {
    let mesh = liver();
    let (model, _) = models(&mesh, 0.45);
    let k = &model.stiffness;
    let n = mesh.vertex_count();
    let (u, a, s) = product_case(n);
    // K with every block rounded to f32 and back, and |K| with |u|, which bounds
    // what the rounding can change in each row.
    let mut rounded = k.clone();
    rounded
        .block
        .iter_mut()
        .for_each(|b| *b = b.cast::<f32>().cast());
    let mut absolute = k.clone();
    absolute.block.iter_mut().for_each(|b| *b = b.abs());
    let u_abs: Vec<Vector3<f64>> = u.iter().map(|v| v.abs()).collect();
    let mut bound = vec![Vector3::zeros(); n];
    absolute.mul(&u_abs, &mut bound);
    let mut exact = vec![Vector3::zeros(); n];
    k.mul_shared(
        None,
        &Parts::new(n, 1, std::iter::empty()),
        a,
        s,
        &u,
        &mut exact,
    );
    let crew = Workers::new(2).unwrap();
    for count in [1, 2, 3] {
        let parts = Parts::new(n, count, std::iter::empty());
        for workers in [None, Some(&crew)] {
            let mut copy = vec![Matrix3::<f32>::repeat(f32::NAN); k.block.len()];
            k.round_f32_shared(workers, &parts, &mut copy);
            for (c, b) in copy.iter().zip(&k.block) {
                assert_eq!(*c, b.cast::<f32>(), "{count} parts: every block rounded");
            }
            let mut got = vec![Vector3::repeat(f64::NAN); n];
            k.mul_shared_by(&copy, workers, &parts, a, s, &u, &mut got);
            let mut want = vec![Vector3::zeros(); n];
            rounded.mul_shared(workers, &parts, a, s, &u, &mut want);
            assert_eq!(
                got, want,
                "{count} parts: the f64 product of the rounded blocks"
            );
            let mut changed = false;
            for i in 0..n {
                let gap = (got[i] - exact[i]).abs();
                // The rounding of the blocks, with a little room for the f64 sums,
                // which run in another order when the mesh is split.
                let allowed =
                    s * F32_ROUNDING * bound[i] * 1.01 + Vector3::repeat(1e-12 * exact[i].amax());
                assert!(
                    gap.iter().zip(allowed.iter()).all(|(g, b)| g <= b),
                    "{count} parts, row {i}: {gap} beyond {allowed}"
                );
                changed |= gap != Vector3::zeros();
            }
            assert!(changed, "the rounding shows in the product");
        }
    }
}
