//! Algorithm 1 of Áfra (2012): front-to-back traversal of the kd-tree through treelets and
//! across blocks, remembering the last voxel met on the path.
//!
//! - At a LOD node whose enclosing-sphere radius r satisfies r ≤ t_entry · C the ray stops on
//!   the node's voxel, at the entry distance of the node's cell, with the look of the faces its
//!   direction sees (spec §6.3). C = poe · 2 tan(fov_y / 2) / image_height is the size of `poe`
//!   pixels per unit of distance, so the test reads "the voxel's radius is at most `poe`
//!   pixels". `poe` 0 never stops (full detail). A voxel or plane that covers only part of its
//!   cell is translucent: [`Tracer::trace_layers`] goes on behind it (spec §5.1).
//! - With R-LODs (Yoon et al. 2006, §4.2) the same test uses the R-LOD's error radius, and a
//!   ray that stops there meets the node's plane: a hit inside the ray's interval in the cell,
//!   widened by the R-LOD's expansion, ends the ray with the plane's normal and colour; a miss
//!   skips the node's subtree.
//! - A child block that is not available ends the ray on the subtree's proxy (skipping the
//!   subtree where the proxy sees nothing from the ray's direction) or, without a proxy, on
//!   the node's voxel (or its plane, as above); a missing triangle block ends it on the last
//!   voxel (or plane) met.
//! - Triangle hits are not clipped to their leaf's cell: every leaf is tested with the ray's
//!   current nearest distance, and a stacked subtree is skipped only when it starts beyond that
//!   nearest hit. Split decisions are widened by a small positional tolerance, so a hit that
//!   rounding puts on the wrong side of a split plane is still found: at worst a few extra
//!   leaves are visited. The same kernel tests the same triangles, so the nearest distance is
//!   exactly the brute-force one.
//! - With a part filter that hides a part ([`Tracer::with_parts`]) a subtree whose stretch of
//!   the ray meets no visible part's box is skipped whole, asked at each LOD node and at least
//!   every third node of a path (`GRID_EVERY`; [`crate::parts::VisibilityGrid`]).
//! - A direction component of ±0 (or one whose reciprocal overflows) makes the ray parallel to
//!   the split plane: it visits the side its origin lies on, both sides when the origin lies on
//!   the plane. No 0 × inf product is formed.

use std::ops::ControlFlow;
use std::sync::Arc;

use arrayvec::ArrayVec;

use oocfmt::records::{Footprint, Sample, Voxel, MAX_TREE_DEPTH, PROXY_DIRECTIONS};

use crate::blocks::{NodeView, Plane, Shown, TreeletData, TriangleData, NONE};
use crate::cache::BlockCache;
use crate::intersect::{major_axis, ray_box, Ray};
use crate::parts::{BlockMask, Cover, PartFilter, VisibilityGrid};
use crate::scene::Scene;

/// Re-exported: the traversal is where a memo is used.
pub use crate::memo::Memo;

/// What a ray ended on.
#[derive(Clone, Debug)]
pub enum Surface {
    /// A triangle of a decoded triangle block, at full detail.
    Triangle {
        /// The triangle block, kept alive for shading after the cache lets it go.
        data: Arc<TriangleData>,
        /// The triangle's index in `data`'s per-triangle arrays ([`TriangleData::positions`]).
        triangle: u32,
        /// The hit's barycentric weights of the triangle's three corners, summing to 1.
        bary: [f32; 3],
    },
    /// A LOD node's voxel as the ray sees it: its only sample, or the blend of the three faces
    /// the ray's direction looks through (spec §6.3).
    Voxel {
        /// Unit normal.
        normal: [f32; 3],
        /// Linear RGB in 0..=1.
        colour: [f32; 3],
    },
    /// A LOD node's proxy, standing in for a subtree whose block is not available: its sample
    /// for the direction nearest the ray's.
    Proxy(Sample),
    /// An R-LOD plane: its unit normal, linear RGB colour and deviation.
    Plane {
        /// The plane's unit normal.
        normal: [f32; 3],
        /// The R-LOD's colour, linear RGB in 0..=1.
        colour: [f32; 3],
        /// δ: the node's triangles lie within this distance of the plane (spec §6.4), so a
        /// secondary ray that starts past it cannot meet them.
        deviation: f32,
    },
}

/// Where a ray ended: how far along it, on what, and how large that surface's error is.
#[derive(Clone, Debug)]
pub struct Hit {
    /// Distance along the ray's direction (the image's depth for a unit direction).
    pub t: f32,
    /// What the ray ended on.
    pub surface: Surface,
    /// The radius of the sphere enclosing the cell of the voxel or proxy the ray ended on
    /// (half the cell's diagonal), or the error radius of the R-LOD: the LOD metric's radius.
    /// Secondary rays leave a voxel or proxy twice this far off, an R-LOD by its deviation
    /// ([`crate::spawn`]). 0 for a triangle.
    pub radius: f32,
    /// σ, the factor on the light's cosine (spec §5.1): 1 for a triangle, a proxy and every
    /// LOD entry of an unfiltered file.
    pub shade: f32,
    /// α, the share of what the ray shows that is this surface (spec §5.1): below 1 what lies
    /// behind shows through ([`Tracer::trace_layers`]). 1 for a triangle.
    pub coverage: f32,
    /// The part the surface is of: a triangle's own part, a LOD entry's part word (the part
    /// covering most of its cell); None for a proxy and in a file without parts.
    pub part: Option<u32>,
}

