//! Re-simulation: the same scene gives zero deviation, another material does not,
//! another mesh is refused; ticks that disagree with their times are refused, and
//! frames the recorder lost are stepped through a burst at a time.

use super::*;

#[test]
fn a_scripted_run_resimulates_with_zero_deviation_and_another_material_does_not() {
    let dir = temp();
    let path = dir.path().join("resim.mcap");
    let (frames, _, _) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();
    // The script pushed into the liver: there is something to reproduce.
    assert!(
        frames
            .iter()
            .any(|f| f.instruments[0].held_vertex_count > 0)
    );
    let mut seen = Vec::new();
    let same = resimulate(&rec, None, |t| seen.push(t)).unwrap();
    assert_eq!(seen, (1..=40).collect::<Vec<u64>>());
    assert_eq!(same.ticks_compared, 40);
    assert_eq!(same.steps, 40);
    assert!(same.is_exact(), "{same:?}");
    assert_eq!(same.worst_surface_tick, None);

    // A stiffer liver under the same hands deforms otherwise: the comparison sees
    // it (and the check above is not blind).
    let mut stiffer = rec.meta().clone();
    assert!(stiffer.scene_toml.contains("young_modulus = 4500.0"));
    stiffer.scene_toml = stiffer
        .scene_toml
        .replace("young_modulus = 4500.0", "young_modulus = 9000.0");
    let other = resimulate_as(&rec, &stiffer, None, |_| {}).unwrap();
    assert_eq!(other.ticks_compared, 40);
    assert!(other.max_surface_deviation_m > 1e-4, "{other:?}");
    assert!(other.max_force_deviation_n > 0.0, "{other:?}");
    assert!(!other.is_exact());
}

#[test]
fn resimulating_on_another_mesh_is_refused() {
    let dir = temp();
    let path = dir.path().join("mesh.mcap");
    record_script(&path, 3);
    let rec = Recording::open(&path).unwrap();
    let mut meta = rec.meta().clone();
    // The SOFA liver scene is a different mesh altogether.
    meta.scene_toml = include_str!("../../../scenes/sofa-liver.toml").into();
    meta.scene_dir = Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"));
    let err = resimulate_as(&rec, &meta, None, |_| {}).unwrap_err();
    assert!(
        matches!(
            err,
            ResimError::MeshSize { .. } | ResimError::MeshMoved { .. }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("not the recorded one"), "{err}");
}

/// A file whose ticks jump ahead of their times (damaged or forged: every frame
/// from tick 3 on renumbered 10⁶ later, its time kept) is refused at the first
/// such frame. Stepped to, the jump ran for minutes, and on a server buffered every
/// stepped frame until memory ran out.
#[test]
fn ticks_that_disagree_with_their_times_are_refused() {
    let dir = temp();
    let path = dir.path().join("jump.mcap");
    record_script_with(&path, 6, |mut f| {
        if f.tick >= 3 {
            f.tick += 1_000_000;
            f.instruments.iter_mut().for_each(|s| s.tick += 1_000_000);
        }
        Some(f)
    });
    let rec = Recording::open(&path).unwrap();
    let mut seen = Vec::new();
    let err = resimulate(&rec, None, |t| seen.push(t)).unwrap_err();
    assert!(
        matches!(
            err,
            ResimError::TickTime {
                tick: 1_000_003,
                ..
            }
        ),
        "{err}"
    );
    assert!(
        err.to_string().contains("ticks and times disagree"),
        "{err}"
    );
    assert_eq!(seen, [1, 2]);
}

/// Frames the recorder lost (ticks 5 to 44 here) are stepped through with the
/// last recorded poses; a re-simulated replay steps them at most
/// [`BURST_TICKS`](crate::service::replay::BURST_TICKS) a burst, so that a long gap
/// is no longer one burst holding every frame stepped (before, the burst that
/// reached tick 45 held 41 ticks' messages).
#[test]
fn lost_frames_are_stepped_through_a_burst_at_a_time() {
    use crate::service::replay::{BURST_TICKS, ReadResimulated, Reader};
    let dir = temp();
    let path = dir.path().join("gap.mcap");
    record_script_with(&path, 60, |f| (!(5..=44).contains(&f.tick)).then_some(f));
    let rec = Recording::open(&path).unwrap();
    let report = resimulate(&rec, None, |_| {}).unwrap();
    assert_eq!(report.steps, 60);
    assert_eq!(report.missing_ticks, 40);
    assert_eq!(report.first_missing_tick, Some(5));

    let mut reader = ReadResimulated::new(Arc::new(rec), "gap.mcap".into(), 0.0, None);
    let mut ticks = Vec::new();
    loop {
        let mut out = Vec::new();
        let more = reader.read(&mut out);
        let frames: Vec<u64> = out
            .iter()
            .filter_map(|m| match &m.as_ref().expect("no failure").message.kind {
                Some(v1::observe_message::Kind::SurfaceFrame(f)) => Some(f.tick),
                _ => None,
            })
            .collect();
        assert!(frames.len() <= BURST_TICKS, "one burst stepped {frames:?}");
        ticks.extend(frames);
        if !more {
            break;
        }
    }
    assert_eq!(ticks, (1..=60).collect::<Vec<u64>>());
}

/// A server reads a re-simulated recording's mesh only inside its own scene
/// directory, or only from the built-in meshes without one: a recording's scene is
/// the file's word, and a forged one naming another file as its mesh had the server
/// read it and quote its first line back to the client.
#[test]
fn a_served_resimulation_reads_no_mesh_outside_the_scene_directory() {
    let dir = temp();
    let path = dir.path().join("forged.mcap");
    record_script(&path, 3);
    let rec = Recording::open(&path).unwrap();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    let secret = dir.path().join("secret.msh");
    std::fs::write(&secret, "the secret first line\n").unwrap();
    let mut forged = rec.meta().clone();
    assert!(forged.scene_toml.contains("\"builtin:liver.msh\""));
    forged.scene_toml = forged.scene_toml.replace(
        "\"builtin:liver.msh\"",
        &format!("{:?}", secret.display().to_string()),
    );
    forged.scene_dir = Some(dir.path().to_path_buf());

    let served = |meshes| match Resimulation::new(&rec, &forged, meshes) {
        Ok(_) => panic!("the forged mesh was read"),
        Err(e) => e.to_string(),
    };
    let outside = served(MeshFiles::Served(Some(&scenes)));
    assert!(outside.contains("outside"), "{outside}");
    let none = served(MeshFiles::Served(None));
    assert!(matches!(
        Resimulation::new(&rec, &forged, MeshFiles::Served(None)).err(),
        Some(ResimError::MeshNotServed)
    ));
    for said in [&outside, &none] {
        assert!(!said.contains("secret first line"), "{said}");
    }
    // On the operator's own machine any file may be the mesh: the same recording
    // reads it (and finds it is no mesh).
    let local = served(MeshFiles::Local(None));
    assert!(local.contains("secret.msh"), "{local}");
    // The recording as made still re-simulates on a server without a scene directory.
    assert!(Resimulation::new(&rec, rec.meta(), MeshFiles::Served(None)).is_ok());
}
