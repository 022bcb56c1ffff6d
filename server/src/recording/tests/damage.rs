//! Files cut short, damaged or not recordings at all: clear errors, never a panic,
//! and every complete chunk recovered.

use super::*;

#[test]
fn a_file_cut_short_recovers_every_complete_chunk() {
    let dir = temp();
    let full = dir.path().join("full.mcap");
    let (boundaries, bytes) = chunked(&full, 24, 4);
    let all = raw_messages(&full);
    assert_eq!(all.len() as u64, boundaries.last().unwrap().1);
    let mut cuts: Vec<(u64, u64, u64)> = Vec::new(); // (offset, at least, at most)
    for w in boundaries.windows(2) {
        let ((a, na), (b, nb)) = (w[0], w[1]);
        cuts.push((a, na, na)); // right after a chunk and its indexes
        cuts.push((a + 1, na, na)); // one byte into the next chunk
        cuts.push(((a + b) / 2, na, nb)); // mid-chunk
        cuts.push((b - 1, na, nb));
    }
    let n = all.len() as u64;
    cuts.push((bytes.len() as u64 - 1, n, n)); // only the end magic missing
    cuts.push((boundaries.last().unwrap().0 + 3, n, n)); // inside the summary
    for (cut, at_least, at_most) in cuts {
        let cut_path = dir.path().join(format!("cut-{cut}.mcap"));
        std::fs::write(&cut_path, &bytes[..cut as usize]).unwrap();
        assert!(matches!(
            Recording::open(&cut_path),
            Err(ReadError::Truncated { .. })
        ));
        let fixed = dir.path().join(format!("fixed-{cut}.mcap"));
        let report = recover(&cut_path, &fixed, Existing::Refuse).unwrap();
        let got = raw_messages(&fixed);
        assert!(
            (at_least..=at_most).contains(&(got.len() as u64)),
            "cut at {cut}: {} messages, expected {at_least}..={at_most}",
            got.len()
        );
        assert_eq!(report.messages, got.len() as u64);
        assert_eq!(got[..], all[..got.len()], "cut at {cut}");
        assert!(report.bytes_kept <= cut);
        // The recovered file is complete: indexed and readable as any recording.
        let rec = Recording::open(&fixed).unwrap();
        assert!(!rec.mcap_summary().chunk_indexes.is_empty());
        assert_eq!(rec.meta().session_id, "s7");
        assert_eq!(rec.message_counts().values().sum::<u64>(), got.len() as u64);
        assert!(summarize(&rec).is_ok());
    }
    // A complete file recovers to the same messages, in place.
    let copy = dir.path().join("copy.mcap");
    std::fs::copy(&full, &copy).unwrap();
    let report = recover(&copy, &copy, Existing::Refuse).unwrap();
    assert!(report.was_complete);
    assert_eq!(raw_messages(&copy), all);
}

#[test]
fn a_recording_of_another_version_is_refused_by_name() {
    let dir = temp();
    let path = dir.path().join("v2.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("protobuf")
        .create(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
    w.write_metadata(&mcap::records::Metadata {
        name: METADATA_NAME.into(),
        metadata: [("format_version".to_string(), "2".to_string())].into(),
    })
    .unwrap();
    w.finish().unwrap();
    drop(w);
    let err = Recording::open(&path).unwrap_err();
    assert!(
        matches!(&err, ReadError::UnsupportedVersion { found, .. } if found == "2"),
        "{err}"
    );
    assert!(err.to_string().contains("version `2`"), "{err}");
}

#[test]
fn files_that_are_not_recordings_give_clear_errors() {
    let dir = temp();
    let write = |name: &str, bytes: &[u8]| -> PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let text = write("notes.mcap", b"this is not a recording at all");
    assert!(matches!(
        Recording::open(&text),
        Err(ReadError::NotMcap { .. })
    ));
    assert!(matches!(
        recover(&text, &dir.path().join("x.mcap"), Existing::Refuse),
        Err(RecoverError::NotMcap { .. })
    ));
    let empty = write("empty.mcap", b"");
    assert!(matches!(
        Recording::open(&empty),
        Err(ReadError::NotMcap { .. })
    ));
    let mut framed = mcap::MAGIC.to_vec();
    framed.extend_from_slice(&[0xAB; 100]);
    framed.extend_from_slice(mcap::MAGIC);
    let garbage = write("garbage.mcap", &framed);
    let err = Recording::open(&garbage).unwrap_err();
    assert!(matches!(err, ReadError::Corrupt { .. }), "{err}");
    assert!(matches!(
        Recording::open(&dir.path().join("missing.mcap")),
        Err(ReadError::Io { .. })
    ));

    // An MCAP file without our metadata.
    let plain = dir.path().join("plain.mcap");
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(&plain).unwrap(),
    ))
    .unwrap();
    w.finish().unwrap();
    drop(w);
    assert!(matches!(
        Recording::open(&plain),
        Err(ReadError::NotARecording { .. })
    ));

    // Damage anywhere in a real recording: an error or a partial read, never a panic.
    let good = dir.path().join("good.mcap");
    record_script(&good, 10);
    let bytes = std::fs::read(&good).unwrap();
    for at in (8..bytes.len()).step_by(bytes.len() / 400 + 1) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x5A;
        if let Ok(rec) = Recording::from_bytes(format!("bad-{at}"), bad.clone()) {
            let _ = rec.messages().count();
            let _ = summarize(&rec);
        }
        let _ =
            crate::recording::recover::recover_bytes("bad", &bad, std::io::Cursor::new(Vec::new()));
    }
}

