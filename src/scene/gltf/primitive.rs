//! One glTF mesh primitive into the scene: its positions (decoded once per accessor), its
//! triangles (every topology, degenerate and non-finite ones dropped with a warning),
//! morph targets at the node's weights, and its material.

use super::tint::TexJob;
use super::{Loader, accessor, json, material};
use crate::scene::Object;
use glam::{DVec3, Vec2, Vec3};
use serde_json::Value;
use std::rc::Rc;

impl Loader<'_> {
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
    pub(super) fn add_primitive(
        &mut self,
        object: &mut Object,
        prim: &Value,
        weights: &[f64],
    ) -> Result<(), String> {
        let root = self.root;
        // The back side of a double-sided surface in our baked export: the material's
        // `doubleSided` makes it again from the front side.
        let side = prim
            .get("extras")
            .and_then(|e| e.get("radiosity"))
            .and_then(|r| r.get("side"));
        if side.and_then(Value::as_str) == Some("back") {
            return Ok(());
        }
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
        let baked = self.infos[material as usize].baked;
        if let Some(ci) = json::index(attrs, "COLOR_0")?.filter(|_| !baked) {
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
                    // In the corners' order of `object.triangles` (swapped for mirrored
                    // transforms, above), so that each corner keeps its own coordinates.
                    let corners = |t: &[u32; 3]| {
                        let mut c = t.map(uv);
                        if mirrored {
                            c.swap(1, 2);
                        }
                        c
                    };
                    uv_sets.push((set, kept.iter().map(corners).collect()));
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
