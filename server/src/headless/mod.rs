//! Stepping a scene with no network: `laparo-server run`.

pub mod out;
pub mod signal;
pub mod trajectory;

use std::time::{Duration, Instant};

use hdrhistogram::Histogram;

use crate::engine::integrate::StepReport;
use crate::engine::scene::limits::{MAX_COORDINATE_M, out_of_place};
use crate::engine::simulation::Simulation;

/// The longest run, simulated seconds (`--seconds`, and a trajectory's last
/// keyframe): eleven and a half days, beyond any session. A run's memory does not
/// grow with its length (tick times go to a histogram), only its wall time does.
pub const MAX_RUN_SECONDS: f64 = 1e6;

/// What a headless run did, with its timing.
#[derive(Clone, Debug)]
pub struct RunSummary {
    pub ticks: u64,
    /// Simulated time, s.
    pub sim_seconds: f64,
    /// Wall time spent in ticks, s.
    pub wall_seconds: f64,
    /// Median, 99th percentile and largest tick time, s (to three significant
    /// digits).
    pub tick_median: f64,
    pub tick_p99: f64,
    pub tick_max: f64,
    /// Largest explicit substep count in a tick.
    pub max_substeps: u32,
    /// Mean CG iterations per tick.
    pub mean_cg_iterations: f64,
    /// Ticks whose solve stopped at the iteration cap.
    pub unconverged: u64,
    /// Largest displacement at the end, m.
    pub max_displacement: f64,
    /// Why the run stopped before its end: the first tick that left the liver beyond
    /// any physical place ([`fault`]), as a served session would have halted there.
    pub fault: Option<String>,
}

/// What is wrong with `sim` after a tick, if anything, by the rule a served session
/// halts on (`session/halt.rs`): a vertex position [`out_of_place`] (not finite or
/// beyond ±[`MAX_COORDINATE_M`]), or an instrument's reaction that is not finite.
/// A pass over the positions, nothing allocated unless there is a fault.
pub fn fault(sim: &Simulation) -> Option<String> {
    if let Some((v, x)) = sim
        .state
        .x
        .iter()
        .enumerate()
        .find(|(_, x)| x.iter().any(|&c| out_of_place(c)))
    {
        return Some(format!(
            "vertex {v} is at ({:.3e}, {:.3e}, {:.3e}) m, beyond the ±{MAX_COORDINATE_M} m a \
             scene's mesh must lie in: the simulation diverged",
            x.x, x.y, x.z
        ));
    }
    sim.instruments
        .iter()
        .find(|i| i.report.reaction.iter().any(|c| !c.is_finite()))
        .map(|i| format!("instrument `{}`'s reaction is not finite", i.name))
}

/// Runs `sim` for `seconds` of simulated time, calling `progress` about ten times.
pub fn run(
    sim: &mut Simulation,
    seconds: f64,
    progress: impl FnMut(&Simulation, &StepReport),
) -> RunSummary {
    run_scripted(sim, seconds, None, progress)
}

/// Runs `sim` with its instruments driven by `script` (the track of each scene
/// instrument, as [`trajectory::Trajectory::match_instruments`] gives them): before
/// each tick every instrument is put where its track is at the end of that tick.
pub fn run_scripted(
    sim: &mut Simulation,
    seconds: f64,
    script: Option<(&trajectory::Trajectory, &[Option<usize>])>,
    progress: impl FnMut(&Simulation, &StepReport),
) -> RunSummary {
    run_observed(sim, seconds, script, progress, |_| true)
}

/// The ticks a run of `seconds` makes at ticks of `dt`: the nearest whole number,
/// at least one.
pub fn tick_count(seconds: f64, dt: f64) -> u64 {
    (seconds / dt).round().max(1.0) as u64
}

