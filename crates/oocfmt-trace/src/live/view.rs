//! One live view: its camera, the quality asked for, its refine schedule and its accumulated
//! image. [`LiveView::next`] says what to render, [`LiveView::render`] renders it through a
//! session cache and returns the frame to show with its figures.

use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;

use super::accumulate::{pass_frame, Accumulator};
use super::schedule::{LiveOptions, Next, Outcome, Plan, Quality, Schedule, Stage};
use crate::parts::PartFilter;
use crate::pick::{pick, Pick};
use crate::render::{Endings, Image, RenderOptions, MAX_SAMPLES};
use crate::section::Section;
use crate::session::{self, Cache};
use crate::{Camera, Scene, TraceError};

/// The most pixels a live view's image may have (4096 × 4096).
pub const MAX_PIXELS: u64 = 1 << 24;

/// The longest side of a live view's image, in pixels (the CLI's limit too).
pub const MAX_SIDE: u32 = 16384;

/// The largest pixels of error a view may ask for.
pub const MAX_POE: f32 = 1024.0;

/// A frame of a live view, ready to show.
pub struct LiveFrame {
    /// The number the caller gave the camera it shows ([`LiveView::set_camera`]).
    pub seq: u64,
    /// What it shows: the frame itself, or with accumulation the average so far.
    pub image: Image,
    /// What was rendered.
    pub plan: Plan,
    /// Its figures.
    pub figures: LiveFigures,
}

/// A live frame's figures, the status line of a viewer.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LiveFigures {
    /// The schedule's stage ([`Stage::name`]).
    pub stage: &'static str,
    /// The last frame of the schedule: nothing better follows until something changes.
    pub last: bool,
    /// The camera or the quality changed while it rendered.
    pub stale: bool,
    /// The rendered width and height (below the asked size while moving).
    pub width: u32,
    /// See `width`.
    pub height: u32,
    /// The pixels of error it was rendered at.
    pub poe: f32,
    /// Samples per pixel in the image shown (more than 1 while accumulating).
    pub samples: u32,
    /// Samples per pixel asked for.
    pub spp: u32,
    /// Milliseconds of its rays and the cache step after them: what the schedule holds to the
    /// target.
    pub ms: f64,
    /// Of `ms`, the cache step.
    pub step_ms: f64,
    /// How its centre rays ended.
    pub primary: Endings,
    /// Of the centre rays that hit the model, the share that ended on a triangle (full detail);
    /// 1 when none hit.
    pub full_detail: f64,
    /// Decoded MiB resident after the step.
    pub cache_mib: f64,
    /// The cache's budget in MiB.
    pub cache_budget_mib: f64,
    /// Blocks requested and not yet loaded, as of the step.
    pub blocks_pending: u64,
    /// Blocks the frame wanted and did not find resident.
    pub blocks_missed: u64,
    /// Blocks made resident per second, over the last second or so ([`LoadRate`]).
    pub blocks_loaded_per_s: f64,
    /// Whether the last settle found every block it wanted (see [`Schedule::complete`]).
    pub complete: bool,
}

/// Blocks loaded per second, measured over windows of at least a second across every frame of
/// a cache (so one rate serves all the views of a viewer).
#[derive(Clone, Debug)]
pub struct LoadRate {
    start: Option<(Instant, u64)>,
    rate: f64,
}

impl LoadRate {
    /// No rate yet.
    pub fn new() -> LoadRate {
        LoadRate {
            start: None,
            rate: 0.0,
        }
    }

    /// The rate with the cache's `loaded` total at `now`.
    pub fn update(&mut self, loaded: u64, now: Instant) -> f64 {
        match self.start {
            None => self.start = Some((now, loaded)),
            Some((t, n)) => {
                let dt = now.saturating_duration_since(t);
                if dt >= Duration::from_secs(1) {
                    self.rate = loaded.saturating_sub(n) as f64 / dt.as_secs_f64();
                    self.start = Some((now, loaded));
                }
            }
        }
        self.rate
    }
}

impl Default for LoadRate {
    fn default() -> Self {
        LoadRate::new()
    }
}

/// One live view ([module documentation](self)).
pub struct LiveView {
    schedule: Schedule,
    /// The camera at the asked size, stored coordinates.
    camera: Option<Camera>,
    seq: u64,
    /// Everything of a frame's options but the PoE and the samples.
    base: RenderOptions,
    accum: Option<Accumulator>,
    /// The view's section plane, world coordinates ([`LiveView::set_section`]).
    section: Option<Section>,
    /// The view's part filter ([`LiveView::set_parts`]).
    parts: Arc<PartFilter>,
}

