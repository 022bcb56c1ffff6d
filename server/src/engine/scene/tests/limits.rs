//! Scenes that validated but could not tick: non-finite physics from values too large
//! or too small, and ticks that never end. Each is refused, naming the key.

use std::path::Path;

use super::*;
use crate::engine::scene::limits::*;

fn scene_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes"))
}

const MINIMAL: &str = r#"
name = "t"
[mesh]
file = "builtin:liver.msh"
scale = 0.03
[material]
young_modulus = 3000.0
poisson_ratio = 0.3
density = 1000.0
[fixed]
nodes = [3, 39, 64]
"#;

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, "test.toml", Some(scene_dir()))
}

fn build(text: &str) -> Result<(), SceneError> {
    parse(text)?.build().map(|_| ())
}

/// The error names `path` and contains `words`.
fn refused(result: Result<(), SceneError>, path: &str, words: &str) {
    match result {
        Err(e @ SceneError::Invalid { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains(&format!("`{path}`")) && msg.contains(words),
                "`{msg}` does not name `{path}` and say `{words}`"
            );
        }
        other => panic!("expected an error naming `{path}`, got {other:?}"),
    }
}

#[test]
fn values_that_overflow_or_underflow_a_tick_are_refused() {
    let cases = [
        (
            "young_modulus = 3000.0",
            "young_modulus = 1e308",
            "material.young_modulus",
        ),
        (
            "young_modulus = 3000.0",
            "young_modulus = 1e-300",
            "material.young_modulus",
        ),
        (
            "poisson_ratio = 0.3",
            "poisson_ratio = 0.4999999",
            "material.poisson_ratio",
        ),
        ("density = 1000.0", "density = 1e-300", "material.density"),
        ("density = 1000.0", "density = 1e300", "material.density"),
    ];
    for (from, to, path) in cases {
        refused(
            parse(&MINIMAL.replace(from, to)).map(|_| ()),
            path,
            "is outside",
        );
    }
    let region = MINIMAL.replace(
        "density = 1000.0",
        "density = 1000.0\n[[material.regions]]\ntag = 1\nyoung_modulus = 1e308",
    );
    refused(
        parse(&region).map(|_| ()),
        "material.regions[0].young_modulus",
        "is outside",
    );
    let more = [
        ("gravity = [0.0, -1e300, 0.0]", "gravity"),
        ("[mechanics]\ndamping = 1e300", "mechanics.damping"),
        (
            "[mechanics]\ncg_tolerance = 1e-300",
            "mechanics.cg_tolerance",
        ),
        (
            "[mechanics]\ncg_max_iterations = 4294967295",
            "mechanics.cg_max_iterations",
        ),
        (
            "[[instruments]]\nname = \"a\"\nradius = 1e300\nlength = 1e301\ntrocar = [0, 0, 0]",
            "instruments[0].radius",
        ),
        (
            "[[instruments]]\nname = \"a\"\nradius = 0.005\nlength = 0.3\ntrocar = [1e300, 0, 0]",
            "instruments[0].trocar",
        ),
        (
            "[[instruments]]\nname = \"a\"\nradius = 0.005\nlength = 0.3\ntrocar = [0, 0, 0]\nfriction = 1e300",
            "instruments[0].friction",
        ),
    ];
    for (extra, path) in more {
        // `gravity` is a top-level key: it goes before the first table.
        let text = if extra.starts_with("gravity") {
            format!("{extra}\n{MINIMAL}")
        } else {
            format!("{MINIMAL}\n{extra}\n")
        };
        refused(parse(&text).map(|_| ()), path, "");
    }
}

#[test]
fn a_mesh_scaled_beyond_the_stated_sizes_is_refused() {
    refused(
        build(&MINIMAL.replace("scale = 0.03", "scale = 1e300")),
        "mesh.scale",
        &format!("at most {MAX_COORDINATE_M} m"),
    );
    refused(
        build(&MINIMAL.replace("scale = 0.03", "scale = 1e-300")),
        "mesh.scale",
        &format!("at least {MIN_MESH_SIZE_M} m"),
    );
    // The size found is echoed as a number reads back (`Number`): in plain
    // decimals where that is short, "12.5 m" and not "1.25e1 m".
    for (scale, said) in [("scale = 1e300", "reaches "), ("scale = 1e-300", "is ")] {
        let e = build(&MINIMAL.replace("scale = 0.03", scale))
            .unwrap_err()
            .to_string();
        let number = e.split(said).nth(1).and_then(|r| r.split(" m").next());
        let number = number.unwrap_or_else(|| panic!("{e}"));
        assert!(number.parse::<f64>().is_ok() && number.len() <= 24, "{e}");
    }
    let e = build(&MINIMAL.replace("scale = 0.03", "scale = 1000"))
        .unwrap_err()
        .to_string();
    let far = e
        .split("reaches ")
        .nth(1)
        .and_then(|r| r.split(" m").next());
    assert!(far.is_some_and(|f| !f.contains('e')), "{e}");
}

