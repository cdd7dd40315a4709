//! `radiosity`: diffuse global illumination for glTF scenes.
//!
//! The pipeline, bottom up (ARCHITECTURE.md has the picture and the module table):
//! [`geometry`], [`cancel`] and [`files`] (shared helpers) → [`accel`] (BVH, shadow rays) → [`scene`]
//! (the CPU truth, opened from glTF or `builtin:`) → [`light`] (lights outside the
//! element system) → [`mesh`] (patches, elements, discontinuity lines, reconstruction) →
//! [`solver`] (form factors, methods, `Solver::step`) and [`reference`] (an unbiased path
//! tracer, the truth they are measured against) → [`export`], [`pipeline`] (scene →
//! mesh → BVH → solver) → [`worker`] (the solver thread) → `view` (the viewer, cargo
//! feature `viewer`) and [`cli`]. Each layer uses only the layers before it
//! (`tests/layers.rs` checks this).

pub mod accel;
pub mod analytic;
pub mod cancel;
pub mod cli;
pub mod export;
pub mod exposure;
pub mod files;
pub mod geometry;
pub mod light;
pub mod mesh;
pub mod pipeline;
pub mod reference;
pub mod scene;
pub mod solver;
#[cfg(feature = "viewer")]
pub mod view;
pub mod worker;
