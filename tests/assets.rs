//! `assets/cornell_box.gltf` is the built-in Cornell box written as glTF. This test keeps the
//! file in step with the code (a regeneration check: set UPDATE_ASSETS=1 to rewrite it) and,
//! independently, checks it against the published dimensions: the file must load back to
//! the box's extents (Cornell "Cornell Box Data": 0–556 × 0–548.8 × 0–559.2 mm) and the
//! five walls, two five-faced blocks and the light, as quads (32 triangles).

use radiosity::scene::{builtin, gltf};
use std::path::Path;

#[test]
fn cornell_box_asset_is_current_and_matches_the_published_box() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell_box.gltf");
    let text = builtin::cornell_box_gltf();
    if std::env::var_os("UPDATE_ASSETS").is_some() {
        std::fs::write(&path, &text).unwrap();
    }
    let on_disk = std::fs::read_to_string(&path)
        .expect("assets/cornell_box.gltf (UPDATE_ASSETS=1 cargo test --test assets)");
    assert!(
        on_disk == text,
        "assets/cornell_box.gltf is stale: run UPDATE_ASSETS=1 cargo test --test assets"
    );
    let scene = gltf::load(&path).unwrap();
    assert_eq!(scene.triangle_count(), 32);
    let (lo, hi) = scene.bounds().unwrap();
    // Published extents in metres; 1e-6 m covers the f32 storage of positions.
    for (got, want) in [
        (lo.x, 0.0),
        (lo.y, 0.0),
        (lo.z, 0.0),
        (hi.x, 0.556),
        (hi.y, 0.5488),
        (hi.z, 0.5592),
    ] {
        assert!((got - want).abs() < 1e-6, "extent {got} vs {want}");
    }
    assert!(scene.has_light());
}
