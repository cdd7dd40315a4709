//! An unbiased Monte Carlo reference: the radiosity B at given surface points, by path
//! tracing the scene itself (no mesh), with a standard error for each value.
//!
//! What it is for: the truth the radiosity solvers are measured against
//! (`radiosity reference`, and `bench`'s per-point errors). It solves the same problem —
//! the same surfaces, reflectances, emitters, punctual lights, sun and sky, one-sided
//! surfaces, transmittance — but its error is only noise, which it estimates: each point's
//! samples are independent, so the standard error of their mean is s/√N, s their sample
//! standard deviation (the estimator itself is in [`path`]).
//!
//! How it runs: in passes. Each pass adds a batch of samples to every point whose standard
//! error is still above `rel_error` × max(B, 2 % of the mean B over the points) in some
//! channel (the floor keeps black points from asking for infinite samples, and matches the
//! per-point error metric's floor); batches double up to 16k samples. Points run in
//! parallel; each point's samples are drawn from a stream of (seed, point, sample index),
//! so the values do not depend on the thread count.
//!
//! A point reached only by rare paths can show no light at all in its first samples, and
//! then its sample variance is zero too: s/√N alone would call it black and done. So the
//! standard error is never taken below 3 h/N, h the light one sample brings when it finds
//! some ([`hit_scale`]): by the rule of three, N samples without a hit put the chance of a
//! hit under 3/N (at 95 %), so the mean under 3 h/N. A point is called black only once
//! that bound is within the target. On the sky-lit Sponza, 16 of the 88 points that the
//! plain rule had left black after 768 samples had light (a floor under a gallery:
//! 0.0008 W/m², a hit in about a thousand samples).
//!
//! Where it is weak: the noise is largest where light arrives along rare paths (deep
//! umbrae lit only by interreflection, points a hair from a small bright emitter); it says
//! so by its standard error rather than by being wrong.

mod path;
pub mod probes;
mod surfaces;

pub use surfaces::Surfaces;

use crate::accel::Bvh;
use crate::cancel::{Cancelled, check};
use crate::light::ExternalLight;
use crate::scene::{Environment, Scene};
use glam::{DVec3, Vec3};
use path::{Rng, Tracer};
use rayon::prelude::*;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// How long and how precisely to sample.
#[derive(Clone, Debug)]
pub struct ReferenceSettings {
    /// Target 1-sigma standard error relative to max(B, 2 % of the mean B), every channel.
    pub rel_error: f64,
    /// Stop after this long even if some points are not there yet.
    pub time_limit: Option<Duration>,
    pub seed: u64,
    /// Fewest samples per point before its error estimate is trusted.
    pub min_samples: u64,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        ReferenceSettings {
            rel_error: 0.01,
            time_limit: None,
            seed: 1,
            // Below a few hundred samples the sample variance itself is too noisy to stop
            // on (a point lit by rare paths can show zero variance in its first samples).
            min_samples: 512,
        }
    }
}

/// The estimate at one point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Mean radiosity B, W/m² per channel.
    pub value: DVec3,
    /// 1-sigma standard error of `value`, per channel.
    pub std_error: DVec3,
    pub samples: u64,
}

/// Running sums of one point's samples.
#[derive(Clone, Copy, Default)]
struct Sums {
    sum: DVec3,
    squares: DVec3,
    n: u64,
    /// Samples that brought some light.
    hits: u64,
}

impl Sums {
    /// The mean and its standard error, s/√N but at least 3 `hit`/N (see the module's doc).
    fn estimate(&self, hit: DVec3) -> Estimate {
        if self.n == 0 {
            return Estimate::default();
        }
        let n = self.n as f64;
        let mean = self.sum / n;
        let var = if self.n > 1 {
            ((self.squares - self.sum * mean) / (n - 1.0)).max(DVec3::ZERO)
        } else {
            DVec3::ZERO
        };
        Estimate {
            value: mean,
            std_error: (var / n).map(f64::sqrt).max(RULE_OF_THREE * hit / n),
            samples: self.n,
        }
    }
}

/// Hits whose absence over N samples bounds a point's hit rate at 3/N with 95 %
/// confidence (the rule of three; Hanley & Lippman-Hand, JAMA 249, 1983).
const RULE_OF_THREE: f64 = 3.0;

/// The light, per channel, that one sample brings when it brings any: the mean of the
/// samples with light over every point so far, and at least what a path that escapes to
/// the sky brings (π L_sky times the largest reflectance at the points: a path's weight
/// never exceeds one). Zero where nothing has been seen and there is no sky.
fn hit_scale(sums: &[Sums], sky_hit: DVec3) -> DVec3 {
    let (sum, hits) = sums
        .iter()
        .fold((DVec3::ZERO, 0u64), |(s, h), x| (s + x.sum, h + x.hits));
    let seen = if hits > 0 {
        sum / hits as f64
    } else {
        DVec3::ZERO
    };
    seen.max(sky_hit)
}

/// A query point located on the scene: frame position, side normal, triangle.
type Located = Option<(Vec3, Vec3, u32)>;

/// Progress after each pass: points done, points in all, the largest relative error left.
pub type Progress<'a> = &'a (dyn Fn(usize, usize, f64) + Sync);