/// The camera's problem, or its pixel count.
pub fn check_camera(camera: &Camera) -> Result<u64, TraceError> {
    camera.frame()?;
    if camera.width > MAX_SIDE || camera.height > MAX_SIDE {
        return Err(TraceError::Camera(format!(
            "{}x{}: a side is longer than {MAX_SIDE} pixels",
            camera.width, camera.height
        )));
    }
    let pixels = u64::from(camera.width) * u64::from(camera.height);
    if pixels > MAX_PIXELS {
        return Err(TraceError::Camera(format!(
            "{}x{} is {pixels} pixels, more than the {MAX_PIXELS} a live view renders",
            camera.width, camera.height
        )));
    }
    Ok(pixels)
}

/// The quality's problem, if any.
pub fn check_quality(q: &Quality) -> Result<(), TraceError> {
    if !(q.poe.is_finite() && (0.0..=MAX_POE).contains(&q.poe)) {
        return Err(TraceError::Options(format!(
            "poe {}: expected 0 to {MAX_POE}",
            q.poe
        )));
    }
    if !(1..=MAX_SAMPLES).contains(&q.spp) {
        return Err(TraceError::Options(format!(
            "spp {}: expected 1 to {MAX_SAMPLES}",
            q.spp
        )));
    }
    Ok(())
}

impl LiveView {
    /// A view with no camera yet, refining to `quality`, its frames otherwise rendered with
    /// `base` (background, lighting; its PoE and samples are the schedule's).
    pub fn new(
        opts: LiveOptions,
        base: RenderOptions,
        quality: Quality,
    ) -> Result<LiveView, TraceError> {
        check_quality(&quality)?;
        Ok(LiveView {
            schedule: Schedule::new(opts, quality),
            camera: None,
            seq: 0,
            base,
            accum: None,
            section: None,
            parts: Arc::new(PartFilter::none()),
        })
    }

    /// The camera (stored coordinates, at the size to show) changed at `now`; `seq` is echoed
    /// in the frames that show it. A camera that cannot make rays, or has more than
    /// [`MAX_PIXELS`], is refused and changes nothing; the camera already shown only takes the
    /// new number.
    pub fn set_camera(&mut self, camera: Camera, seq: u64, now: Instant) -> Result<(), TraceError> {
        let pixels = check_camera(&camera)?;
        self.seq = seq;
        if self.camera == Some(camera) {
            return Ok(());
        }
        self.camera = Some(camera);
        self.accum = None;
        self.schedule.camera(now, pixels);
        Ok(())
    }

    /// The view's section plane (world coordinates; None: no cut) changed at `now`: the
    /// picture starts refining again, as after a camera move. The view sets it on the scene
    /// before each of its frames and picks ([`Scene::set_section`]): the views of one scene
    /// render one at a time, so each sees its own.
    pub fn set_section(&mut self, section: Option<Section>, now: Instant) {
        if section == self.section {
            return;
        }
        self.section = section;
        self.accum = None;
        if let Some(c) = &self.camera {
            self.schedule
                .camera(now, u64::from(c.width) * u64::from(c.height));
        }
    }

    /// The view's section plane.
    pub fn section(&self) -> Option<Section> {
        self.section
    }

    /// The view's part filter (made for the scene's part table) changed at `now`: the picture
    /// refines again. Set on the scene before each of the view's frames and picks, as the
    /// section plane is.
    pub fn set_parts(&mut self, filter: Arc<PartFilter>, now: Instant) {
        if *filter == *self.parts {
            return;
        }
        self.parts = filter;
        self.accum = None;
        if let Some(c) = &self.camera {
            self.schedule
                .camera(now, u64::from(c.width) * u64::from(c.height));
        }
    }

    /// Sets the view's section plane and part filter on `scene`.
    fn put_on(&self, scene: &Scene) {
        scene.set_section(self.section);
        scene.set_shared_parts(Arc::clone(&self.parts));
    }

    /// The quality asked for changed; refused (changing nothing) when out of range.
    pub fn set_quality(&mut self, quality: Quality) -> Result<(), TraceError> {
        check_quality(&quality)?;
        if quality != self.schedule.asked() {
            self.accum = None;
            self.schedule.quality(quality);
        }
        Ok(())
    }

    /// What to do at `now`.
    pub fn next(&mut self, now: Instant) -> Next {
        if self.camera.is_none() {
            return Next::Idle;
        }
        self.schedule.next(now)
    }

    /// The schedule, for its state.
    pub fn schedule(&self) -> &Schedule {
        &self.schedule
    }

