//! The refine schedule of a live view: what the next frame renders (its resolution, pixels of
//! error and sample) given how the camera moved and how long the last frames took. Pure
//! bookkeeping, with the time passed in, so that it is tested without a scene.
//!
//! While the camera moves, frames hold [`LiveOptions::target_ms`]: the resolution follows the
//! measured cost per pixel (at a PoE of at least 1, which costs little to see while moving and
//! lets coarser levels stand in for blocks), and only when the smallest scale is still too slow
//! does the PoE rise, doubling up to [`LiveOptions::max_moving_poe`]. Once the camera has stayed
//! put for [`LiveOptions::still_ms`] the view refines: full resolution at the moving PoE
//! ([`Stage::Sharpen`]), then the PoE asked for until a frame finds every block it wants
//! ([`Stage::Settle`], sample 0 of `spp`), then passes through the other samples averaged
//! into `spp` ([`Stage::Accumulate`]). A new camera restarts the schedule at once; a frame planned before it
//! is stale.

use std::time::{Duration, Instant};

use crate::session::MAX_SETTLE_FRAMES;

/// How a live view trades detail for frame time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiveOptions {
    /// Milliseconds a frame may take (render and cache step) while the camera moves.
    pub target_ms: f64,
    /// Milliseconds the camera must stay put before the view refines: shorter, and a slow
    /// drag pays for full-resolution frames between its steps.
    pub still_ms: f64,
    /// The smallest share of the asked width and height a moving frame renders at.
    pub min_scale: f64,
    /// The coarsest pixels of error a moving frame takes when the smallest scale is not fast
    /// enough.
    pub max_moving_poe: f32,
}

impl LiveOptions {
    /// 66 ms frames (15 per second) while moving, refining after 200 ms still, down to an
    /// eighth of the resolution, and up to 8 pixels of error.
    pub const DEFAULT: LiveOptions = LiveOptions {
        target_ms: 66.0,
        still_ms: 200.0,
        min_scale: 0.125,
        max_moving_poe: 8.0,
    };
}

impl Default for LiveOptions {
    fn default() -> Self {
        LiveOptions::DEFAULT
    }
}

/// What a view asks for once the camera is still.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    /// Pixels of error of the still image (0: full detail).
    pub poe: f32,
    /// Samples per pixel the still image accumulates (1: the settled frame is the last).
    pub spp: u32,
}

/// Where in the schedule a frame is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The camera moves: resolution and PoE chosen to hold the target frame time.
    Moving,
    /// Still: full resolution at the moving PoE, a quick first sharp image.
    Sharpen,
    /// Still: full resolution at the asked PoE, rendered again while blocks arrive until a
    /// frame finds every block it wants.
    Settle,
    /// Still and settled: a pass through another sample of each pixel added to the average.
    Accumulate,
    /// Nothing left to do until the camera or the quality changes.
    Done,
}

impl Stage {
    /// The name the figures and the page use.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Moving => "moving",
            Stage::Sharpen => "sharpen",
            Stage::Settle => "settle",
            Stage::Accumulate => "accumulate",
            Stage::Done => "done",
        }
    }
}

/// One frame to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    /// The stage it belongs to.
    pub stage: Stage,
    /// Share of the asked width and height, in (0, 1].
    pub scale: f64,
    /// Pixels of error.
    pub poe: f32,
    /// The sample of the still image's `spp` the frame renders: 0 while settling, k > 0 the
    /// accumulation pass k ([`crate::live::accumulate::pass_frame`]; sample 0 of 1 is the pixel
    /// centres). Moving and sharpening frames go through the centres whatever it says.
    pub sample: u32,
    /// The camera and quality it was planned for; a later change makes it stale.
    pub generation: u64,
}

/// What the caller does next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Next {
    /// Render this frame now.
    Render(Plan),
    /// Nothing to render before this instant, unless the camera or the quality changes.
    Sleep(Instant),
    /// Nothing to render until the camera or the quality changes.
    Idle,
}

/// What a rendered frame cost and found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Milliseconds of the frame: its rays and the cache step after it.
    pub ms: f64,
    /// Pixels rendered.
    pub pixels: u64,
    /// Blocks the frame wanted and did not find (0: complete at its PoE).
    pub wanted: u64,
}

/// What became of a finished frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Verdict {
    /// The camera or the quality changed while it rendered.
    pub stale: bool,
    /// It is the last frame of the schedule: nothing better follows until something changes.
    pub last: bool,
    /// An accumulation pass that counts (one that wanted blocks is rendered again instead).
    pub keep: bool,
}