#[test]
fn the_bounds_admit_the_shipped_scenes_and_the_extremes_stay_finite() {
    Scene::default_scene().build().unwrap();
    Scene::load(&scene_dir().join("sofa-liver.toml"))
        .unwrap()
        .build()
        .unwrap();
    // Every range at its stiff, heavy, fast end at once: the ticks stay finite.
    let extreme = format!(
        "gravity = [{g:?}, {g:?}, -{g:?}]\n{}\n[mechanics]\ndamping = {MAX_DAMPING:?}\n\
         cg_tolerance = {MIN_CG_TOLERANCE:?}\ncg_max_iterations = 2000\nrate_hz = 1.0\n",
        MINIMAL
            .replace("young_modulus = 3000.0", "young_modulus = 1e12")
            .replace(
                "poisson_ratio = 0.3",
                &format!("poisson_ratio = {MAX_POISSON_RATIO}")
            )
            .replace("density = 1000.0", "density = 0.01"),
        g = MAX_GRAVITY
    );
    let mut sim = parse(&extreme).unwrap().build().unwrap();
    for _ in 0..3 {
        sim.tick();
        assert!(
            sim.state.x.iter().all(|p| p.iter().all(|c| c.is_finite())),
            "tick {}",
            sim.tick
        );
    }
}

#[test]
fn an_explicit_scene_whose_ticks_need_too_many_substeps_is_refused() {
    // Within every range, but stiff, light and slow: the stable step is about a
    // nanosecond, so a 1 s tick would need about 10⁹ substeps.
    let text = format!(
        "{}\n[mechanics]\nintegrator = \"explicit\"\nrate_hz = 1.0\n",
        MINIMAL
            .replace("young_modulus = 3000.0", "young_modulus = 1e12")
            .replace("density = 1000.0", "density = 0.01")
    );
    refused(build(&text), "mechanics.integrator", "substeps a tick");
    let e = build(&text).unwrap_err().to_string();
    assert!(
        e.contains("implicit") && e.contains("rate_hz") && e.contains("density"),
        "the error says what to change: {e}"
    );
    // The same scene at the default liver material is far within the bound.
    let fine = text
        .replace("young_modulus = 1e12", "young_modulus = 3000.0")
        .replace("density = 0.01", "density = 1000.0");
    let sim = parse(&fine).unwrap().build().unwrap();
    let work = sim.integrator.explicit_substeps_f64(sim.dt) * sim.mesh.vertex_count() as f64;
    assert!(work <= MAX_TICK_WORK, "{work}");
}

#[test]
fn a_cg_cap_too_high_for_the_mesh_is_refused() {
    // liver-5k has 1408 vertices: 10⁵ iterations a tick is 1.4·10⁸ vertex-iterations.
    let text = format!(
        "{}\n[mechanics]\ncg_max_iterations = {MAX_CG_ITERATIONS}\n",
        MINIMAL.replace("builtin:liver.msh", "../meshes/liver-5k.msh")
    );
    refused(
        build(&text),
        "mechanics.cg_max_iterations",
        "at most 71022 iterations",
    );
    // The same cap is fine on the 181-vertex liver.
    build(&MINIMAL.replace("scale = 0.03", "scale = 0.03\n").replace(
        "nodes = [3, 39, 64]",
        &format!("nodes = [3, 39, 64]\n[mechanics]\ncg_max_iterations = {MAX_CG_ITERATIONS}"),
    ))
    .unwrap();
}