/// The reference radiosity at world `points` with outward normals (the side asked about):
/// one [`Estimate`] per point, in order; zero with zero error where no surface faces that
/// way. Stops when every point meets `settings.rel_error`, at the time limit, or with
/// `Err(Cancelled)` when `cancel` is raised.
pub fn estimate(
    scene: &Scene,
    points: &[(DVec3, DVec3)],
    settings: &ReferenceSettings,
    progress: Progress<'_>,
    cancel: &AtomicBool,
) -> Result<Vec<Estimate>, Cancelled> {
    let start = Instant::now();
    let surfaces = Surfaces::new(scene);
    let bvh = Bvh::build(&surfaces.triangles, &surfaces.transmittance);
    let (lights, sky) = split_sky(scene);
    let tracer = Tracer {
        surfaces: &surfaces,
        bvh: &bvh,
        lights,
        sky,
    };
    let located: Vec<Located> = points
        .par_iter()
        .map(|(p, n)| {
            surfaces
                .locate(surfaces.frame.to_local(*p), n.as_vec3())
                .map(|(t, q, side)| (q, side, t))
        })
        .collect();
    let sky_hit = located
        .iter()
        .flatten()
        .map(|&(_, _, own)| surfaces.reflectance[own as usize].as_dvec3())
        .fold(DVec3::ZERO, DVec3::max)
        * std::f64::consts::PI
        * sky.as_dvec3();
    let mut sums = vec![Sums::default(); points.len()];
    let mut done: Vec<bool> = located.iter().map(Option::is_none).collect();
    let mut batch = 256u64;
    loop {
        check(cancel)?;
        let todo: Vec<usize> = (0..points.len()).filter(|&i| !done[i]).collect();
        if todo.is_empty() {
            break;
        }
        let added: Vec<Sums> = todo
            .par_iter()
            .map(|&i| {
                let (x, n, own) = located[i].expect("only located points are sampled");
                let mut s = sums[i];
                for k in s.n..s.n + batch {
                    let mut rng = Rng::new(settings.seed, i as u64, k);
                    let b = tracer.radiosity(x, n, own, &mut rng);
                    let b = if b.is_finite() { b } else { DVec3::ZERO };
                    s.sum += b;
                    s.squares += b * b;
                    s.hits += u64::from(b.max_element() > 0.0);
                }
                s.n += batch;
                s
            })
            .collect();
        for (&i, s) in todo.iter().zip(added) {
            sums[i] = s;
        }
        let hit = hit_scale(&sums, sky_hit);
        let estimates: Vec<Estimate> = sums.iter().map(|s| s.estimate(hit)).collect();
        let floor = floor(&estimates, &located, hit);
        let mut worst = 0.0f64;
        for (i, e) in estimates.iter().enumerate() {
            if located[i].is_none() {
                continue;
            }
            let rel = relative_error(e, floor);
            worst = worst.max(rel);
            done[i] = e.samples >= settings.min_samples && rel <= settings.rel_error;
        }
        let finished = done.iter().filter(|d| **d).count();
        progress(finished, points.len(), worst);
        if settings.time_limit.is_some_and(|t| start.elapsed() >= t) {
            break;
        }
        batch = (batch * 2).min(1 << 14);
    }
    let hit = hit_scale(&sums, sky_hit);
    Ok(sums.iter().map(|s| s.estimate(hit)).collect())
}

/// The punctual lights and sun (for next-event estimation) apart from the sky radiance
/// (met by escaping paths). A scene opened with no light already has the default sky
/// ([`Scene::ensure_light`]).
fn split_sky(scene: &Scene) -> (ExternalLight, Vec3) {
    let env = scene.environment.clone();
    let sky = env.as_ref().map_or(Vec3::ZERO, |e| e.sky);
    let lights = ExternalLight {
        lights: scene.lights.clone(),
        environment: env.and_then(|e| {
            e.sun.map(|sun| Environment {
                sky: Vec3::ZERO,
                sun: Some(sun),
            })
        }),
    };
    (lights, sky)
}

/// 2 % of the mean value over the located points, per channel: the floor of the relative
/// error's denominator. In a channel where no point has any light yet, 2 % of the light
/// one `hit` brings, the only scale there is (a set of points all sealed off from the
/// light is called black once 3 h/N is within the target of it).
fn floor(estimates: &[Estimate], located: &[Located], hit: DVec3) -> DVec3 {
    let (sum, count) = estimates
        .iter()
        .zip(located)
        .filter(|(_, l)| l.is_some())
        .fold((DVec3::ZERO, 0usize), |(s, c), (e, _)| (s + e.value, c + 1));
    if count == 0 {
        return DVec3::ZERO;
    }
    let mean = sum / count as f64;
    DVec3::select(mean.cmpgt(DVec3::ZERO), mean, hit) * 0.02
}

/// The largest channel's standard error over max(value, floor).
fn relative_error(e: &Estimate, floor: DVec3) -> f64 {
    let denom = e.value.max(floor);
    (0..3)
        .map(|c| {
            if denom[c] > 0.0 {
                e.std_error[c] / denom[c]
            } else if e.std_error[c] > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}
