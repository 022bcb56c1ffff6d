//! laparo server library: the simulation engine (synchronous, free of networking);
//! the frame layer, which says what a scene and each of its ticks are in the
//! contract's terms; and the session, recording and service layers above them.
//!
//! Its documentation is for those who work on it: built with private items
//! (`cargo doc --document-private-items`, as CI builds it), where the links from
//! public items to the private stages and helpers they describe resolve.
#![allow(rustdoc::private_intra_doc_links)]

pub mod console;
pub mod engine;
pub mod export;
pub mod frame;
pub mod headless;
pub mod output;
pub mod recording;
pub mod service;
pub mod session;
