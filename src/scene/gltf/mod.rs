//! glTF 2.0 import ([`load`]) and export ([`write_gltf`]).
//!
//! The importer reads `.gltf` (JSON with external or `data:` buffers and images) and `.glb`
//! (JSON + BIN chunk) files. It walks the JSON itself (`serde_json::Value`, see
//! `json.rs`) rather than through the `gltf` crate: that crate's typed schema rejects valid
//! files (a scene without `nodes`, integers written as `1.0`, `KHR_mesh_quantization`,
//! textures whose image is missing) and panics on some invalid ones, and a viewer must
//! neither refuse the former nor crash on the latter. Every accessor read is
//! bounds-checked (`accessor.rs`); the whole load still runs under `catch_unwind`, so a bug
//! becomes a [`LoadError`] rather than a crash.
//!
//! What comes out (units: ARCHITECTURE.md, "Units and conventions"):
//! - one [`Object`] per (node, mesh) of the default scene (or scene 0, or every root node
//!   when there are no scenes), all its primitives merged, `world_from_local` composed in
//!   f64 from the node hierarchy (TRS or `matrix`);
//! - **winding:** `Object::triangles` are counter-clockwise seen from the front *in world
//!   space*. When a node's transform mirrors (negative determinant) the loader swaps two
//!   indices of every triangle, so downstream code never has to look at
//!   [`Object::mirrors`] to get the front side right;
//! - triangles from modes 4, 5 and 6 (strips and fans unrolled per §3.7.2.1); points and
//!   lines are skipped. Triangles with out-of-range indices, non-finite vertices or zero
//!   area (in world space) are dropped, each kind counted in one warning;
//! - materials per `material.rs`; per-triangle means of base-colour and emissive textures
//!   (and of `COLOR_0`) in `Object::reflectance_tint` / `emission_tint`, alpha coverage in
//!   `Object::transmittance` (`texture.rs`);
//! - `KHR_lights_punctual` lights placed by their nodes (`light.rs`).
//!
//! Every recovered problem is one line in `Scene::warnings`, starting with the file path.
//! Nothing here adds a default light: the caller decides (`Scene::ensure_light`).

mod accessor;
mod json;
mod light;
mod material;
mod primitive;
mod source;
mod texture;
mod tint;
mod warnings;
mod write;

pub use write::write_gltf;

use crate::scene::{Light, Material, Object, Scene};
use glam::{DMat4, DQuat, DVec3, Vec3};
use material::MatInfo;
use serde_json::Value;
use source::Buffers;
use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use tint::TexJob;
use warnings::Warnings;

/// Why a glTF file could not be loaded. Its `Display` is one line: the file, then the problem.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file itself could not be read.
    #[error("{path}: cannot read the file: {error}")]
    Io {
        /// The scene file.
        path: String,
        /// The operating system's error, in the message rather than as the error's
        /// `source`, so that a chain printed with `{:#}` names it once.
        error: std::io::Error,
    },
    /// The file is not valid glTF 2.0 in a way that cannot be worked around (broken
    /// container or JSON, a buffer that cannot be loaded, …).
    #[error("{path}: {message}")]
    Invalid {
        /// The scene file.
        path: String,
        /// What is wrong, one line.
        message: String,
    },
    /// The file is valid but needs something this loader does not do (an extension in
    /// `extensionsRequired`, such as Draco mesh compression).
    #[error("{path}: {message}")]
    Unsupported {
        /// The scene file.
        path: String,
        /// What is missing, one line.
        message: String,
    },
    /// The load was stopped by its cancel flag (another scene was opened).
    #[error("{path}: loading cancelled")]
    Cancelled {
        /// The scene file.
        path: String,
    },
    /// The loader itself failed (a bug): the panic was caught and turned into this error.
    #[error("{path}: internal error while loading (a bug in the loader): {message}")]
    Internal {
        /// The scene file.
        path: String,
        /// The panic message.
        message: String,
    },
}

/// The error text of a stage stopped by the cancel flag (turned into
/// [`LoadError::Cancelled`] by [`load_cancellable`]).
const CANCELLED: &str = "cancelled";

/// Extensions whose presence in `extensionsRequired` we can honour.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "KHR_materials_transmission",
    "KHR_mesh_quantization",
];

/// Loads a glTF 2.0 scene (`.gltf` or `.glb`) from `path`.
///
/// Recoverable problems become lines in `Scene::warnings`; unrecoverable ones a
/// [`LoadError`] naming the file. Never panics on bad input.
pub fn load(path: &Path) -> Result<Scene, LoadError> {
    load_cancellable(path, crate::cancel::never())
}

