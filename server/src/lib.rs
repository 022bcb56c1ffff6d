//! laparo server library: the simulation engine (synchronous, free of networking) and,
//! as they land, the session, service and recording layers around it.

pub mod engine;
pub mod export;
pub mod headless;
pub mod recording;
pub mod service;
pub mod session;
