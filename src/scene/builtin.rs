//! Built-in scenes: the Cornell box from its published measurements and the analytic
//! scenes the tests need (white-furnace enclosures whose answer is known in closed form).
//!
//! Cornell box geometry: "Cornell Box Data", Cornell University Program of Computer
//! Graphics, <https://www.graphics.cornell.edu/online/box/data.html> (millimetres; converted
//! to metres here). Reflectances are the RGB values commonly used for its measured spectra
//! (white 0.725/0.71/0.68, red 0.63/0.065/0.05, green 0.14/0.45/0.091, as in Bitterli's
//! rendering resources and Mitsuba's `cornell_box()`); the light's radiance (17, 12, 4)
//! W/(m²·sr) is the same source's RGB rendering of the measured lamp.

use super::{Material, Object, Scene};
use glam::{DMat4, DVec3, Vec3};

/// Names accepted by [`by_name`] (`builtin:NAME` on the command line).
pub const NAMES: &[&str] = &["cornell", "furnace-cube", "furnace-sphere", "penumbra"];

/// A built-in scene by name: `cornell` (the default scene), `furnace-cube` and
/// `furnace-sphere` (ρ = 0.5, E = 1), `penumbra` (see [`penumbra`]).
pub fn by_name(name: &str) -> Option<Scene> {
    match name {
        "cornell" | "cornell-box" => Some(cornell_box()),
        "furnace-cube" => Some(furnace_box(DVec3::ZERO, DVec3::ONE, 0.5, 1.0)),
        "furnace-sphere" => Some(furnace_sphere(DVec3::ZERO, 1.0, 3, 0.5, 1.0)),
        "penumbra" => Some(penumbra()),
        _ => None,
    }
}

const WHITE: Vec3 = Vec3::new(0.725, 0.71, 0.68);
const RED: Vec3 = Vec3::new(0.63, 0.065, 0.05);
const GREEN: Vec3 = Vec3::new(0.14, 0.45, 0.091);

/// Appends a planar quad (given in millimetres, any winding) to `object`, wound so that its
/// normal points towards `toward` (or away from it when `outward`).
fn push_quad(object: &mut Object, mm: [[f64; 3]; 4], material: u32, toward: DVec3, outward: bool) {
    let p: Vec<DVec3> = mm.iter().map(|v| DVec3::from(*v) * 1e-3).collect();
    let n = (p[1] - p[0]).cross(p[2] - p[0]);
    let centre = (p[0] + p[1] + p[2] + p[3]) / 4.0;
    let faces_toward = n.dot(toward - centre) > 0.0;
    let order: [usize; 4] = if faces_toward != outward {
        [0, 1, 2, 3]
    } else {
        [3, 2, 1, 0]
    };
    let base = object.positions.len() as u32;
    for &i in &order {
        object.positions.push(p[i].as_vec3());
    }
    object.triangles.push([base, base + 1, base + 2]);
    object.triangles.push([base, base + 2, base + 3]);
    object.triangle_material.extend([material, material]);
}