/// [`load`], stopping with [`LoadError::Cancelled`] soon after `cancel` is raised: it is
/// checked between nodes, between images and between the primitives of the texture pass.
pub fn load_cancellable(path: &Path, cancel: &AtomicBool) -> Result<Scene, LoadError> {
    let shown = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|error| LoadError::Io {
        path: shown.clone(),
        error,
    })?;
    let dir = path.parent().unwrap_or(Path::new(""));
    match std::panic::catch_unwind(AssertUnwindSafe(|| load_bytes(&shown, dir, &bytes, cancel))) {
        // Whatever failed after the flag was raised was stopped by it.
        Ok(Err(_)) if cancel.load(Ordering::Relaxed) => Err(LoadError::Cancelled { path: shown }),
        Ok(result) => result,
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(LoadError::Internal {
                path: shown,
                message: one_line(&message),
            })
        }
    }
}

/// Collapses a message to one line.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

fn load_bytes(
    shown: &str,
    dir: &Path,
    bytes: &[u8],
    cancel: &AtomicBool,
) -> Result<Scene, LoadError> {
    let invalid = |message: String| LoadError::Invalid {
        path: shown.to_string(),
        message: one_line(&message),
    };
    let unsupported = |message: String| LoadError::Unsupported {
        path: shown.to_string(),
        message: one_line(&message),
    };
    let mut warnings = Warnings::new(shown);
    let container = source::split(bytes).map_err(invalid)?;
    for n in container.notes {
        warnings.line(n);
    }
    let root: Value = serde_json::from_slice(container.json)
        .map_err(|e| invalid(format!("not a glTF file: the JSON does not parse ({e})")))?;
    if !root.is_object() {
        return Err(invalid("not a glTF file: the JSON is not an object".into()));
    }
    let version = root
        .get("asset")
        .and_then(|a| a.get("version"))
        .and_then(Value::as_str)
        .ok_or_else(|| invalid("not a glTF 2.0 file: no `asset.version`".into()))?;
    if version.split('.').next() != Some("2") {
        return Err(unsupported(format!(
            "glTF version {version} is not supported (only 2.x)"
        )));
    }
    if let Some(min) = root["asset"].get("minVersion").and_then(Value::as_str)
        && min != "2.0"
    {
        return Err(unsupported(format!(
            "the file needs glTF {min}; only 2.0 is supported"
        )));
    }
    for ext in json::array(&root, "extensionsRequired").map_err(invalid)? {
        let ext = ext.as_str().unwrap_or("?");
        if ext == "KHR_draco_mesh_compression" {
            return Err(unsupported(
                "Draco-compressed meshes (KHR_draco_mesh_compression) are not supported".into(),
            ));
        }
        if !SUPPORTED_REQUIRED.contains(&ext) {
            return Err(unsupported(format!(
                "the file requires the extension {ext}, which is not supported"
            )));
        }
    }
    // The top-level arrays must be arrays; a wrong type there is not worth guessing around.
    for key in [
        "nodes",
        "meshes",
        "accessors",
        "bufferViews",
        "buffers",
        "materials",
        "scenes",
    ] {
        json::array(&root, key).map_err(invalid)?;
    }
    let buffers_def = json::array(&root, "buffers").unwrap_or(&[]);
    let buffers = Buffers::new(dir, buffers_def, container.bin.map(<[u8]>::to_vec));
    let mut loader = Loader {
        root: &root,
        dir,
        buffers,
        warn: warnings,
        materials: Vec::new(),
        infos: Vec::new(),
        default_material: None,
        objects: Vec::new(),
        lights: Vec::new(),
        light_defs: light::definitions(&root),
        jobs: Vec::new(),
        images: Vec::new(),
        positions: HashMap::new(),
        missing_uv_warned: Vec::new(),
        cancel,
    };
    loader.run().map_err(invalid)?;
    let Loader {
        mut warn,
        materials,
        objects,
        lights,
        buffers,
        images,
        ..
    } = loader;
    for n in buffers.notes.take() {
        warn.line(n);
    }
    Ok(Scene {
        name: shown.to_string(),
        objects,
        materials,
        lights,
        environment: None,
        images,
        warnings: warn.finish(),
    })
}

