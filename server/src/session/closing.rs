//! Closing: a reason told once and watched by many. A session closes once (an
//! instructor closes it, it is idle, the server shuts down) and the server shuts
//! down once; every stream of it watches, and ends with the reason.

use tokio::sync::watch;

/// Whether something has closed, and why: the first reason given wins; later ones
/// are ignored.
#[derive(Debug)]
pub struct Closing {
    reason: watch::Sender<Option<String>>,
}

impl Default for Closing {
    fn default() -> Self {
        Closing {
            reason: watch::channel(None).0,
        }
    }
}

impl Closing {
    /// Not closed.
    pub fn new() -> Self {
        Self::default()
    }

    /// Closes with `reason`. `true` the first time only: the caller then does what
    /// closing means (tells the streams, stops the thread) once.
    pub fn close(&self, reason: &str) -> bool {
        self.reason.send_if_modified(|r| {
            if r.is_none() {
                *r = Some(reason.to_string());
                true
            } else {
                false
            }
        })
    }

    pub fn is_closed(&self) -> bool {
        self.reason.borrow().is_some()
    }

    /// A watch on the reason: `None` until closed.
    pub fn watch(&self) -> watch::Receiver<Option<String>> {
        self.reason.subscribe()
    }
}

/// Resolves with the reason once `watch` says closed; never when what it watches
/// is gone unclosed (nothing will close it then).
pub async fn closed(watch: &mut watch::Receiver<Option<String>>) -> String {
    let reason = match watch.wait_for(Option::is_some).await {
        Ok(reason) => reason.clone(),
        Err(_) => None,
    };
    match reason {
        Some(reason) => reason,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn the_first_reason_is_told_once_to_every_watcher() {
        let closing = Closing::new();
        let (mut early, late) = (closing.watch(), closing.watch());
        assert!(!closing.is_closed());
        assert_eq!(*early.borrow(), None);
        assert!(closing.close("idle timeout"));
        assert!(!closing.close("server shutting down"));
        assert!(closing.is_closed());
        assert_eq!(closed(&mut early).await, "idle timeout");
        assert_eq!(late.borrow().as_deref(), Some("idle timeout"));
        // A watch taken after closing sees it at once.
        assert_eq!(closed(&mut closing.watch()).await, "idle timeout");
    }
}