/// The Cornell box (metres): open front at z = 0, camera conventionally at (0.278, 0.273,
/// −0.8) looking along +z; red wall at x ≈ 0.55 (left in that view), green at x = 0.
pub fn cornell_box() -> Scene {
    let materials = vec![
        Material::diffuse("white", WHITE),
        Material::diffuse("red", RED),
        Material::diffuse("green", GREEN),
        Material::emitter("light", Vec3::splat(0.78), Vec3::new(17.0, 12.0, 4.0)),
    ];
    let inside = DVec3::new(0.278, 0.274, 0.280);
    let mut room = Object {
        name: "room".into(),
        world_from_local: DMat4::IDENTITY,
        ..Default::default()
    };
    let floor = [
        [552.8, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 559.2],
        [549.6, 0.0, 559.2],
    ];
    let ceiling = [
        [556.0, 548.8, 0.0],
        [556.0, 548.8, 559.2],
        [0.0, 548.8, 559.2],
        [0.0, 548.8, 0.0],
    ];
    let back = [
        [549.6, 0.0, 559.2],
        [0.0, 0.0, 559.2],
        [0.0, 548.8, 559.2],
        [556.0, 548.8, 559.2],
    ];
    let green = [
        [0.0, 0.0, 559.2],
        [0.0, 0.0, 0.0],
        [0.0, 548.8, 0.0],
        [0.0, 548.8, 559.2],
    ];
    let red = [
        [552.8, 0.0, 0.0],
        [549.6, 0.0, 559.2],
        [556.0, 548.8, 559.2],
        [556.0, 548.8, 0.0],
    ];
    push_quad(&mut room, floor, 0, inside, false);
    push_quad(&mut room, ceiling, 0, inside, false);
    push_quad(&mut room, back, 0, inside, false);
    push_quad(&mut room, green, 2, inside, false);
    push_quad(&mut room, red, 1, inside, false);

    // The published light lies in the ceiling plane; it is lowered by 0.1 mm so that it is
    // unambiguously in front of the ceiling (the usual fix, e.g. in pbrt's scene files).
    let mut light = Object {
        name: "light".into(),
        world_from_local: DMat4::IDENTITY,
        ..Default::default()
    };
    let lamp = [
        [343.0, 548.7, 227.0],
        [343.0, 548.7, 332.0],
        [213.0, 548.7, 332.0],
        [213.0, 548.7, 227.0],
    ];
    push_quad(&mut light, lamp, 3, DVec3::new(0.278, 0.0, 0.28), false);

    let short_block: [[[f64; 3]; 4]; 5] = [
        [
            [130.0, 165.0, 65.0],
            [82.0, 165.0, 225.0],
            [240.0, 165.0, 272.0],
            [290.0, 165.0, 114.0],
        ],
        [
            [290.0, 0.0, 114.0],
            [290.0, 165.0, 114.0],
            [240.0, 165.0, 272.0],
            [240.0, 0.0, 272.0],
        ],
        [
            [130.0, 0.0, 65.0],
            [130.0, 165.0, 65.0],
            [290.0, 165.0, 114.0],
            [290.0, 0.0, 114.0],
        ],
        [
            [82.0, 0.0, 225.0],
            [82.0, 165.0, 225.0],
            [130.0, 165.0, 65.0],
            [130.0, 0.0, 65.0],
        ],
        [
            [240.0, 0.0, 272.0],
            [240.0, 165.0, 272.0],
            [82.0, 165.0, 225.0],
            [82.0, 0.0, 225.0],
        ],
    ];
    let tall_block: [[[f64; 3]; 4]; 5] = [
        [
            [423.0, 330.0, 247.0],
            [265.0, 330.0, 296.0],
            [314.0, 330.0, 456.0],
            [472.0, 330.0, 406.0],
        ],
        [
            [423.0, 0.0, 247.0],
            [423.0, 330.0, 247.0],
            [472.0, 330.0, 406.0],
            [472.0, 0.0, 406.0],
        ],
        [
            [472.0, 0.0, 406.0],
            [472.0, 330.0, 406.0],
            [314.0, 330.0, 456.0],
            [314.0, 0.0, 456.0],
        ],
        [
            [314.0, 0.0, 456.0],
            [314.0, 330.0, 456.0],
            [265.0, 330.0, 296.0],
            [265.0, 0.0, 296.0],
        ],
        [
            [265.0, 0.0, 296.0],
            [265.0, 330.0, 296.0],
            [423.0, 330.0, 247.0],
            [423.0, 0.0, 247.0],
        ],
    ];
    let mut objects = vec![room, light];
    for (name, faces, centre) in [
        ("short block", short_block, DVec3::new(0.186, 0.0825, 0.168)),
        ("tall block", tall_block, DVec3::new(0.3685, 0.165, 0.351)),
    ] {
        let mut block = Object {
            name: name.into(),
            world_from_local: DMat4::IDENTITY,
            ..Default::default()
        };
        for face in faces {
            push_quad(&mut block, face, 0, centre, true);
        }
        objects.push(block);
    }
    Scene {
        name: "builtin:cornell".into(),
        objects,
        materials,
        ..Default::default()
    }
}

/// A closed box of size `size` with its minimum corner at `origin`, normals inward, every
/// face reflecting `rho` and emitting radiosity `emitted` (so radiance `emitted / π`).
/// White furnace: in a closed enclosure Σ_j F_ij = 1, so B = E / (1 − ρ) exactly.
pub fn furnace_box(origin: DVec3, size: DVec3, rho: f32, emitted: f32) -> Scene {
    furnace_box_split(origin, size, rho, emitted, None)
}

