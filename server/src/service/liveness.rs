//! Whether a station is still there.
//!
//! A station holds instruments; one that went silent (its program hangs, its
//! network is cut without a reset) or froze (it still sends but no longer reads)
//! would hold them for ever and keep its session from idling out. So a station
//! must, within every [station timeout](StationTimeout):
//!
//! - send a message (a pose, a `Heartbeat`, anything): else it is **silent**;
//! - take the server's messages when some wait for it: a message waiting in its
//!   outgoing queue ([`OUTBOUND`](super::stream::OUTBOUND) deep) at every check
//!   for the whole timeout while none was taken is a **frozen** client. (The queue
//!   fills once the client's HTTP/2 flow-control window is full: a client that
//!   does not read stops releasing it. A slow client that still reads takes
//!   messages within the timeout and skips frames instead.)
//!
//! Checked every [`StationTimeout::check_period`] (a tenth of the timeout), so a
//! station is released within 1.1 timeouts of its last sign of life.

use std::fmt;
use std::future::Future;
use std::ops::RangeInclusive;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use laparo_proto::text::Number;
use tokio::sync::{mpsc, oneshot};
use tokio_stream::Stream;
use tokio_stream::wrappers::ReceiverStream;

/// How long a station may stay silent or frozen before it loses its instruments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StationTimeout(Duration);

impl StationTimeout {
    /// The range a station timeout is checked into, s. Below half a second a
    /// network hiccup or a garbage-collection pause of a client releases
    /// instruments in use; above an hour an abandoned station keeps a session
    /// alive through a whole training slot.
    pub const RANGE_S: RangeInclusive<f64> = 0.5..=3600.0;

    /// 5 s: a station sends poses at hundreds of hertz and a heartbeat every
    /// second when it has none, so 5 s of nothing is not a stall of the network
    /// (the pose-rate limit absorbs stalls of that order) but a station gone.
    pub const DEFAULT: StationTimeout = StationTimeout(Duration::from_secs(5));

    /// `seconds`, when within [`RANGE_S`](Self::RANGE_S); else an error stating
    /// the range (the caller names the flag or field).
    pub fn from_secs(seconds: f64) -> Result<Self, String> {
        if Self::RANGE_S.contains(&seconds) {
            Ok(StationTimeout(Duration::from_secs_f64(seconds)))
        } else {
            Err(format!(
                "{} s is outside [{}, {}] s",
                Number(seconds),
                Self::RANGE_S.start(),
                Self::RANGE_S.end()
            ))
        }
    }

    pub fn duration(self) -> Duration {
        self.0
    }

    /// How often a station's liveness is checked: a tenth of the timeout.
    pub fn check_period(self) -> Duration {
        self.0 / 10
    }
}

impl Default for StationTimeout {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a station is taken for gone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gone {
    /// It sent nothing for this long.
    Silent(Duration),
    /// Messages waited for it and it took none for this long.
    Frozen(Duration),
}

impl fmt::Display for Gone {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Gone::Silent(d) => write!(f, "sent nothing for {:.1} s", d.as_secs_f64()),
            Gone::Frozen(d) => write!(
                f,
                "took none of the server's messages for {:.1} s",
                d.as_secs_f64()
            ),
        }
    }
}

/// When a station's stream last took a message from its queue, shared by the
/// stream ([`Outbound`]) and the station's reader ([`Liveness`]).
#[derive(Debug)]
pub struct Taken {
    origin: Instant,
    /// Nanoseconds from `origin` to the last take.
    nanos: AtomicU64,
}

impl Taken {
    pub fn new(origin: Instant) -> Arc<Self> {
        Arc::new(Taken {
            origin,
            nanos: AtomicU64::new(0),
        })
    }

    fn mark(&self) {
        let n = self.origin.elapsed().as_nanos().min(u128::from(u64::MAX)) as u64;
        self.nanos.store(n, Ordering::Relaxed);
    }

    fn last(&self) -> Instant {
        self.origin + Duration::from_nanos(self.nanos.load(Ordering::Relaxed))
    }
}

/// A station's signs of life.
#[derive(Debug)]
pub struct Liveness {
    timeout: Duration,
    heard: Instant,
    taken: Arc<Taken>,
    /// Since when messages have waited for the station at every check.
    waiting_since: Option<Instant>,
}

impl Liveness {
    /// A station that joined at `now`.
    pub fn new(timeout: StationTimeout, now: Instant, taken: Arc<Taken>) -> Self {
        taken.nanos.store(
            now.saturating_duration_since(taken.origin).as_nanos() as u64,
            Ordering::Relaxed,
        );
        Liveness {
            timeout: timeout.duration(),
            heard: now,
            taken,
            waiting_since: None,
        }
    }

    /// The station sent a message at `now`.
    pub fn heard(&mut self, now: Instant) {
        self.heard = now;
    }

