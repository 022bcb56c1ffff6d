//! Pose-to-state latency: the wall time from sending a `DevicePose` to receiving the
//! first `InstrumentState` whose `pose_sequence` is that pose's sequence number, i.e.
//! the first mechanics tick that used the pose, as seen by the station.
//!
//! [`SendTimes`] remembers when each recent sequence number was sent, in a ring
//! indexed by sequence number (no allocation after it is made); [`LatencyHistogram`]
//! records the latencies in microseconds with three significant digits.

use std::time::{Duration, Instant};

use hdrhistogram::Histogram;

/// Latencies above this (60 s) are recorded as this.
const HIGHEST_US: u64 = 60_000_000;

/// The send times of the last `capacity` sequence numbers.
///
/// Slot `sequence % capacity` holds `(sequence, time)`: a sequence number older than
/// `capacity` sends has been overwritten and is unknown, as is one never sent.
#[derive(Clone, Debug)]
pub struct SendTimes {
    slots: Vec<Option<(u64, Instant)>>,
}

impl SendTimes {
    /// A ring for the last `capacity` (at least 1) sequence numbers.
    pub fn new(capacity: usize) -> Self {
        SendTimes {
            slots: vec![None; capacity.max(1)],
        }
    }

    /// How many sequence numbers the ring remembers.
    pub fn capacity(&self) -> usize {
        self.slots.len()
    }

    fn index(&self, sequence: u64) -> usize {
        (sequence % self.slots.len() as u64) as usize
    }

    /// Remembers that `sequence` was sent at `at`, forgetting the sequence number
    /// `capacity` before it.
    pub fn record(&mut self, sequence: u64, at: Instant) {
        let i = self.index(sequence);
        self.slots[i] = Some((sequence, at));
    }

    /// When `sequence` was sent, if the ring still remembers it; it is forgotten
    /// then, so that one pose gives one latency however many states echo it.
    pub fn take(&mut self, sequence: u64) -> Option<Instant> {
        let i = self.index(sequence);
        match self.slots[i] {
            Some((s, at)) if s == sequence => {
                self.slots[i] = None;
                Some(at)
            }
            _ => None,
        }
    }
}

/// Latency percentiles, ms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatencySummary {
    /// Latencies recorded.
    pub count: u64,
    /// Median, ms.
    pub p50_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// 99.9th percentile, ms.
    pub p999_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
}

impl std::fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.count == 0 {
            return write!(f, "no samples");
        }
        write!(
            f,
            "p50 {:.2} ms, p99 {:.2} ms, p99.9 {:.2} ms, max {:.2} ms ({} samples)",
            self.p50_ms, self.p99_ms, self.p999_ms, self.max_ms, self.count
        )
    }
}

/// A histogram of latencies, µs, three significant digits.
#[derive(Clone, Debug)]
pub struct LatencyHistogram {
    us: Histogram<u64>,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHistogram {
    /// An empty histogram from 1 µs to 60 s.
    pub fn new() -> Self {
        LatencyHistogram {
            us: Histogram::new_with_bounds(1, HIGHEST_US, 3).expect("valid fixed histogram bounds"),
        }
    }

    /// Records one latency (clamped to 1 µs … 60 s).
    pub fn record(&mut self, latency: Duration) {
        let us = (latency.as_micros().min(u128::from(HIGHEST_US)) as u64).max(1);
        self.us.saturating_record(us);
    }

    /// Adds every latency of `other`.
    pub fn merge(&mut self, other: &LatencyHistogram) {
        // Same bounds on both sides: adding cannot fail.
        let _ = self.us.add(&other.us);
    }

    /// Latencies recorded.
    pub fn len(&self) -> u64 {
        self.us.len()
    }

    /// Whether none was recorded.
    pub fn is_empty(&self) -> bool {
        self.us.is_empty()
    }

    /// The percentiles so far.
    pub fn summary(&self) -> LatencySummary {
        if self.us.is_empty() {
            return LatencySummary::default();
        }
        let ms = |us: u64| us as f64 / 1000.0;
        LatencySummary {
            count: self.us.len(),
            p50_ms: ms(self.us.value_at_quantile(0.5)),
            p99_ms: ms(self.us.value_at_quantile(0.99)),
            p999_ms: ms(self.us.value_at_quantile(0.999)),
            max_ms: ms(self.us.max()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn remembers_each_sequence_once() {
        let t0 = Instant::now();
        let mut ring = SendTimes::new(8);
        ring.record(3, t0);
        ring.record(4, t0 + Duration::from_millis(4));
        assert_eq!(ring.take(4), Some(t0 + Duration::from_millis(4)));
        assert_eq!(ring.take(4), None, "one pose gives one latency");
        assert_eq!(ring.take(3), Some(t0));
    }

    #[test]
    fn wraparound_forgets_the_oldest() {
        let t0 = Instant::now();
        let mut ring = SendTimes::new(4);
        for s in 0..6 {
            ring.record(s, t0 + Duration::from_millis(s));
        }
        // 0 and 1 were overwritten by 4 and 5, which share their slots.
        assert_eq!(ring.take(0), None);
        assert_eq!(ring.take(1), None);
        assert_eq!(ring.take(2), Some(t0 + Duration::from_millis(2)));
        assert_eq!(ring.take(5), Some(t0 + Duration::from_millis(5)));
    }

    #[test]
    fn unknown_sequences_are_ignored() {
        let mut ring = SendTimes::new(4);
        assert_eq!(ring.take(0), None);
        ring.record(1, Instant::now());
        assert_eq!(ring.take(9), None, "same slot, another sequence");
        assert_eq!(ring.take(u64::MAX), None);
        assert!(ring.take(1).is_some());
        assert_eq!(SendTimes::new(0).capacity(), 1);
    }

    #[test]
    fn histogram_reports_milliseconds_and_merges() {
        let mut a = LatencyHistogram::new();
        assert_eq!(a.summary(), LatencySummary::default());
        for ms in 1..=100 {
            a.record(Duration::from_millis(ms));
        }
        let mut b = LatencyHistogram::new();
        b.record(Duration::from_secs(3600));
        a.merge(&b);
        let s = a.summary();
        assert_eq!(s.count, 101);
        assert!((s.p50_ms - 51.0).abs() < 0.1, "{s:?}");
        assert!((s.max_ms - 60_000.0).abs() < 60.0, "{s:?}");
    }
}
