//! Look-ahead prefetching after iWalk (Correa, Klosowski and Silva 2002, §4): after each frame
//! of a walkthrough, predict the next cameras from the linear and angular speed of the last two
//! rendered ones, trace a coarse grid of probe rays from each prediction against what is
//! resident (with the frame's LOD metric, so a probe wants what the frame would), and hand the
//! blocks the probes wanted and did not find to the asynchronous cache as prefetch requests: a
//! queue of its own, served only when no demand fetch waits and only up to a per-frame budget
//! of decoded bytes ([`crate::cache::asynchronous::AsyncOptions::prefetch_bytes`]).
//!
//! The probes see resident blocks without marking them used (a guess must not keep a block
//! from eviction) and never wait: a probe ray stops where a block is missing, as a frame's ray
//! does, so a predicted view is fetched level by level, one level per frame.

use std::sync::{Arc, Mutex, PoisonError};

use rayon::prelude::*;
use rustc_hash::FxHashMap as HashMap;

use super::{AsyncCache, BlockCache, CacheStats, Data, Wish};
use crate::blocks::{TreeletData, TriangleData};
use crate::camera::{cross, dot, length, normalize, sub, Camera};
use crate::scene::Scene;
use crate::traverse::{Memo, Tracer};

/// Frames ahead predicted by default: the blocks for camera i + 2 are fetched during frame
/// i + 1 and are resident for frame i + 2, where a demand fetch would show them at i + 3.
pub const DEFAULT_FRAMES_AHEAD: u32 = 2;

/// Rows of probe rays per predicted camera by default (the columns follow the aspect ratio).
pub const DEFAULT_PROBE_ROWS: u32 = 48;

/// The most rows of probe rays.
pub const MAX_PROBE_ROWS: u32 = 1024;

/// The camera `k` frames after `current`, moving on with the linear speed of the eye and the
/// angular speed of the view direction between `previous` and `current` (and the change of
/// field of view). The look-at point stays at the current distance along the turned view
/// direction; up turns with it. None when the prediction is not a valid camera (a field of
/// view leaving (0°, 180°), non-finite numbers).
pub fn predict(previous: &Camera, current: &Camera, k: f64) -> Option<Camera> {
    let velocity = sub(current.eye, previous.eye);
    let eye = [0, 1, 2].map(|i| current.eye[i] + k * velocity[i]);
    let f0 = sub(previous.look_at, previous.eye);
    let f1 = sub(current.look_at, current.eye);
    let distance = length(f1);
    if length(f0) == 0.0 || distance == 0.0 {
        return None;
    }
    let (f0, f1) = (normalize(f0), normalize(f1));
    let axis = cross(f0, f1);
    let sin = length(axis);
    let angle = sin.atan2(dot(f0, f1));
    // No turn, or a half turn whose axis is undefined: the view direction keeps still.
    let (forward, up) = if sin > 1e-12 {
        let axis = axis.map(|c| c / sin);
        (
            rotate(f1, axis, k * angle),
            rotate(current.up, axis, k * angle),
        )
    } else {
        (f1, current.up)
    };
    let camera = Camera {
        eye,
        look_at: [0, 1, 2].map(|i| eye[i] + distance * forward[i]),
        up,
        fov_y: current.fov_y + k * (current.fov_y - previous.fov_y),
        ..*current
    };
    camera.frame().ok().map(|_| camera)
}

/// `v` turned by `angle` radians around the unit `axis` (Rodrigues).
fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
    let (s, c) = angle.sin_cos();
    let kxv = cross(axis, v);
    let kv = dot(axis, v);
    [0, 1, 2].map(|i| v[i] * c + kxv[i] * s + axis[i] * kv * (1.0 - c))
}

/// What one look-ahead step did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LookAheadStep {
    /// Predicted cameras probed (0 until two frames have been rendered).
    pub cameras: u32,
    /// Probe rays traced from the predicted cameras, over all of them.
    pub probe_rays: u64,
    /// Blocks handed to the cache as prefetch requests (within the per-frame budget).
    pub queued: u64,
}

/// The look-ahead of a walkthrough: call [`LookAhead::after_frame`] after each frame's step
/// between frames.
#[derive(Clone, Debug)]
pub struct LookAhead {
    previous: Option<Camera>,
    frames_ahead: u32,
    probe_rows: u32,
}

impl LookAhead {
    /// Predicts `frames_ahead` cameras (1 ..) after each frame and traces `probe_rows` rows of
    /// probe rays (1 ..= [`MAX_PROBE_ROWS`]) from each.
    pub fn new(frames_ahead: u32, probe_rows: u32) -> LookAhead {
        LookAhead {
            previous: None,
            frames_ahead: frames_ahead.max(1),
            probe_rows: probe_rows.clamp(1, MAX_PROBE_ROWS),
        }
    }

    /// Frame `camera` was rendered at PoE `poe` (and the cache's step after it ran): predicts
    /// the next cameras, probes them and queues what they want in `cache`.
    pub fn after_frame(
        &mut self,
        scene: &Scene,
        cache: &AsyncCache,
        camera: &Camera,
        poe: f32,
    ) -> LookAheadStep {
        let Some(previous) = self.previous.replace(*camera) else {
            return LookAheadStep::default();
        };
        let probe = Probe::new(cache);
        let mut step = LookAheadStep::default();
        for k in 1..=self.frames_ahead {
            let Some(predicted) = predict(&previous, camera, f64::from(k)) else {
                continue;
            };
            step.cameras += 1;
            step.probe_rays += probe.trace(scene, &predicted, poe, self.probe_rows);
        }
        step.queued = cache.prefetch(probe.into_wanted()) as u64;
        step
    }
}

