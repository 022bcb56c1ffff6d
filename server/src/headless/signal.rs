//! SIGINT (Ctrl-C) and SIGTERM during `laparo-server run`.
//!
//! Killed by the signal's default action, a run could die halfway through writing
//! a series frame, leaving its `OUT.<pid>.part` beside the output (see
//! [`crate::output`]). Instead the first signal raises a flag: the step in flight
//! ends at its next CG iteration or explicit substep (the integrator polls the
//! flag, [`crate::engine::integrate::Integrator::set_interrupt`]), no frame is
//! written after it, and the run ends with an error saying where it stopped, every
//! part file removed. A second signal ends the process at once (exit status 130),
//! for a user who will not wait for a file being written.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A flag raised by the first SIGINT or SIGTERM after this call; the handlers are
/// installed before it returns, so no signal in between is lost to the default
/// action. If they cannot be installed (no runtime, no thread), the failure is
/// logged and the flag is never raised: the signals then act as they did.
pub fn stop_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    #[cfg(unix)]
    if let Err(e) = watch(flag.clone()) {
        tracing::warn!("Ctrl-C will end the run without cleaning up: {e}");
    }
    flag
}

/// SIGINT and SIGTERM, installed together and awaited as one: the two signals that
/// ask a server or a run to stop.
#[cfg(unix)]
pub struct StopSignals {
    interrupt: tokio::signal::unix::Signal,
    terminate: tokio::signal::unix::Signal,
}

#[cfg(unix)]
impl StopSignals {
    /// Installs both handlers; must be called within a tokio runtime. From here on
    /// neither signal takes its default action.
    pub fn install() -> std::io::Result<Self> {
        use tokio::signal::unix::{SignalKind, signal};
        Ok(StopSignals {
            interrupt: signal(SignalKind::interrupt())?,
            terminate: signal(SignalKind::terminate())?,
        })
    }

    /// The next SIGINT or SIGTERM.
    pub async fn recv(&mut self) {
        tokio::select! {
            _ = self.interrupt.recv() => {}
            _ = self.terminate.recv() => {}
        }
    }
}

#[cfg(unix)]
fn watch(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()?;
    let mut signals = {
        let _entered = runtime.enter();
        StopSignals::install()?
    };
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            runtime.block_on(async move {
                signals.recv().await;
                flag.store(true, Ordering::Relaxed);
                super::out::tell(format_args!(
                    "stopping at the end of this tick (a second signal stops now)"
                ));
                signals.recv().await;
                std::process::exit(130);
            })
        })?;
    Ok(())
}
