//! `radiosity`: diffuse global illumination for glTF scenes.
//!
//! The pipeline (DESIGN.md §1): [`scene`] (CPU truth) → [`mesh`] (patches and elements) →
//! [`accel`] (BVH, occlusion) → [`solver`] (form factors, methods, `Solver::step`). The core
//! has no GUI or GPU dependency; `cli` drives it from the command line and [`worker`] from
//! a thread for the viewer ([`view`]).

pub mod accel;
pub mod analytic;
pub mod cli;
pub mod export;
pub mod files;
pub mod geometry;
pub mod light;
pub mod mesh;
pub mod pipeline;
pub mod scene;
pub mod solver;
#[cfg(feature = "viewer")]
pub mod view;
pub mod worker;