/// The last LOD node met on a ray's path: its voxel ends the ray where the data below is
/// missing.
#[derive(Clone, Copy)]
struct LastVoxel<'m> {
    data: &'m TreeletData,
    lod: u32,
    radius: f32,
    t: f32,
    /// Where the ray leaves the node's cell.
    t1: f32,
}

impl LastVoxel<'_> {
    /// What the node shows this ray, and where: its voxel at the cell's entry, or its plane's
    /// hit (None when the plane is missed).
    fn shown(&self, ray: &Ray) -> Option<(f32, Best<'static>)> {
        let (look, _) = self.data.look(self.lod)?;
        let part = self.data.lod_part(self.lod);
        shown(&look, ray, self.t, self.t1, self.radius, part)
    }
}

/// What a LOD node of part word `part` showing `shown` gives a ray crossing its cell in
/// [t0, t1], and where; None when a plane is missed.
pub(crate) fn shown(
    shown: &Shown,
    ray: &Ray,
    t0: f32,
    t1: f32,
    radius: f32,
    part: Option<u32>,
) -> Option<(f32, Best<'static>)> {
    let part = part.unwrap_or(NONE);
    match shown {
        Shown::Voxel(v) => {
            let look = voxel_look(v, ray);
            Some((t0, Best::Voxel { look, radius, part }))
        }
        Shown::Plane(p) => plane_hit(p, ray, t0, t1).map(|t| {
            (
                t,
                Best::Plane {
                    normal: p.normal,
                    colour: p.colour,
                    deviation: p.deviation,
                    radius,
                    coverage: p.coverage,
                    shade: p.shade,
                    part,
                },
            )
        }),
    }
}

/// Where the ray meets the plane within [t0, t1] widened by the plane's expansion (a distance
/// in space, so over the direction's length in t), at t > 0; None for a miss or a ray
/// parallel to the plane.
fn plane_hit(p: &Plane, ray: &Ray, t0: f32, t1: f32) -> Option<f32> {
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let denom = dot(p.normal, ray.dir);
    if denom == 0.0 || !denom.is_finite() {
        return None;
    }
    let t = (p.offset - dot(p.normal, ray.org)) / denom;
    let len = dot(ray.dir, ray.dir).sqrt();
    let widen = if len > 0.0 { p.expansion / len } else { 0.0 };
    (t > 0.0 && t >= t0 - widen && t <= t1 + widen).then_some(t)
}

/// A subtree waiting on the stack: its treelet block and node, the ray's interval in its cell
/// and how many LOD nodes lie above it, so that the last of them is its last voxel. The LOD
/// nodes above every stacked subtree are on the path to the node being visited (the stack
/// holds far siblings of that path), so one stack of them, cut back to `lods` when the entry
/// is popped, serves all entries: an entry stays 24 bytes.
#[derive(Clone, Copy)]
struct Entry<'m> {
    data: &'m TreeletData,
    node: u32,
    t0: f32,
    t1: f32,
    lods: u8,
    /// Nodes on the path before the part filter's grid is asked again ([`grid_due`]).
    due: u8,
    /// Every grid cell around the ray's stretch in an ancestor's cell is near a visible part
    /// ([`Cover::Full`]), so is every one around this stretch, which lies inside it: the grid
    /// need not be asked again below.
    full: bool,
}

/// The LOD nodes on the path to the node being visited, outermost first.
type Lasts<'m> = ArrayVec<LastVoxel<'m>, { MAX_TREE_DEPTH as usize }>;

/// One ray's walk through the tree: the ray and its tolerance, the subtrees waiting, the LOD
/// nodes on the path, and the nearest surface found so far (at `best_t`).
struct Walk<'r, 'm> {
    ray: &'r Ray,
    memo: &'m Memo,
    eps: f32,
    stack: ArrayVec<Entry<'m>, { MAX_TREE_DEPTH as usize }>,
    lasts: Lasts<'m>,
    best: Best<'m>,
    best_t: f32,
    /// Whether translucent surfaces are collected in `layers` (the ray goes on behind them)
    /// rather than ending the ray like opaque ones.
    collect: bool,
    layers: Collected<'m>,
}

impl<'m> Walk<'_, 'm> {
    /// Keeps `found` when it is nearer than the nearest surface so far: as the nearest, or,
    /// when collecting, as a layer the ray goes on behind ([`Collected::keep`]).
    #[inline(always)]
    fn offer(&mut self, found: Option<(f32, Best<'m>)>) {
        let Some((t, s)) = found.filter(|&(t, _)| t < self.best_t) else {
            return;
        };
        if self.collect && self.layers.keep(t, s) {
            return;
        }
        self.best_t = t;
        self.best = s;
    }
}

/// The translucent surfaces one ray has met, in the order found, and what they let through
/// together: the state the single-ray walk and the packet walk share when they collect
/// layers ([`Tracer::trace_layers`], [`Tracer::trace_packet_layers`]).
#[derive(Clone)]
pub(crate) struct Collected<'m> {
    layers: ArrayVec<(f32, Best<'m>), MAX_LAYERS>,
    through: f32,
}

