//! Re-simulation: the same scene gives zero deviation, another material does not,
//! and another mesh is refused.

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