#[test]
fn a_refinement_beyond_the_stated_bounds_is_refused_before_any_work() {
    refused(
        parse(&MINIMAL.replace("scale = 0.03", "scale = 0.03\nrefine = 4")).map(|_| ()),
        "mesh.refine",
        &format!("outside [0, {MAX_REFINE}]"),
    );
    // liver-5k's 5174 tetrahedra refined three times would be 2.6 million.
    let text = MINIMAL
        .replace("builtin:liver.msh", "../meshes/liver-5k.msh")
        .replace("scale = 0.03", "scale = 0.03\nrefine = 3");
    refused(
        build(&text),
        "mesh.refine",
        &format!("5174 tetrahedra refined 3 times would be 2649088, more than {MAX_REFINED_TETS}"),
    );
    // Refined once, the liver keeps its file's nodes as supports.
    let sim = parse(&MINIMAL.replace("scale = 0.03", "scale = 0.03\nrefine = 1"))
        .unwrap()
        .build()
        .unwrap();
    assert_eq!(sim.mesh.tets.len(), 8 * 596);
    assert_eq!(sim.fixed, [3, 39, 64]);
}

#[test]
fn a_refinement_that_would_flatten_a_nearly_flat_tetrahedron_names_mesh_refine() {
    // One tetrahedron 1.3e-12 of the way from flat (6V / L³; the mesh check refuses
    // 1e-12 and below): it loads, but its inner children are flatter than that.
    let dir = std::env::temp_dir().join(format!("laparo-refine-flat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("nearly-flat.msh");
    std::fs::write(
        &file,
        "$NOD\n4\n1 0 0 0\n2 0.1 0 0\n3 0.05 0.08660254037844387 0\n\
         4 0.05000000000000001 0.028867513459481287 1.5011106998930272e-13\n$ENDNOD\n\
         $ELM\n1\n1 4 1 1 4 1 2 3 4\n$ENDELM\n",
    )
    .unwrap();
    let text = MINIMAL
        .replace("builtin:liver.msh", &file.display().to_string())
        .replace("nodes = [3, 39, 64]", "nodes = [1]");
    let unrefined = build(&text);
    let refined = build(&text.replace("scale = 0.03", "scale = 0.03\nrefine = 1"));
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(unrefined.is_ok(), "{unrefined:?}");
    refused(
        refined,
        "mesh.refine",
        "refinement 1 of 1 cannot be simulated: its tetrahedron 1",
    );
}

/// A point or vector is exactly three numbers: the TOML reader left what followed
/// the third unread, so `gravity = [0.0, -9.81, 0.0, "junk"]` passed as gravity.
/// Too few or too many are refused, naming the key.
#[test]
fn a_point_of_other_than_three_numbers_is_refused() {
    let instrument = "[[instruments]]\nname = \"a\"\nradius = 0.005\nlength = 0.3\n";
    for (text, path) in [
        (
            format!("gravity = [0.0, -9.81, 0.0, 1.0]\n{MINIMAL}"),
            "gravity",
        ),
        (format!("gravity = [0.0, -9.81]\n{MINIMAL}"), "gravity"),
        (
            format!("{MINIMAL}\n{instrument}trocar = [0.0, 0.0, 0.0, 7.0]\n"),
            "instruments[0].trocar",
        ),
        (
            format!("{MINIMAL}boxes = [{{ min = [0, 0, 0, 0], max = [1, 1, 1] }}]\n"),
            "fixed.boxes[0].min",
        ),
    ] {
        match parse(&text) {
            Err(e @ SceneError::Parse { .. }) => {
                let said = e.to_string();
                assert!(said.contains(path) && said.contains("3 numbers"), "{said}");
            }
            other => panic!("{text}: expected a parse error naming {path}, got {other:?}"),
        }
    }
    let good =
        format!("gravity = [0.0, -9.81, 0.0]\n{MINIMAL}\n{instrument}trocar = [0.0, 0.0, 0.1]\n");
    assert_eq!(parse(&good).unwrap().gravity, [0.0, -9.81, 0.0]);
}

#[test]
fn a_name_longer_than_a_client_may_send_is_refused() {
    // 256 bytes is what a client may send for a scene or an instrument to claim: a
    // longer name loaded and listed as available, and could never be asked for.
    let long = "n".repeat(MAX_NAME_BYTES + 1);
    let named = MINIMAL.replace("name = \"t\"", &format!("name = \"{long}\""));
    refused(build(&named), "name", "257 bytes, over the limit of 256");
    let fits = MINIMAL.replace("name = \"t\"", &format!("name = \"{}\"", "é".repeat(128)));
    build(&fits).unwrap();
    let instrument = format!(
        "{MINIMAL}[[instruments]]\nname = \"{long}\"\nradius = 0.005\nlength = 0.3\ntrocar = [0.0, 0.0, 0.1]\n"
    );
    refused(
        build(&instrument),
        "instruments[0].name",
        "over the limit of 256",
    );
}