impl<'m> Collected<'m> {
    pub(crate) fn new() -> Collected<'m> {
        Collected {
            layers: ArrayVec::new(),
            through: 1.0,
        }
    }

    /// Keeps surface `s` at `t` (nearer than the ray's nearest opaque one) as a layer the
    /// ray goes on behind, when it is translucent ([`is_translucent`]) and room is left.
    /// False: it ends the ray, as opaque; so does one after which the layers would let
    /// less than [`MIN_TRANSMITTANCE`] through, since what is behind could hardly show.
    #[inline(always)]
    pub(crate) fn keep(&mut self, t: f32, s: Best<'m>) -> bool {
        let coverage = s.coverage();
        if self.layers.is_full() || !is_translucent(coverage) {
            return false;
        }
        let through = self.through * (1.0 - coverage.max(0.0));
        if through < MIN_TRANSMITTANCE {
            return false;
        }
        self.layers.push((t, s));
        self.through = through;
        true
    }

    /// Writes into `out` the layers in front of the nearest opaque surface `best` at
    /// `best_t`, nearest first, and that surface.
    pub(crate) fn finish(&mut self, best_t: f32, best: Best<'m>, out: &mut Layers) {
        let layers = &mut self.layers;
        layers.retain(|(t, _)| *t <= best_t);
        layers.sort_by(|a, b| a.0.total_cmp(&b.0));
        out.translucent.clear();
        out.translucent
            .extend(layers.iter().filter_map(|&(t, s)| s.hit(t)));
        out.end = best.hit(best_t);
    }
}

/// Whether a surface of coverage `coverage` lets what lies behind show: by at least
/// [`MIN_TRANSMITTANCE`] (an entry covering more than nine tenths of its cell is shown opaque
/// without looking behind it).
#[inline(always)]
pub(crate) fn is_translucent(coverage: f32) -> bool {
    1.0 - coverage >= MIN_TRANSMITTANCE
}

/// What a ray meets ([`Tracer::trace_layers`]): the translucent surfaces in front, nearest
/// first, and the surface it ends on (None: it leaves the scene, or the layers let nothing
/// through).
#[derive(Clone, Debug, Default)]
pub struct Layers {
    /// Surfaces that let at least [`MIN_TRANSMITTANCE`] of what lies behind show, at most
    /// [`MAX_LAYERS`].
    pub translucent: ArrayVec<Hit, MAX_LAYERS>,
    /// The opaque surface behind them.
    pub end: Option<Hit>,
}

/// The most translucent surfaces one ray collects; past them the next surface ends it, opaque
/// (spec §5.1 allows a cap). Past a few layers what is left behind hardly shows.
pub const MAX_LAYERS: usize = 16;

/// Transmittance below which the next surface ends the ray as if opaque: what would still
/// show behind it is at most a tenth of the pixel. Nearly every cell of a rough surface is a
/// little short of full coverage, and looking behind each cost more time than it changed the
/// picture (`docs/benchmarks.md`).
pub const MIN_TRANSMITTANCE: f32 = 0.1;

/// The grid the walk without one is handed and never asks.
pub(crate) static NO_GRID: VisibilityGrid = VisibilityGrid::EMPTY;

/// How many nodes down a path the part filter's grid is asked at least once, besides at every
/// LOD node: often enough to cut a hidden subtree within a few levels, rarely enough that the
/// question (some 50 instructions) does not cost more than the nodes it saves.
pub(crate) const GRID_EVERY: u8 = 3;

/// Whether the node about to be visited asks the grid ([`GRID_EVERY`]): each LOD node (where
/// skipping also spares the child block's look-up) and at least every `GRID_EVERY`-th node of
/// a path. `due` counts the nodes still to pass, carried down the path and onto the stack, so
/// the answer depends on the path alone: a ray in a packet asks where it asks alone.
#[inline(always)]
pub(crate) fn grid_due(due: &mut u8, lod: bool) -> bool {
    if *due == 0 || lod {
        *due = GRID_EVERY - 1;
        true
    } else {
        *due -= 1;
        false
    }
}

/// Makes `lv` the last voxel of the path (dropping the outermost when a corrupt tree is deeper
/// than any path can be) and returns the count to store in entries below it.
pub(crate) fn push_last<T, const CAP: usize>(lasts: &mut ArrayVec<T, CAP>, lv: T) -> u8 {
    if lasts.is_full() {
        lasts.remove(0);
    }
    let _ = lasts.try_push(lv);
    lasts.len() as u8
}

/// The nearest surface found so far, borrowed from the memo until the ray is done.
#[derive(Clone, Copy)]
pub(crate) enum Best<'m> {
    None,
    Triangle {
        data: &'m Arc<TriangleData>,
        triangle: u32,
        bary: [f32; 3],
    },
    /// What a voxel shows the ray, the radius of its cell and its part word ([`NONE`]: none).
    Voxel {
        look: VoxelLook,
        radius: f32,
        part: u32,
    },
    /// A proxy's sample and the radius of its node's cell.
    Proxy(Sample, f32),
    Plane {
        normal: [f32; 3],
        colour: [f32; 3],
        deviation: f32,
        radius: f32,
        coverage: f32,
        shade: f32,
        part: u32,
    },
}