/// Accumulation passes that wanted blocks are rendered again at most this many times, then
/// kept.
const MAX_PASS_TRIES: u32 = 3;

/// The scale of the first moving frame, before any cost is known.
const FIRST_SCALE: f64 = 0.5;

/// The scale grows by at most this factor from one frame to the next: a frame that was quick
/// because its blocks were missing must not buy a full-resolution frame at once.
const MAX_GROWTH: f64 = 1.5;

/// Scale changes smaller than this share are not made, so frames keep their size.
const DEADBAND: f64 = 0.05;

/// The moving PoE halves again only with this much headroom in scale at the smallest scale
/// (about 2.5 times in time, more than halving the PoE costs on the measured models).
const POE_DOWN_HEADROOM: f64 = 1.6;

/// The refine schedule of one view ([module documentation](self)).
#[derive(Clone, Debug)]
pub struct Schedule {
    opts: LiveOptions,
    quality: Quality,
    /// Bumped by every change of camera or quality.
    generation: u64,
    /// When the camera last changed; None before the first camera.
    changed_at: Option<Instant>,
    /// The newest camera has no moving frame yet.
    dirty: bool,
    stage: Stage,
    /// Pixels of the asked image.
    full_pixels: u64,
    /// The scale of moving frames.
    scale: f64,
    /// The pixels of error of moving frames.
    moving_poe: f32,
    /// Milliseconds per pixel at `moving_poe`, smoothed; None until measured.
    cost: Option<f64>,
    /// The accumulation pass being rendered.
    sample: u32,
    /// Frames rendered for the current settle or pass.
    tries: u32,
    /// When the current settle or pass is rendered again (blocks being fetched meanwhile).
    resume_at: Option<Instant>,
    /// The last settle found every block it wanted.
    complete: bool,
}

impl Schedule {
    /// A schedule with nothing to render until its first camera.
    pub fn new(opts: LiveOptions, quality: Quality) -> Schedule {
        Schedule {
            opts,
            quality,
            generation: 0,
            changed_at: None,
            dirty: false,
            stage: Stage::Done,
            full_pixels: 1,
            scale: FIRST_SCALE.max(opts.min_scale).min(1.0),
            moving_poe: base_poe(quality.poe).min(opts.max_moving_poe.max(1.0)),
            cost: None,
            sample: 0,
            tries: 0,
            resume_at: None,
            complete: false,
        }
    }

    /// The camera changed at `now` to one of `pixels` pixels: the schedule starts again.
    pub fn camera(&mut self, now: Instant, pixels: u64) {
        self.generation += 1;
        self.changed_at = Some(now);
        self.dirty = true;
        self.stage = Stage::Moving;
        self.full_pixels = pixels.max(1);
        self.restart_still();
    }

    /// The still image asked for changed: refinement starts again at the new PoE (a moving
    /// camera is left to move).
    pub fn quality(&mut self, quality: Quality) {
        if quality == self.quality {
            return;
        }
        self.quality = quality;
        self.generation += 1;
        let base = base_poe(quality.poe);
        if self.moving_poe < base {
            self.moving_poe = base;
            self.cost = None;
        }
        if self.stage != Stage::Moving && self.changed_at.is_some() {
            self.stage = Stage::Settle;
        }
        self.restart_still();
    }

    fn restart_still(&mut self) {
        self.sample = 0;
        self.tries = 0;
        self.resume_at = None;
        self.complete = false;
    }

    /// The stage the next frame belongs to.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The quality asked for.
    pub fn asked(&self) -> Quality {
        self.quality
    }

    /// Whether the last settle found every block it wanted (false while it has not ended, and
    /// when [`MAX_SETTLE_FRAMES`] frames were not enough).
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// The scale and PoE of the next moving frame.
    pub fn moving(&self) -> (f64, f32) {
        (self.scale, self.moving_poe)
    }

    fn plan(&self, stage: Stage, scale: f64, poe: f32) -> Plan {
        Plan {
            stage,
            scale,
            poe,
            sample: self.sample,
            generation: self.generation,
        }
    }

