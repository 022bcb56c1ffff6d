use std::path::Path;

use super::*;
use crate::engine::integrate::IntegratorKind;

fn scene_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes"))
}

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, "test.toml", Some(scene_dir()))
}

const MINIMAL: &str = r#"
name = "t"
[mesh]
file = "builtin:liver.msh"
[material]
young_modulus = 3000.0
poisson_ratio = 0.3
density = 1.0
[fixed]
nodes = [3, 39, 64]
"#;

fn expect_path(result: Result<Scene, SceneError>, path: &str) -> String {
    match result {
        Err(e @ (SceneError::Parse { .. } | SceneError::Invalid { .. })) => {
            let msg = e.to_string();
            assert!(
                msg.contains(&format!("`{path}`")),
                "message `{msg}` does not name `{path}`"
            );
            msg
        }
        other => panic!("expected an error naming `{path}`, got {other:?}"),
    }
}

#[test]
fn shipped_scenes_parse_and_build() {
    let default = Scene::default_scene();
    assert_eq!(default.instruments.len(), 2);
    assert!(
        default
            .instruments
            .iter()
            .all(|i| i.radius == 0.005 && i.length == 0.3)
    );
    let sim = default.build().unwrap();
    let (lo, hi) = sim.mesh.bounding_box();
    let size = (hi - lo).max();
    assert!(
        (0.15..=0.25).contains(&size),
        "default liver is {size} m across"
    );
    let sofa = Scene::load(&scene_dir().join("sofa-liver.toml"))
        .unwrap()
        .build()
        .unwrap();
    assert_eq!(sofa.fixed, vec![3, 39, 64]);
    assert_eq!(sofa.integrator.config().kind, IntegratorKind::Implicit);
    assert!((sofa.dt - 0.02).abs() < 1e-15);
}

#[test]
fn default_liver_sags_under_five_percent_of_its_size() {
    // The supports are a region, so the static sag under gravity stays small enough
    // for linear elasticity (small strains) to hold.
    let mut sim = Scene::default_scene().build().unwrap();
    let report = sim.solve_static();
    assert!(report.converged);
    let (lo, hi) = sim.mesh.bounding_box();
    let size = (hi - lo).max();
    let sag = sim.max_displacement();
    println!(
        "default scene: {} fixed of {} vertices, sag {:.4} m = {:.2}% of {:.3} m",
        sim.fixed.len(),
        sim.mesh.vertex_count(),
        sag,
        100.0 * sag / size,
        size
    );
    assert!(
        sag > 0.0 && sag < 0.05 * size,
        "sag {sag} m for a {size} m liver"
    );
}

#[test]
fn unknown_keys_are_named_with_their_path() {
    expect_path(
        parse(&MINIMAL.replace("density = 1.0", "density = 1.0\nstiffness = 2")),
        "material.stiffness",
    );
    let msg = expect_path(
        parse(&format!(
            "{MINIMAL}\n[[instruments]]\nname = \"a\"\nradius = 0.005\nlength = 0.3\ntrocar = [0, 0, 0]\ncolour = 1\n"
        )),
        "instruments[0].colour",
    );
    assert!(msg.contains("expected one of"), "{msg}");
}

#[test]
fn wrong_types_name_the_key_and_line() {
    let msg = expect_path(
        parse(&MINIMAL.replace("poisson_ratio = 0.3", "poisson_ratio = \"a lot\"")),
        "material.poisson_ratio",
    );
    assert!(msg.contains("test.toml:7:"), "{msg}");
}

