//! Picking: what one ray meets, and of which part (`render --pick`, a viewer's click). A pick
//! is one ray traced like a primary ray of a frame at the same pixels of error and with the
//! scene's part filter ([`Scene::set_parts`]: a hidden part cannot be picked), but it never
//! ends on a stand-in: where the cache does not hold a block the ray needs (the asynchronous
//! cache, before its fetchers got there), the pick reads and decodes that block itself and
//! waits, without adding it to the cache. One ray needs few blocks, so this is quick even
//! cold; a block that cannot be read makes the pick an error. At full detail a pick answers
//! the triangle (block id, index in the block) and its part; on a LOD entry, the entry's part
//! word: the part that covers most of its cell.

use std::sync::{Arc, Mutex};

use serde::Serialize;

use crate::blocks::{TreeletData, TriangleData};
use crate::cache::{BlockCache, CacheStats};
use crate::camera::Camera;
use crate::error::TraceError;
use crate::intersect::Ray;
use crate::parts::part_path;
use crate::scene::Scene;
use crate::section::Clip;
use crate::spawn::triangle_normal;
use crate::traverse::{Memo, Surface, Tracer};

/// What a pick found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Pick {
    /// Distance from the ray's origin (the eye) to the hit, world units.
    pub distance: f64,
    /// The hit point, world coordinates.
    pub point: [f64; 3],
    /// The surface's unit normal there, turned towards the ray's origin: a triangle's
    /// geometric normal, a LOD entry's normal as the ray sees it.
    pub normal: [f32; 3],
    /// At full detail, the triangle hit; None on a LOD entry.
    pub triangle: Option<PickedTriangle>,
    /// At full detail, the hit triangle's corners, world coordinates (a viewer's measure snaps
    /// to the nearest when it is close on screen); None on a LOD entry.
    pub corners: Option<[[f64; 3]; 3]>,
    /// The part: the triangle's, or the LOD entry's part word; None in a file without parts.
    pub part: Option<u32>,
    /// The part's name.
    pub part_name: Option<String>,
    /// The part's path: the names from its top-level part down, joined with `/`.
    pub part_path: Option<String>,
    /// Whether the ray ended on a LOD entry (within the pixels of error) rather than on a
    /// triangle.
    pub lod: bool,
}

/// A triangle as a pick names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct PickedTriangle {
    /// The id of the triangle block that holds it.
    pub block: u32,
    /// Its index among the block's triangles.
    pub index: u32,
}

/// Picks pixel (`x`, `y`) of `camera` (stored coordinates, as for [`crate::render()`]): its
/// centre ray, at `poe` pixels of error. None when the ray meets nothing visible.
pub fn pick(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    (x, y): (u32, u32),
    poe: f32,
) -> Result<Option<Pick>, TraceError> {
    if !(poe.is_finite() && poe >= 0.0) {
        return Err(TraceError::Options(format!(
            "--poe {poe}: expected a finite number >= 0"
        )));
    }
    let frame = camera.frame()?;
    if x >= frame.width() || y >= frame.height() {
        return Err(TraceError::Options(format!(
            "--pick {x},{y}: outside the {}x{} image",
            frame.width(),
            frame.height()
        )));
    }
    let lod_c = (f64::from(poe) * frame.pixel_angle()) as f32;
    pick_ray(scene, cache, &frame.ray(x, y), lod_c)
}

/// Picks along `ray` (stored coordinates) with the LOD constant `lod_c` (0: full detail; see
/// [`crate::traverse`]). None when the ray meets nothing visible.
pub fn pick_ray(
    scene: &Scene,
    cache: &dyn BlockCache,
    ray: &Ray,
    lod_c: f32,
) -> Result<Option<Pick>, TraceError> {
    let waiting = Waiting {
        scene,
        cache,
        failed: Mutex::new(None),
    };
    let filter = scene.parts();
    let tracer = Tracer::new(scene, &waiting, lod_c).with_parts(&filter);
    let memo = Memo::new(scene);
    // A section hides what it cuts away from picks as from frames.
    let clip = scene.stored_section().map_or(Clip::Whole, |s| s.clip(ray));
    let hit = clip
        .ray(ray)
        .and_then(|r| tracer.trace(&r, &memo))
        .filter(|h| h.t <= clip.limit());
    let failed = waiting
        .failed
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take();
    if let Some(e) = failed {
        return Err(TraceError::Format(e));
    }
    let Some(hit) = hit else {
        return Ok(None);
    };
    let m = scene.metadata();
    let d64 = ray.dir.map(f64::from);
    let len = (d64[0] * d64[0] + d64[1] * d64[1] + d64[2] * d64[2]).sqrt();
    let t = f64::from(hit.t) + f64::from(clip.start());
    let point = [0, 1, 2].map(|k| f64::from(ray.org[k]) + t * d64[k] + m.scene.origin[k]);
    let world = |p: &[f32; 3]| [0, 1, 2].map(|k| f64::from(p[k]) + m.scene.origin[k]);
    let (normal, triangle, corners) = match &hit.surface {
        Surface::Triangle { data, triangle, .. } => {
            let at = data.positions.get(*triangle as usize);
            let n = at.and_then(triangle_normal).map(|n| n.map(|c| c as f32));
            let picked = PickedTriangle {
                block: data.block,
                index: *triangle,
            };
            (
                n,
                Some(picked),
                at.map(|v| [world(&v[0]), world(&v[1]), world(&v[2])]),
            )
        }
        Surface::Voxel { normal, .. } | Surface::Plane { normal, .. } => {
            (Some(*normal), None, None)
        }
        Surface::Proxy(s) => (Some(s.normal()), None, None),
    };
    let normal = facing(normal.unwrap_or(ray.dir.map(|c| -c)), ray.dir);
    let part = hit.part;
    Ok(Some(Pick {
        distance: t * len,
        point,
        normal,
        lod: triangle.is_none(),
        triangle,
        corners,
        part,
        part_name: part.and_then(|p| m.parts.get(p as usize).map(|x| x.name.clone())),
        part_path: part.and_then(|p| part_path(&m.parts, p)),
    }))
}

/// `n` as a unit vector turned against `dir` (towards the ray's origin).
fn facing(n: [f32; 3], dir: [f32; 3]) -> [f32; 3] {
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let len = dot(n, n).sqrt();
    let n = if len > 0.0 && len.is_finite() {
        n.map(|c| c / len)
    } else {
        n
    };
    if dot(n, dir) > 0.0 {
        n.map(|c| -c)
    } else {
        n
    }
}

/// A cache that never says "not yet": what the cache does not hold, the pick reads itself
/// (the first failure is kept for the pick to report).
struct Waiting<'c> {
    scene: &'c Scene,
    cache: &'c dyn BlockCache,
    failed: Mutex<Option<oocfmt::Error>>,
}

impl Waiting<'_> {
    fn read<T>(&self, load: impl FnOnce() -> oocfmt::Result<T>) -> Option<Arc<T>> {
        match load() {
            Ok(d) => Some(Arc::new(d)),
            Err(e) => {
                let mut f = self.failed.lock().unwrap_or_else(|e| e.into_inner());
                f.get_or_insert(e);
                None
            }
        }
    }
}

impl BlockCache for Waiting<'_> {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        self.cache
            .treelets(id)
            .or_else(|| self.read(|| self.scene.load_treelets(id)))
    }

    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        self.cache
            .triangles(id)
            .or_else(|| self.read(|| self.scene.load_triangles(id)))
    }

    fn stats(&self) -> CacheStats {
        self.cache.stats()
    }
}