/// The asynchronous cache as probe rays see it: resident blocks without marking them used, and
/// the requests gathered here instead of queued as demand.
struct Probe<'a> {
    cache: &'a AsyncCache,
    wanted: Mutex<HashMap<u32, Wish>>,
}

impl<'a> Probe<'a> {
    fn new(cache: &'a AsyncCache) -> Probe<'a> {
        Probe {
            cache,
            wanted: Mutex::default(),
        }
    }

    /// Traces `rows` rows of rays, evenly spread over the image of `camera`, with the LOD
    /// metric of its full resolution at `poe`. Returns the number of rays.
    fn trace(&self, scene: &Scene, camera: &Camera, poe: f32, rows: u32) -> u64 {
        let Ok(frame) = camera.frame() else {
            return 0;
        };
        let (w, h) = (f64::from(frame.width()), f64::from(frame.height()));
        let rows = rows.min(frame.height());
        let cols = ((f64::from(rows) * w / h).round() as u32).clamp(1, frame.width());
        let lod_c = f64::from(poe) * frame.pixel_angle();
        // The probes pass the hidden parts as the frames will.
        let parts = scene.parts();
        let tracer = Tracer::new(scene, self, lod_c as f32).with_parts(&parts);
        (0..rows)
            .into_par_iter()
            .map_init(
                || Memo::pooled(scene),
                |memo, row| {
                    memo.clear();
                    let y = (f64::from(row) + 0.5) * h / f64::from(rows);
                    for col in 0..cols {
                        let x = (f64::from(col) + 0.5) * w / f64::from(cols);
                        tracer.trace(&frame.ray_at(x, y), memo);
                    }
                    memo.flush(self);
                },
            )
            .count();
        u64::from(rows) * u64::from(cols)
    }

    fn into_wanted(self) -> Vec<(u32, Wish)> {
        self.wanted
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner)
            .into_iter()
            .collect()
    }
}

impl BlockCache for Probe<'_> {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        match self.cache.peek(id)? {
            Data::Treelets(d) => Some(d),
            Data::Triangles(_) => None,
        }
    }

    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        match self.cache.peek(id)? {
            Data::Triangles(d) => Some(d),
            Data::Treelets(_) => None,
        }
    }

    fn request(&self, wanted: &[(u32, Wish)]) {
        let mut all = self.wanted.lock().unwrap_or_else(PoisonError::into_inner);
        for (id, w) in wanted {
            all.entry(*id).or_default().merge(w);
        }
    }

    fn stats(&self) -> CacheStats {
        self.cache.stats()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn cam(eye: [f64; 3], look_at: [f64; 3]) -> Camera {
        Camera {
            eye,
            look_at,
            up: [0.0, 1.0, 0.0],
            fov_y: 45.0,
            width: 64,
            height: 48,
        }
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-9)
    }

    #[test]
    fn a_straight_move_goes_on_at_the_same_speed() {
        let a = cam([0.0, 0.0, 10.0], [0.0, 0.0, 0.0]);
        let b = cam([0.0, 0.0, 9.0], [0.0, 0.0, -1.0]);
        let p = predict(&a, &b, 2.0).unwrap();
        assert!(close(p.eye, [0.0, 0.0, 7.0]), "{p:?}");
        assert!(close(p.look_at, [0.0, 0.0, -3.0]), "{p:?}");
        assert!(close(p.up, [0.0, 1.0, 0.0]));
    }

    #[test]
    fn a_turn_goes_on_at_the_same_angular_speed() {
        // An orbit around the origin, 10° a frame, always looking at the centre: the
        // prediction's view direction has turned by another 10° per frame.
        let at = |deg: f64| {
            let r = deg.to_radians();
            cam([10.0 * r.sin(), 0.0, 10.0 * r.cos()], [0.0; 3])
        };
        let p = predict(&at(0.0), &at(10.0), 2.0).unwrap();
        let f = normalize(sub(p.look_at, p.eye));
        let want = normalize(sub([0.0; 3], at(30.0).eye));
        assert!(close(f, want), "{f:?} {want:?}");
        assert!((length(sub(p.look_at, p.eye)) - 10.0).abs() < 1e-9);
        // The eye moves on along the chord's direction (linear speed only).
        let step = sub(at(10.0).eye, at(0.0).eye);
        let eye = [0, 1, 2].map(|i| at(10.0).eye[i] + 2.0 * step[i]);
        assert!(close(p.eye, eye));
    }

    #[test]
    fn a_still_camera_predicts_itself_and_a_bad_prediction_is_none() {
        let a = cam([1.0, 2.0, 3.0], [0.0; 3]);
        assert_eq!(predict(&a, &a, 3.0), Some(a));
        let wide = Camera { fov_y: 170.0, ..a };
        let wider = Camera { fov_y: 178.0, ..a };
        assert_eq!(predict(&wide, &wider, 1.0), None);
    }
}