/// [`furnace_box`] whose faces are each cut into a sliver triangle of aspect ratio about
/// `1 / sliver` along one edge plus two ordinary triangles, to test sliver handling.
pub fn furnace_box_slivers(
    origin: DVec3,
    size: DVec3,
    rho: f32,
    emitted: f32,
    sliver: f64,
) -> Scene {
    furnace_box_split(origin, size, rho, emitted, Some(sliver))
}

fn furnace_box_split(
    origin: DVec3,
    size: DVec3,
    rho: f32,
    emitted: f32,
    sliver: Option<f64>,
) -> Scene {
    let material = Material::emitter(
        "furnace",
        Vec3::splat(rho),
        Vec3::splat(emitted / std::f32::consts::PI),
    );
    // Geometry is built in a local frame around the box's centre and placed by the
    // transform, as a real file would, so precision far from the origin is tested too.
    let half = size * 0.5;
    let mut object = Object {
        name: "box".into(),
        world_from_local: DMat4::from_translation(origin + half),
        ..Default::default()
    };
    let c = |sx: f64, sy: f64, sz: f64| DVec3::new(sx * half.x, sy * half.y, sz * half.z);
    // Each face as (corner, edge u, edge v) with u × v pointing inward.
    let faces = [
        (c(-1., -1., -1.), DVec3::Z * size.z, DVec3::X * size.x), // y = min, normal +y
        (c(-1., 1., -1.), DVec3::X * size.x, DVec3::Z * size.z),  // y = max, normal −y
        (c(-1., -1., -1.), DVec3::X * size.x, DVec3::Y * size.y), // z = min, normal +z
        (c(-1., -1., 1.), DVec3::Y * size.y, DVec3::X * size.x),  // z = max, normal −z
        (c(-1., -1., -1.), DVec3::Y * size.y, DVec3::Z * size.z), // x = min, normal +x
        (c(1., -1., -1.), DVec3::Z * size.z, DVec3::Y * size.y),  // x = max, normal −x
    ];
    for (p, u, v) in faces {
        let base = object.positions.len() as u32;
        let mut push = |q: DVec3| {
            object.positions.push(q.as_vec3());
        };
        match sliver {
            None => {
                for q in [p, p + u, p + u + v, p + v] {
                    push(q);
                }
                object.triangles.push([base, base + 1, base + 2]);
                object.triangles.push([base, base + 2, base + 3]);
            }
            Some(s) => {
                // p, p+u, p+u+s·v is the sliver; the rest of the face is a quad.
                for q in [p, p + u, p + u + v * s, p + u + v, p + v] {
                    push(q);
                }
                object.triangles.push([base, base + 1, base + 2]);
                object.triangles.push([base, base + 2, base + 3]);
                object.triangles.push([base, base + 3, base + 4]);
            }
        }
    }
    object.triangle_material = vec![0; object.triangles.len()];
    Scene {
        name: "builtin:furnace-box".into(),
        objects: vec![object],
        materials: vec![material],
        ..Default::default()
    }
}

/// A closed icosphere of radius `radius` (subdivided `level` times), normals inward, every
/// triangle reflecting `rho` and emitting radiosity `emitted`. Being a closed convex
/// polyhedron, B = E / (1 − ρ) holds exactly for its discretisation too.
pub fn furnace_sphere(centre: DVec3, radius: f64, level: u32, rho: f32, emitted: f32) -> Scene {
    let (positions, mut triangles) = icosphere(level);
    for t in &mut triangles {
        t.swap(1, 2); // icosphere faces outward; the furnace needs them inward
    }
    let object = Object {
        name: "sphere".into(),
        positions: positions.iter().map(|p| (*p * radius).as_vec3()).collect(),
        triangle_material: vec![0; triangles.len()],
        triangles,
        world_from_local: DMat4::from_translation(centre),
        ..Default::default()
    };
    Scene {
        name: "builtin:furnace-sphere".into(),
        objects: vec![object],
        materials: vec![Material::emitter(
            "furnace",
            Vec3::splat(rho),
            Vec3::splat(emitted / std::f32::consts::PI),
        )],
        ..Default::default()
    }
}

