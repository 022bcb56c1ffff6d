//! Contact against an exact solution: the instrument's tip indenting a block of
//! tissue 0.5–2 mm gives Hertz's force within 10% (the set-up and the references:
//! `common/hertz.rs`).

mod common;

use common::hertz::*;

#[test]
fn a_tip_indenting_a_block_gives_hertz_force_within_ten_percent() {
    let mut sim = block_scene();
    let e_star = plane_strain_modulus(&sim);
    let r = sim.instruments[0].radius;
    for d in [0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3] {
        let i = indent(&mut sim, d);
        let (h, b) = (hertz(e_star, r, d), bonded_layer(e_star, r, d));
        let case = format!(
            "d = {} mm: {:.5} N against Hertz {h:.5} N ({:+.1}%), bonded layer {b:.5} N ({:+.1}%), {} held, {} passes (last change {:.0e})",
            d * 1e3,
            i.force,
            100.0 * (i.force / h - 1.0),
            100.0 * (i.force / b - 1.0),
            i.held,
            i.passes,
            i.change
        );
        println!("{case}");
        assert!(i.change <= PASS_TOLERANCE, "never settled: {case}");
        assert!((i.force / h - 1.0).abs() <= 0.10, "{case}");
    }
}
