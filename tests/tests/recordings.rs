//! Recordings through a real server: a session recorded, listed and replayed as
//! recorded.

use laparo_proto::v1;
use laparo_tests::recordings::*;
use laparo_tests::server::*;
use tonic::Code;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_is_recorded_through_a_real_server() {
    use laparo_server::recording::Recording;
    let (server, ch, dir) = recording_server("rec").await;
    let Recorded {
        file,
        closed,
        joined,
    } = record_press(&ch, &dir, 0.0).await;
    // Closing waited for the mechanics thread, which finished the file.
    let recording = Recording::open(&file).unwrap();
    server.shutdown().await.unwrap();
    let surfaces = recording.surfaces().unwrap();
    let poses = recording.poses().unwrap();
    assert!(
        surfaces.len() as u64 >= closed.tick.saturating_sub(2),
        "{} vs {}",
        surfaces.len(),
        closed.tick
    );
    assert_eq!(poses.len() as u64, closed.poses_accepted);
    assert!(poses.iter().all(|p| p.message.instrument == "left"));
    // The deformed surface is in it: some vertex moved more than 6 mm from rest.
    let rest = joined.scene.unwrap().rest_surface.unwrap().positions;
    assert!(surfaces.iter().any(|s| {
        s.message
            .positions
            .iter()
            .zip(&rest)
            .any(|(p, r)| (p - r).abs() > 0.006)
    }));
    // The recorded poses through the recorded scene again: the same surfaces and
    // forces at every tick, to the bit.
    let resim = laparo_server::recording::resimulate(&recording, None, |_| {}).unwrap();
    assert_eq!(resim.ticks_compared, surfaces.len() as u64);
    assert!(resim.is_exact(), "{resim:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_is_listed_and_replayed_as_recorded() {
    use laparo_server::recording::Recording;
    let (server, ch, dir) = recording_server("replay").await;
    let rec = record_press(&ch, &dir, 2.0).await;
    let name = rec.file.file_name().unwrap().to_str().unwrap().to_string();
    let recording = Recording::open(&rec.file).unwrap();
    let file = recorded_messages(&recording);
    let surfaces = recording.surfaces().unwrap();
    let last = surfaces.last().unwrap().message.clone();
    let scene = recording.scene().unwrap();
    let rate = scene.summary.as_ref().unwrap().mechanics_rate_hz;

    // The list: the session, its scene, start, duration and the file's size.
    let mut recordings = v1::recordings_client::RecordingsClient::new(ch.clone());
    let listed = recordings
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner()
        .recordings;
    assert_eq!(listed.len(), 1, "{listed:?}");
    let info = &listed[0];
    assert_eq!(info.file, name);
    assert_eq!(info.session_id, rec.closed.session_id);
    assert_eq!(info.scene, rec.closed.scene);
    assert_eq!(info.start, rec.closed.created_at);
    assert!(!info.in_progress);
    assert_eq!(info.size_bytes, std::fs::metadata(&rec.file).unwrap().len());
    assert_eq!(info.duration_s.to_bits(), last.sim_time_s.to_bits());
    assert!(
        (info.duration_s - last.tick as f64 / rate).abs() < 1e-9,
        "{} s for {} ticks at {rate} Hz",
        info.duration_s,
        last.tick
    );
    assert!(last.tick <= rec.closed.tick && info.duration_s >= 2.0);

    // At 20×: the scene, then every frame, state and event of the file in its
    // order, frames bit for bit, each no earlier than its time allows.
    let (got, end) = replay_all(&ch, None, replay_request(&name, Some(20.0), None))
        .await
        .unwrap();
    end.unwrap();
    assert_eq!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(scene.clone()))
    );
    let sent: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    let all: Vec<v1::ObserveMessage> = file.iter().map(|(_, m)| m.clone()).collect();
    assert_eq!(sent.len(), all.len());
    assert!(sent == all, "the replay differs from the file");
    let frame_bits = |ms: &[v1::ObserveMessage]| ms.iter().filter_map(bits).collect::<Vec<_>>();
    assert_eq!(frame_bits(&sent), frame_bits(&all));
    assert_eq!(frame_bits(&sent).len(), surfaces.len());
    let ticks: Vec<u64> = sent
        .iter()
        .filter_map(|m| match &m.kind {
            Some(v1::observe_message::Kind::SurfaceFrame(f)) => Some(f.tick),
            _ => None,
        })
        .collect();
    assert!(ticks.windows(2).all(|w| w[0] < w[1]), "ticks out of order");
    assert!(
        sent.iter()
            .any(|m| matches!(m.kind, Some(v1::observe_message::Kind::Event(_))))
    );
    assert_paced(&got, 0.0, 20.0);

    // Re-simulated at 50×: the recorded poses through the scene again give the
    // same frames and instrument states, to the bit and in the same order, and the
    // same events (their order among the session's other events may differ).
    let (got, end) = replay_all(
        &ch,
        None,
        v1::ReplayRequest {
            mode: v1::ReplayMode::Resimulate as i32,
            ..replay_request(&name, Some(50.0), None)
        },
    )
    .await
    .unwrap();
    end.unwrap();
    assert_eq!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(scene.clone()))
    );
    let again: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    let split = |ms: &[v1::ObserveMessage]| {
        let (mut ticks, mut events) = (Vec::new(), Vec::new());
        for m in ms {
            match &m.kind {
                Some(v1::observe_message::Kind::Event(e)) => {
                    events.push((e.tick, e.kind, e.instrument.clone(), e.detail.clone()))
                }
                _ => ticks.push(m.clone()),
            }
        }
        events.sort();
        (ticks, events)
    };
    let (again_ticks, again_events) = split(&again);
    let (recorded_ticks, recorded_events) = split(&all);
    assert_eq!(again_ticks.len(), recorded_ticks.len());
    assert!(again_ticks == recorded_ticks, "the re-simulation differs");
    assert_eq!(again_events, recorded_events);
    assert!(
        again_events
            .iter()
            .any(|e| e.1 == v1::EventKind::ContactBegan as i32),
        "the press made contact, and the re-simulation found it again"
    );
    assert_paced(&got, 0.0, 50.0);

    // From an offset, at 2×: the state at the offset first, then nothing earlier,
    // paced by the time after the offset.
    let offset = 1.0;
    let (got, end) = replay_all(&ch, None, replay_request(&name, Some(2.0), Some(offset)))
        .await
        .unwrap();
    end.unwrap();
    assert!(matches!(
        got[0].1.kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    let sent: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    assert!(sent == expected_from(&file, offset));
    let frame_times: Vec<f64> = sent
        .iter()
        .filter(|m| bits(m).is_some())
        .map(|m| sim_time(m).unwrap())
        .collect();
    let newest_before = surfaces
        .iter()
        .map(|s| s.message.sim_time_s)
        .filter(|t| *t <= offset)
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(frame_times[0].to_bits(), newest_before.to_bits());
    assert!(frame_times[1..].iter().all(|t| *t > offset));
    assert_paced(&got, offset, 2.0);
    let span = (last.sim_time_s - offset) / 2.0;
    let wall = got.last().unwrap().0.as_secs_f64();
    assert!(
        wall >= span - 1e-3 && wall < span + 15.0,
        "{wall} s for {span} s of replay"
    );
    // From the very end: the last tick alone.
    let (got, end) = replay_all(
        &ch,
        None,
        replay_request(&name, Some(50.0), Some(info.duration_s)),
    )
    .await
    .unwrap();
    end.unwrap();
    let sent: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    assert!(sent == expected_from(&file, info.duration_s));
    assert_eq!(sent.iter().filter_map(bits).count(), 1);
    // From the duration as a summary prints it, to the millisecond: rounded, it
    // may lie up to half a millisecond past the last tick, and must give the same.
    let printed = info.duration_s + 0.4e-3;
    let (got, end) = replay_all(&ch, None, replay_request(&name, Some(50.0), Some(printed)))
        .await
        .unwrap();
    end.unwrap();
    let from_printed: Vec<v1::ObserveMessage> = got[1..].iter().map(|(_, m)| m.clone()).collect();
    assert_eq!(
        from_printed.iter().filter_map(bits).collect::<Vec<_>>(),
        sent.iter().filter_map(bits).collect::<Vec<_>>(),
        "a replay from {printed} s, the printed end, shows the last tick"
    );
    // Past that, the refusal gives the duration as printed.
    let past = recordings
        .replay(replay_request(&name, None, Some(info.duration_s + 1e-3)))
        .await
        .expect_err("a start past the end is refused");
    assert_eq!(past.code(), Code::OutOfRange);
    let lasts = format!("which lasts {:.3} s", info.duration_s);
    assert!(past.message().ends_with(&lasts), "{}", past.message());

    // Every bad request gets its code.
    let code = |r: Result<_, tonic::Status>| r.err().map(|s: tonic::Status| s.code());
    let bad =
        |file: &str, speed: Option<f64>, offset: Option<f64>| replay_request(file, speed, offset);
    let cases = [
        (bad("../escape.mcap", None, None), Code::InvalidArgument),
        (
            bad(&format!("../{name}"), None, None),
            Code::InvalidArgument,
        ),
        (
            bad(&format!("{}/{name}", dir.display()), None, None),
            Code::InvalidArgument,
        ),
        (bad("sub/x.mcap", None, None), Code::InvalidArgument),
        (bad("..", None, None), Code::InvalidArgument),
        (bad("", None, None), Code::InvalidArgument),
        (bad("a\\b.mcap", None, None), Code::InvalidArgument),
        (bad("notes.txt", None, None), Code::InvalidArgument),
        (bad("nope.mcap", None, None), Code::NotFound),
        (bad(&name, Some(0.0), None), Code::InvalidArgument),
        (bad(&name, Some(-2.0), None), Code::InvalidArgument),
        (bad(&name, Some(f64::NAN), None), Code::InvalidArgument),
        (bad(&name, Some(f64::INFINITY), None), Code::InvalidArgument),
        (bad(&name, Some(1000.0), None), Code::InvalidArgument),
        (bad(&name, None, Some(-0.5)), Code::InvalidArgument),
        (bad(&name, None, Some(f64::NAN)), Code::InvalidArgument),
        (
            bad(&name, None, Some(info.duration_s + 0.5)),
            Code::OutOfRange,
        ),
        (
            v1::ReplayRequest {
                mode: 99,
                ..bad(&name, None, None)
            },
            Code::InvalidArgument,
        ),
    ];
    for (request, expected) in cases {
        let what = format!("{request:?}");
        let got = recordings.replay(request).await;
        assert_eq!(code(got), Some(expected), "{what}");
    }

    // Files that are not recordings, or cannot be replayed, in the directory.
    let bytes = std::fs::read(&rec.file).unwrap();
    std::fs::write(dir.join("notes.mcap"), b"not a recording").unwrap();
    std::fs::write(dir.join("cut.mcap"), &bytes[..bytes.len() * 3 / 4]).unwrap();
    let chunks = &recording.mcap_summary().chunk_indexes;
    assert!(chunks.len() >= 2, "{} chunks", chunks.len());
    let chunk = &chunks[1];
    let mut damaged = bytes.clone();
    let middle = (chunk.chunk_start_offset + chunk.chunk_length / 2) as usize;
    for b in &mut damaged[middle..middle + 16] {
        *b ^= 0xA5;
    }
    std::fs::write(dir.join("damaged.mcap"), &damaged).unwrap();
    let listed = recordings
        .list_recordings(v1::ListRecordingsRequest {})
        .await
        .unwrap()
        .into_inner()
        .recordings;
    assert!(listed.contains(info));
    assert!(listed.iter().all(|r| r.file != "notes.mcap"), "{listed:?}");
    // Cut short by a stopped server: listed as unfinished, replayed once recovered.
    let cut = listed.iter().find(|r| r.file == "cut.mcap").unwrap();
    assert_eq!(cut.state, v1::RecordingState::Unfinished as i32);
    assert!(!cut.in_progress);
    for file in ["notes.mcap", "cut.mcap"] {
        let status = recordings.replay(bad(file, None, None)).await.unwrap_err();
        assert_eq!(status.code(), Code::FailedPrecondition, "{file}");
        // Named by its name: the server's directory is none of the client's business.
        let message = status.message();
        assert!(
            message.contains(file) && !message.contains(&*dir.to_string_lossy()),
            "{message}"
        );
    }
    let damaged = match replay_all(&ch, None, bad("damaged.mcap", Some(100.0), None)).await {
        Err(status) => status,
        Ok((_, end)) => end.expect_err("the damaged chunk ends the replay"),
    };
    assert_eq!(damaged.code(), Code::DataLoss, "{damaged:?}");

    // Shutting down ends a replay as it ends live streams.
    let mut slow = recordings
        .replay(bad(&name, Some(0.01), None))
        .await
        .unwrap()
        .into_inner();
    assert!(matches!(
        slow.message().await.unwrap().unwrap().kind,
        Some(v1::observe_message::Kind::Scene(_))
    ));
    let shutdown = tokio::spawn(server.shutdown());
    let status = tokio::time::timeout(WAIT, async {
        loop {
            match slow.message().await {
                Ok(Some(_)) => {}
                Ok(None) => return None,
                Err(status) => return Some(status),
            }
        }
    })
    .await
    .unwrap()
    .expect("the replay ends with a status");
    assert_eq!(status.code(), Code::Unavailable, "{status:?}");
    assert!(status.message().contains("shutting down"), "{status:?}");
    shutdown.await.unwrap().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