/// Unit icosphere with outward counter-clockwise faces.
pub fn icosphere(level: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| DVec3::from(*p).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::BTreeMap::new();
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<DVec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                (v.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

/// Writes the built-in Cornell box as a glTF 2.0 file (embedded buffer), so users can open
/// the same scene in other tools. Used to produce `assets/cornell_box.gltf`.
pub fn cornell_box_gltf() -> String {
    super::gltf::write_gltf(&cornell_box())
}

/// The `penumbra` scene's dimensions (metres): a floor square of half-width
/// `PENUMBRA_FLOOR` at y = 0 (ρ = [`PENUMBRA_RHO`]); a square emitter of half-width
/// `PENUMBRA_LIGHT` at height `PENUMBRA_LIGHT_Y` facing down (radiance 1, black); a black
/// square occluder of half-width `PENUMBRA_OCCLUDER` at height `PENUMBRA_OCCLUDER_Y`,
/// centred at (`PENUMBRA_OCCLUDER_X`, `PENUMBRA_OCCLUDER_Z`).
pub const PENUMBRA_FLOOR: f64 = 1.0;
pub const PENUMBRA_LIGHT: f64 = 0.25;
pub const PENUMBRA_LIGHT_Y: f64 = 1.0;
pub const PENUMBRA_OCCLUDER: f64 = 0.2;
pub const PENUMBRA_OCCLUDER_Y: f64 = 0.2;
pub const PENUMBRA_OCCLUDER_X: f64 = 0.1;
pub const PENUMBRA_OCCLUDER_Z: f64 = 0.05;
pub const PENUMBRA_RHO: f32 = 0.5;

/// An analytic shadow: a square emitter over a floor with a floating square occluder,
/// all parallel. The emitter and the occluder are black, so the light the floor reflects
/// never comes back: B_floor(x) = ρ · π L · F(x → the part of the emitter the occluder
/// leaves visible), which is exact by polygon clipping (`radiosity::analytic`): umbra,
/// penumbra and full light with a closed form everywhere.
pub fn penumbra() -> Scene {
    let square = |o: &mut Object, c: DVec3, half: f64, material: u32, up: bool| {
        let base = o.positions.len() as u32;
        let (x0, x1, z0, z1) = (c.x - half, c.x + half, c.z - half, c.z + half);
        for (x, z) in [(x0, z0), (x0, z1), (x1, z1), (x1, z0)] {
            o.positions.push(DVec3::new(x, c.y, z).as_vec3());
        }
        // Counter-clockwise seen from +y as listed; reversed to face down.
        if up {
            o.triangles.push([base, base + 1, base + 2]);
            o.triangles.push([base, base + 2, base + 3]);
        } else {
            o.triangles.push([base, base + 2, base + 1]);
            o.triangles.push([base, base + 3, base + 2]);
        }
        o.triangle_material.extend([material, material]);
    };
    let object = |name: &str| Object {
        name: name.into(),
        world_from_local: DMat4::IDENTITY,
        ..Default::default()
    };
    let mut floor = object("floor");
    square(&mut floor, DVec3::ZERO, PENUMBRA_FLOOR, 0, true);
    let mut light = object("light");
    square(
        &mut light,
        DVec3::new(0.0, PENUMBRA_LIGHT_Y, 0.0),
        PENUMBRA_LIGHT,
        1,
        false,
    );
    let mut occluder = object("occluder");
    square(
        &mut occluder,
        DVec3::new(
            PENUMBRA_OCCLUDER_X,
            PENUMBRA_OCCLUDER_Y,
            PENUMBRA_OCCLUDER_Z,
        ),
        PENUMBRA_OCCLUDER,
        2,
        false,
    );
    let mut black = Material::diffuse("black occluder", Vec3::ZERO);
    black.double_sided = true;
    Scene {
        name: "builtin:penumbra".into(),
        objects: vec![floor, light, occluder],
        materials: vec![
            Material::diffuse("floor", Vec3::splat(PENUMBRA_RHO)),
            Material::emitter("light", Vec3::ZERO, Vec3::ONE),
            black,
        ],
        lights: Vec::new(),
        environment: None,
        images: Vec::new(),
        warnings: Vec::new(),
    }
}