/// As [`run_scripted`], with `after_tick` called after every tick (outside the
/// timing, e.g. to export a frame); the run stops early when it returns false.
pub fn run_observed(
    sim: &mut Simulation,
    seconds: f64,
    script: Option<(&trajectory::Trajectory, &[Option<usize>])>,
    mut progress: impl FnMut(&Simulation, &StepReport),
    mut after_tick: impl FnMut(&Simulation) -> bool,
) -> RunSummary {
    let ticks = tick_count(seconds, sim.dt);
    // Tick times in nanoseconds to three significant digits, from 1 ns to an hour
    // (a longer tick counts as an hour), in memory that does not grow with the run.
    let mut times = Histogram::<u64>::new_with_bounds(1, 3_600_000_000_000, 3)
        .expect("bounds and three significant digits are valid");
    let mut wall = Duration::ZERO;
    let mut ran = 0u64;
    let (mut max_substeps, mut cg_total, mut unconverged) = (0, 0u64, 0);
    let every = (ticks / 10).max(1);
    let mut stopped = None;
    for k in 1..=ticks {
        if let Some((traj, tracks)) = script {
            let t = sim.time + sim.dt;
            for (i, track) in tracks.iter().enumerate() {
                sim.set_pose(i, track.and_then(|tr| traj.tracks[tr].pose_at(t)));
            }
        }
        let start = Instant::now();
        let report = sim.tick();
        let took = start.elapsed();
        wall += took;
        ran += 1;
        times.saturating_record(took.as_nanos().min(u64::MAX as u128) as u64);
        max_substeps = max_substeps.max(report.substeps);
        cg_total += report.cg_iterations as u64;
        unconverged += u64::from(!report.converged);
        if k % every == 0 || k == ticks {
            progress(sim, &report);
        }
        if let Some(what) = fault(sim) {
            // The tick's progress line, then the fault: nothing after it means
            // anything.
            progress(sim, &report);
            stopped = Some(format!("tick {} (t = {:.3} s): {what}", sim.tick, sim.time));
            break;
        }
        if !after_tick(sim) {
            break;
        }
    }
    let at = |q: f64| times.value_at_quantile(q) as f64 * 1e-9;
    let ticks = ran;
    RunSummary {
        ticks,
        sim_seconds: ticks as f64 * sim.dt,
        wall_seconds: wall.as_secs_f64(),
        tick_median: at(0.5),
        tick_p99: at(0.99),
        tick_max: times.max() as f64 * 1e-9,
        max_substeps,
        mean_cg_iterations: cg_total as f64 / ticks as f64,
        unconverged,
        max_displacement: sim.max_displacement(),
        fault: stopped,
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;

    use super::*;
    use crate::engine::scene::Scene;

    #[test]
    fn a_run_stops_at_the_first_tick_that_leaves_the_liver_out_of_place() {
        let mut sim = Scene::default_scene().build().unwrap();
        assert_eq!(fault(&sim), None);
        sim.state.x[5] = Point3::new(0.0, 2.0 * MAX_COORDINATE_M, 0.0);
        let said = fault(&sim).unwrap();
        assert!(
            said.contains("vertex 5") && said.contains("diverged"),
            "{said}"
        );
        sim.state.x[5] = Point3::new(f64::NAN, 0.0, 0.0);
        assert!(fault(&sim).unwrap().contains("vertex 5"));
        // A tick cannot bring a free vertex that is not a number back (one thrown a
        // kilometre, the implicit step can): the run stops at its first tick, and
        // says so.
        sim.state.x[5] = sim.mesh.positions[5];
        let free = (0..sim.state.x.len())
            .find(|v| !sim.fixed.contains(&(*v as u32)))
            .unwrap();
        sim.state.x[free] = Point3::new(f64::NAN, 0.0, 0.0);
        let ticks = std::cell::Cell::new(0);
        let summary = run_observed(
            &mut sim,
            1.0,
            None,
            |_, _| {},
            |_| {
                ticks.set(ticks.get() + 1);
                true
            },
        );
        assert_eq!(summary.ticks, 1);
        assert_eq!(ticks.get(), 0, "after_tick ran on a diverged state");
        assert!(summary.fault.unwrap().starts_with("tick 1 "));
    }
}