    /// What to do at `now`.
    pub fn next(&mut self, now: Instant) -> Next {
        let Some(changed) = self.changed_at else {
            return Next::Idle;
        };
        if self.stage == Stage::Moving {
            if self.dirty {
                return Next::Render(self.plan(Stage::Moving, self.scale, self.moving_poe));
            }
            let still_at = changed + millis(self.opts.still_ms);
            if now < still_at {
                return Next::Sleep(still_at);
            }
            // The moving frame was already full resolution at the moving PoE: nothing to
            // sharpen.
            let sharp = self.scale >= 1.0 || self.moving_poe == self.quality.poe;
            self.stage = if sharp { Stage::Settle } else { Stage::Sharpen };
        }
        match self.stage {
            Stage::Sharpen => Next::Render(self.plan(Stage::Sharpen, 1.0, self.moving_poe)),
            Stage::Settle | Stage::Accumulate => match self.resume_at {
                Some(t) if now < t => Next::Sleep(t),
                _ => Next::Render(self.plan(self.stage, 1.0, self.quality.poe)),
            },
            Stage::Moving | Stage::Done => Next::Idle,
        }
    }

    /// `plan` was rendered with `outcome`, finishing at `now`.
    pub fn finished(&mut self, plan: Plan, outcome: Outcome, now: Instant) -> Verdict {
        if matches!(plan.stage, Stage::Moving | Stage::Sharpen) && plan.poe == self.moving_poe {
            self.measure(outcome);
        }
        let stale = plan.generation != self.generation || plan.stage != self.stage;
        if stale {
            return Verdict {
                stale: true,
                last: false,
                keep: false,
            };
        }
        let mut keep = false;
        match plan.stage {
            Stage::Moving => {
                self.dirty = false;
                self.steer();
            }
            Stage::Sharpen => {
                self.stage = Stage::Settle;
                self.tries = 0;
            }
            Stage::Settle => {
                self.tries += 1;
                if outcome.wanted > 0 && self.tries < MAX_SETTLE_FRAMES {
                    self.resume_at = Some(now + self.wait());
                } else {
                    self.complete = outcome.wanted == 0;
                    self.tries = 0;
                    self.resume_at = None;
                    self.sample = 1;
                    self.stage = if self.quality.spp > 1 {
                        Stage::Accumulate
                    } else {
                        Stage::Done
                    };
                }
            }
            Stage::Accumulate => {
                self.tries += 1;
                if outcome.wanted > 0 && self.tries < MAX_PASS_TRIES {
                    self.resume_at = Some(now + self.wait());
                } else {
                    keep = true;
                    self.tries = 0;
                    self.resume_at = None;
                    self.sample += 1;
                    if self.sample >= self.quality.spp {
                        self.stage = Stage::Done;
                    }
                }
            }
            Stage::Done => {}
        }
        Verdict {
            stale: false,
            last: self.stage == Stage::Done,
            keep,
        }
    }

    /// Ends the schedule until the next change (a frame that could not be rendered).
    pub fn halt(&mut self) {
        self.stage = Stage::Done;
        self.dirty = false;
    }

    /// How long a settle or pass that wanted blocks waits for the fetchers before it renders
    /// again: one target frame, so a still view costs the render threads little while they load.
    fn wait(&self) -> Duration {
        millis(self.opts.target_ms)
    }

    /// Adds a frame at the moving PoE to the cost per pixel.
    fn measure(&mut self, outcome: Outcome) {
        if !(outcome.ms.is_finite() && outcome.ms >= 0.0) || outcome.pixels == 0 {
            return;
        }
        let per_pixel = outcome.ms / outcome.pixels as f64;
        self.cost = Some(match self.cost {
            Some(c) => 0.5 * c + 0.5 * per_pixel,
            None => per_pixel,
        });
    }

    /// Chooses the next moving frame's scale and PoE from the measured cost: at the base PoE
    /// the scale that holds the target (lowered or raised, within the deadband and the growth
    /// limit); below the smallest scale the PoE doubles, and with headroom again it halves.
    fn steer(&mut self) {
        let Some(cost) = self.cost else {
            return;
        };
        let opts = &self.opts;
        let fits = (opts.target_ms / (cost * self.full_pixels as f64).max(1e-12)).sqrt();
        let base = base_poe(self.quality.poe);
        let max_poe = opts.max_moving_poe.max(base);
        if self.moving_poe > base {
            self.scale = opts.min_scale;
            if fits >= opts.min_scale * POE_DOWN_HEADROOM {
                self.moving_poe = (self.moving_poe / 2.0).max(base);
                self.cost = None;
            } else if fits < opts.min_scale && self.moving_poe < max_poe {
                self.moving_poe = (self.moving_poe * 2.0).min(max_poe);
                self.cost = None;
            }
            return;
        }
        if fits < opts.min_scale && self.moving_poe < max_poe {
            self.scale = opts.min_scale;
            self.moving_poe = (self.moving_poe * 2.0).min(max_poe);
            self.cost = None;
            return;
        }
        let want = fits.min(self.scale * MAX_GROWTH).clamp(opts.min_scale, 1.0);
        let edge = want == 1.0 || want == opts.min_scale;
        if edge || (want - self.scale).abs() > DEADBAND * self.scale {
            self.scale = want;
        }
    }
}