#[test]
fn out_of_range_values_are_named_with_their_path() {
    let cases = [
        (
            "poisson_ratio = 0.3",
            "poisson_ratio = 0.5",
            "material.poisson_ratio",
        ),
        (
            "young_modulus = 3000.0",
            "young_modulus = -1.0",
            "material.young_modulus",
        ),
        ("density = 1.0", "density = 0.0", "material.density"),
        (
            "file = \"builtin:liver.msh\"",
            "file = \"builtin:liver.msh\"\nscale = nan",
            "mesh.scale",
        ),
        (
            "nodes = [3, 39, 64]",
            "nodes = []\nboxes = [{ min = [1, 0, 0], max = [0, 1, 1] }]",
            "fixed.boxes[0]",
        ),
    ];
    for (from, to, path) in cases {
        expect_path(parse(&MINIMAL.replace(from, to)), path);
    }
    let mech = [
        ("rate_hz = 0.0", "mechanics.rate_hz"),
        ("damping = -1.0", "mechanics.damping"),
        ("cg_tolerance = 0.0", "mechanics.cg_tolerance"),
        ("cg_max_iterations = 0", "mechanics.cg_max_iterations"),
    ];
    for (line, path) in mech {
        expect_path(parse(&format!("{MINIMAL}\n[mechanics]\n{line}\n")), path);
    }
    let instrument = |body: &str| format!("{MINIMAL}\n[[instruments]]\nname = \"a\"\n{body}\n");
    expect_path(
        parse(&instrument(
            "radius = 0.0\nlength = 0.3\ntrocar = [0, 0, 0]",
        )),
        "instruments[0].radius",
    );
    expect_path(
        parse(&instrument(
            "radius = 0.005\nlength = inf\ntrocar = [0, 0, 0]",
        )),
        "instruments[0].length",
    );
    expect_path(
        parse(&format!(
            "{}\n[[instruments]]\nname = \"a\"\nradius = 0.005\nlength = 0.3\ntrocar = [0, 0, 0]",
            instrument("radius = 0.005\nlength = 0.3\ntrocar = [0, 0, 0]")
        )),
        "instruments[1].name",
    );
    expect_path(
        parse(&MINIMAL.replace("name = \"t\"", "name = \"t\"\ngravity = [0, nan, 0]")),
        "gravity",
    );
}

#[test]
fn build_errors_name_their_key() {
    let build = |text: &str| parse(text).and_then(|s| s.build().map(|_| s));
    expect_path(
        build(&MINIMAL.replace("[3, 39, 64]", "[3, 181]")),
        "fixed.nodes[1]",
    );
    expect_path(
        build(&MINIMAL.replace(
            "nodes = [3, 39, 64]",
            "boxes = [{ min = [50, 50, 50], max = [60, 60, 60] }]",
        )),
        "fixed.boxes[0]",
    );
    expect_path(
        build(&MINIMAL.replace(
            "density = 1.0",
            "density = 1.0\n[[material.regions]]\ntag = 7\nyoung_modulus = 1e4",
        )),
        "material.regions[0].tag",
    );
    expect_path(
        build(&MINIMAL.replace("builtin:liver.msh", "builtin:kidney.msh")),
        "mesh.file",
    );
    expect_path(
        build(&format!(
            "{}\n[mechanics]\nintegrator = \"static\"\n",
            MINIMAL.replace("[3, 39, 64]", "[3, 39]")
        )),
        "fixed",
    );
    match build(&MINIMAL.replace("builtin:liver.msh", "no-such-mesh.msh")) {
        Err(SceneError::Mesh { .. }) => {}
        other => panic!("expected a mesh error, got {other:?}"),
    }
}

#[test]
fn regions_get_their_own_material() {
    let scene = parse(&MINIMAL.replace(
        "density = 1.0",
        "density = 1.0\n[[material.regions]]\ntag = 1\nyoung_modulus = 9000.0",
    ))
    .unwrap();
    let sim = scene.build().unwrap();
    // Every tetrahedron of liver.msh has physical tag 1.
    assert!(
        sim.model
            .tet_material
            .iter()
            .all(|&m| sim.model.materials[m as usize].young_modulus == 9000.0)
    );
    assert_eq!(sim.model.materials[1].poisson_ratio, 0.3);
}
