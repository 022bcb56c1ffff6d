//! laparo server library: the simulation engine (synchronous, free of networking);
//! the frame layer, which says what a scene and each of its ticks are in the
//! contract's terms; and the session, recording and service layers above them.

pub mod console;
pub mod engine;
pub mod export;
pub mod frame;
pub mod headless;
pub mod recording;
pub mod service;
pub mod session;