    /// Whether the station is gone at `now`, `waiting` saying whether messages
    /// wait for it in its queue.
    pub fn check(&mut self, now: Instant, waiting: bool) -> Option<Gone> {
        let silent = now.saturating_duration_since(self.heard);
        if silent >= self.timeout {
            return Some(Gone::Silent(silent));
        }
        self.waiting_since = if waiting {
            Some(self.waiting_since.unwrap_or(now))
        } else {
            None
        };
        let since = self.waiting_since?.max(self.taken.last());
        let frozen = now.saturating_duration_since(since);
        (frozen >= self.timeout).then_some(Gone::Frozen(frozen))
    }
}

/// Messages to one client.
pub type Message<M> = Result<M, tonic::Status>;

/// The stream a station receives: its queue, each message taken marked in
/// [`Taken`], until it is cut with a status, which then goes out before anything
/// still queued and ends the stream.
pub struct Outbound<M> {
    queue: Option<ReceiverStream<Message<M>>>,
    cut: Option<oneshot::Receiver<tonic::Status>>,
    taken: Arc<Taken>,
}

impl<M> Outbound<M> {
    /// The stream of `queue`, ended early by a status sent on the returned handle.
    pub fn new(
        queue: mpsc::Receiver<Message<M>>,
        taken: Arc<Taken>,
    ) -> (Self, oneshot::Sender<tonic::Status>) {
        let (cut_tx, cut) = oneshot::channel();
        let stream = Outbound {
            queue: Some(ReceiverStream::new(queue)),
            cut: Some(cut),
            taken,
        };
        (stream, cut_tx)
    }
}

impl<M> Stream for Outbound<M> {
    type Item = Message<M>;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
        let this = &mut *self;
        if let Some(cut) = &mut this.cut {
            match Pin::new(cut).poll(cx) {
                Poll::Ready(Ok(status)) => {
                    // Dropping the queue also ends whoever still sends into it.
                    this.cut = None;
                    this.queue = None;
                    return Poll::Ready(Some(Err(status)));
                }
                // Never cut: the station ended by itself.
                Poll::Ready(Err(_)) => this.cut = None,
                Poll::Pending => {}
            }
        }
        let Some(queue) = &mut this.queue else {
            return Poll::Ready(None);
        };
        let next = Pin::new(queue).poll_next(cx);
        if let Poll::Ready(Some(_)) = &next {
            this.taken.mark();
        }
        next
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(origin: Instant, ms: u64) -> Instant {
        origin + Duration::from_millis(ms)
    }

    #[test]
    fn station_timeouts_within_the_range_pass_and_others_are_refused() {
        assert_eq!(
            StationTimeout::from_secs(0.5).unwrap().duration(),
            Duration::from_millis(500)
        );
        assert!(StationTimeout::from_secs(3600.0).is_ok());
        for bad in [0.0, 0.49, -1.0, 3600.5, 1e20, f64::INFINITY, f64::NAN] {
            let e = StationTimeout::from_secs(bad).unwrap_err();
            assert!(e.contains("[0.5, 3600] s"), "{bad}: {e}");
        }
        let e = StationTimeout::from_secs(1e20).unwrap_err();
        assert!(e.starts_with("1e20 s is outside"), "{e}");
    }

    #[test]
    fn a_silent_station_is_gone_after_the_timeout_and_not_before() {
        let t0 = Instant::now();
        let timeout = StationTimeout::from_secs(1.0).unwrap();
        let mut live = Liveness::new(timeout, t0, Taken::new(t0));
        assert_eq!(live.check(at(t0, 999), false), None);
        live.heard(at(t0, 500));
        assert_eq!(live.check(at(t0, 1499), false), None);
        assert_eq!(
            live.check(at(t0, 1500), false),
            Some(Gone::Silent(Duration::from_secs(1)))
        );
    }

    #[test]
    fn a_station_that_takes_nothing_while_messages_wait_is_frozen() {
        let t0 = Instant::now();
        let taken = Taken::new(t0);
        let timeout = StationTimeout::from_secs(1.0).unwrap();
        let mut live = Liveness::new(timeout, t0, taken.clone());
        // It keeps sending, so it is never silent.
        for ms in (0..=2000).step_by(100) {
            live.heard(at(t0, ms));
            let gone = live.check(at(t0, ms), ms >= 300);
            if ms < 1300 {
                assert_eq!(gone, None, "{ms} ms");
            } else {
                assert_eq!(gone, Some(Gone::Frozen(Duration::from_millis(ms - 300))));
                return;
            }
        }
        unreachable!("the station was found frozen");
    }

    #[test]
    fn nothing_waiting_or_a_recent_take_is_not_frozen() {
        let t0 = Instant::now();
        let taken = Taken::new(t0);
        let timeout = StationTimeout::from_secs(1.0).unwrap();
        let mut live = Liveness::new(timeout, t0, taken.clone());
        for ms in (0..=3000).step_by(100) {
            live.heard(at(t0, ms));
            // Waiting only now and then: a client that drains its queue.
            assert_eq!(live.check(at(t0, ms), ms % 500 != 0), None, "{ms} ms");
        }
    }
}
