use super::stiffness::{Fit, MIN_INDENTATION, RANGE, Sample, geometric_shaft, geometric_tip};

#[test]
fn punch_stiffness_is_proportional_to_e() {
    let (r, nu) = (0.005, 0.45);
    let k1 = geometric_tip(r, (1000.0, nu));
    assert!((geometric_tip(r, (7000.0, nu)) / k1 - 7.0).abs() < 1e-12);
    // Boussinesq: 2 r E / (1 − ν²).
    assert!((k1 - 2.0 * r * 1000.0 / (1.0 - nu * nu)).abs() < 1e-12);
    // A longer shaft contact is stiffer; a zero-length one is a 2r × 2r square punch.
    let short = geometric_shaft(r, 0.0, (1000.0, nu));
    assert!(geometric_shaft(r, 0.05, (1000.0, nu)) > 2.0 * short);
    let side = (4.0 * r * r / std::f64::consts::PI).sqrt();
    assert!((short - geometric_tip(side, (1000.0, nu))).abs() < 1e-12);
}

#[test]
fn the_fit_reproduces_the_reaction_and_keeps_its_stiffness_below_the_floor() {
    let mut fit = Fit::default();
    // Before any trustworthy sample: the geometric λ, and a depth that still gives the
    // reaction exactly.
    let (lambda, depth) = fit.fit(
        Sample {
            indentation: MIN_INDENTATION / 2.0,
            push: 0.01,
        },
        50.0,
    );
    assert_eq!(lambda, 50.0);
    assert!((lambda * depth - 0.01).abs() < 1e-15);
    // A sample: the secant R / δ.
    let (lambda, depth) = fit.fit(
        Sample {
            indentation: 0.004,
            push: 0.6,
        },
        50.0,
    );
    assert!((lambda - 150.0).abs() < 1e-9 && (depth - 0.004).abs() < 1e-15);
    // Below the floor again: λ kept, force still R.
    let (lambda, depth) = fit.fit(
        Sample {
            indentation: 0.0,
            push: 0.003,
        },
        50.0,
    );
    assert!((lambda - 150.0).abs() < 1e-9 && (lambda * depth - 0.003).abs() < 1e-15);
    // A wild sample is held within RANGE of the geometric value, the force still R.
    let (lambda, depth) = fit.fit(
        Sample {
            indentation: 1e-3,
            push: 1e6,
        },
        50.0,
    );
    assert_eq!(lambda, 50.0 * RANGE);
    assert!((lambda * depth - 1e6).abs() < 1e-6);
    // A pulling reaction is no push: zero depth.
    assert_eq!(
        fit.fit(
            Sample {
                indentation: 0.002,
                push: -0.1,
            },
            50.0
        )
        .1,
        0.0
    );
}

#[test]
fn a_pull_teaches_no_stiffness() {
    // 0.1 N of push for 2 mm of indentation: λ = 50 N/m. Then the tissue pulls (a
    // vertex dragged back out): no push, no depth, and the last λ is kept.
    let mut fit = Fit::default();
    let (lambda, depth) = fit.fit(
        Sample {
            indentation: 0.002,
            push: 0.1,
        },
        40.0,
    );
    assert!((lambda - 50.0).abs() < 1e-9 && (lambda * depth - 0.1).abs() < 1e-12);
    let (lambda, depth) = fit.fit(
        Sample {
            indentation: 0.002,
            push: -0.3,
        },
        40.0,
    );
    assert!(
        (lambda - 50.0).abs() < 1e-9 && depth == 0.0,
        "{lambda} {depth}"
    );
}
