//! The scene file format (TOML), its defaults and its range checks.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::SceneError;
use super::files::{MAX_SCENE_BYTES, read_bounded};
use super::limits::*;
use crate::engine::contact::MAX_INSTRUMENTS;
use crate::engine::elastic::Formulation;
use crate::engine::integrate::{IntegratorKind, PreconditionerKind, StiffnessStorage};
use crate::engine::local_model::ForceModelKind;
use crate::engine::workers::MAX_THREADS;

/// A scene as declared in its TOML file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Short name, unique among the scenes a server offers.
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub mesh: MeshSpec,
    pub material: MaterialSpec,
    #[serde(default)]
    pub fixed: FixedSpec,
    /// Gravity, m/s², in the scene frame; `[0, 0, 0]` turns it off.
    #[serde(default, deserialize_with = "three")]
    pub gravity: [f64; 3],
    #[serde(default)]
    pub mechanics: MechanicsSpec,
    #[serde(default)]
    pub instruments: Vec<InstrumentSpec>,
    #[serde(default)]
    pub contact: ContactSpec,
    #[serde(default)]
    pub force_model: ForceModelSpec,
    #[serde(default)]
    pub recording: RecordingSpec,
    /// The folder relative paths are resolved against (the scene file's folder).
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
    /// When set, the mesh file must lie inside this folder (the server's scene
    /// directory), symlinks followed; `None` (a scene given on the command line, or
    /// built from a recording): anywhere. Either way only a regular file of at most
    /// [`super::MAX_MESH_BYTES`] is read.
    #[serde(skip)]
    pub mesh_root: Option<PathBuf>,
    /// Where the scene came from, for messages.
    #[serde(skip)]
    pub source: String,
    /// The TOML text the scene was parsed from, as recordings keep it.
    #[serde(skip)]
    pub text: String,
}

/// The volume mesh.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// Gmsh `.msh` file (v1 or v2.2), relative to the scene file, or `builtin:NAME` for
    /// a mesh embedded in the binary.
    pub file: String,
    /// Metres per mesh unit.
    #[serde(default = "one")]
    pub scale: f64,
    /// Translate the scaled mesh so that its bounding-box centre is at the origin.
    #[serde(default)]
    pub center: bool,
    /// Times the mesh is refined when loaded, 0 to [`MAX_REFINE`]: each time every
    /// tetrahedron is split into eight at its edges' midpoints, the shape and volume
    /// kept exactly (see `TetMesh::refined`), to at most [`MAX_REFINED_TETS`]
    /// tetrahedra. The file's vertices keep their numbers in `fixed.nodes`; the
    /// midpoint of the file's `e`-th edge (edges `[i, j]`, `i < j`, in lexicographic
    /// order) is vertex `n + e` of the first refinement, `n` the file's count.
    #[serde(default)]
    pub refine: u32,
}

/// The most refinements a scene asks of its mesh (`mesh.refine`): three take SOFA's
/// 596-tetrahedron liver to 305,152, the size of the largest liver meshed from file.
pub const MAX_REFINE: u32 = 3;

/// The most tetrahedra a refined mesh may have (`mesh.refine`): what a mesh file of
/// [`MAX_MESH_BYTES`](super::MAX_MESH_BYTES) holds at about 32 bytes a tetrahedron.
pub const MAX_REFINED_TETS: usize = 1 << 20;

/// Material of the whole mesh, with optional per-region overrides.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E, Pa.
    pub young_modulus: f64,
    /// Poisson's ratio ν, in [0, 0.5).
    pub poisson_ratio: f64,
    /// Density ρ, kg/m³.
    pub density: f64,
    /// `"linear"` or `"corotational"` (see [`Formulation`]); linear when absent, so
    /// that scenes written before the choice existed, and the recordings that keep
    /// them, replay as they ran. The liver scenes set `"corotational"`.
    #[serde(default)]
    pub model: Formulation,
    /// Materials of tetrahedra with a given physical tag.
    #[serde(default)]
    pub regions: Vec<RegionSpec>,
}

/// The material of one tagged region of the mesh; unset fields take the scene's.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// The Gmsh physical tag of the region's tetrahedra.
    pub tag: i32,
    pub young_modulus: Option<f64>,
    pub poisson_ratio: Option<f64>,
    pub density: Option<f64>,
}

/// Vertices held in place (supports).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixedSpec {
    /// Vertex indices, 0-based in file order.
    #[serde(default)]
    pub nodes: Vec<u32>,
    /// Axis-aligned boxes in metres (after scaling and centring): every vertex inside
    /// one is fixed.
    #[serde(default)]
    pub boxes: Vec<BoxSpec>,
    /// With `boxes`, fix only surface vertices inside them (an attachment on the
    /// surface, not a block of tissue).
    #[serde(default)]
    pub surface_only: bool,
}

