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
mod source;
mod texture;
mod tint;
mod warnings;
mod write;

pub use write::write_gltf;

use crate::scene::{Light, Material, Object, Scene};
use glam::{DMat4, DQuat, DVec3, Vec2, Vec3};
use material::MatInfo;
use serde_json::Value;
use source::Buffers;
use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::rc::Rc;
use tint::TexJob;
use warnings::Warnings;

/// Why a glTF file could not be loaded. Its `Display` is one line: the file, then the problem.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file itself could not be read.
    #[error("{path}: cannot read the file: {source}")]
    Io {
        /// The scene file.
        path: String,
        /// The operating system's error.
        source: std::io::Error,
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
    /// The loader itself failed (a bug): the panic was caught and turned into this error.
    #[error("{path}: internal error while loading (a bug in the loader): {message}")]
    Internal {
        /// The scene file.
        path: String,
        /// The panic message.
        message: String,
    },
}

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
    let shown = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| LoadError::Io {
        path: shown.clone(),
        source,
    })?;
    let dir = path.parent().unwrap_or(Path::new(""));
    match std::panic::catch_unwind(AssertUnwindSafe(|| load_bytes(&shown, dir, &bytes))) {
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

fn load_bytes(shown: &str, dir: &Path, bytes: &[u8]) -> Result<Scene, LoadError> {
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
        positions: HashMap::new(),
        missing_uv_warned: Vec::new(),
    };
    loader.run().map_err(invalid)?;
    let Loader {
        mut warn,
        materials,
        objects,
        lights,
        buffers,
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
    /// Decoded POSITION accessors (meshes instanced by several nodes are read once).
    positions: HashMap<usize, Rc<Vec<Vec3>>>,
    /// Materials already warned about for a missing TEXCOORD set.
    missing_uv_warned: Vec<usize>,
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
        tint::apply_textures(
            self.root,
            &self.buffers,
            self.dir,
            &self.jobs,
            &self.infos,
            &self.materials,
            &mut self.objects,
            &mut self.warn,
        )
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

    /// POSITION accessor `i`, decoded once.
    fn positions(&mut self, i: usize) -> Result<Rc<Vec<Vec3>>, String> {
        if let Some(p) = self.positions.get(&i) {
            return Ok(p.clone());
        }
        let a = accessor::read(self.root, &self.buffers, i, &["VEC3"])?;
        let p: Rc<Vec<Vec3>> = Rc::new(
            (0..a.count())
                .map(|k| {
                    let e = a.element(k);
                    Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32)
                })
                .collect(),
        );
        self.positions.insert(i, p.clone());
        Ok(p)
    }

    /// Appends one primitive's valid triangles to `object`.
    fn add_primitive(
        &mut self,
        object: &mut Object,
        prim: &Value,
        weights: &[f64],
    ) -> Result<(), String> {
        let root = self.root;
        let mode = json::uint(prim, "mode")?.unwrap_or(4);
        match mode {
            4..=6 => {}
            0..=3 => {
                self.warn.skipped_points_lines += 1;
                return Ok(());
            }
            m => return Err(format!("unknown primitive mode {m}")),
        }
        let attrs = prim
            .get("attributes")
            .filter(|a| a.is_object())
            .ok_or("no `attributes`")?;
        let pos_index = json::index(attrs, "POSITION")?.ok_or("no POSITION attribute")?;
        let mut positions = self.positions(pos_index)?;
        if weights.iter().any(|&w| w != 0.0) {
            positions = Rc::new(self.morph(prim, &positions, weights)?);
        }
        let n = positions.len();
        let indices = match json::index(prim, "indices")? {
            Some(i) => Some(accessor::read_indices(root, &self.buffers, i)?),
            None => None,
        };
        let vertex = |k: usize| -> u32 {
            match &indices {
                Some(ix) => ix[k],
                None => k as u32,
            }
        };
        let len = indices.as_ref().map_or(n, Vec::len);
        // §3.7.2.1: strips p_i = {v_i, v_(i+(1+i%2)), v_(i+(2−i%2))}; fans p_i = {v_(i+1), v_(i+2), v_0}.
        let corners: Vec<[u32; 3]> = match mode {
            4 => (0..len / 3)
                .map(|t| [vertex(3 * t), vertex(3 * t + 1), vertex(3 * t + 2)])
                .collect(),
            5 => (0..len.saturating_sub(2))
                .map(|i| [vertex(i), vertex(i + 1 + i % 2), vertex(i + 2 - i % 2)])
                .collect(),
            _ => (0..len.saturating_sub(2))
                .map(|i| [vertex(i + 1), vertex(i + 2), vertex(0)])
                .collect(),
        };

        let world = object.world_from_local;
        let world_pos: Vec<DVec3> = positions
            .iter()
            .map(|p| world.transform_point3(p.as_dvec3()))
            .collect();
        let mut kept: Vec<[u32; 3]> = Vec::with_capacity(corners.len());
        for t in corners {
            if t.iter().any(|&v| v as usize >= n) {
                self.warn.out_of_range += 1;
                continue;
            }
            let [a, b, c] = t.map(|v| world_pos[v as usize]);
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                self.warn.non_finite += 1;
                continue;
            }
            // Zero area: the cross product vanishes relative to the longest edge. 1e-12 is
            // far above f64 rounding of f32 inputs (~1e-16) and far below any real sliver.
            let cross = (b - a).cross(c - a).length();
            let longest = (b - a)
                .length_squared()
                .max((c - a).length_squared())
                .max((c - b).length_squared());
            let has_area = cross > 1e-12 * longest; // false for NaN too
            if !has_area {
                self.warn.degenerate += 1;
                continue;
            }
            kept.push(t);
        }
        if kept.is_empty() {
            return Ok(());
        }

        let material = self.material_for(prim);
        let mirrored = world.determinant() < 0.0;
        let first = object.triangles.len();
        let mut remap = vec![u32::MAX; n];
        for t in &kept {
            let mut out = [0u32; 3];
            for (o, &v) in out.iter_mut().zip(t) {
                let r = &mut remap[v as usize];
                if *r == u32::MAX {
                    *r = object.positions.len() as u32;
                    object.positions.push(positions[v as usize]);
                }
                *o = *r;
            }
            if mirrored {
                out.swap(1, 2); // keep counter-clockwise in world space
            }
            object.triangles.push(out);
            object.triangle_material.push(material);
        }

        // COLOR_0 multiplies the base colour (§3.7.2.1); its mean over a linear triangle is
        // the mean of its corners.
        if let Some(ci) = json::index(attrs, "COLOR_0")? {
            match accessor::read(root, &self.buffers, ci, &["VEC3", "VEC4"]) {
                Ok(colors) if colors.count() >= n => {
                    let tint = &mut object.reflectance_tint;
                    tint.resize(object.triangles.len(), Vec3::ONE);
                    for (k, t) in kept.iter().enumerate() {
                        let mut sum = Vec3::ZERO;
                        for &v in t {
                            let e = colors.element(v as usize);
                            sum += Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32);
                        }
                        tint[first + k] = (sum / 3.0).clamp(Vec3::ZERO, Vec3::ONE);
                    }
                }
                Ok(_) => self.warn.line(format!(
                    "accessors[{ci}]: COLOR_0 has fewer elements than POSITION; ignored"
                )),
                Err(e) => self.warn.line(format!("COLOR_0: {e}; ignored")),
            }
        }

        // Texture coordinates for the texture pass.
        let info = &self.infos[material as usize];
        let mut sets: Vec<u32> = [&info.base_tex, &info.emissive_tex]
            .into_iter()
            .flatten()
            .map(|t| t.tex_coord)
            .collect();
        sets.dedup();
        let mut uv_sets = Vec::new();
        for set in sets {
            let key = format!("TEXCOORD_{set}");
            let uvs = match json::index(attrs, &key)? {
                Some(a) => accessor::read(root, &self.buffers, a, &["VEC2"]).and_then(|a| {
                    (a.count() >= n)
                        .then_some(a)
                        .ok_or_else(|| "fewer elements than POSITION".into())
                }),
                None => Err("missing".to_string()),
            };
            match uvs {
                Ok(a) => {
                    let uv = |v: u32| {
                        let e = a.element(v as usize);
                        Vec2::new(e[0] as f32, e[1] as f32)
                    };
                    uv_sets.push((set, kept.iter().map(|t| t.map(uv)).collect()));
                }
                Err(e) => {
                    if !self.missing_uv_warned.contains(&(material as usize)) {
                        self.missing_uv_warned.push(material as usize);
                        let name = &self.materials[material as usize].name;
                        self.warn.line(format!("{key} of a primitive using material '{name}': {e}; its texture is ignored there"));
                    }
                }
            }
        }
        if !uv_sets.is_empty() {
            self.jobs.push(TexJob {
                object: self.objects.len(),
                first,
                material: material as usize,
                uv_sets,
            });
        }
        Ok(())
    }

    /// Positions with the morph targets' POSITION displacements added, weighted.
    fn morph(&mut self, prim: &Value, base: &[Vec3], weights: &[f64]) -> Result<Vec<Vec3>, String> {
        let mut out = base.to_vec();
        for (target, &w) in json::array(prim, "targets")?.iter().zip(weights) {
            if w == 0.0 {
                continue;
            }
            if let Some(a) = json::index(target, "POSITION")? {
                let d = accessor::read(self.root, &self.buffers, a, &["VEC3"])?;
                for (k, p) in out.iter_mut().enumerate().take(d.count()) {
                    let e = d.element(k);
                    *p += Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32) * w as f32;
                }
            }
        }
        Ok(out)
    }

    /// The material index of a primitive (the glTF default material when it has none).
    fn material_for(&mut self, prim: &Value) -> u32 {
        match json::index(prim, "material") {
            Ok(Some(m)) if m < self.infos.len() => return m as u32,
            Ok(Some(m)) => self.warn.line(format!(
                "material {m} does not exist; the default material is used"
            )),
            Ok(None) => {}
            Err(e) => self
                .warn
                .line(format!("primitive {e}; the default material is used")),
        }
        *self.default_material.get_or_insert_with(|| {
            let (m, info) = material::default_material();
            self.materials.push(m);
            self.infos.push(info);
            (self.materials.len() - 1) as u32
        })
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