/// The state of one load: the parsed file, what has been built so far, and the warnings.
struct Loader<'a> {
    root: &'a Value,
    dir: &'a Path,
    buffers: Buffers<'a>,
    warn: Warnings,
    materials: Vec<Material>,
    infos: Vec<MatInfo>,
    default_material: Option<u32>,
    objects: Vec<Object>,
    lights: Vec<Light>,
    light_defs: Vec<Result<light::LightDef, String>>,
    jobs: Vec<TexJob>,
    /// The texture pass's decoded images (for the display).
    images: Vec<std::sync::Arc<crate::scene::Image>>,
    /// Decoded POSITION accessors (meshes instanced by several nodes are read once).
    positions: HashMap<usize, Rc<Vec<Vec3>>>,
    /// Materials already warned about for a missing TEXCOORD set.
    missing_uv_warned: Vec<usize>,
    /// Raised to stop the load.
    cancel: &'a AtomicBool,
}

impl Loader<'_> {
    fn run(&mut self) -> Result<(), String> {
        let root = self.root;
        for (i, def) in json::array(root, "materials")?.iter().enumerate() {
            let (m, info) = material::convert(root, i, def, &mut self.warn);
            self.materials.push(m);
            self.infos.push(info);
        }
        // Dangling texture → image references are reported even when no material uses them.
        let images = json::array(root, "images").map(<[Value]>::len).unwrap_or(0);
        for (t, tex) in json::array(root, "textures")
            .unwrap_or(&[])
            .iter()
            .enumerate()
        {
            if let Ok(Some(i)) = json::index(tex, "source")
                && i >= images
            {
                self.warn.line(format!("textures[{t}]: its image {i} does not exist (the file has {images} images); untextured"));
            }
        }
        self.traverse()?;
        self.images = tint::apply_textures(
            self.root,
            &self.buffers,
            self.dir,
            &self.jobs,
            &self.infos,
            &mut self.materials,
            &mut self.objects,
            &mut self.warn,
            self.cancel,
        )?;
        Ok(())
    }

    /// The root nodes to draw: the `scene`'s, else scene 0's, else every parentless node.
    fn root_nodes(&mut self) -> Result<Vec<usize>, String> {
        let root = self.root;
        let scenes = json::array(root, "scenes")?;
        let nodes = json::array(root, "nodes")?;
        let chosen = match json::index(root, "scene") {
            Ok(Some(s)) if s < scenes.len() => Some(s),
            Ok(Some(s)) => {
                if !scenes.is_empty() {
                    self.warn
                        .line(format!("`scene` {s} does not exist; using scene 0"));
                }
                (!scenes.is_empty()).then_some(0)
            }
            Ok(None) => (!scenes.is_empty()).then_some(0),
            Err(e) => {
                self.warn.line(format!("{e}; using scene 0"));
                (!scenes.is_empty()).then_some(0)
            }
        };
        if let Some(s) = chosen {
            let list = json::array(&scenes[s], "nodes").map_err(|e| format!("scenes[{s}]: {e}"))?;
            let mut out = Vec::new();
            for v in list {
                match json::as_uint(v) {
                    Some(n) => out.push(n as usize),
                    None => self.warn.line(format!(
                        "scenes[{s}].nodes: {} is not a node index",
                        json::describe(v)
                    )),
                }
            }
            return Ok(out);
        }
        // No scenes: draw every node that is nobody's child.
        let mut is_child = vec![false; nodes.len()];
        for n in nodes {
            for c in json::array(n, "children").unwrap_or(&[]) {
                if let Some(c) = json::as_uint(c).filter(|&c| (c as usize) < nodes.len()) {
                    is_child[c as usize] = true;
                }
            }
        }
        Ok((0..nodes.len()).filter(|&n| !is_child[n]).collect())
    }

    /// Walks the node tree depth-first without recursion; each node is visited at most
    /// once, so cycles and shared children cannot hang or duplicate anything.
    fn traverse(&mut self) -> Result<(), String> {
        let root = self.root;
        let nodes = json::array(root, "nodes")?;
        let mut visited = vec![false; nodes.len()];
        let mut stack: Vec<(usize, DMat4)> = self
            .root_nodes()?
            .into_iter()
            .rev()
            .map(|n| (n, DMat4::IDENTITY))
            .collect();
        while let Some((n, parent)) = stack.pop() {
            if self.cancel.load(Ordering::Relaxed) {
                return Err(CANCELLED.into());
            }
            let Some(node) = nodes.get(n) else {
                self.warn.line(format!("node {n} does not exist; skipped"));
                continue;
            };
            if visited[n] {
                self.warn.revisited_nodes += 1;
                continue;
            }
            visited[n] = true;
            let local = match node_transform(node) {
                Ok(m) => m,
                Err(e) => {
                    self.warn
                        .line(format!("nodes[{n}]: {e}; node and its children skipped"));
                    continue;
                }
            };
            let world = parent * local;
            if node.get("skin").is_some() {
                self.warn.skinned += 1;
            }
            match json::index(node, "mesh") {
                Ok(Some(m)) => self.add_mesh(n, node, m, world)?,
                Ok(None) => {}
                Err(e) => self.warn.line(format!("nodes[{n}]: {e}; mesh skipped")),
            }
            if let Some(ext) = json::extension(node, "KHR_lights_punctual") {
                self.add_light(n, ext, world);
            }
            match json::array(node, "children") {
                Ok(children) => {
                    for c in children.iter().rev() {
                        match json::as_uint(c) {
                            Some(c) => stack.push((c as usize, world)),
                            None => self.warn.line(format!(
                                "nodes[{n}].children: {} is not a node index",
                                json::describe(c)
                            )),
                        }
                    }
                }
                Err(e) => self.warn.line(format!("nodes[{n}]: {e}; children skipped")),
            }
        }
        Ok(())
    }

    fn add_light(&mut self, n: usize, ext: &Value, world: DMat4) {
        let at = format!("nodes[{n}].KHR_lights_punctual");
        let l = match json::index(ext, "light") {
            Ok(Some(l)) => l,
            Ok(None) => return self.warn.line(format!("{at}: no `light`; skipped")),
            Err(e) => return self.warn.line(format!("{at}: {e}; skipped")),
        };
        match self.light_defs.get(l) {
            None => self
                .warn
                .line(format!("{at}: light {l} does not exist; skipped")),
            Some(Err(e)) => self
                .warn
                .line(format!("KHR_lights_punctual light {l}: {e}; skipped")),
            Some(Ok(def)) => match light::place(def, world) {
                Ok(light) => self.lights.push(light),
                Err(e) => self.warn.line(format!("{at}: light {l} skipped: {e}")),
            },
        }
    }

    fn add_mesh(&mut self, n: usize, node: &Value, m: usize, world: DMat4) -> Result<(), String> {
        let root = self.root;
        let Some(mesh) = json::array(root, "meshes")?.get(m) else {
            self.warn
                .line(format!("nodes[{n}]: mesh {m} does not exist; skipped"));
            return Ok(());
        };
        let name = json::name(node)
            .or_else(|| json::name(mesh))
            .map(str::to_string)
            .unwrap_or_else(|| format!("mesh {m}"));
        let weights: Vec<f64> = [node, mesh]
            .iter()
            .find_map(|v| v.get("weights").and_then(Value::as_array))
            .map(|w| w.iter().map(|x| x.as_f64().unwrap_or(0.0)).collect())
            .unwrap_or_default();
        let mut object = Object {
            name,
            world_from_local: world,
            ..Default::default()
        };
        let primitives = match json::array(mesh, "primitives") {
            Ok(p) => p,
            Err(e) => {
                self.warn.line(format!("meshes[{m}]: {e}; skipped"));
                return Ok(());
            }
        };
        for (p, prim) in primitives.iter().enumerate() {
            let result = self.add_primitive(&mut object, prim, &weights);
            if let Some(fatal) = self.buffers.failure() {
                return Err(fatal);
            }
            if let Err(e) = result {
                self.warn.line(format!(
                    "meshes[{m}].primitives[{p}]: {e}; primitive skipped"
                ));
            }
        }
        if !object.triangles.is_empty() {
            self.objects.push(object);
        }
        Ok(())
    }
}

/// A node's local transform: `matrix` (column-major) if given, else T · R · S (§3.5.3).
fn node_transform(node: &Value) -> Result<DMat4, String> {
    let m = if let Some(m) = json::numbers::<16>(node, "matrix")? {
        DMat4::from_cols_array(&m)
    } else {
        let t = json::numbers::<3>(node, "translation")?.unwrap_or([0.0; 3]);
        let r = json::numbers::<4>(node, "rotation")?.unwrap_or([0.0, 0.0, 0.0, 1.0]);
        let s = json::numbers::<3>(node, "scale")?.unwrap_or([1.0; 3]);
        let q = DQuat::from_array(r);
        let len = q.length();
        if !(len.is_finite() && len > 0.0) {
            return Err(format!("rotation {r:?} is not a valid quaternion"));
        }
        DMat4::from_scale_rotation_translation(DVec3::from(s), q / len, DVec3::from(t))
    };
    if !m.is_finite() {
        return Err("transform is not finite".into());
    }
    Ok(m)
}