/// A point or vector: an array of exactly three numbers. serde reads `[f64; 3]` as
/// a tuple of three, and the TOML reader leaves what follows unread:
/// `gravity = [0.0, -9.81, 0.0, "junk"]` passed as gravity.
fn three<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    let v: Vec<f64> = Vec::deserialize(d)?;
    <[f64; 3]>::try_from(v.as_slice())
        .map_err(|_| serde::de::Error::invalid_length(v.len(), &"an array of 3 numbers"))
}

/// An axis-aligned box, m.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    #[serde(deserialize_with = "three")]
    pub min: [f64; 3],
    #[serde(deserialize_with = "three")]
    pub max: [f64; 3],
}

/// The mechanics loop.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanicsSpec {
    /// `explicit`, `implicit` or `static`.
    #[serde(default = "default_integrator")]
    pub integrator: IntegratorKind,
    /// Mechanics ticks per second, Hz.
    #[serde(default = "default_rate")]
    pub rate_hz: f64,
    /// Mass-proportional damping α, 1/s.
    #[serde(default = "default_damping")]
    pub damping: f64,
    /// Relative conjugate-gradient tolerance (implicit and static).
    #[serde(default = "default_cg_tolerance")]
    pub cg_tolerance: f64,
    /// Conjugate-gradient iteration cap per tick.
    #[serde(default = "default_cg_max_iterations")]
    pub cg_max_iterations: u32,
    /// The conjugate-gradient preconditioner (implicit and static): `"auto"` (the
    /// default: multigrid on meshes of at least
    /// [`AUTO_AMG_VERTICES`](crate::engine::integrate::AUTO_AMG_VERTICES) vertices,
    /// block Jacobi on smaller ones and whenever `threads` splits the mesh),
    /// `"block-jacobi"` or `"amg"` (smoothed-aggregation
    /// multigrid, built when the scene is).
    #[serde(default)]
    pub preconditioner: PreconditionerKind,
    /// Threads an implicit tick shares its products, vector updates and corotational
    /// update with, this session's mechanics thread included (1 to
    /// [`crate::engine::workers::MAX_THREADS`]; default 1; no more run
    /// than the machine has cores). A mesh is split into one part a thread, each of
    /// at least [`MIN_PART_VERTICES`](crate::engine::elastic::MIN_PART_VERTICES)
    /// vertices, and then renumbered when loaded; results differ from one part's in
    /// the last bits.
    #[serde(default = "default_threads")]
    pub threads: usize,
    /// The precision the implicit solve's products read the stiffness in, and the
    /// multigrid hierarchy's sparse matrices: `"auto"` (the default: f32 for each
    /// when its f64 bytes reach
    /// [`F32_FROM_BYTES`](crate::engine::integrate::F32_FROM_BYTES), the blocks
    /// of liver-300k and the hierarchies of liver-80k and 300k), `"f64"` or `"f32"`
    /// (copies rounded to f32, each entry widened as it is read). See
    /// [`StiffnessStorage`].
    #[serde(default)]
    pub stiffness: StiffnessStorage,
}

impl Default for MechanicsSpec {
    fn default() -> Self {
        MechanicsSpec {
            integrator: default_integrator(),
            rate_hz: default_rate(),
            damping: default_damping(),
            cg_tolerance: default_cg_tolerance(),
            cg_max_iterations: default_cg_max_iterations(),
            preconditioner: PreconditionerKind::default(),
            threads: default_threads(),
            stiffness: StiffnessStorage::default(),
        }
    }
}

/// A laparoscopic instrument: the points within `radius` of the segment from its tip
/// `P` to `P + length·Z`, entering the body through a fixed trocar point.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentSpec {
    pub name: String,
    /// Shaft radius r, m.
    pub radius: f64,
    /// Shaft length l inside the body, m.
    pub length: f64,
    /// Trocar point, m, in the scene frame; torques are taken about it.
    #[serde(deserialize_with = "three")]
    pub trocar: [f64; 3],
    /// Whether the tip pushes tissue.
    #[serde(default = "yes")]
    pub tip_contact: bool,
    /// Whether the shaft pushes tissue.
    #[serde(default = "yes")]
    pub shaft_contact: bool,
    /// Coulomb friction coefficient μ between instrument and tissue: a held vertex
    /// stays held while the tissue's tangential force on it is at most μ times its
    /// normal push, and slips otherwise.
    #[serde(default = "default_friction")]
    pub friction: f64,
}