#[test]
fn the_duration_is_the_last_frames_time_from_the_index_or_every_frame() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (boundaries, bytes) = chunked(&path, 24, 5);
    let rec = Recording::open(&path).unwrap();
    assert!(rec.is_complete());
    let surfaces = rec.surfaces().unwrap();
    let last = surfaces.last().unwrap().message.sim_time_s;
    assert_eq!(rec.duration_s().unwrap().to_bits(), last.to_bits());
    assert_eq!(
        rec.duration_s().unwrap().to_bits(),
        summarize(&rec).unwrap().duration_s.to_bits()
    );
    // Cut after each closed chunk: read as far as it goes, the duration is that of
    // the last tick of the complete chunks, and nothing else is lost.
    for (k, &(cut, messages)) in boundaries.iter().enumerate().skip(1) {
        let cut_bytes = bytes[..cut as usize + 1].to_vec();
        assert!(matches!(
            Recording::from_bytes("cut".into(), cut_bytes.clone()),
            Err(ReadError::Truncated { .. })
        ));
        let partial = Recording::from_unfinished_bytes("cut".into(), cut_bytes).unwrap();
        assert!(!partial.is_complete());
        assert_eq!(partial.meta(), rec.meta());
        assert_eq!(partial.scene().unwrap(), rec.scene().unwrap());
        let ticks = (5 * k).min(24);
        assert_eq!(
            partial.duration_s().unwrap().to_bits(),
            surfaces[ticks - 1].message.sim_time_s.to_bits(),
            "cut after chunk {k}"
        );
        // messages() leaves out the Foxglove channel: a scene update every third
        // tick at 60 Hz.
        let drawn = (ticks as u64).div_ceil(foxglove_scene::stride(60.0));
        assert_eq!(partial.messages().count() as u64 + drawn, messages);
        assert_eq!(partial.surfaces().unwrap()[..], surfaces[..ticks]);
    }
    // Complete bytes read unfinished are just the recording.
    let whole = Recording::from_unfinished_bytes("whole".into(), bytes).unwrap();
    assert!(whole.is_complete());
    assert_eq!(whole.surfaces().unwrap(), surfaces);
}

#[test]
fn a_recovery_over_an_open_recording_leaves_it_reading_what_was_written() {
    let dir = temp();
    let path = dir.path().join("open.mcap");
    // 24 ticks in chunks of 5.
    let (boundaries, bytes) = chunked(&path, 24, 5);
    let rec = Recording::open(&path).unwrap();
    assert!(rec.is_complete());
    let before = rec.surfaces().unwrap();
    assert_eq!(before.len(), 24);
    // Cut after the second chunk: an unfinished file.
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..boundaries[2].0 as usize]).unwrap();
    let partial = Recording::open_unfinished(&cut).unwrap();
    assert!(!partial.is_complete());
    // Recovering the cut copy over the open file renames a new file over it: the
    // open recording reads through its own handle, and still reads every tick as
    // written.
    // Not without being asked: another recording there is not replaced.
    let err = recover(&cut, &path, Existing::Refuse).unwrap_err();
    assert!(matches!(err, RecoverError::OutputExists { .. }), "{err}");
    assert!(err.to_string().contains("--replace"), "{err}");
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
    recover(&cut, &path, Existing::Replace).unwrap();
    assert_eq!(rec.surfaces().unwrap(), before);
    // And the path now holds the shorter recovered recording.
    let now = Recording::open(&path).unwrap();
    assert!(now.is_complete());
    assert_eq!(now.surfaces().unwrap()[..], before[..10]);
}

