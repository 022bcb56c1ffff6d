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

#[cfg(unix)]
fn watch(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    use tokio::signal::unix::{SignalKind, signal};

    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .build()?;
    let (mut interrupt, mut terminate) = {
        let _entered = runtime.enter();
        (
            signal(SignalKind::interrupt())?,
            signal(SignalKind::terminate())?,
        )
    };
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            runtime.block_on(async move {
                tokio::select! {
                    _ = interrupt.recv() => {}
                    _ = terminate.recv() => {}
                }
                flag.store(true, Ordering::Relaxed);
                eprintln!("stopping at the end of this tick (a second signal stops now)");
                tokio::select! {
                    _ = interrupt.recv() => {}
                    _ = terminate.recv() => {}
                }
                std::process::exit(130);
            })
        })?;
    Ok(())
}