/// μ = 1: the hold lasts while the tissue's pull along the instrument's surface is at
/// most its push on it. With 0.3 (wet tissue on a polished instrument), tissue under a tip pressed at 30°
/// slipped off it every tick. Higher values make the tissue stick and drag along with
/// a sliding instrument.
fn default_friction() -> f64 {
    1.0
}

/// The contact stage.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Settle the free tissue around the vertices the contact steps jump, so that the
    /// first-contact tick's force is that of the tissue, not of one vertex pushed
    /// against fixed neighbours (`engine/contact/settle.rs`). On unless the scene
    /// turns it off; off, a first contact reports up to 49× the steady force (ν =
    /// 0.499) and an explicit step on stiff tissue can chatter.
    #[serde(default = "default_settle")]
    pub settle: bool,
    /// Scale the force on the tip's end from the patch of vertices the mesh holds to
    /// the tip's own footprint (`engine/contact/footprint.rs`), so that a press gives
    /// the same force on a coarse liver as on a fine one. On unless the scene turns
    /// it off; off, a tip press on the 5k liver gives up to 2.7× the footprint's
    /// force, and the press's force spreads ±44% over liver-5k, 20k and 80k.
    #[serde(default = "default_footprint")]
    pub footprint: bool,
}

impl Default for ContactSpec {
    fn default() -> Self {
        ContactSpec {
            settle: default_settle(),
            footprint: default_footprint(),
        }
    }
}

/// The contact's jumps are settled unless the scene says otherwise.
fn default_settle() -> bool {
    true
}

/// The tip's force is its footprint's unless the scene asks for the held patch's.
fn default_footprint() -> bool {
    true
}

/// How reaction forces are computed.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceModelSpec {
    #[serde(default)]
    pub kind: ForceModelKind,
}

/// Session recording.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordingSpec {
    #[serde(default = "yes")]
    pub enabled: bool,
}

impl Default for RecordingSpec {
    fn default() -> Self {
        RecordingSpec { enabled: true }
    }
}

fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}
fn default_integrator() -> IntegratorKind {
    IntegratorKind::Implicit
}
fn default_rate() -> f64 {
    60.0
}
fn default_damping() -> f64 {
    10.0
}
fn default_threads() -> usize {
    1
}

fn default_cg_tolerance() -> f64 {
    1e-4
}
fn default_cg_max_iterations() -> u32 {
    1000
}