/// Traces rays through one scene's kd-tree at one LOD constant, reading blocks from the cache
/// through each tile's [`Memo`]; read-only once built, so a frame's threads share it.
pub struct Tracer<'a> {
    pub(crate) cache: &'a dyn BlockCache,
    pub(crate) root: Option<(u32, u32)>,
    pub(crate) lo: [f32; 3],
    pub(crate) hi: [f32; 3],
    pub(crate) proxies: &'a [oocfmt::records::ProxyRecord],
    /// Positional tolerance of split decisions: some ulps of the scene's coordinates.
    eps: f32,
    /// The LOD constant C (see the module comment); 0 never stops at a voxel.
    pub(crate) lod_c: f32,
    /// The most nodes a ray (or a packet) visits: as many as the file's treelet blocks can
    /// hold ([`Scene::node_bound`]). A well-formed tree never reaches it.
    pub(crate) max_visits: u64,
    /// The part filter, when it hides a part ([`Tracer::with_parts`]); None costs the hot
    /// loop one branch per leaf and per LOD node.
    pub(crate) parts: Option<&'a PartFilter>,
    /// The filter's grid of visible parts' boxes, when it hides a part: a node whose stretch of
    /// the ray meets none of them is skipped whole. None: the walks run their copy without
    /// the question, which costs nothing per node.
    pub(crate) grid: Option<&'a VisibilityGrid>,
}

/// One side of a split: left or right child, interval.
type Side = (bool, f32, f32);

/// A child to visit: node index, interval.
type Visit = (u32, f32, f32);

/// The children to visit, nearest first, given the sides a split yields and which child node
/// (if any) each side names.
fn ordered(
    (near, far): (Option<Side>, Option<Side>),
    child: impl Fn(bool) -> Option<u32>,
) -> Option<(Visit, Option<Visit>)> {
    let pick = |s: Option<Side>| {
        let (is_left, t0, t1) = s?;
        Some((child(is_left)?, t0, t1))
    };
    match (pick(near), pick(far)) {
        (Some(n), f) => Some((n, f)),
        (None, f) => f.map(|f| (f, None)),
    }
}

/// The inner-node step of [`Tracer::trace_to`] for a ray parallel to the split plane of axis
/// `a` at `split` (see [`split_sides`]): `at` moves to the near child of `[left, right]`, the
/// far one is stacked. Breaks where no child is visited.
#[inline(always)]
fn parallel_step<'m>(
    w: &mut Walk<'_, 'm>,
    at: &mut Entry<'m>,
    (a, split): (u8, f32),
    [left, right]: [u32; 2],
) -> ControlFlow<()> {
    let sides = split_sides(w.ray, a, split, at.t0, at.t1, w.eps);
    let child = |is_left| {
        let c = if is_left { left } else { right };
        (c != NONE).then_some(c)
    };
    let Some((near, far)) = ordered(sides, child) else {
        return ControlFlow::Break(());
    };
    if let Some((fc, f0, f1)) = far {
        let _ = w.stack.try_push(Entry {
            node: fc,
            t0: f0,
            t1: f1,
            ..*at
        });
    }
    (at.node, at.t0, at.t1) = near;
    ControlFlow::Continue(())
}

/// The inner-node step of [`Tracer::trace_to`] for a ray that crosses the split plane of axis
/// `a` at `split`: [`split_sides`] and [`ordered`] written out, as this is most of the work of
/// a ray. `at` moves to the near child of `[left, right]` that the ray visits, the far one is
/// stacked when the ray visits both. Breaks where it visits neither.
#[inline(always)]
fn crossing_step<'m>(
    w: &mut Walk<'_, 'm>,
    at: &mut Entry<'m>,
    axes: &Axes,
    (a, split): (u8, f32),
    [left, right]: [u32; 2],
) -> ControlFlow<()> {
    let k = usize::from(a.min(2));
    let ts = (split - axes.org[k]) * axes.inv[k];
    let tol = axes.tol[k];
    let (first, second) = if axes.left_first[k] {
        (left, right)
    } else {
        (right, left)
    };
    let before = ts + tol >= at.t0 && first != NONE;
    let after = ts - tol <= at.t1 && second != NONE;
    let mid = clamp_mid(ts, at.t0, at.t1);
    match (before, after) {
        (true, true) => {
            let _ = w.stack.try_push(Entry {
                node: second,
                t0: mid,
                ..*at
            });
            (at.node, at.t1) = (first, mid);
        }
        (true, false) => (at.node, at.t1) = (first, mid),
        (false, true) => (at.node, at.t0) = (second, mid),
        (false, false) => return ControlFlow::Break(()),
    }
    ControlFlow::Continue(())
}

/// What the split decisions of one ray read per axis, worked out once per ray rather than at
/// every inner node.
struct Axes {
    org: [f32; 3],
    inv: [f32; 3],
    /// The positional tolerance over the direction: `eps · |inv|`.
    tol: [f32; 3],
    /// The left child comes first along the ray (positive direction).
    left_first: [bool; 3],
    /// The ray is parallel to the axis's planes (see [`split_sides`]).
    parallel: [bool; 3],
}

