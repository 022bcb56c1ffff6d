//! What the force loop measures about itself.
//!
//! [`StatsRecorder`] records every tick without allocating (its histogram is sized
//! once, up front); [`LoopStats`] is a plain copy of the figures, cheap to publish to
//! another thread.
//!
//! Jitter is `|actual period − nominal period|`, the actual period being the haptic
//! time between two successive ticks. On the loop's own thread haptic time is wall
//! time since the loop started, so this is the scheduling jitter the device feels;
//! driven in simulated time it is whatever the driver's steps make it.

use hdrhistogram::Histogram;
use nalgebra::Vector3;

/// Jitter above this (1 s) is recorded as this in the percentiles; the exact maximum
/// is kept apart.
const JITTER_HIGHEST_NS: u64 = 1_000_000_000;

/// A snapshot of the force loop's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoopStats {
    /// Ticks run.
    pub ticks: u64,
    /// Haptic time from the first tick to the last, s.
    pub elapsed_s: f64,
    /// Achieved rate: ticks after the first per elapsed haptic (on the loop thread,
    /// wall) time, Hz; 0 before two ticks.
    pub rate_hz: f64,
    /// Period jitter `|actual − nominal|`, s.
    pub jitter: Jitter,
    /// Largest change of the rendered force from one tick to the next, N.
    pub max_force_step: f64,
    /// Haptic time since the model in use arrived, at the last tick, s.
    pub model_age_s: f64,
    /// Largest such age over all ticks with a model, s.
    pub max_model_age_s: f64,
    /// Mechanics tick of the model in use, if any.
    pub model_tick: Option<u64>,
    /// Models taken from the inbox.
    pub models_received: u64,
    /// Ticks whose force exceeded the device's limit and was scaled down to it.
    pub clamped_ticks: u64,
    /// Ticks whose force was not finite and was rendered as zero.
    pub non_finite_ticks: u64,
    /// Ticks on which the passivity controller damped the models' force
    /// ([`super::passivity`]).
    pub damped_ticks: u64,
    /// Deadlines skipped by the loop thread to resynchronise after running late by
    /// more than a period.
    pub missed_deadlines: u64,
}

/// Percentiles of the period jitter, s (three significant digits).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Jitter {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Largest, exact.
    pub max: f64,
}

/// Records the force loop's figures tick by tick; allocation-free after `new`.
#[derive(Debug)]
pub struct StatsRecorder {
    nominal_period_s: f64,
    jitter_ns: Histogram<u64>,
    first_t: Option<f64>,
    last_t: f64,
    last_force: Vector3<f64>,
    stats: LoopStats,
}

/// How one tick's force was limited.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// Within the device's limit, rendered as computed.
    None,
    /// Over the limit, scaled down to it.
    Clamped,
    /// Not finite, rendered as zero.
    NonFinite,
}

impl StatsRecorder {
    /// A recorder for a loop of nominal period `nominal_period_s`.
    pub fn new(nominal_period_s: f64) -> Self {
        StatsRecorder {
            nominal_period_s,
            jitter_ns: Histogram::new_with_bounds(1, JITTER_HIGHEST_NS, 3)
                .expect("valid fixed histogram bounds"),
            first_t: None,
            last_t: 0.0,
            last_force: Vector3::zeros(),
            stats: LoopStats::default(),
        }
    }

    /// Records one tick at haptic time `t` that rendered `force` (after limiting) with
    /// the model that arrived at `model` = `(arrival time, mechanics tick)`, if any.
    pub fn record_tick(
        &mut self,
        t: f64,
        force: &Vector3<f64>,
        limit: Limit,
        model: Option<(f64, u64)>,
    ) {
        let s = &mut self.stats;
        match self.first_t {
            None => self.first_t = Some(t),
            Some(first) => {
                let jitter = ((t - self.last_t) - self.nominal_period_s).abs();
                self.jitter_ns
                    .saturating_record((jitter * 1e9).round().min(u64::MAX as f64) as u64);
                s.jitter.max = s.jitter.max.max(jitter);
                s.max_force_step = s.max_force_step.max((force - self.last_force).norm());
                s.elapsed_s = t - first;
            }
        }
        self.last_t = t;
        self.last_force = *force;
        s.ticks += 1;
        match limit {
            Limit::None => {}
            Limit::Clamped => s.clamped_ticks += 1,
            Limit::NonFinite => s.non_finite_ticks += 1,
        }
        match model {
            Some((arrival, tick)) => {
                s.model_age_s = t - arrival;
                s.max_model_age_s = s.max_model_age_s.max(s.model_age_s);
                s.model_tick = Some(tick);
            }
            None => {
                s.model_age_s = 0.0;
                s.model_tick = None;
            }
        }
    }

    /// Counts one model taken from the inbox.
    pub fn record_model(&mut self) {
        self.stats.models_received += 1;
    }

    /// Counts `n` deadlines skipped.
    pub fn record_missed(&mut self, n: u64) {
        self.stats.missed_deadlines += n;
    }

    /// The figures so far. Does not allocate; scans the histogram once.
    pub fn snapshot(&self) -> LoopStats {
        let mut stats = self.stats;
        stats.rate_hz = if stats.ticks > 1 && stats.elapsed_s > 0.0 {
            (stats.ticks - 1) as f64 / stats.elapsed_s
        } else {
            0.0
        };
        if !self.jitter_ns.is_empty() {
            let mut q = self.jitter_ns.value_at_quantiles([0.5, 0.99, 0.999]);
            let mut next = || q.next().unwrap_or(0) as f64 * 1e-9;
            stats.jitter.p50 = next();
            stats.jitter.p99 = next();
            stats.jitter.p999 = next();
        }
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_rate_jitter_and_force_steps() {
        let mut r = StatsRecorder::new(1e-3);
        let f = |x: f64| Vector3::new(x, 0.0, 0.0);
        r.record_tick(0.0, &f(0.0), Limit::None, None);
        r.record_tick(1e-3, &f(0.5), Limit::Clamped, Some((1e-3, 7)));
        r.record_tick(2.5e-3, &f(0.25), Limit::NonFinite, Some((1e-3, 7)));
        r.record_model();
        r.record_missed(3);
        let s = r.snapshot();
        assert_eq!(s.ticks, 3);
        assert!((s.rate_hz - 2.0 / 2.5e-3).abs() < 1e-6);
        assert!((s.jitter.max - 0.5e-3).abs() < 1e-12);
        assert!((s.jitter.p999 - 0.5e-3).abs() < 1e-6);
        assert_eq!(s.max_force_step, 0.5);
        assert_eq!((s.clamped_ticks, s.non_finite_ticks), (1, 1));
        assert_eq!(s.model_tick, Some(7));
        assert!((s.model_age_s - 1.5e-3).abs() < 1e-15);
        assert_eq!((s.models_received, s.missed_deadlines), (1, 3));
    }
}
