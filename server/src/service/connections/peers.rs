//! Connections counted per peer address, and the refusals of peers at their limit,
//! logged once per interval (see [`connections`](super)).

use std::collections::HashMap;
use std::net::{IpAddr, Ipv6Addr};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::time::Instant;

/// How long a peer refused past its limit is logged once for, and how often the
/// refusals of an interval are summed up in one line.
pub const REFUSAL_LOG_INTERVAL: Duration = Duration::from_secs(10);
/// Most peers logged by address in one [`REFUSAL_LOG_INTERVAL`]; the others are
/// only counted in the interval's summary, so that many peers cannot grow the log
/// (nor the memory of who was logged) without bound.
pub const REFUSAL_LOG_PEERS: usize = 16;

/// The address a peer is counted under, `None` for loopback (not counted per
/// peer): an IPv4-mapped IPv6 address as IPv4, an IPv6 one as its /64.
pub(super) fn peer_key(ip: IpAddr) -> Option<IpAddr> {
    let ip = ip.to_canonical();
    if ip.is_loopback() {
        return None;
    }
    Some(match ip {
        IpAddr::V4(_) => ip,
        IpAddr::V6(v6) => IpAddr::V6(Ipv6Addr::from(u128::from(v6) & !(u64::MAX as u128))),
    })
}

/// Counts the open connections of each peer address (only those with one open:
/// at most the server's connection limit of entries).
#[derive(Debug, Default)]
pub struct PeerCounts(Mutex<HashMap<IpAddr, usize>>);

impl PeerCounts {
    /// Connections open now from the peer counted as `key`.
    pub fn get(&self, key: IpAddr) -> usize {
        let counts = self.0.lock().unwrap_or_else(|e| e.into_inner());
        counts.get(&key).copied().unwrap_or(0)
    }

    /// A slot for peer `key` if it has fewer than `max` open.
    pub(super) fn take(self: &Arc<Self>, key: IpAddr, max: usize) -> Option<PeerSlot> {
        let mut counts = self.0.lock().unwrap_or_else(|e| e.into_inner());
        let n = counts.entry(key).or_insert(0);
        if *n >= max {
            if *n == 0 {
                counts.remove(&key);
            }
            return None;
        }
        *n += 1;
        Some(PeerSlot {
            counts: self.clone(),
            key,
        })
    }
}

/// One connection of a peer, released when dropped.
#[derive(Debug)]
pub(super) struct PeerSlot {
    counts: Arc<PeerCounts>,
    key: IpAddr,
}

impl Drop for PeerSlot {
    fn drop(&mut self) {
        let mut counts = self.counts.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(n) = counts.get_mut(&self.key) {
            *n -= 1;
            if *n == 0 {
                counts.remove(&self.key);
            }
        }
    }
}

/// The refusals of peers past their limit in the current
/// [`REFUSAL_LOG_INTERVAL`]: the first of each peer is logged (up to
/// [`REFUSAL_LOG_PEERS`] peers), and at the interval's end one line sums them up.
#[derive(Debug)]
pub(super) struct PeerRefusals {
    since: Instant,
    /// Peers logged this interval, and how many of their connections were refused.
    logged: HashMap<IpAddr, u64>,
    /// Connections refused this interval from peers past [`REFUSAL_LOG_PEERS`].
    unlogged: u64,
}

/// What [`PeerRefusals`] says of an interval that ended.
#[derive(Debug, PartialEq, Eq)]
pub(super) struct RefusalSummary {
    connections: u64,
    /// Peers logged by address; more may have been refused unnamed.
    named_peers: usize,
    /// Connections refused from peers not named.
    unnamed: u64,
}

impl PeerRefusals {
    pub(super) fn new(now: Instant) -> Self {
        PeerRefusals {
            since: now,
            logged: HashMap::new(),
            unlogged: 0,
        }
    }

    /// When the current interval ends, if it holds refusals to sum up.
    pub(super) fn due(&self) -> Option<Instant> {
        (!self.logged.is_empty()).then_some(self.since + REFUSAL_LOG_INTERVAL)
    }

    /// Ends the interval if it is over: its summary, if it refused anything.
    pub(super) fn roll(&mut self, now: Instant) -> Option<RefusalSummary> {
        if now < self.since + REFUSAL_LOG_INTERVAL {
            return None;
        }
        let summary = (!self.logged.is_empty()).then(|| RefusalSummary {
            connections: self.logged.values().sum::<u64>() + self.unlogged,
            named_peers: self.logged.len(),
            unnamed: self.unlogged,
        });
        *self = PeerRefusals::new(now);
        summary
    }

