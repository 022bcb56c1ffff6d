//! The files a scene names: only regular files, within the size limits, and for a
//! served scene only inside its scene directory. Nothing blocks or reads without end.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use super::*;

const LIVER: &str = include_str!("../../../../meshes/liver.msh");

/// A served scene `name.toml` in `dir` whose mesh is `mesh` (as written in the file).
fn write_scene(dir: &Path, name: &str, mesh: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "name = \"{name}\"\n[mesh]\nfile = \"{mesh}\"\nscale = 0.03\n\
             [material]\nyoung_modulus = 3000.0\npoisson_ratio = 0.3\ndensity = 1000.0\n\
             [fixed]\nnodes = [3, 39, 64]\n"
        ),
    )
    .unwrap();
    path
}

fn mkfifo(path: &Path) {
    let status = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .unwrap();
    assert!(status.success());
}

/// Runs `f` on a thread and gives its result, or panics if it has not finished within
/// 20 s (a read blocked on a FIFO would never finish).
fn bounded<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(20))
        .expect("the read finished instead of blocking")
}

/// Builds the served scene at `scene` of `dir`, on a bounded thread.
fn build_served(scene: PathBuf, dir: PathBuf) -> Result<(), String> {
    bounded(move || {
        Scene::load_served(&scene, &dir)
            .and_then(|s| s.build())
            .map(|_| ())
            .map_err(|e| e.to_string())
    })
}

#[test]
fn a_served_scene_builds_its_mesh_from_its_directory() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("liver.msh"), LIVER).unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::write(dir.path().join("meshes/liver.msh"), LIVER).unwrap();
    let d = dir.path().to_path_buf();
    build_served(write_scene(&d, "a", "liver.msh"), d.clone()).unwrap();
    build_served(write_scene(&d, "b", "meshes/liver.msh"), d.clone()).unwrap();
    build_served(write_scene(&d, "c", "./meshes/../liver.msh"), d.clone()).unwrap();
}

#[test]
fn a_fifo_mesh_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    mkfifo(&d.join("pipe.msh"));
    let served = build_served(write_scene(&d, "a", "pipe.msh"), d.clone()).unwrap_err();
    assert!(
        served.contains("`mesh.file`") && served.contains("FIFO"),
        "{served}"
    );
    // The headless path reads the mesh relative to its scene file, with the same
    // regular-file check.
    let scene = write_scene(&d, "b", "pipe.msh");
    let headless = bounded(move || Scene::load(&scene).unwrap().build().map(|_| ()))
        .unwrap_err()
        .to_string();
    assert!(headless.contains("FIFO"), "{headless}");
}

#[test]
fn devices_and_directories_are_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    std::fs::create_dir(d.join("folder.msh")).unwrap();
    let e = build_served(write_scene(&d, "a", "folder.msh"), d.clone()).unwrap_err();
    assert!(e.contains("directory, not a regular file"), "{e}");
    // /dev/zero never ends: unconfined (headless), it is refused as a device.
    let scene = write_scene(&d, "b", "/dev/zero");
    let e = bounded(move || Scene::load(&scene).unwrap().build().map(|_| ()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("character device"), "{e}");
    // Served, it is outside the scene directory to begin with.
    let e = build_served(write_scene(&d, "c", "/dev/zero"), d.clone()).unwrap_err();
    assert!(e.contains("outside the scene directory"), "{e}");
}

#[test]
fn served_meshes_outside_the_scene_directory_are_refused() {
    let root = tempfile::tempdir().unwrap();
    let scenes = root.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    let outside = root.path().join("liver.msh");
    std::fs::write(&outside, LIVER).unwrap();
    std::os::unix::fs::symlink(&outside, scenes.join("link.msh")).unwrap();
    for (name, mesh) in [
        ("up", "../liver.msh".to_string()),
        ("absolute", outside.display().to_string()),
        ("link", "link.msh".to_string()),
    ] {
        let e = build_served(write_scene(&scenes, name, &mesh), scenes.clone()).unwrap_err();
        assert!(
            e.contains("`mesh.file`") && e.contains("outside the scene directory"),
            "{name}: {e}"
        );
    }
    // The same mesh is fine for a scene given on the command line.
    let scene = write_scene(&scenes, "headless", "../liver.msh");
    Scene::load(&scene).unwrap().build().unwrap();
}

