//! The MCAP side of a recording: the file's schemas and channels, one message per
//! pose, surface frame, instrument state and event, a Foxglove scene update per
//! tick, and chunks closed often enough that a killed server loses at most the last
//! second.
//!
//! Synchronous and single-threaded: [`super::recorder`] runs it on its own thread.

use std::fs::File;
use std::io::{Read, Seek, Write};
use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

use foxglove::Encode;
use foxglove::schemas::SceneUpdate;
use laparo_proto::v1;
use mcap::{McapError, McapResult};
use prost::Message;

use super::chunked::ChunkedWriter;
use super::foxglove_scene::{self, SceneUpdates};
use super::{
    FORMAT_VERSION, METADATA_NAME, SCHEMA_EVENT, SCHEMA_INSTRUMENT, SCHEMA_POSE, SCHEMA_SCENE,
    SCHEMA_SURFACE, TOPIC_EVENTS, TOPIC_FOXGLOVE_SCENE, TOPIC_INSTRUMENTS, TOPIC_POSES,
    TOPIC_SCENE, TOPIC_SURFACE, sim_log_time, unix_ns,
};
use crate::frame::Frame;

/// Longest a written message stays in an open chunk: past this the chunk is closed
/// and flushed to the file. Half the one second a crash may lose, so that a busy
/// recorder thread that checks late still keeps within it.
pub const FLUSH_INTERVAL: Duration = Duration::from_millis(500);

/// What a recording says about its session, written once at its start.
#[derive(Clone, Debug)]
pub struct SessionHeader {
    pub session_id: String,
    /// The scene's name (`SceneSummary.name`).
    pub scene_name: String,
    /// The scene's TOML text as the server read it.
    pub scene_toml: String,
    /// The folder its relative paths (the mesh) resolve against; `None` for the
    /// embedded default scene.
    pub scene_dir: Option<std::path::PathBuf>,
    /// When the session started; tick log times count from it.
    pub start: SystemTime,
    pub description: v1::SceneDescription,
}

/// Channel ids of the six topics.
#[derive(Clone, Copy, Debug)]
struct Channels {
    scene: u16,
    poses: u16,
    surface: u16,
    instruments: u16,
    events: u16,
    foxglove_scene: u16,
}

/// An MCAP file being written.
pub struct McapSink<W: Read + Write + Seek> {
    writer: ChunkedWriter<W>,
    channels: Channels,
    start_ns: u64,
    sequence: u32,
    buf: Vec<u8>,
    /// Builds the `/foxglove/scene` updates.
    scene_updates: SceneUpdates,
    /// One tick in how many gets a scene update ([`foxglove_scene::stride`]).
    foxglove_stride: u64,
    /// When the oldest message of the open chunk was written; `None`: no open chunk.
    open_since: Option<Instant>,
    /// Messages written so far.
    pub messages: u64,
}

impl McapSink<File> {
    /// Creates `path` (failing if it exists) and writes the session's header; a
    /// file whose header cannot be written (a full disk) is removed (see
    /// [`created`]).
    pub fn create(path: &Path, header: &SessionHeader) -> McapResult<Self> {
        created(path, |file| McapSink::new(file, header))
    }
}

/// Creates `path` (failing if it exists; readable, for the summary the writer reads
/// back at its finish) and hands it to `start`, which writes
/// what makes it a recording; when `start` fails the file is removed, so that a
/// failed start leaves no empty or headless `.mcap` for listings to trip over.
pub fn created<T>(path: &Path, start: impl FnOnce(File) -> McapResult<T>) -> McapResult<T> {
    let file = File::options()
        .read(true)
        .write(true)
        .create_new(true)
        .open(path)?;
    super::lock::hold(&file, path);
    start(file).inspect_err(|_| {
        let _ = std::fs::remove_file(path);
    })
}

