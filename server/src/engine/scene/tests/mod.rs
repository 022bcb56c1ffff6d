use std::path::Path;

use super::*;

mod files;
mod limits;

pub(crate) fn scene_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes"))
}

pub(crate) fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, "test.toml", Some(scene_dir()))
}

pub(crate) const MINIMAL: &str = r#"
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

pub(crate) fn expect_path(result: Result<Scene, SceneError>, path: &str) -> String {
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
fn a_syntax_error_names_the_text_it_points_at_and_no_empty_key() {
    // A key written twice: the error has no key path, and named none ("``").
    let twice = format!("{MINIMAL}\n[fixed]\nnodes = [1]\n");
    let e = parse(&twice).unwrap_err().to_string();
    assert!(e.contains(": `fixed`: duplicate key"), "{e}");
    let e = parse("").unwrap_err().to_string();
    assert!(e.starts_with("test.toml:1: missing field `name`"), "{e}");
    assert!(!e.contains("``"), "{e}");
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
        ("file = \"builtin:liver.msh\"", "file = \" \"", "mesh.file"),
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
        ("threads = 0", "mechanics.threads"),
        ("threads = 65", "mechanics.threads"),
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
fn the_elastic_model_is_linear_unless_the_scene_says_corotational() {
    use crate::engine::elastic::Formulation;
    assert_eq!(parse(MINIMAL).unwrap().material.model, Formulation::Linear);
    let corot = parse(&MINIMAL.replace("density = 1.0", "density = 1.0\nmodel = \"corotational\""));
    assert_eq!(corot.unwrap().material.model, Formulation::Corotational);
    let msg = expect_path(
        parse(&MINIMAL.replace("density = 1.0", "density = 1.0\nmodel = \"neohookean\"")),
        "material.model",
    );
    assert!(
        msg.contains("linear") && msg.contains("corotational"),
        "{msg}"
    );
    // Both liver scenes are corotational: SOFA's liver demo as SOFA's, the default
    // scene because instruments turn the tissue they push.
    for (file, model) in [
        ("default.toml", Formulation::Corotational),
        ("sofa-liver.toml", Formulation::Corotational),
    ] {
        let scene = Scene::load(&scene_dir().join(file)).unwrap();
        assert_eq!(scene.material.model, model, "{file}");
    }
}

#[test]
fn a_scene_runs_on_one_thread_unless_it_says_more() {
    assert_eq!(parse(MINIMAL).unwrap().mechanics.threads, 1);
    let two = parse(&format!("{MINIMAL}\n[mechanics]\nthreads = 2\n")).unwrap();
    assert_eq!(two.mechanics.threads, 2);
}

/// A `[mechanics]` choice `key`: absent it is `default`, each of `names` parses to
/// its value, and an unknown name is refused naming the key and the choices
/// `listed`.
fn mechanics_choice<T: PartialEq + std::fmt::Debug>(
    key: &str,
    get: impl Fn(&Scene) -> T,
    default: T,
    names: &[(&str, T)],
    unknown: &str,
    listed: &[&str],
) {
    assert_eq!(get(&parse(MINIMAL).unwrap()), default);
    for (name, value) in names {
        let scene = parse(&format!("{MINIMAL}\n[mechanics]\n{key} = \"{name}\"\n"));
        assert_eq!(&get(&scene.unwrap()), value, "{key} = {name}");
    }
    let msg = expect_path(
        parse(&format!("{MINIMAL}\n[mechanics]\n{key} = \"{unknown}\"\n")),
        &format!("mechanics.{key}"),
    );
    assert!(listed.iter().all(|l| msg.contains(l)), "{msg}");
}

#[test]
fn the_preconditioner_is_auto_unless_the_scene_names_one() {
    use crate::engine::integrate::PreconditionerKind;
    mechanics_choice(
        "preconditioner",
        |s| s.mechanics.preconditioner,
        PreconditionerKind::Auto,
        &[
            ("auto", PreconditionerKind::Auto),
            ("block-jacobi", PreconditionerKind::BlockJacobi),
            ("amg", PreconditionerKind::Amg),
        ],
        "ilu",
        &["block-jacobi", "amg"],
    );
}

#[test]
fn the_stiffness_storage_is_auto_unless_the_scene_names_one() {
    use crate::engine::integrate::StiffnessStorage;
    mechanics_choice(
        "stiffness",
        |s| s.mechanics.stiffness,
        StiffnessStorage::Auto,
        &[
            ("auto", StiffnessStorage::Auto),
            ("f64", StiffnessStorage::F64),
            ("f32", StiffnessStorage::F32),
        ],
        "f16",
        &["f32", "f64"],
    );
}

#[test]
fn the_contact_is_settled_unless_the_scene_says_not() {
    assert!(parse(MINIMAL).unwrap().contact.settle);
    assert!(crate::engine::scene::Scene::default_scene().contact.settle);
    let scene = parse(&format!("{MINIMAL}\n[contact]\nsettle = false\n"));
    assert!(!scene.unwrap().contact.settle);
    expect_path(
        parse(&format!("{MINIMAL}\n[contact]\nsettle = 1\n")),
        "contact.settle",
    );
    expect_path(
        parse(&format!("{MINIMAL}\n[contact]\nsettling = true\n")),
        "contact.settling",
    );
}

#[test]
fn the_tip_force_is_scaled_to_its_footprint_unless_the_scene_says_not() {
    assert!(parse(MINIMAL).unwrap().contact.footprint);
    assert!(
        crate::engine::scene::Scene::default_scene()
            .contact
            .footprint
    );
    let scene = parse(&format!("{MINIMAL}\n[contact]\nfootprint = false\n")).unwrap();
    assert!(!scene.contact.footprint && scene.contact.settle);
    expect_path(
        parse(&format!("{MINIMAL}\n[contact]\nfootprint = \"on\"\n")),
        "contact.footprint",
    );
}

#[test]
fn the_force_rendered_is_the_reaction_unless_the_scene_asks_for_the_papers() {
    use crate::engine::local_model::ForceModelKind;
    assert_eq!(
        parse(MINIMAL).unwrap().force_model.kind,
        ForceModelKind::Calibrated
    );
    assert_eq!(
        crate::engine::scene::Scene::default_scene()
            .force_model
            .kind,
        ForceModelKind::Calibrated
    );
    let scene = parse(&format!("{MINIMAL}\n[force_model]\nkind = \"geometric\"\n"));
    assert_eq!(scene.unwrap().force_model.kind, ForceModelKind::Geometric);
    expect_path(
        parse(&format!("{MINIMAL}\n[force_model]\nkind = \"flat\"\n")),
        "force_model.kind",
    );
}