impl Axes {
    fn new(ray: &Ray, eps: f32) -> Axes {
        Axes {
            org: ray.org,
            inv: ray.inv,
            tol: ray.inv.map(|i| eps * i.abs()),
            left_first: ray.dir.map(|d| d > 0.0),
            parallel: [0, 1, 2].map(|k| ray.dir[k] == 0.0 || !ray.inv[k].is_finite()),
        }
    }
}

impl<'a> Tracer<'a> {
    /// `lod_c` = poe · (world size of a pixel per unit distance).
    pub fn new(scene: &'a Scene, cache: &'a dyn BlockCache, lod_c: f32) -> Tracer<'a> {
        let m = scene.metadata();
        let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
        let scale = lo.iter().chain(&hi).fold(0f32, |a, &c| a.max(c.abs()));
        Tracer {
            cache,
            root: m.root.map(|r| (r.block, r.treelet)),
            lo,
            hi,
            proxies: scene.proxies(),
            eps: scale.max(f32::MIN_POSITIVE) * 4e-6,
            lod_c: if lod_c.is_finite() && lod_c > 0.0 {
                lod_c
            } else {
                0.0
            },
            max_visits: scene.node_bound(),
            parts: None,
            grid: None,
        }
    }

    /// Rays that skip the parts `filter` hides: a hidden triangle is dropped before its
    /// intersection test, and a LOD entry whose part word is hidden neither ends a ray nor
    /// stands in for its missing subtree (the ray goes on to the finer levels, where what
    /// stays visible is drawn as it is). At each LOD node, and at least every third node of a
    /// path, the ray asks the filter's [`VisibilityGrid`] whether its stretch in the node's
    /// cell (widened by the ray's tolerance) meets a visible part's box; where it does not,
    /// the node is skipped with its subtree, at any level. Every visible hit lies in its
    /// part's box and in the stretch of each node on the path to a leaf that holds it, so no
    /// visible hit is lost. A filter that hides nothing changes nothing here (highlighting is
    /// the shading's, [`crate::shade::Lighting::with_parts`]).
    pub fn with_parts(mut self, filter: &'a PartFilter) -> Tracer<'a> {
        self.parts = (filter.hidden() > 0).then_some(filter);
        self.grid = self.parts.and_then(PartFilter::grid);
        self
    }

    /// Where the ray first meets the scene, or None.
    pub fn trace(&self, ray: &Ray, memo: &Memo) -> Option<Hit> {
        self.trace_to(ray, f32::INFINITY, memo)
    }

    /// Where the ray first meets the scene closer than `t_max` (exclusive), or None: a shadow
    /// ray towards a light at distance `t_max` is occluded when this returns a hit.
    pub fn trace_to(&self, ray: &Ray, t_max: f32, memo: &Memo) -> Option<Hit> {
        self.walk_one(ray, t_max, memo, false).end
    }

    /// Every surface the ray meets closer than `t_max`, front to back, up to the first opaque
    /// one (spec §5.1): the translucent ones it goes on behind, then what it ends on (None:
    /// it leaves the scene). One walk of the tree: behind a translucent LOD entry the walk
    /// goes on with the cells behind it, as it does past an empty one.
    pub fn trace_layers(&self, ray: &Ray, t_max: f32, memo: &Memo) -> Layers {
        self.walk_one(ray, t_max, memo, true)
    }

    /// The walk of [`Tracer::trace_to`] (`collect` false: the nearest surface ends the ray)
    /// and [`Tracer::trace_layers`] (`collect` true).
    fn walk_one(&self, ray: &Ray, t_max: f32, memo: &Memo, collect: bool) -> Layers {
        // Two copies of the walk: without a grid not even its branch is in the node loop (on
        // a close view of the CAD scene that branch cost 3-5 %).
        match self.grid {
            Some(g) => self.walk_with::<true>(ray, t_max, memo, collect, g),
            None => self.walk_with::<false>(ray, t_max, memo, collect, &NO_GRID),
        }
    }

    /// [`Tracer::walk_one`], asking `grid` where `GRID`.
    fn walk_with<const GRID: bool>(
        &self,
        ray: &Ray,
        t_max: f32,
        memo: &Memo,
        collect: bool,
        grid: &VisibilityGrid,
    ) -> Layers {
        let none = Layers {
            translucent: ArrayVec::new(),
            end: None,
        };
        let eps = self.ray_eps(ray);
        let t_max = if t_max.is_nan() { f32::INFINITY } else { t_max };
        let Some((t0, t1)) = ray_box(ray, self.lo, self.hi, eps, 0.0, t_max) else {
            return none;
        };
        let Some((root_block, root_treelet)) = self.root else {
            return none;
        };
        let Some(root_data) = memo.treelets(self.cache, root_block) else {
            memo.want(root_block, f32::INFINITY, t0);
            return none;
        };
        let Some(&root) = root_data.roots.get(root_treelet as usize) else {
            return none;
        };
        let mut w = Walk {
            ray,
            memo,
            eps,
            stack: ArrayVec::new(),
            lasts: Lasts::new(),
            best: Best::None,
            best_t: t_max,
            collect,
            layers: Collected::new(),
        };
        w.stack.push(Entry {
            data: root_data,
            node: root,
            t0,
            t1,
            lods: 0,
            due: 0,
            full: false,
        });
        let axes = Axes::new(ray, eps);
        let mut visited = 0u64;
        'ray: while let Some(mut at) = w.stack.pop() {
            if at.t0 > w.best_t + eps {
                continue;
            }
            w.lasts.truncate(usize::from(at.lods));
            while let Some(n) = at.data.node(at.node) {
                visited += 1;
                // Each node of a tree has one parent, so a ray meets it once at most; past
                // that, treelets are shared and the paths may be too many to walk (spec §12).
                if visited > self.max_visits {
                    break 'ray;
                }
                // Where the filter leaves nothing visible along the ray in this cell, the
                // subtree shows nothing: skipped as if empty.
                if GRID {
                    let lod = matches!(n, NodeView::Lod { .. });
                    if grid_due(&mut at.due, lod) && !at.full {
                        match grid.cover_segment(ray, at.t0, at.t1, eps) {
                            Cover::None => break,
                            Cover::Some => {}
                            Cover::Full => at.full = true,
                        }
                    }
                }
                match n {
                    NodeView::Inner {
                        axis: a,
                        split,
                        left,
                        right,
                    } => {
                        let children = [left, right];
                        let step = if axes.parallel[usize::from(a.min(2))] {
                            parallel_step(&mut w, &mut at, (a, split), children)
                        } else {
                            crossing_step(&mut w, &mut at, &axes, (a, split), children)
                        };
                        if step.is_break() {
                            break;
                        }
                    }
                    NodeView::Lod {
                        axis: a,
                        split,
                        lod,
                    } => {
                        if self.lod_step(&mut w, &mut at, (a, split), lod).is_break() {
                            break;
                        }
                    }
                    NodeView::Leaf {
                        first,
                        count,
                        block,
                    } => {
                        self.leaf_step(&mut w, at.t0, (first, count), block);
                        break;
                    }
                }
            }
        }
        memo.visited.set(memo.visited.get() + visited);
        let mut out = Layers::default();
        w.layers.finish(w.best_t, w.best, &mut out);
        out
    }

    /// The LOD step of [`Tracer::trace_to`], at the LOD node of `at` with split `(axis,
    /// split)` and LOD entry `lod`: the node becomes the path's last voxel; the ray stops on
    /// it when the LOD metric says so, ends on its proxy, voxel or plane when the child block
    /// is not available, and otherwise goes on into the child treelets (`at` moves to the near
    /// one, the far one is stacked). Breaks where the path ends.
    #[inline(always)]
    fn lod_step<'m>(
        &self,
        w: &mut Walk<'_, 'm>,
        at: &mut Entry<'m>,
        (a, split): (u8, f32),
        lod: u32,
    ) -> ControlFlow<()> {
        let (data, ray) = (at.data, w.ray);
        let Some(l) = data.lods.get(lod as usize) else {
            return ControlFlow::Break(());
        };
        at.lods = push_last(
            &mut w.lasts,
            LastVoxel {
                data,
                lod,
                radius: l.radius,
                t: at.t0,
                t1: at.t1,
            },
        );
        let hidden = self.hides_lod(data, lod);
        let stop = !hidden && self.lod_c > 0.0 && l.radius <= at.t0 * self.lod_c;
        let child = if stop {
            None
        } else {
            w.memo.treelets(self.cache, l.child_block)
        };
        let Some(child) = child else {
            if hidden {
                // Neither its look nor its proxy: they show mostly a hidden part. The ray
                // passes the cell until the finer levels arrive.
                w.memo.want(l.child_block, l.radius, at.t0);
                return ControlFlow::Break(());
            }
            let Some((look, proxy)) = data.look(lod) else {
                return ControlFlow::Break(());
            };
            let (t0, t1) = (at.t0, at.t1);
            let own = || shown(&look, ray, t0, t1, l.radius, data.lod_part(lod));
            let found = if stop {
                own()
            } else {
                w.memo.want(l.child_block, l.radius, t0);
                // A proxy that sees nothing in the ray's direction skips the subtree.
                match proxy.and_then(|p| self.proxies.get(p as usize)) {
                    Some(p) => Some(proxy_sample(&p.samples, ray))
                        .filter(|s| !s.is_empty())
                        .map(|s| (t0, Best::Proxy(s, l.radius))),
                    None => opaque(own()),
                }
            };
            w.offer(found);
            return ControlFlow::Break(());
        };
        let sides = split_sides(ray, a, split, at.t0, at.t1, w.eps);
        let root = |is_left| {
            let t = if is_left { l.left } else { l.right };
            let root = *child.roots.get(t as usize)?;
            (t != NONE && root != NONE).then_some(root)
        };
        let Some((near, far)) = ordered(sides, root) else {
            return ControlFlow::Break(());
        };
        if let Some((fc, f0, f1)) = far {
            let _ = w.stack.try_push(Entry {
                data: child,
                node: fc,
                t0: f0,
                t1: f1,
                lods: at.lods,
                due: at.due,
                full: at.full,
            });
        }
        at.data = child;
        (at.node, at.t0, at.t1) = near;
        ControlFlow::Continue(())
    }

    /// The leaf step of [`Tracer::trace_to`], at a leaf of `(first, count)` list entries in
    /// triangle block `block`, entered at `t0`: the nearest of its triangles, or, when the
    /// block is not available, the path's last voxel (the block is wanted either way).
    #[inline(always)]
    fn leaf_step(&self, w: &mut Walk<'_, '_>, t0: f32, (first, count): (u16, u16), block: u32) {
        let (td, mask) = match self.parts {
            None => (w.memo.triangles(self.cache, block), BlockMask::NoneHidden),
            Some(f) => match w.memo.masked(self.cache, block, f) {
                Some((td, mask)) => (Some(td), mask),
                None => (None, BlockMask::NoneHidden),
            },
        };
        match td {
            Some(td) => {
                let first = usize::from(first);
                let list = td.list.get(first..first + usize::from(count));
                let list = list.unwrap_or(&[]);
                let nearest = match (mask, self.parts) {
                    (BlockMask::NoneHidden, _) | (_, None) => {
                        w.ray.nearest(list, &td.positions, w.best_t)
                    }
                    (BlockMask::AllHidden, _) => None,
                    (BlockMask::Mixed, Some(f)) => {
                        let mut visible = w.memo.visible.borrow_mut();
                        visible_entries(list, td, f, &mut visible);
                        w.ray.nearest(&visible, &td.positions, w.best_t)
                    }
                };
                if let Some((ti, h)) = nearest {
                    w.best_t = h.t;
                    w.best = Best::Triangle {
                        data: td,
                        triangle: u32::from(ti),
                        bary: h.bary,
                    };
                }
            }
            None => match w.lasts.last() {
                Some(lv) => {
                    w.memo.want(block, lv.radius, lv.t);
                    // A hidden LOD entry stands in for nothing.
                    if !self.hides_lod(lv.data, lv.lod) {
                        let found = opaque(lv.shown(w.ray));
                        w.offer(found);
                    }
                }
                None => w.memo.want(block, f32::INFINITY, t0),
            },
        }
    }

    /// Whether the part filter hides LOD node `lod` of `data` (by its part word).
    #[inline]
    pub(crate) fn hides_lod(&self, data: &TreeletData, lod: u32) -> bool {
        self.parts.is_some_and(|f| f.hides(data.lod_part(lod)))
    }

    /// The positional tolerance of a ray's split decisions: the scene's, or some ulps of the
    /// origin's coordinates when they are larger.
    pub(crate) fn ray_eps(&self, ray: &Ray) -> f32 {
        self.eps
            .max(ray.org.iter().fold(0f32, |a, &c| a.max(c.abs())) * 4e-6)
    }
}