    /// Counts a refusal of `peer`: `true` if it is to be logged (its first this
    /// interval, and room for its address).
    pub(super) fn refuse(&mut self, peer: IpAddr) -> bool {
        if let Some(n) = self.logged.get_mut(&peer) {
            *n += 1;
            return false;
        }
        if self.logged.len() >= REFUSAL_LOG_PEERS {
            self.unlogged += 1;
            return false;
        }
        self.logged.insert(peer, 1);
        true
    }
}

/// Logs the summary of an interval of refusals.
pub(super) fn log_summary(summary: RefusalSummary, per_peer: usize) {
    tracing::warn!(
        "refused {} connections in the last {} s from peers at their limit of {per_peer} \
         (--max-connections-per-peer): {} peers named above{}",
        summary.connections,
        REFUSAL_LOG_INTERVAL.as_secs(),
        summary.named_peers,
        if summary.unnamed > 0 {
            format!(", {} connections from others", summary.unnamed)
        } else {
            String::new()
        }
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_peer_is_counted_by_address_loopback_not_at_all() {
        let ip = |s: &str| s.parse::<IpAddr>().unwrap();
        assert_eq!(peer_key(ip("127.0.0.1")), None);
        assert_eq!(peer_key(ip("127.3.2.1")), None);
        assert_eq!(peer_key(ip("::1")), None);
        // Loopback through a dual-stack listener.
        assert_eq!(peer_key(ip("::ffff:127.0.0.1")), None);
        assert_eq!(peer_key(ip("192.0.2.7")), Some(ip("192.0.2.7")));
        assert_eq!(peer_key(ip("::ffff:192.0.2.7")), Some(ip("192.0.2.7")));
        // Any address of one /64 is the same peer; another /64 is another.
        assert_eq!(
            peer_key(ip("2001:db8:1:2:aaaa::1")),
            Some(ip("2001:db8:1:2::"))
        );
        assert_eq!(
            peer_key(ip("2001:db8:1:2:ffff:ffff:ffff:ffff")),
            Some(ip("2001:db8:1:2::"))
        );
        assert_eq!(peer_key(ip("2001:db8:1:3::1")), Some(ip("2001:db8:1:3::")));
    }

    #[test]
    fn a_peers_count_never_passes_its_limit_and_others_are_counted_apart() {
        let counts = Arc::new(PeerCounts::default());
        let (a, b) = ("192.0.2.1".parse().unwrap(), "192.0.2.2".parse().unwrap());
        let first = counts.take(a, 2).unwrap();
        let _second = counts.take(a, 2).unwrap();
        assert!(counts.take(a, 2).is_none());
        assert_eq!(counts.get(a), 2);
        let other = counts.take(b, 2).unwrap();
        drop(first);
        assert_eq!(counts.get(a), 1);
        assert!(counts.take(a, 2).is_some());
        // A peer with nothing open leaves no entry behind.
        drop(other);
        assert!(!counts.0.lock().unwrap().contains_key(&b));
    }

    #[test]
    fn refusals_are_logged_once_per_peer_and_interval_and_summed_up() {
        let start = Instant::now();
        let mut refusals = PeerRefusals::new(start);
        assert_eq!(refusals.due(), None, "nothing to sum up");
        let peer = |i: u32| IpAddr::from(std::net::Ipv4Addr::from(0xc000_0200 + i));
        assert!(refusals.refuse(peer(0)));
        for _ in 0..1000 {
            assert!(!refusals.refuse(peer(0)), "said once");
        }
        for i in 1..100 {
            assert_eq!(refusals.refuse(peer(i)), i < REFUSAL_LOG_PEERS as u32);
        }
        assert_eq!(refusals.logged.len(), REFUSAL_LOG_PEERS);
        assert_eq!(refusals.due(), Some(start + REFUSAL_LOG_INTERVAL));
        assert_eq!(refusals.roll(start + REFUSAL_LOG_INTERVAL / 2), None);
        assert_eq!(
            refusals.roll(start + REFUSAL_LOG_INTERVAL),
            Some(RefusalSummary {
                connections: 1000 + 100,
                named_peers: REFUSAL_LOG_PEERS,
                unnamed: 100 - REFUSAL_LOG_PEERS as u64,
            })
        );
        // A new interval: the peer is said again, once.
        assert!(refusals.refuse(peer(0)));
        assert!(!refusals.refuse(peer(0)));
    }
}
