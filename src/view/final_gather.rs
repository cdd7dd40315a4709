//! The viewer's "Final gather" toggle: while the camera rests on a converged solution, the
//! view fills in with final-gathered pixels (`gathered`) over the rasterised picture,
//! coarse to fine (blocks of 8, 4, 2, then single pixels) and from the centre out, on a
//! thread of its own. Any camera move, resize, exposure change or new solution drops the
//! gathered picture at once and starts again once the camera rests; the UI never waits
//! for it, and the status line says how far it has come.

use super::camera::Camera;
use super::gathered::{GatheredView, SurfaceTextures, encode};
use super::render::Display;
use crate::solver::gather::Gatherer;
use eframe::egui;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long the camera must rest before gathering starts.
pub(super) const REST: Duration = Duration::from_millis(300);

/// The error the viewer's gather allows per node: 4× `probe`'s default. Measured on the
/// Cornell box's 299 bench points against the path tracer: 1.36 % RMS against 1.16 %,
/// with a 160 × 120 picture gathered 3.9× faster (2.0 s against 7.7 s on 2 cores).
pub(super) const VIEW_GATHER_ERROR: f32 = 0.002;

/// Block sizes of the passes, coarse to fine.
const LEVELS: [u32; 4] = [8, 4, 2, 1];

/// What a gathered picture depends on: when any of it changes, the picture is stale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Key {
    pub camera: Camera,
    pub size: [u32; 2],
    pub ev: f32,
    pub tonemap: super::render::ToneMap,
    pub textures: bool,
    /// The snapshot version the gatherer was made from.
    pub version: u64,
}

/// The picture so far, shared with the gathering thread.
pub(super) struct Picture {
    pub size: [u32; 2],
    /// sRGB-encoded RGBA, alpha 0 where nothing is gathered yet.
    pub rgba: Vec<u8>,
    /// Block size of the pass under way (1: the last).
    pub level: u32,
    /// Fraction of all passes' blocks done.
    pub done: f32,
    pub finished: bool,
    /// Seconds the passes have taken so far.
    pub seconds: f64,
    /// Changed since the UI last uploaded it.
    pub changed: bool,
}

/// One gathering pass over the view, running on its own thread until done or cancelled.
pub(super) struct Pass {
    pub key: Key,
    cancel: Arc<AtomicBool>,
    pub picture: Arc<Mutex<Picture>>,
}

impl Pass {
    /// Starts gathering `key`'s view of `gatherer` on a new thread, with the scene's
    /// `textures` when the display shows them.
    pub(super) fn start(
        key: Key,
        gatherer: Arc<Gatherer>,
        display: Display,
        textures: SurfaceTextures,
    ) -> Pass {
        let [w, h] = key.size;
        let picture = Arc::new(Mutex::new(Picture {
            size: key.size,
            rgba: vec![0; (w * h * 4) as usize],
            level: LEVELS[0],
            done: 0.0,
            finished: false,
            seconds: 0.0,
            changed: false,
        }));
        let cancel = Arc::new(AtomicBool::new(false));
        let (shared, stop) = (picture.clone(), cancel.clone());
        std::thread::spawn(move || {
            let view = GatheredView {
                gatherer: &gatherer,
                camera: &key.camera,
                size: key.size,
                samples: 1,
                display,
                textures: &textures,
            };
            fill(&view, &shared, &stop);
        });
        Pass {
            key,
            cancel,
            picture,
        }
    }
}

impl Drop for Pass {
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

/// Runs the passes of [`LEVELS`] over `view` into `picture` until done or `cancel`.
fn fill(view: &GatheredView, picture: &Mutex<Picture>, cancel: &AtomicBool) {
    let start = Instant::now();
    let [w, h] = view.size;
    let total: usize = LEVELS
        .iter()
        .map(|&b| (w.div_ceil(b) * h.div_ceil(b)) as usize)
        .sum();
    let mut done = 0usize;
    for level in LEVELS {
        // Blocks of this level, nearest the centre first.
        let (bw, bh) = (w.div_ceil(level), h.div_ceil(level));
        let mut blocks: Vec<(u32, u32)> =
            (0..bh).flat_map(|y| (0..bw).map(move |x| (x, y))).collect();
        let centre = (w as f32 / 2.0, h as f32 / 2.0);
        blocks.sort_by(|a, b| {
            let d = |(x, y): (u32, u32)| {
                let (px, py) = ((x * level) as f32 - centre.0, (y * level) as f32 - centre.1);
                px * px + py * py
            };
            d(*a).total_cmp(&d(*b))
        });
        for chunk in blocks.chunks(256) {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            let colours: Vec<[u8; 4]> = chunk
                .par_iter()
                .map(|&(bx, by)| {
                    let x = (bx * level + level / 2).min(w - 1);
                    let y = (by * level + level / 2).min(h - 1);
                    encode(view.pixel(x, y))
                })
                .collect();
            done += chunk.len();
            let mut p = picture.lock().unwrap_or_else(|e| e.into_inner());
            for (&(bx, by), c) in chunk.iter().zip(&colours) {
                for y in by * level..((by + 1) * level).min(h) {
                    for x in bx * level..((bx + 1) * level).min(w) {
                        let i = ((y * w + x) * 4) as usize;
                        p.rgba[i..i + 4].copy_from_slice(c);
                    }
                }
            }
            p.level = level;
            p.done = done as f32 / total as f32;
            p.seconds = start.elapsed().as_secs_f64();
            p.changed = true;
        }
    }
    let mut p = picture.lock().unwrap_or_else(|e| e.into_inner());
    p.finished = true;
    p.seconds = start.elapsed().as_secs_f64();
    p.changed = true;
}

/// The picture as an egui image (for the texture over the 3D view).
pub(super) fn colour_image(p: &Picture) -> egui::ColorImage {
    egui::ColorImage::from_rgba_unmultiplied([p.size[0] as usize, p.size[1] as usize], &p.rgba)
}