/// The entries of a leaf's `list` in block `td` whose triangles `filter` does not hide, in
/// order, into `out`: one look-up per triangle, before and instead of its intersection test.
#[inline]
pub(crate) fn visible_entries(
    list: &[u16],
    td: &TriangleData,
    filter: &PartFilter,
    out: &mut Vec<u16>,
) {
    out.clear();
    out.extend(
        list.iter()
            .copied()
            .filter(|&ti| !filter.hides(td.part(u32::from(ti)))),
    );
}

/// `found` made opaque: a LOD entry shown because the data below it is missing stands in for
/// that data, and going on behind it would want blocks a full-detail ray never reaches.
#[inline(always)]
pub(crate) fn opaque(found: Option<(f32, Best<'_>)>) -> Option<(f32, Best<'_>)> {
    found.map(|(t, b)| (t, b.opaque()))
}

impl<'m> Best<'m> {
    /// The same surface with coverage 1.
    #[inline(always)]
    fn opaque(self) -> Best<'m> {
        match self {
            Best::Voxel { look, radius, part } => Best::Voxel {
                look: VoxelLook {
                    coverage: 1.0,
                    ..look
                },
                radius,
                part,
            },
            Best::Plane {
                normal,
                colour,
                deviation,
                radius,
                shade,
                part,
                ..
            } => Best::Plane {
                normal,
                colour,
                deviation,
                radius,
                coverage: 1.0,
                shade,
                part,
            },
            other => other,
        }
    }
}