#[test]
fn a_mesh_over_the_size_limit_is_refused_naming_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    // Sparse: no disk space used.
    let big = std::fs::File::create(d.join("big.msh")).unwrap();
    big.set_len(MAX_MESH_BYTES + 1).unwrap();
    let e = build_served(write_scene(&d, "a", "big.msh"), d.clone()).unwrap_err();
    assert!(
        e.contains(&format!("limit of {MAX_MESH_BYTES} bytes")),
        "{e}"
    );
    // liver-300k's mesh (16.7 MB) is well within it.
    const LIVER_300K_BYTES: u64 = 16_749_333;
    const { assert!(LIVER_300K_BYTES * 2 <= MAX_MESH_BYTES) };
}

#[test]
fn scene_files_get_the_same_checks() {
    let root = tempfile::tempdir().unwrap();
    let scenes = root.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    mkfifo(&scenes.join("pipe.toml"));
    let (s, d) = (scenes.join("pipe.toml"), scenes.clone());
    let e = bounded(move || Scene::load_served(&s, &d).map(|_| ()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("FIFO"), "{e}");
    let big = std::fs::File::create(scenes.join("big.toml")).unwrap();
    big.set_len(MAX_SCENE_BYTES + 1).unwrap();
    let e = Scene::load_served(&scenes.join("big.toml"), &scenes)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("limit of {MAX_SCENE_BYTES} bytes")),
        "{e}"
    );
    let outside = write_scene(root.path(), "outside", "liver.msh");
    std::os::unix::fs::symlink(&outside, scenes.join("link.toml")).unwrap();
    let e = Scene::load_served(&scenes.join("link.toml"), &scenes)
        .unwrap_err()
        .to_string();
    assert!(e.contains("outside the scene directory"), "{e}");
}

/// A scene file that is not there, or not text, is named once with what is wrong
/// ("cannot read: cannot read: No such file…" said it twice).
#[test]
fn a_missing_or_binary_scene_file_is_named_with_what_is_wrong() {
    let root = tempfile::tempdir().unwrap();
    let missing = root.path().join("missing.toml");
    let e = Scene::load(&missing).unwrap_err().to_string();
    assert_eq!(e.matches("cannot read").count(), 1, "{e}");
    assert!(
        e.starts_with(&format!("{}: cannot read: ", missing.display())),
        "{e}"
    );
    let binary = root.path().join("binary.toml");
    std::fs::write(&binary, [0xff, 0xfe, 0x00]).unwrap();
    let e = Scene::load(&binary).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: is not UTF-8 text", binary.display())),
        "{e}"
    );
}

#[test]
fn one_file_is_the_same_under_any_link_and_another_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.mcap");
    let b = dir.path().join("b.mcap");
    std::fs::write(&a, b"same bytes").unwrap();
    std::fs::write(&b, b"same bytes").unwrap();
    let hard = dir.path().join("hard.mcap");
    std::fs::hard_link(&a, &hard).unwrap();
    let soft = dir.path().join("soft.mcap");
    std::os::unix::fs::symlink(&a, &soft).unwrap();
    assert!(same_file(&a, &a));
    assert!(same_file(&a, &hard), "a hard link is the same file");
    assert!(same_file(&soft, &a), "a symbolic link is the same file");
    assert!(!same_file(&a, &b), "equal contents are not the same file");
    assert!(!same_file(&a, &dir.path().join("missing")));
}

#[test]
fn a_file_is_named_by_its_kind() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("link");
    std::os::unix::fs::symlink("/dev/null", &link).unwrap();
    let fifo = dir.path().join("fifo");
    mkfifo(&fifo);
    let kind = |p: &Path| file_kind(&std::fs::symlink_metadata(p).unwrap());
    assert_eq!(kind(dir.path()), "directory");
    assert_eq!(kind(&link), "symbolic link");
    assert_eq!(kind(&fifo), "FIFO (named pipe)");
    assert_eq!(kind(Path::new("/dev/null")), "character device");
}