/// The PoE moving frames start from: the asked one, at least 1.
fn base_poe(asked: f32) -> f32 {
    asked.max(1.0)
}

fn millis(ms: f64) -> Duration {
    Duration::from_secs_f64((ms / 1e3).clamp(0.0, 3600.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    const Q: Quality = Quality { poe: 0.0, spp: 1 };
    const FULL: u64 = 1000 * 1000;

    fn at(t0: Instant, ms: u64) -> Instant {
        t0 + Duration::from_millis(ms)
    }

    /// Renders whatever the schedule asks at `now` with a cost of `ms_per_mpixel` per million
    /// pixels at `poe` 1 (halved per doubling of the PoE), wanting `wanted` blocks.
    fn step(s: &mut Schedule, now: Instant, ms_per_mpixel: f64, wanted: u64) -> Option<Plan> {
        let Next::Render(p) = s.next(now) else {
            return None;
        };
        let pixels = ((FULL as f64) * p.scale * p.scale) as u64;
        let ms = ms_per_mpixel * pixels as f64 / 1e6 / f64::from(p.poe.max(1.0));
        s.finished(p, Outcome { ms, pixels, wanted }, now);
        Some(p)
    }

    #[test]
    fn nothing_to_do_before_the_first_camera() {
        let mut s = Schedule::new(LiveOptions::DEFAULT, Q);
        assert_eq!(s.next(Instant::now()), Next::Idle);
    }

    #[test]
    fn moving_frames_hold_the_target_by_resolution() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Q);
        // 264 ms for a full frame: a half-resolution frame holds 66 ms.
        let mut last = None;
        for i in 0..20 {
            s.camera(at(t0, i * 16), FULL);
            last = step(&mut s, at(t0, i * 16), 264.0, 0);
        }
        let p = last.unwrap_or_else(|| panic!("a moving frame"));
        assert_eq!(p.stage, Stage::Moving);
        assert!((p.scale - 0.5).abs() < 0.03, "{p:?}");
        assert_eq!(p.poe, 1.0, "the PoE stays at 1 while resolution suffices");
    }

    #[test]
    fn a_fast_model_moves_at_full_resolution() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Q);
        let mut scales = Vec::new();
        for i in 0..8 {
            s.camera(at(t0, i * 16), FULL);
            scales.extend(step(&mut s, at(t0, i * 16), 20.0, 0).map(|p| p.scale));
        }
        // Growth is limited to 1.5 per frame: 0.5, 0.75, 1.
        assert_eq!(scales[..3], [0.5, 0.75, 1.0]);
        assert!(scales.iter().skip(2).all(|&s| s == 1.0), "{scales:?}");
    }

    #[test]
    fn too_slow_at_the_smallest_scale_raises_the_poe_and_headroom_lowers_it() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Q);
        // 20 s per full frame at PoE 1: even an eighth of the resolution takes 312 ms.
        let mut poes = Vec::new();
        for i in 0..30 {
            s.camera(at(t0, i * 16), FULL);
            poes.extend(step(&mut s, at(t0, i * 16), 20_000.0, 0).map(|p| p.poe));
        }
        assert_eq!(poes.last(), Some(&8.0), "{poes:?}");
        assert_eq!(s.moving().0, LiveOptions::DEFAULT.min_scale);
        // The model got cheap: the PoE comes back down to 1, then the resolution goes up.
        for i in 30..60 {
            s.camera(at(t0, i * 16), FULL);
            step(&mut s, at(t0, i * 16), 20.0, 0);
        }
        assert_eq!(s.moving(), (1.0, 1.0));
    }

    #[test]
    fn still_refines_sharpen_then_settle_then_accumulate() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Quality { poe: 0.0, spp: 3 });
        s.camera(t0, FULL);
        let moving = step(&mut s, t0, 264.0, 5).unwrap_or_else(|| panic!("moving"));
        assert_eq!((moving.stage, moving.scale), (Stage::Moving, 0.5));
        // Within the still delay nothing is rendered.
        assert_eq!(s.next(at(t0, 100)), Next::Sleep(at(t0, 200)));
        let sharpen = step(&mut s, at(t0, 200), 264.0, 2).unwrap_or_else(|| panic!("sharpen"));
        assert_eq!(
            (sharpen.stage, sharpen.scale, sharpen.poe),
            (Stage::Sharpen, 1.0, 1.0)
        );
        // Settle at the asked PoE while blocks are wanted, one target frame apart.
        let settle = step(&mut s, at(t0, 500), 264.0, 4).unwrap_or_else(|| panic!("settle"));
        assert_eq!((settle.stage, settle.poe), (Stage::Settle, 0.0));
        assert_eq!(s.next(at(t0, 510)), Next::Sleep(at(t0, 566)));
        let Next::Render(p) = s.next(at(t0, 566)) else {
            panic!("settle again")
        };
        let v = s.finished(
            p,
            Outcome {
                ms: 1.0,
                pixels: FULL,
                wanted: 0,
            },
            at(t0, 600),
        );
        assert_eq!(
            v,
            Verdict {
                stale: false,
                last: false,
                keep: false
            }
        );
        assert!(s.complete());
        // Two passes make three samples, the last one last.
        let mut verdicts = Vec::new();
        for (k, t) in [(1, 610), (2, 620)] {
            let Next::Render(p) = s.next(at(t0, t)) else {
                panic!("pass {k}")
            };
            assert_eq!((p.stage, p.sample), (Stage::Accumulate, k));
            verdicts.push(s.finished(
                p,
                Outcome {
                    ms: 1.0,
                    pixels: FULL,
                    wanted: 0,
                },
                at(t0, t),
            ));
        }
        assert!(verdicts.iter().all(|v| v.keep && !v.stale));
        assert_eq!(
            verdicts.iter().map(|v| v.last).collect::<Vec<_>>(),
            [false, true]
        );
        assert_eq!(s.next(at(t0, 700)), Next::Idle);
    }

    #[test]
    fn a_new_camera_makes_the_frame_in_flight_stale_and_restarts() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Quality { poe: 1.0, spp: 1 });
        s.camera(t0, FULL);
        step(&mut s, t0, 100.0, 0);
        let Next::Render(settle) = s.next(at(t0, 300)) else {
            panic!("settle")
        };
        assert_eq!(
            settle.stage,
            Stage::Settle,
            "moving at the asked PoE: no sharpen"
        );
        s.camera(at(t0, 310), FULL);
        let v = s.finished(
            settle,
            Outcome {
                ms: 1.0,
                pixels: FULL,
                wanted: 0,
            },
            at(t0, 320),
        );
        assert!(v.stale && !v.last);
        let Next::Render(p) = s.next(at(t0, 320)) else {
            panic!("moving")
        };
        assert_eq!(p.stage, Stage::Moving);
    }

    #[test]
    fn the_quality_restarts_refinement_without_moving() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Quality { poe: 2.0, spp: 1 });
        s.camera(t0, FULL);
        step(&mut s, t0, 10.0, 0);
        let p = step(&mut s, at(t0, 300), 10.0, 0).unwrap_or_else(|| panic!("settle"));
        assert_eq!((p.stage, p.poe), (Stage::Settle, 2.0));
        assert_eq!(s.next(at(t0, 400)), Next::Idle);
        s.quality(Quality { poe: 0.5, spp: 1 });
        let p = step(&mut s, at(t0, 410), 10.0, 0).unwrap_or_else(|| panic!("settle"));
        assert_eq!((p.stage, p.poe), (Stage::Settle, 0.5));
        assert_eq!(s.next(at(t0, 420)), Next::Idle);
    }

    #[test]
    fn a_settle_that_never_completes_ends_after_the_limit() {
        let t0 = Instant::now();
        let mut s = Schedule::new(LiveOptions::DEFAULT, Q);
        s.camera(t0, FULL);
        step(&mut s, t0, 10.0, 0);
        let mut frames = 0;
        let mut t = 300;
        while let Some(p) = step(&mut s, at(t0, t), 10.0, 7) {
            assert_ne!(p.stage, Stage::Moving);
            frames += 1;
            t += 100;
        }
        assert_eq!(s.next(at(t0, t)), Next::Idle);
        assert!(!s.complete());
        // The sharpen frame at PoE 1, then the settle frames up to the limit.
        assert_eq!(frames, 1 + MAX_SETTLE_FRAMES);
    }
}
