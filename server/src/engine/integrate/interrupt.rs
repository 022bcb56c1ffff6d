//! Ending a step early: a flag another thread raises (the session closing, the server
//! shutting down), read between explicit substeps and between conjugate-gradient
//! iterations. Reading it is one relaxed atomic load: no allocation, no lock.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// The flag a step polls; the default is never raised.
#[derive(Clone, Debug, Default)]
pub struct Interrupt(Option<Arc<AtomicBool>>);

impl Interrupt {
    /// Polls `flag`: a step stops once it is `true`.
    pub fn new(flag: Arc<AtomicBool>) -> Self {
        Interrupt(Some(flag))
    }

    /// Whether the step should stop now.
    #[inline]
    pub fn is_raised(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }
}
