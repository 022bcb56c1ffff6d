//! How often one station may join: the bound on the events a station causes
//! across rejoins.
//!
//! Every join and every leave is an event copied to each observer and into the
//! recording. A client that joins and leaves in a loop would otherwise produce
//! events as fast as the network carries them. Joins are counted per caller (the
//! token's name, and the peer's address) in a token bucket: [`JOIN_BURST`] at once,
//! then [`JOINS_PER_SECOND`]; beyond that a join answers `RESOURCE_EXHAUSTED`
//! naming the limit. One station then causes at most
//! `2 · (JOIN_BURST + JOINS_PER_SECOND · t)` join and leave events in `t` seconds.

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Instant;

use tonic::Status;

/// Joins one caller may make at once. A caller is a token's name and a peer
/// address, so a whole lab behind one token and one address is one caller: 256
/// covers the 64-session, 2-station soak and `laparo load --stations 32` runs side
/// by side, with room.
pub const JOIN_BURST: f64 = 256.0;
/// Joins per second one caller may sustain after its burst: a station rejoining
/// after a dropped connection is one join; 50 a second bounds a churning client
/// to 100 join and leave events a second, each under the name limits.
pub const JOINS_PER_SECOND: f64 = 50.0;
/// Callers remembered at most; beyond, the full buckets (idle callers) are forgotten.
const CALLERS: usize = 4096;

/// Token buckets of joins, per caller.
#[derive(Default)]
pub struct JoinRate {
    buckets: Mutex<HashMap<String, (f64, Instant)>>,
}

impl JoinRate {
    /// Takes one join from `caller`'s bucket at `now`, or refuses it.
    pub fn admit(&self, caller: &str, now: Instant) -> Result<(), Status> {
        let mut buckets = self.buckets.lock().unwrap_or_else(|e| e.into_inner());
        if buckets.len() >= CALLERS && !buckets.contains_key(caller) {
            buckets.retain(|_, (tokens, at)| refill(*tokens, *at, now) < JOIN_BURST);
            if buckets.len() >= CALLERS {
                return Err(Status::resource_exhausted(format!(
                    "too many callers joining at once (limit {CALLERS})"
                )));
            }
        }
        let (tokens, at) = buckets
            .entry(caller.to_string())
            .or_insert((JOIN_BURST, now));
        let available = refill(*tokens, *at, now);
        if available < 1.0 {
            return Err(Status::resource_exhausted(format!(
                "joining too often: at most {JOIN_BURST} joins at once, then {JOINS_PER_SECOND} a second, per caller"
            )));
        }
        *tokens = available - 1.0;
        *at = now;
        Ok(())
    }
}

/// The bucket `tokens` at `at`, refilled to `now` and capped at the burst.
fn refill(tokens: f64, at: Instant, now: Instant) -> f64 {
    let dt = now.saturating_duration_since(at).as_secs_f64();
    (tokens + dt * JOINS_PER_SECOND).min(JOIN_BURST)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_burst_passes_then_the_sustained_rate_and_no_more() {
        let rate = JoinRate::default();
        let t0 = Instant::now();
        for _ in 0..JOIN_BURST as usize {
            rate.admit("a", t0).unwrap();
        }
        let e = rate.admit("a", t0).unwrap_err();
        assert_eq!(e.code(), tonic::Code::ResourceExhausted);
        assert!(e.message().contains("a second"));
        // Another caller has its own bucket.
        rate.admit("b", t0).unwrap();
        // One second later exactly JOINS_PER_SECOND more pass.
        let t1 = t0 + Duration::from_secs(1);
        for _ in 0..JOINS_PER_SECOND as usize {
            rate.admit("a", t1).unwrap();
        }
        assert!(rate.admit("a", t1).is_err());
    }
}
