//! Stability grid: E ∈ {1 kPa, 100 kPa, 10 MPa} × ν ∈ {0.3, 0.49} × tick ∈ {1, 20, 50 ms},
//! explicit and implicit, on SOFA's liver and on liver-5k, each set up as the default
//! scene (scaled to 0.19 m, held at its upper face and underside, gravity on).
//!
//! From rest, each case runs 1.5 s of simulated time. Properties checked:
//! - no NaN or infinity, ever;
//! - energy bounded: the total mechanical energy starts at 0, and exact damped dynamics
//!   only lose energy; it never exceeds 1% of |E_static| (the depth of the static
//!   minimum). Backward Euler is dissipative outright; symplectic Euler conserves a
//!   shadow energy that differs from the true one by O(hω), seen here up to 0.3%;
//! - the state settles: after 1.5 s every vertex is within 1e-3 · (largest static
//!   displacement) of the static equilibrium. The mass damping α = 10/s makes every
//!   underdamped mode decay as e^{−αt/2} = e^{−7.5} ≈ 5.5e-4 by then.
//!
//! Each (mesh, integrator, E) triple is a test of its own so the harness runs them on
//! every core.

mod common;

use common::*;

const SECONDS: f64 = 1.5;

fn grid(mesh: &str, integrator: &str, e: f64) {
    grid_nu(mesh, integrator, e, &[0.3, 0.49]);
}

fn grid_nu(mesh: &str, integrator: &str, e: f64, nus: &[f64]) {
    for &nu in nus {
        for tick in [0.001, 0.02, 0.05] {
            let run = run_to_rest(default_variant(mesh, e, nu, tick, integrator), SECONDS);
            let case = format!("{mesh} {integrator} E={e:e} ν={nu} tick={tick}: {run:?}");
            assert!(run.finite, "non-finite state: {case}");
            assert!(run.static_energy < 0.0, "{case}");
            assert!(
                run.max_energy <= 0.01 * run.static_energy.abs(),
                "energy grew: {case}"
            );
            assert!(run.settle_error <= 1e-3, "did not settle: {case}");
        }
    }
}

const SOFA: &str = "builtin:liver.msh";

#[test]
fn sofa_liver_explicit_1kpa() {
    grid(SOFA, "explicit", 1e3);
}
#[test]
fn sofa_liver_explicit_100kpa() {
    grid(SOFA, "explicit", 1e5);
}
#[test]
fn sofa_liver_explicit_10mpa() {
    grid(SOFA, "explicit", 1e7);
}
#[test]
fn sofa_liver_implicit_1kpa() {
    grid(SOFA, "implicit", 1e3);
}
#[test]
fn sofa_liver_implicit_100kpa() {
    grid(SOFA, "implicit", 1e5);
}
#[test]
fn sofa_liver_implicit_10mpa() {
    grid(SOFA, "implicit", 1e7);
}
#[test]
fn liver_5k_explicit_1kpa() {
    grid(LIVER_5K, "explicit", 1e3);
}
#[test]
fn liver_5k_explicit_100kpa() {
    grid(LIVER_5K, "explicit", 1e5);
}
#[test]
fn liver_5k_explicit_10mpa_nu_0_3() {
    grid_nu(LIVER_5K, "explicit", 1e7, &[0.3]);
}
#[test]
fn liver_5k_explicit_10mpa_nu_0_49() {
    grid_nu(LIVER_5K, "explicit", 1e7, &[0.49]);
}
#[test]
fn liver_5k_implicit_1kpa() {
    grid(LIVER_5K, "implicit", 1e3);
}
#[test]
fn liver_5k_implicit_100kpa() {
    grid(LIVER_5K, "implicit", 1e5);
}
#[test]
fn liver_5k_implicit_10mpa() {
    grid(LIVER_5K, "implicit", 1e7);
}