impl Best<'_> {
    /// The share of what the ray shows that is this surface (1 but for translucent LOD
    /// entries).
    #[inline(always)]
    fn coverage(&self) -> f32 {
        match self {
            Best::Voxel { look, .. } => look.coverage,
            Best::Plane { coverage, .. } => *coverage,
            _ => 1.0,
        }
    }

    /// The hit this nearest surface at `t` makes; None for none.
    pub(crate) fn hit(self, t: f32) -> Option<Hit> {
        let (mut shade, mut coverage) = (1.0, 1.0);
        let word = |p: u32| (p != NONE).then_some(p);
        let (surface, radius, part) = match self {
            Best::None => return None,
            Best::Triangle {
                data,
                triangle,
                bary,
            } => (
                Surface::Triangle {
                    data: Arc::clone(data),
                    triangle,
                    bary,
                },
                0.0,
                data.part(triangle),
            ),
            Best::Voxel { look, radius, part } => {
                (shade, coverage) = (look.shade, look.coverage);
                let (normal, colour) = (look.normal, look.colour);
                (Surface::Voxel { normal, colour }, radius, word(part))
            }
            Best::Proxy(s, r) => (Surface::Proxy(s), r, None),
            Best::Plane {
                normal,
                colour,
                deviation,
                radius,
                coverage: c,
                shade: s,
                part,
            } => {
                (shade, coverage) = (s, c);
                let surface = Surface::Plane {
                    normal,
                    colour,
                    deviation,
                };
                (surface, radius, word(part))
            }
        };
        Some(Hit {
            t,
            surface,
            radius,
            shade,
            coverage,
            part,
        })
    }
}

