//! A scripted run read back: every message bit for bit, every schema the
//! contract's, the summary's measures, and a decoding with nothing but the schemas
//! in the file.

use super::*;

#[test]
fn a_scripted_run_reads_back_bit_for_bit() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (frames, poses, header) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();

    let meta = rec.meta();
    assert_eq!(meta.format_version, FORMAT_VERSION);
    assert_eq!(meta.session_id, "s7");
    assert_eq!(meta.scene, header.scene_name);
    assert_eq!(meta.scene_toml, header.scene_toml);
    assert!(!meta.scene_toml.is_empty());
    assert_eq!(meta.start_unix_ns, unix_ns(header.start));
    assert_eq!(rec.scene().unwrap(), header.description);

    let surfaces = rec.surfaces().unwrap();
    assert_eq!(surfaces.len(), frames.len());
    for (s, f) in surfaces.iter().zip(&frames) {
        assert_eq!(s.message.tick, f.tick);
        assert_eq!(s.message.sim_time_s.to_bits(), f.sim_time.to_bits());
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&s.message.positions), bits(&f.surface));
        assert_eq!(s.log_time, sim_log_time(meta.start_unix_ns, f.sim_time));
    }
    let states = rec.instrument_states().unwrap();
    let expected: Vec<_> = frames.iter().flat_map(|f| f.instruments.clone()).collect();
    assert_eq!(
        states.into_iter().map(|s| s.message).collect::<Vec<_>>(),
        expected
    );
    assert_eq!(
        rec.poses()
            .unwrap()
            .into_iter()
            .map(|p| p.message)
            .collect::<Vec<_>>(),
        poses
    );
    // Log times of ticks never go back.
    let times: Vec<u64> = rec.surfaces().unwrap().iter().map(|s| s.log_time).collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]));
    let counts = rec.message_counts();
    assert_eq!(counts[TOPIC_SURFACE], 40);
    assert_eq!(counts[TOPIC_POSES], 40);
    assert_eq!(counts[TOPIC_SCENE], 1);
    // Scene updates for Foxglove at most 20 a second: ticks 1, 4, … at 60 Hz.
    let stride = foxglove_scene::stride(60.0);
    assert_eq!(stride, 3);
    assert_eq!(counts[TOPIC_FOXGLOVE_SCENE], 40u64.div_ceil(stride));
    // The contract's messages alone, decoded; the viewers' channel is left alone.
    let decoded = rec.messages().map(Result::unwrap).count() as u64;
    assert_eq!(
        decoded,
        counts.values().sum::<u64>() - counts[TOPIC_FOXGLOVE_SCENE]
    );
}

#[test]
fn every_schema_is_the_contract_named_by_its_message() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    record_script(&path, 3);
    let rec = Recording::open(&path).unwrap();
    let summary = rec.mcap_summary();
    assert_eq!(summary.channels.len(), 6);
    for channel in summary.channels.values() {
        assert_eq!(channel.message_encoding, "protobuf");
        let schema = channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "protobuf");
        if channel.topic == TOPIC_FOXGLOVE_SCENE {
            // Foxglove's own schema (tests/scene_updates.rs).
            continue;
        }
        assert_eq!(&schema.data[..], laparo_proto::FILE_DESCRIPTOR_SET);
        let set = prost_types::FileDescriptorSet::decode(&*schema.data).unwrap();
        let (package, message) = schema.name.rsplit_once('.').unwrap();
        assert!(
            set.file
                .iter()
                .any(|f| f.package() == package
                    && f.message_type.iter().any(|m| m.name() == message)),
            "{} is not in its schema's descriptors",
            schema.name
        );
    }
    let topics: std::collections::BTreeSet<_> = summary
        .channels
        .values()
        .map(|c| c.topic.as_str())
        .collect();
    assert_eq!(
        topics,
        [
            TOPIC_SCENE,
            TOPIC_POSES,
            TOPIC_SURFACE,
            TOPIC_INSTRUMENTS,
            TOPIC_EVENTS,
            TOPIC_FOXGLOVE_SCENE
        ]
        .into_iter()
        .collect()
    );
}