#[test]
fn a_damaged_chunk_is_left_out_and_every_chunk_after_it_kept() {
    let dir = temp();
    let full = dir.path().join("full.mcap");
    let (boundaries, bytes) = chunked(&full, 24, 4);
    let all = raw_messages(&full);
    // Damage the compressed data of the second chunk: its record still frames,
    // its contents do not decompress.
    let ((b1, n1), (b2, n2)) = (boundaries[1], boundaries[2]);
    let chunks = Recording::open(&full)
        .unwrap()
        .mcap_summary()
        .chunk_indexes
        .clone();
    let chunk = chunks
        .iter()
        .find(|c| (b1..b2).contains(&c.chunk_start_offset))
        .expect("a chunk between the first two flushes")
        .clone();
    let mut damaged = bytes.clone();
    damaged[(chunk.chunk_start_offset + chunk.chunk_length - 16) as usize] ^= 0x5A;
    let path = dir.path().join("damaged.mcap");
    std::fs::write(&path, &damaged).unwrap();

    let out = dir.path().join("fixed.mcap");
    let report = recover(&path, &out, Existing::Refuse).unwrap();
    assert!(report.was_complete);
    assert_eq!(report.damaged_chunks.len(), 1, "{report:?}");
    let at = format!("bytes {}..", chunk.chunk_start_offset);
    assert!(report.damaged_chunks[0].contains(&at), "{report:?}");
    assert!(report.stopped_at.is_none(), "{report:?}");
    assert_eq!(report.chunks as usize, chunks.len() - 1);
    // Every message but the damaged chunk's, in order.
    let (n1, n2) = (n1 as usize, n2 as usize);
    let expected: Vec<_> = all[..n1].iter().chain(&all[n2..]).cloned().collect();
    assert_eq!(report.orphaned_messages, 0);
    assert_eq!(raw_messages(&out), expected);
    assert_eq!(report.messages as usize, expected.len());
    assert!(Recording::open(&out).unwrap().is_complete());

    // In place, the damaged chunk would be lost for good: refused, file untouched.
    let err = recover(&path, &path, Existing::Refuse).unwrap_err();
    assert!(matches!(err, RecoverError::WouldLose { .. }), "{err}");
    let text = err.to_string();
    assert!(
        text.contains("damaged chunk") && text.contains("--out"),
        "{text}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), damaged);
    // A file cut short (what a killed server leaves) still recovers in place.
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..(b2 + 5) as usize]).unwrap();
    let report = recover(&cut, &cut, Existing::Refuse).unwrap();
    assert!(!report.lost_more_than_a_tail(), "{report:?}");
    assert_eq!(raw_messages(&cut), all[..n2]);
}

#[test]
fn a_recovery_writes_only_a_regular_file_and_leaves_others_alone() {
    let dir = temp();
    let good = dir.path().join("good.mcap");
    record_script(&good, 10);
    let outputs = dir.path().join("outputs");
    std::fs::create_dir(&outputs).unwrap();
    let link = dir.path().join("link.mcap");
    let target = dir.path().join("target.txt");
    std::fs::write(&target, b"keep me").unwrap();
    std::os::unix::fs::symlink(&target, &link).unwrap();
    for (out, kind) in [(&outputs, "directory"), (&link, "symbolic link")] {
        let err = recover(&good, out, Existing::Refuse).unwrap_err();
        assert!(
            matches!(&err, RecoverError::OutputNotRegular { kind: k, .. } if *k == kind),
            "{err}"
        );
        assert!(err.to_string().contains("not a regular file"), "{err}");
    }
    assert!(std::fs::symlink_metadata(&link).unwrap().is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), b"keep me");
    // A file of the user's beside the output, named as a scratch file might be,
    // is not touched.
    let out = dir.path().join("fixed.mcap");
    let theirs = dir.path().join("fixed.mcap.part");
    std::fs::write(&theirs, b"mine").unwrap();
    recover(&good, &out, Existing::Refuse).unwrap();
    assert_eq!(std::fs::read(&theirs).unwrap(), b"mine");
    assert_eq!(raw_messages(&out), raw_messages(&good));
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".part"))
        .collect();
    assert_eq!(names, ["fixed.mcap.part"]);
}

