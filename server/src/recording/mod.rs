//! Session recordings: one MCAP file per session, readable by any MCAP tool.
//!
//! The file's profile is `protobuf`; every message type of the contract has a
//! schema whose data is the contract's encoded `FileDescriptorSet`
//! ([`laparo_proto::FILE_DESCRIPTOR_SET`]) and whose name is the message's full
//! name, so a reader needs nothing of ours to decode it. Topics:
//!
//! | topic             | message                       | log time                      |
//! |-------------------|-------------------------------|-------------------------------|
//! | `/scene`          | `laparo.v1.SceneDescription`  | session start (written once)  |
//! | `/poses`          | `laparo.v1.DevicePose`        | when the server received it   |
//! | `/surface`        | `laparo.v1.SurfaceFrame`      | session start + sim time      |
//! | `/instruments`    | `laparo.v1.InstrumentState`   | session start + sim time      |
//! | `/events`         | `laparo.v1.Event`             | session start + sim time      |
//! | `/foxglove/scene` | `foxglove.SceneUpdate`        | session start + sim time      |
//!
//! `/foxglove/scene` is for viewers: its schema is Foxglove's own, as the
//! `foxglove` crate states it, and each tick's update draws the deformed liver,
//! the instruments' shafts and their forces ([`foxglove_scene`]), so the file opens
//! in Foxglove as a 3D scene. Its liver is an indexed triangle list (three points
//! per triangle would be three times the bytes), and it is written for the first
//! tick and then at most 20 times a simulated second
//! ([`foxglove_scene::MAX_RATE_HZ`]): at every tick it was 81% of a liver-20k file,
//! f64 points against `/surface`'s f32.
//! [`Recording::messages`] skips it; [`Recording::scene_updates`] decodes it on
//! demand. In Foxglove's Plot panel the fields of `/instruments` plot as they are,
//! by message path: the force's magnitude, its components and its axial part, for
//! example `/instruments{instrument=="left"}.force.magnitude_n`.
//!
//! Log times are ns since the Unix epoch; ticks are stamped from simulated time so
//! that a replay is deterministic, while publish times are wall-clock. The metadata
//! record `laparo.scene` holds the scene's TOML text, the session id, the scene
//! name, the start time and the format version ([`FORMAT_VERSION`]).
//!
//! - [`writer`]: the MCAP side — schemas, channels, chunks closed at least once a
//!   second so that a killed server loses at most the last second.
//! - [`chunked`]: the MCAP file written in constant memory, however long the
//!   session records: the chunk index is read back from the file at its finish,
//!   not held (the mcap crate's writer holds ~300 bytes a chunk until then).
//! - [`foxglove_scene`]: a tick as a Foxglove `SceneUpdate`, built on the recorder
//!   thread.
//! - [`recorder`]: the thread that owns a writer, fed through a bounded channel the
//!   mechanics thread never waits on; drops and failures are counted and reported.
//! - [`source`]: a recording's bytes, read a record at a time through the file
//!   handle (never mapped: a file cut short under a reader is an error, not SIGBUS).
//! - [`reader`]: opens a recording, checks its version, decodes its messages.
//! - [`summary`]: what a reviewer wants first: duration, path lengths, forces.
//! - [`list`](mod@list): what a recordings directory holds: session, scene, start,
//!   duration, size, and whether a file is finished, still being written or was
//!   cut short; only regular files, never through a symbolic link, read within
//!   stated bounds and cached by name, size and modification time.
//! - [`records`]: walks a file's records, bounding every length a damaged file
//!   states.
//! - [`recover`](mod@recover): rewrites the file a killed server left into a valid,
//!   indexed one.
//! - [`resim`]: runs the recorded poses through the recorded scene again and
//!   compares: zero deviation with the same build, since the engine is
//!   deterministic.

pub mod chunked;
pub mod foxglove_scene;
pub mod intact_summary;
pub mod list;
pub mod lock;
pub mod reader;
pub mod recorder;
pub mod records;
pub mod recover;
pub mod resim;
pub mod source;
pub mod space;
pub mod summary;
pub mod writer;

pub use list::{FileState, Listed, Lister, Listing, list};
pub use reader::{ReadError, Recorded, Recording, RecordingMeta};
pub use recorder::{Item, Recorder, RecorderError, RecorderStats, RecorderWatch, Report};
pub use recover::{Existing, RecoverError, Recovery, recover};
pub use resim::{
    MeshFiles, ResimError, ResimReport, Resimulation, Resimulator, Stepped, resimulate,
    resimulate_as,
};
pub use summary::{InstrumentSummary, RecordingSummary, summarize};
pub use writer::{McapSink, SessionHeader};

/// Version of the layout above, in the `laparo.scene` metadata record; a reader
/// refuses any other.
pub const FORMAT_VERSION: &str = "1";
/// Name of the metadata record describing the session.
pub const METADATA_NAME: &str = "laparo.scene";

pub const TOPIC_SCENE: &str = "/scene";
pub const TOPIC_POSES: &str = "/poses";
pub const TOPIC_SURFACE: &str = "/surface";
pub const TOPIC_INSTRUMENTS: &str = "/instruments";
pub const TOPIC_EVENTS: &str = "/events";
pub const TOPIC_FOXGLOVE_SCENE: &str = "/foxglove/scene";

/// Schema names: the full protobuf names of the messages on each topic.
pub const SCHEMA_SCENE: &str = "laparo.v1.SceneDescription";
pub const SCHEMA_POSE: &str = "laparo.v1.DevicePose";
pub const SCHEMA_SURFACE: &str = "laparo.v1.SurfaceFrame";
pub const SCHEMA_INSTRUMENT: &str = "laparo.v1.InstrumentState";
pub const SCHEMA_EVENT: &str = "laparo.v1.Event";
/// Schema name on `/foxglove/scene`, Foxglove's.
pub const SCHEMA_FOXGLOVE_SCENE: &str = "foxglove.SceneUpdate";

/// ns since the Unix epoch (0 before it).
pub fn unix_ns(t: std::time::SystemTime) -> u64 {
    t.duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos().min(u64::MAX as u128) as u64)
        .unwrap_or(0)
}

/// Log time of something at simulated time `sim_time` s of a session that started
/// at `start_ns`.
pub fn sim_log_time(start_ns: u64, sim_time: f64) -> u64 {
    start_ns.saturating_add((sim_time.max(0.0) * 1e9).round() as u64)
}

#[cfg(test)]
mod tests;