impl Scene {
    /// Parses and checks a scene. `source` names it in messages; `base_dir` resolves its
    /// relative mesh path.
    pub fn parse(text: &str, source: &str, base_dir: Option<&Path>) -> Result<Scene, SceneError> {
        let parse_error = |path: String, err: &toml::de::Error| SceneError::Parse {
            scene: source.to_string(),
            path,
            line: err
                .span()
                .map(|s| 1 + text[..s.start.min(text.len())].matches('\n').count()),
            message: err.message().to_string(),
        };
        // A syntax error has no key path; the text it points at names the key (a key
        // written twice) when that is short and on one line.
        let spanned = |err: &toml::de::Error| {
            err.span()
                .and_then(|s| text.get(s))
                .map(str::trim)
                .filter(|t| !t.is_empty() && t.len() <= 64 && !t.contains('\n'))
                .map_or_else(String::new, |t| {
                    laparo_proto::text::printable(t).to_string()
                })
        };
        let de = toml::Deserializer::parse(text).map_err(|e| parse_error(spanned(&e), &e))?;
        let mut scene: Scene = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            parse_error(if path == "." { String::new() } else { path }, e.inner())
        })?;
        scene.base_dir = base_dir.map(Path::to_path_buf);
        scene.source = source.to_string();
        scene.text = text.to_string();
        scene.validate()?;
        Ok(scene)
    }

    /// Reads and checks a scene file (a regular file of at most
    /// [`super::MAX_SCENE_BYTES`]); its mesh is read relative to it.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::load_from(path, None)
    }

    /// Reads and checks a scene file of a server's scene directory `dir`: the file and
    /// its mesh must lie inside `dir` (symlinks followed), as well as being regular
    /// files within the size limits.
    pub fn load_served(path: &Path, dir: &Path) -> Result<Scene, SceneError> {
        let mut scene = Scene::load_from(path, Some(dir))?;
        scene.mesh_root = Some(dir.to_path_buf());
        Ok(scene)
    }

    fn load_from(path: &Path, root: Option<&Path>) -> Result<Scene, SceneError> {
        let source = path.display().to_string();
        let io = |message: String| SceneError::Io {
            scene: source.clone(),
            message,
        };
        let bytes = read_bounded(path, root, MAX_SCENE_BYTES).map_err(|e| io(e.to_string()))?;
        let text = String::from_utf8(bytes).map_err(|e| io(format!("is not UTF-8 text: {e}")))?;
        Scene::parse(&text, &source, path.parent())
    }

    /// The embedded default scene.
    pub fn default_scene() -> Scene {
        Scene::parse(super::DEFAULT_SCENE, "builtin:default.toml", None)
            .expect("the embedded default scene is valid")
    }

    pub(crate) fn invalid(
        &self,
        path: impl Into<String>,
        message: impl Into<String>,
    ) -> SceneError {
        SceneError::Invalid {
            scene: self.source.clone(),
            path: path.into(),
            message: message.into(),
        }
    }

    /// A name within [`MAX_NAME_BYTES`].
    fn check_name_length(&self, path: &str, name: &str) -> Result<(), SceneError> {
        let max = super::limits::MAX_NAME_BYTES;
        if name.len() > max {
            return Err(self.invalid(
                path,
                format!(
                    "is {} bytes, over the limit of {max} bytes (a client could not ask for it)",
                    name.len()
                ),
            ));
        }
        Ok(())
    }

    /// Range and consistency checks; each error names the key's path.
    fn validate(&self) -> Result<(), SceneError> {
        if self.name.trim().is_empty() {
            return Err(self.invalid("name", "must not be empty"));
        }
        self.check_name_length("name", &self.name)?;
        if self.mesh.file.trim().is_empty() {
            return Err(self.invalid(
                "mesh.file",
                "is empty: name a .msh file (beside the scene, or builtin:liver.msh)",
            ));
        }
        self.check_positive("mesh.scale", self.mesh.scale)?;
        if self.mesh.refine > MAX_REFINE {
            return Err(self.invalid(
                "mesh.refine",
                format!("{} is outside [0, {MAX_REFINE}]", self.mesh.refine),
            ));
        }
        self.check_material(
            "material",
            Some(self.material.young_modulus),
            Some(self.material.poisson_ratio),
            Some(self.material.density),
        )?;
        let mut tags = std::collections::HashSet::new();
        for (k, r) in self.material.regions.iter().enumerate() {
            let path = format!("material.regions[{k}]");
            if !tags.insert(r.tag) {
                return Err(self.invalid(
                    format!("{path}.tag"),
                    format!("tag {} is given twice", r.tag),
                ));
            }
            self.check_material(&path, r.young_modulus, r.poisson_ratio, r.density)?;
        }
        for (k, b) in self.fixed.boxes.iter().enumerate() {
            let path = format!("fixed.boxes[{k}]");
            if b.min
                .iter()
                .chain(&b.max)
                .any(|v| !within(*v, MAX_COORDINATE_M))
            {
                return Err(self.invalid(
                    path,
                    format!("corners must be finite and within ±{MAX_COORDINATE_M} m"),
                ));
            }
            if (0..3).any(|a| b.min[a] > b.max[a]) {
                return Err(self.invalid(path, "min must not exceed max on any axis"));
            }
        }
        if self.gravity.iter().any(|g| !within(*g, MAX_GRAVITY)) {
            return Err(self.invalid(
                "gravity",
                format!("each component must be finite and within ±{MAX_GRAVITY} m/s²"),
            ));
        }
        let m = &self.mechanics;
        if !(m.rate_hz.is_finite() && (1.0..=10_000.0).contains(&m.rate_hz)) {
            return Err(self.invalid(
                "mechanics.rate_hz",
                format!("{} is outside [1, 10000] Hz", m.rate_hz),
            ));
        }
        if !(m.damping.is_finite() && (0.0..=MAX_DAMPING).contains(&m.damping)) {
            return Err(self.invalid(
                "mechanics.damping",
                format!("{} is outside [0, {MAX_DAMPING}] (1/s)", m.damping),
            ));
        }
        if !(m.cg_tolerance.is_finite()
            && m.cg_tolerance >= MIN_CG_TOLERANCE
            && m.cg_tolerance < 1.0)
        {
            return Err(self.invalid(
                "mechanics.cg_tolerance",
                format!(
                    "{} is outside [{MIN_CG_TOLERANCE:e}, 1): below {MIN_CG_TOLERANCE:e} \
                     the residual is round-off that CG cannot reduce",
                    m.cg_tolerance
                ),
            ));
        }
        if !(1..=MAX_CG_ITERATIONS).contains(&m.cg_max_iterations) {
            return Err(self.invalid(
                "mechanics.cg_max_iterations",
                format!(
                    "{} is outside [1, {MAX_CG_ITERATIONS}] (the work of a tick is bounded)",
                    m.cg_max_iterations
                ),
            ));
        }
        if !(1..=MAX_THREADS).contains(&m.threads) {
            return Err(self.invalid(
                "mechanics.threads",
                format!("{} is outside [1, {MAX_THREADS}]", m.threads),
            ));
        }
        if self.instruments.len() > MAX_INSTRUMENTS {
            return Err(self.invalid(
                "instruments",
                format!(
                    "{} instruments; a scene has at most {}",
                    self.instruments.len(),
                    MAX_INSTRUMENTS
                ),
            ));
        }
        let mut names = std::collections::HashSet::new();
        for (k, ins) in self.instruments.iter().enumerate() {
            let path = format!("instruments[{k}]");
            if ins.name.trim().is_empty() {
                return Err(self.invalid(format!("{path}.name"), "must not be empty"));
            }
            self.check_name_length(&format!("{path}.name"), &ins.name)?;
            if !names.insert(ins.name.as_str()) {
                return Err(self.invalid(
                    format!("{path}.name"),
                    format!("instrument `{}` is declared twice", ins.name),
                ));
            }
            self.check_range(
                &format!("{path}.radius"),
                ins.radius,
                (0.0, MAX_INSTRUMENT_RADIUS_M),
                "m",
            )?;
            self.check_range(
                &format!("{path}.length"),
                ins.length,
                (0.0, MAX_INSTRUMENT_LENGTH_M),
                "m",
            )?;
            if ins.radius >= ins.length {
                return Err(
                    self.invalid(format!("{path}.radius"), "must be smaller than the length")
                );
            }
            if ins.trocar.iter().any(|v| !within(*v, MAX_COORDINATE_M)) {
                return Err(self.invalid(
                    format!("{path}.trocar"),
                    format!("must be finite and within ±{MAX_COORDINATE_M} m"),
                ));
            }
            if !(ins.friction.is_finite() && (0.0..=MAX_FRICTION).contains(&ins.friction)) {
                return Err(self.invalid(
                    format!("{path}.friction"),
                    format!("{} is outside [0, {MAX_FRICTION}]", ins.friction),
                ));
            }
        }
        Ok(())
    }

    fn check_positive(&self, path: &str, v: f64) -> Result<(), SceneError> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(self.invalid(path, format!("{v} must be finite and > 0")))
        }
    }

    /// `v` finite, `lo < v ≤ hi`.
    fn check_range(
        &self,
        path: &str,
        v: f64,
        (lo, hi): (f64, f64),
        unit: &str,
    ) -> Result<(), SceneError> {
        if v.is_finite() && lo < v && v <= hi {
            Ok(())
        } else {
            Err(self.invalid(path, format!("{v} is outside ({lo}, {hi}] {unit}")))
        }
    }

    fn check_material(
        &self,
        path: &str,
        e: Option<f64>,
        nu: Option<f64>,
        rho: Option<f64>,
    ) -> Result<(), SceneError> {
        if let Some(e) = e
            && !(e.is_finite() && (MIN_YOUNG_MODULUS_PA..=MAX_YOUNG_MODULUS_PA).contains(&e))
        {
            return Err(self.invalid(
                format!("{path}.young_modulus"),
                format!("{e} is outside [{MIN_YOUNG_MODULUS_PA}, {MAX_YOUNG_MODULUS_PA:e}] Pa"),
            ));
        }
        if let Some(nu) = nu {
            // ν = 0.5 is incompressible: λ = Eν/((1+ν)(1−2ν)) is infinite, and it grows
            // without bound on the way there (see MAX_POISSON_RATIO). Negative
            // (auxetic) ratios are not tissue.
            if !(nu.is_finite() && (0.0..=MAX_POISSON_RATIO).contains(&nu)) {
                return Err(self.invalid(
                    format!("{path}.poisson_ratio"),
                    format!("{nu} is outside [0, {MAX_POISSON_RATIO}]"),
                ));
            }
        }
        if let Some(rho) = rho
            && !(rho.is_finite() && (MIN_DENSITY..=MAX_DENSITY).contains(&rho))
        {
            return Err(self.invalid(
                format!("{path}.density"),
                format!("{rho} is outside [{MIN_DENSITY}, {MAX_DENSITY:e}] kg/m³"),
            ));
        }
        Ok(())
    }
}

/// `v` finite and `|v| ≤ bound`.
fn within(v: f64, bound: f64) -> bool {
    v.is_finite() && v.abs() <= bound
}