    /// What pixel (`x`, `y`) of the full-size image shows, at the PoE of the still image
    /// ([`crate::pick::pick`]: it waits for the blocks its ray needs, so it answers the finest
    /// surface there whatever the cache holds); None on the background.
    pub fn pick(
        &self,
        scene: &Scene,
        cache: &Cache,
        (x, y): (u32, u32),
    ) -> Result<Option<Pick>, TraceError> {
        let camera = self
            .camera
            .ok_or_else(|| TraceError::Camera("the view has no camera yet".into()))?;
        self.put_on(scene);
        pick(
            scene,
            cache.get(),
            &camera,
            (x, y),
            self.schedule.asked().poe,
        )
    }

    /// Renders `plan` (from [`LiveView::next`]) of `scene` through `cache`, steps the cache, and
    /// lets an async cache's fetchers work freely until the next frame; `rate` measures loads.
    /// An error (a frame that cannot be rendered) halts the schedule until the next change.
    pub fn render(
        &mut self,
        plan: Plan,
        scene: &Scene,
        cache: &Cache,
        rate: &mut LoadRate,
    ) -> Result<LiveFrame, TraceError> {
        let result = self.render_plan(plan, scene, cache, rate);
        if result.is_err() {
            self.schedule.halt();
        }
        result
    }

    fn render_plan(
        &mut self,
        plan: Plan,
        scene: &Scene,
        cache: &Cache,
        rate: &mut LoadRate,
    ) -> Result<LiveFrame, TraceError> {
        let full = self
            .camera
            .ok_or_else(|| TraceError::Camera("the view has no camera yet".into()))?;
        // The still frames go through the points of `render --spp`'s samples; the others
        // through the pixel centres.
        let aimed = match plan.stage {
            Stage::Settle | Stage::Accumulate => {
                pass_frame(&full, plan.sample, self.schedule.asked().spp)?
            }
            _ => scaled(&full, plan.scale).frame()?,
        };
        let opts = RenderOptions {
            poe: plan.poe,
            spp: 1,
            ..self.base
        };
        self.put_on(scene);
        let frame = session::frame_aimed(scene, cache.get(), &aimed, &opts)?;
        if let Some(ac) = cache.as_async() {
            ac.idle();
        }
        let now = Instant::now();
        let stats = &frame.stats;
        let c = &stats.cache;
        let outcome = Outcome {
            ms: stats.ms + frame.step_ms,
            pixels: u64::from(aimed.width()) * u64::from(aimed.height()),
            wanted: c.blocks_wanted_last_frame,
        };
        let verdict = self.schedule.finished(plan, outcome, now);
        let p = stats.primary;
        let hits = p.triangle + p.voxel + p.rlod + p.proxy;
        let figures = LiveFigures {
            stage: plan.stage.name(),
            last: verdict.last,
            stale: verdict.stale,
            width: aimed.width(),
            height: aimed.height(),
            poe: plan.poe,
            samples: 1,
            spp: self.schedule.asked().spp,
            ms: outcome.ms,
            step_ms: frame.step_ms,
            primary: p,
            full_detail: if hits == 0 {
                1.0
            } else {
                p.triangle as f64 / hits as f64
            },
            cache_mib: c.bytes_resident as f64 / 1048576.0,
            cache_budget_mib: c.budget_bytes as f64 / 1048576.0,
            blocks_pending: c.blocks_pending,
            blocks_missed: c.blocks_wanted_last_frame,
            blocks_loaded_per_s: rate.update(c.blocks_loaded, now),
            complete: self.schedule.complete(),
        };
        let mut out = LiveFrame {
            seq: self.seq,
            image: frame.image,
            plan,
            figures,
        };
        if verdict.stale {
            return Ok(out);
        }
        match plan.stage {
            Stage::Settle => self.accum = Some(Accumulator::new(&out.image)),
            Stage::Accumulate => {
                if let Some(acc) = &mut self.accum {
                    if verdict.keep {
                        acc.add(&out.image);
                    }
                    out.image = acc.image();
                    out.figures.samples = acc.samples();
                }
            }
            _ => {}
        }
        Ok(out)
    }
}

/// `camera` at `scale` of its width and height (at least a pixel each).
fn scaled(camera: &Camera, scale: f64) -> Camera {
    if scale >= 1.0 {
        return *camera;
    }
    let dim = |d: u32| ((f64::from(d) * scale).round() as u32).clamp(1, d.max(1));
    Camera {
        width: dim(camera.width),
        height: dim(camera.height),
        ..*camera
    }
}
