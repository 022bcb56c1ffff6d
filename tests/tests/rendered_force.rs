//! What the trainee's hand feels against what the tissue pushes with: the force the
//! client's loop renders at 1 kHz from the server's local models, against the
//! elastic reaction the engine computes when it runs at haptic rate itself.

use laparo_client::gestures::PROBE_SECONDS;
use laparo_server::engine::local_model::ForceModelKind;
use laparo_server::engine::scene::Scene;
use laparo_tests::coupled::{front_probe, probed, reaction_history, settled};
use nalgebra::Vector3;

const HAPTIC_HZ: f64 = 1000.0;

/// The force-error bench's probe (`tests/benches/force_error.rs`: the default liver,
/// 8 mm past its front face, a 20 mm slide, then the withdrawal), with the mechanics
/// at 60 Hz and the calibrated force model: the force the loop renders at each
/// millisecond lies within 5% RMS of the elastic reaction, `−Σ (K u)_i` over the held
/// vertices, of the same probe run by the engine at 1 kHz. The RMS is over the whole
/// 4 s probe, both over `N = 4000` haptic ticks: `√(Σ |F_r − F|² / N) ≤ 0.05 √(Σ |F|² /
/// N)`.
///
/// What sets the error: the local model is exact at the pose of its tick and
/// extrapolates linearly between ticks, so while pressed the error is the tissue's
/// own change within 1/60 s (0.0096 N RMS before the withdrawal against 0.458 N RMS
/// force, at the commit that added this test). Most of the rest is the withdrawal,
/// where the tissue the tip held is let go on one tick of either engine (the bench's
/// tables split the error by phase and list the reference's let-go ticks). The whole
/// came to 4.4%. With the tip's reach at 1.25 radii (`engine/contact/hold.rs`,
/// `TIP_REACH`, 1.5 since 1e22eef) it was 15.7%, nearly all of it in the withdrawal:
/// the 1 kHz engine let go at 3.452 s, its triangles 1.25 radii from the tip, where
/// it now lets go at 3.543 s, at 1.51 radii, within the 60 Hz tick that lets go.
/// At 120 Hz the figure is 8.5% (its let-go falls on another tick); the issue's
/// bound is at 60 Hz.
#[test]
fn the_rendered_force_at_60_hz_is_within_5_percent_rms_of_the_reaction() {
    let ticks = (PROBE_SECONDS * HAPTIC_HZ).round() as usize;
    let start = settled(Scene::default_scene(), 60.0, ForceModelKind::Geometric);
    let probe = front_probe(&start, 0.008, 0.02);
    let mut reference = settled(Scene::default_scene(), HAPTIC_HZ, ForceModelKind::Geometric);
    let truth = reaction_history(&mut reference, &probe, ticks, HAPTIC_HZ, |_, _| {});
    let sim = settled(Scene::default_scene(), 60.0, ForceModelKind::Calibrated);
    let c = probed(sim, &probe, HAPTIC_HZ, ticks, |_, _| {});
    let rendered: Vec<Vector3<f64>> = c
        .haptics
        .device()
        .recorded()
        .map(|r| r.force.force)
        .collect();
    assert_eq!(
        rendered.len(),
        ticks,
        "the device kept every force it was sent"
    );
    let rms = |v: &mut dyn Iterator<Item = Vector3<f64>>| {
        (v.map(|f| f.norm_squared()).sum::<f64>() / ticks as f64).sqrt()
    };
    let force = rms(&mut truth.iter().copied());
    let error = rms(&mut rendered.iter().zip(&truth).map(|(r, f)| r - f));
    println!(
        "reference RMS {force:.4} N, rendered error RMS {error:.4} N ({:.1}%)",
        100.0 * error / force
    );
    // The probe presses: a reference with no force would make any rendering pass.
    assert!(force > 0.1, "the probe pressed with {force:.4} N RMS");
    assert!(
        error <= 0.05 * force,
        "rendered force {error:.4} N RMS off the reaction, {:.1}% of its {force:.4} N RMS",
        100.0 * error / force
    );
}