#[test]
fn the_summary_measures_the_scripted_push() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (frames, _, header) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();
    let s = summarize(&rec).unwrap();
    assert_eq!(s.ticks, 40);
    assert_eq!(s.poses, 40);
    assert_eq!(
        s.duration_s.to_bits(),
        frames.last().unwrap().sim_time.to_bits()
    );
    let left = &s.instruments["left"];
    assert_eq!(left.ticks_with_pose, 40);
    // 39 steps of 1 mm.
    assert!(
        (left.path_length_m - 0.039).abs() < 1e-9,
        "{}",
        left.path_length_m
    );
    let forces: Vec<f64> = frames
        .iter()
        .map(|f| {
            let v = f.instruments[0]
                .force
                .as_ref()
                .and_then(|f| f.force)
                .unwrap_or_default();
            (v.x * v.x + v.y * v.y + v.z * v.z).sqrt()
        })
        .collect();
    let max = forces.iter().cloned().fold(0.0, f64::max);
    assert!(max > 0.0, "the push never touched the liver");
    assert_eq!(left.max_force_n, max);
    assert!((left.mean_force_n - forces.iter().sum::<f64>() / 40.0).abs() < 1e-12);
    let contact = frames
        .iter()
        .filter(|f| f.instruments[0].contact != v1::ContactState::None as i32)
        .count() as u64;
    assert_eq!(left.contact_ticks, contact);
    let rate = header.description.summary.unwrap().mechanics_rate_hz;
    assert!((left.time_in_contact_s - contact as f64 / rate).abs() < 1e-12);
    assert!(left.max_force_jump_n > 0.0 && left.max_force_jump_n <= max + 1e-12);
    // The other instrument never had a pose.
    let right = &s.instruments["right"];
    assert_eq!((right.ticks_with_pose, right.path_length_m), (0, 0.0));
}

#[test]
fn a_recording_decodes_with_nothing_but_the_schemas_in_it() {
    use prost_reflect::{DescriptorPool, DynamicMessage, Value};
    let dir = temp();
    let path = dir.path().join("generic.mcap");
    let (frames, poses, _) = record_script(&path, 12);
    // A generic reader: the mcap crate's message stream, and for each message the
    // descriptors its channel's schema carries; nothing of the contract's types.
    let bytes = std::fs::read(&path).unwrap();
    let mut by_topic: std::collections::BTreeMap<String, Vec<DynamicMessage>> = Default::default();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .expect("every channel has a schema");
        let pool = DescriptorPool::decode(&*schema.data).unwrap();
        let descriptor = pool
            .get_message_by_name(&schema.name)
            .unwrap_or_else(|| panic!("{} is not in its own schema", schema.name));
        let message = DynamicMessage::decode(descriptor, &*m.data).unwrap();
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push(message);
    }
    let field = |m: &DynamicMessage, name: &str| m.get_field_by_name(name).unwrap().into_owned();
    // Every tick's surface, field by field.
    let surfaces = &by_topic[TOPIC_SURFACE];
    assert_eq!(surfaces.len(), frames.len());
    for (m, f) in surfaces.iter().zip(&frames) {
        assert_eq!(field(m, "tick"), Value::U64(f.tick));
        assert_eq!(field(m, "sim_time_s"), Value::F64(f.sim_time));
        let Value::List(positions) = field(m, "positions") else {
            panic!("positions is not a list");
        };
        let positions: Vec<u32> = positions
            .iter()
            .map(|v| v.as_f32().unwrap().to_bits())
            .collect();
        assert_eq!(
            positions,
            f.surface.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
    // Every pose, with its nested tip.
    let recorded = &by_topic[TOPIC_POSES];
    assert_eq!(recorded.len(), poses.len());
    for (m, p) in recorded.iter().zip(&poses) {
        assert_eq!(field(m, "sequence"), Value::U64(p.sequence));
        let Value::Message(pose) = field(m, "pose") else {
            panic!("pose is not a message");
        };
        let Value::Message(tip) = field(&pose, "tip") else {
            panic!("tip is not a message");
        };
        assert_eq!(field(&tip, "z"), Value::F64(p.pose.unwrap().tip.unwrap().z));
    }
    // The instruments' states: the force, as the contract names it.
    let states = &by_topic[TOPIC_INSTRUMENTS];
    let expected: Vec<_> = frames.iter().flat_map(|f| f.instruments.clone()).collect();
    assert_eq!(states.len(), expected.len());
    let mut pushed = false;
    for (m, s) in states.iter().zip(&expected) {
        assert_eq!(field(m, "instrument"), Value::String(s.instrument.clone()));
        assert_eq!(
            field(m, "held_vertex_count"),
            Value::U32(s.held_vertex_count)
        );
        // The force's magnitude is a field of its own, for plotting.
        let Value::Message(force) = field(m, "force") else {
            panic!("force is not a message");
        };
        let f = s.force.unwrap().force.unwrap();
        let norm = (f.x * f.x + f.y * f.y + f.z * f.z).sqrt();
        let Value::F64(magnitude) = field(&force, "magnitude_n") else {
            panic!("magnitude_n is not a double");
        };
        assert!(
            (magnitude - norm).abs() <= 1e-12 * norm.max(1.0),
            "{magnitude} vs {norm}"
        );
        pushed |= magnitude > 0.0;
    }
    assert!(pushed, "the script never pushed");
    // Foxglove's scene updates decode with their own schema: the liver and every
    // instrument with its force arrow.
    let updates = &by_topic[TOPIC_FOXGLOVE_SCENE];
    assert!(!updates.is_empty());
    for u in updates {
        let Value::List(entities) = field(u, "entities") else {
            panic!("entities is not a list");
        };
        assert_eq!(entities.len(), 1 + 2 * frames[0].instruments.len());
    }
    assert_eq!(by_topic[TOPIC_SCENE].len(), 1);
}