#[test]
fn a_damaged_metadata_record_is_named_by_its_offset_in_the_file() {
    let dir = temp();
    let good = dir.path().join("good.mcap");
    record_script(&good, 5);
    let index = Recording::open(&good)
        .unwrap()
        .mcap_summary()
        .metadata_indexes
        .iter()
        .find(|m| m.name == METADATA_NAME)
        .unwrap()
        .clone();
    let mut bytes = std::fs::read(&good).unwrap();
    let at = index.offset as usize;
    // The record's length, one byte longer than the index says it is.
    let length = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap());
    bytes[at + 1..at + 9].copy_from_slice(&(length + 1).to_le_bytes());
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let err = Recording::open(&bad).unwrap_err().to_string();
    assert!(err.contains(&format!("byte {at}")), "{err}");
    assert!(!err.contains("byte 0"), "{err}");
}

#[test]
fn a_file_cut_before_its_description_says_so_and_one_cut_after_reads() {
    let dir = temp();
    let full = dir.path().join("full.mcap");
    let (boundaries, bytes) = chunked(&full, 8, 4);
    let metadata = Recording::open(&full)
        .unwrap()
        .mcap_summary()
        .metadata_indexes
        .iter()
        .find(|m| m.name == "laparo.scene")
        .expect("the recording's description")
        .clone();
    // The scene's chunk comes first, then the description, then the first flush.
    let (start, end) = (metadata.offset, metadata.offset + metadata.length);
    assert!(16 < start && end <= boundaries[0].0, "{start}..{end}");
    for cut in [8, 9, 16, start / 2, start - 1, start, start + 1, end - 1] {
        let err =
            Recording::from_unfinished_bytes(format!("cut-{cut}"), bytes[..cut as usize].to_vec())
                .map(|_| ())
                .unwrap_err();
        assert!(
            matches!(err, ReadError::CutBeforeDescription { .. }),
            "cut at {cut}: {err}"
        );
        assert!(err.to_string().contains("cut short"), "{err}");
        // Recovering it has nothing to keep.
        let path = dir.path().join(format!("cut-{cut}.mcap"));
        std::fs::write(&path, &bytes[..cut as usize]).unwrap();
        assert!(matches!(
            recover(&path, &dir.path().join("x.mcap"), Existing::Refuse),
            Err(RecoverError::NothingToRecover { .. })
        ));
    }
    for cut in [end, boundaries[0].0] {
        let rec =
            Recording::from_unfinished_bytes(format!("cut-{cut}"), bytes[..cut as usize].to_vec())
                .unwrap();
        assert_eq!(rec.meta().session_id, "s7");
    }
}

#[test]
fn a_damaged_schema_is_reported_and_written_sound() {
    let dir = temp();
    let good = dir.path().join("good.mcap");
    record_script(&good, 6);
    // Schema records are written outside chunks, with no CRC: damage the data of
    // the first (laparo's descriptor set) so that it no longer decodes.
    let mut bytes = std::fs::read(&good).unwrap();
    let own = laparo_proto::FILE_DESCRIPTOR_SET;
    let at = bytes
        .windows(64)
        .position(|w| w == &own[..64])
        .expect("the descriptor set is in the file");
    bytes[at..at + 16].fill(0xFF);
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let out = dir.path().join("fixed.mcap");
    let report = recover(&bad, &out, Existing::Refuse).unwrap();
    assert_eq!(report.damaged_schemas.len(), 1, "{report:?}");
    assert!(
        report.damaged_schemas[0].contains("written from this build's"),
        "{report:?}"
    );
    // Nothing is lost, so the same recovery may be done in place.
    assert!(!report.lost_more_than_a_tail());
    assert_eq!(raw_messages(&out), raw_messages(&good));
    // Every schema of the recovered file defines the message it names.
    let summary = Recording::open(&out).unwrap().mcap_summary().clone();
    for schema in summary.schemas.values() {
        let pool = prost_reflect::DescriptorPool::decode(&schema.data[..]).unwrap();
        assert!(
            pool.get_message_by_name(&schema.name).is_some(),
            "{}",
            schema.name
        );
    }
    // A sound file reports none.
    let again = recover(&good, &dir.path().join("again.mcap"), Existing::Refuse).unwrap();
    assert!(again.damaged_schemas.is_empty(), "{again:?}");
}