impl<W: Read + Write + Seek> McapSink<W> {
    /// Starts a recording on `w`: the schemas and channels, the scene on `/scene`
    /// and the `laparo.scene` metadata, then closes the first chunk so that a file
    /// cut short anywhere later still says what it records.
    pub fn new(w: W, header: &SessionHeader) -> McapResult<Self> {
        // Chunks are built whole in memory and written with one call each, so the
        // file needs no buffering of its own.
        let mut writer = ChunkedWriter::new(w, "protobuf")?;
        let channel = |writer: &mut ChunkedWriter<W>, topic: &str, name: &str| {
            let schema = writer.add_schema(name, "protobuf", laparo_proto::FILE_DESCRIPTOR_SET)?;
            writer.add_channel(schema, topic, "protobuf")
        };
        let channels = Channels {
            scene: channel(&mut writer, TOPIC_SCENE, SCHEMA_SCENE)?,
            poses: channel(&mut writer, TOPIC_POSES, SCHEMA_POSE)?,
            surface: channel(&mut writer, TOPIC_SURFACE, SCHEMA_SURFACE)?,
            instruments: channel(&mut writer, TOPIC_INSTRUMENTS, SCHEMA_INSTRUMENT)?,
            events: channel(&mut writer, TOPIC_EVENTS, SCHEMA_EVENT)?,
            foxglove_scene: {
                let schema = SceneUpdate::get_schema().ok_or_else(|| {
                    McapError::Io(std::io::Error::other(
                        "foxglove states no SceneUpdate schema",
                    ))
                })?;
                let schema = writer.add_schema(&schema.name, &schema.encoding, &schema.data)?;
                writer.add_channel(
                    schema,
                    TOPIC_FOXGLOVE_SCENE,
                    &SceneUpdate::get_message_encoding(),
                )?
            },
        };
        let start_ns = unix_ns(header.start);
        let mut sink = McapSink {
            writer,
            channels,
            start_ns,
            sequence: 0,
            buf: Vec::new(),
            scene_updates: SceneUpdates::new(&header.description),
            foxglove_stride: foxglove_scene::stride(
                header
                    .description
                    .summary
                    .as_ref()
                    .map_or(0.0, |s| s.mechanics_rate_hz),
            ),
            open_since: None,
            messages: 0,
        };
        sink.write(channels.scene, start_ns, start_ns, &header.description)?;
        let start = start_ns.to_string();
        let dir = header.scene_dir.as_ref().map(|d| d.display().to_string());
        let mut pairs = vec![
            ("format_version", FORMAT_VERSION),
            ("session_id", header.session_id.as_str()),
            ("scene", header.scene_name.as_str()),
            ("start_unix_ns", start.as_str()),
            ("scene_toml", header.scene_toml.as_str()),
        ];
        if let Some(dir) = &dir {
            pairs.push(("scene_dir", dir.as_str()));
        }
        // The format orders a metadata map by key, as a BTreeMap writes it.
        pairs.sort_by_key(|&(k, _)| k);
        sink.writer.write_metadata(METADATA_NAME, pairs)?;
        sink.flush()?;
        Ok(sink)
    }

    /// Log time of simulated time `sim_time`, ns since the Unix epoch.
    pub fn log_time(&self, sim_time: f64) -> u64 {
        sim_log_time(self.start_ns, sim_time)
    }

    fn write(
        &mut self,
        channel: u16,
        log_time: u64,
        publish_time: u64,
        m: &impl Message,
    ) -> McapResult<()> {
        self.write_with(channel, log_time, publish_time, |buf| m.encode(buf))
    }

    /// Writes the message that `encode` puts in the (cleared) buffer.
    fn write_with<E: std::error::Error + Send + Sync + 'static>(
        &mut self,
        channel: u16,
        log_time: u64,
        publish_time: u64,
        encode: impl FnOnce(&mut Vec<u8>) -> Result<(), E>,
    ) -> McapResult<()> {
        self.buf.clear();
        encode(&mut self.buf).map_err(|e| McapError::Io(std::io::Error::other(e)))?;
        self.writer
            .write_message(channel, self.sequence, log_time, publish_time, &self.buf)?;
        self.sequence = self.sequence.wrapping_add(1);
        self.messages += 1;
        self.open_since.get_or_insert_with(Instant::now);
        Ok(())
    }

    /// A pose as the server accepted it, stamped with when it was received.
    pub fn write_pose(&mut self, received: SystemTime, pose: &v1::DevicePose) -> McapResult<()> {
        let t = unix_ns(received);
        self.write(self.channels.poses, t, t, pose)
    }

    /// One tick: the surface, every instrument's state, then the tick's Foxglove
    /// scene update if the tick is drawn ([`foxglove_scene::drawn`]). `wall` is when the tick was published.
    pub fn write_frame(&mut self, frame: &Frame, wall: SystemTime) -> McapResult<()> {
        let (log, publish) = (self.log_time(frame.sim_time), unix_ns(wall));
        let surface = v1::SurfaceFrame {
            tick: frame.tick,
            sim_time_s: frame.sim_time,
            positions: frame.surface.clone(),
        };
        self.write(self.channels.surface, log, publish, &surface)?;
        for state in &frame.instruments {
            self.write(self.channels.instruments, log, publish, state)?;
        }
        if !foxglove_scene::drawn(frame.tick, self.foxglove_stride) {
            return Ok(());
        }
        let update = self.scene_updates.update(frame, log);
        self.write_with(self.channels.foxglove_scene, log, publish, |buf| {
            Encode::encode(&update, buf)
        })
    }

    /// An event; `wall` is when it happened.
    pub fn write_event(&mut self, event: &v1::Event, wall: SystemTime) -> McapResult<()> {
        let log = self.log_time(event.sim_time_s);
        self.write(self.channels.events, log, unix_ns(wall), event)
    }

    /// Closes the open chunk if it has been open for [`FLUSH_INTERVAL`].
    pub fn flush_if_due(&mut self) -> McapResult<()> {
        match self.open_since {
            Some(t) if t.elapsed() >= FLUSH_INTERVAL => self.flush(),
            _ => Ok(()),
        }
    }

    /// Closes the open chunk and flushes it to the file.
    pub fn flush(&mut self) -> McapResult<()> {
        self.open_since = None;
        Ok(self.writer.flush()?)
    }

    /// Writes the summary and footer and hands back the stream.
    pub fn finish(self) -> McapResult<W> {
        Ok(self.writer.finish()?)
    }
}
