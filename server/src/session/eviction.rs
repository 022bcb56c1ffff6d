//! Ending a station from outside its stream: an instructor evicts it.
//!
//! Each station of the roster has a one-shot handle: [`Session::evict`] takes it
//! under the roster lock and hands the station's stream an [`Eviction`]; the stream
//! stops reading, ends with a status naming who evicted it and why, frees its
//! instruments (withdrawn from the body, as when a station leaves) and says so
//! through [`Eviction::done`]. The station's own task does the freeing, so that no
//! pose it was reading can land after its instruments are free; the evicting call
//! waits for it, at most [`EVICTION_WAIT`], and frees them itself past that.

use std::time::Duration;

use laparo_proto::v1;
use tokio::sync::oneshot;

use super::{Roster, Session};

/// How long [`Session::evict`] waits for the station's stream to free its
/// instruments. The stream's task only has to notice (it waits on the handle with
/// its reads), so a second means the runtime is stuck, not slow.
pub const EVICTION_WAIT: Duration = Duration::from_secs(1);

/// Who ends a station, and why; handed to the station's stream.
#[derive(Debug)]
pub struct Eviction {
    /// The caller that evicted the station (its token's name), printable.
    pub by: String,
    /// Why, printable.
    pub reason: String,
    /// Sent once the station's instruments are free.
    pub done: oneshot::Sender<()>,
}

impl Session {
    /// The handle through which station `station`, just added to `roster`, learns
    /// that it is evicted (under the same roster lock as [`Session::add_station`]).
    /// The handle is dropped when the station is removed.
    pub fn eviction_handle(roster: &mut Roster, station: u64) -> oneshot::Receiver<Eviction> {
        let (tx, rx) = oneshot::channel();
        roster.evictions.insert(station, tx);
        rx
    }

    /// Evicts station `station` on behalf of `by` for `reason`: its stream ends and
    /// its instruments are free when this returns. The station as it was, or
    /// `None` when the session has no such station.
    pub async fn evict(&self, station: u64, by: &str, reason: &str) -> Option<v1::StationInfo> {
        let (info, handle) = {
            let mut roster = self.roster();
            let info = roster.stations.get(&station).cloned()?;
            (info, roster.evictions.remove(&station))
        };
        let (done_tx, done) = oneshot::channel();
        let handed = handle.is_some_and(|h| {
            h.send(Eviction {
                by: by.to_string(),
                reason: reason.to_string(),
                done: done_tx,
            })
            .is_ok()
        });
        if !handed || !matches!(tokio::time::timeout(EVICTION_WAIT, done).await, Ok(Ok(()))) {
            // The stream is ending by itself, or did not answer in time: free the
            // instruments here (removing a station twice is harmless).
            self.remove_station(station);
        }
        Some(info)
    }
}