/// The crossing distance `ts` of a split plane clamped to the ray's interval [t0, t1]:
/// max(ts, t0) then min(.., t1), written as comparisons so that the single-ray and the packet
/// traversal round ±0 alike (and compile to single `maxss`/`minss`). ts is not NaN when a
/// side is taken: a NaN fails both side tests.
#[inline(always)]
pub(crate) fn clamp_mid(ts: f32, t0: f32, t1: f32) -> f32 {
    let m = if t0 > ts { t0 } else { ts };
    if t1 < m {
        t1
    } else {
        m
    }
}

/// The children a ray in [t0, t1] visits at a split plane, nearest first, with their
/// intervals.
fn split_sides(
    ray: &Ray,
    axis: u8,
    split: f32,
    t0: f32,
    t1: f32,
    eps: f32,
) -> (Option<Side>, Option<Side>) {
    let k = usize::from(axis.min(2));
    let (o, d, inv) = (ray.org[k], ray.dir[k], ray.inv[k]);
    if d == 0.0 || !inv.is_finite() {
        return if o < split - eps {
            (Some((true, t0, t1)), None)
        } else if o > split + eps {
            (Some((false, t0, t1)), None)
        } else {
            (Some((true, t0, t1)), Some((false, t0, t1)))
        };
    }
    // The side the ray is on before it crosses the plane depends on the direction's sign
    // only: the crossing distance may be negative (the plane is behind) without changing which
    // side comes first.
    let left_before = d > 0.0;
    let ts = (split - o) * inv;
    let tol = eps * inv.abs();
    let mid = clamp_mid(ts, t0, t1);
    let before = (ts + tol >= t0).then_some((left_before, t0, mid));
    let after = (ts - tol <= t1).then_some((!left_before, mid, t1));
    match before {
        Some(b) => (Some(b), after),
        None => (after, None),
    }
}

/// What a voxel shows a ray: a unit normal, a colour, the shade σ and the coverage α (spec
/// §5.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VoxelLook {
    pub normal: [f32; 3],
    pub colour: [f32; 3],
    pub shade: f32,
    pub coverage: f32,
}

/// What voxel `v` shows a ray along `ray.dir` (spec §6.3): a 1-sample voxel its sample; a
/// 6-sample voxel the blend of the three faces the direction looks through, face `a` weighted
/// by |dₐ| (its share of a cube's silhouette) times its coverage, so the look turns smoothly
/// with the view instead of jumping where the entry face changes. Each face's normal faces
/// its own rays; they are turned to face this one before they are summed.
pub(crate) fn voxel_look(v: &Voxel, ray: &Ray) -> VoxelLook {
    let one = |s: Sample, f: Footprint| VoxelLook {
        normal: s.normal(),
        colour: s.colour(),
        shade: f.shade_f32(),
        coverage: f.coverage_f32(),
    };
    let Voxel::Six(..) = v else {
        let (s, f) = v.face(0);
        return one(s, f);
    };
    let d = ray.dir;
    let (mut normal, mut colour, mut shade) = ([0f32; 3], [0f32; 3], 0f32);
    let (mut seen, mut all) = (0f32, 0f32);
    for (a, &da) in d.iter().enumerate() {
        let (s, f) = v.face(2 * a + usize::from(da < 0.0));
        let n = s.normal();
        let w = da.abs() * f.coverage_f32();
        let turn = if n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0.0 {
            -w
        } else {
            w
        };
        for ((o, n), (c, x)) in normal
            .iter_mut()
            .zip(n)
            .zip(colour.iter_mut().zip(s.colour()))
        {
            *o += turn * n;
            *c += w * x;
        }
        shade += w * f.shade_f32();
        seen += w;
        all += da.abs();
    }
    let len = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
    if !(seen > 0.0 && len > 0.0 && len.is_finite() && all > 0.0) {
        // Nothing seen from this side (or opposite faces cancel): transparent.
        let (s, f) = v.face(2 * major_axis(d) + usize::from(d[major_axis(d)] < 0.0));
        return VoxelLook {
            coverage: 0.0,
            ..one(s, f)
        };
    }
    VoxelLook {
        normal: normal.map(|x| x / len),
        colour: colour.map(|x| x / seen),
        shade: (shade / seen).min(1.0),
        coverage: (seen / all).min(1.0),
    }
}

/// The proxy sample whose direction is nearest the ray's.
pub(crate) fn proxy_sample(samples: &[Sample; 18], ray: &Ray) -> Sample {
    let mut best = (f32::NEG_INFINITY, samples[0]);
    for (d, s) in PROXY_DIRECTIONS.iter().zip(samples) {
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let dot = (d[0] * ray.dir[0] + d[1] * ray.dir[1] + d[2] * ray.dir[2]) / len;
        if dot > best.0 {
            best = (dot, *s);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_stack_entry_and_a_last_voxel_are_24_bytes() {
        assert_eq!(std::mem::size_of::<super::Entry<'_>>(), 24);
        assert_eq!(std::mem::size_of::<super::LastVoxel<'_>>(), 24);
    }
}
