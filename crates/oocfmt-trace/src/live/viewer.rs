//! The render thread behind a viewer: one scene and one cache, any number of views
//! (browser tabs), one frame at a time. Callers post cameras, qualities and picks from any thread;
//! the newest camera of a view replaces one not yet taken up, and each finished frame goes to
//! the view's sink, which keeps only the newest too (a viewer's sender drops frames it could not
//! send in time). Views with work take turns, a frame each.
//!
//! Locks: `Shared::state` guards the views, their inboxes and the shutdown flag; it is never
//! held while rendering or while a sink runs, and nothing else is taken under it.

use std::collections::BTreeMap;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Instant;

use super::schedule::{LiveOptions, Next, Plan, Quality};
use super::view::{check_camera, check_quality, LiveFrame, LiveView, LoadRate};
use crate::parts::PartFilter;
use crate::pick::Pick;
use crate::render::RenderOptions;
use crate::section::Section;
use crate::session::{stored_point, Cache};
use crate::{Camera, Scene, TraceError};

/// What a view's sink receives.
pub enum Event {
    /// A frame to show.
    Frame(Arc<LiveFrame>),
    /// The answer to [`Viewer::pick`].
    Pick(Picked),
    /// A frame could not be rendered, or a pick failed; the text says why. After a frame's
    /// failure the view waits for the next change.
    Error(String),
}

/// A pick's answer: the caller's number for it, the pixel, and what it met (None: the
/// background).
pub struct Picked {
    /// The number given to [`Viewer::pick`].
    pub seq: u64,
    /// The pixel picked, in the full-size image.
    pub pixel: (u32, u32),
    /// What the pixel's centre ray met first.
    pub hit: Option<Pick>,
}

/// Picks a view may have waiting; more replace the oldest.
const MAX_PENDING_PICKS: usize = 8;

/// Where a view's frames go; called on the render thread, so it should only hand them on.
pub type Sink = Box<dyn FnMut(Event) + Send>;

/// A view's number within its viewer.
pub type ViewId = u64;

struct Slot {
    /// Out while its frame renders.
    view: Option<(LiveView, Sink)>,
    /// A camera (stored coordinates) not yet given to the view, its number and arrival.
    camera: Option<(Camera, u64, Instant)>,
    quality: Option<Quality>,
    /// A section plane not yet given to the view (the inner None: no cut).
    section: Option<Option<Section>>,
    /// A part filter not yet given to the view.
    parts: Option<Arc<PartFilter>>,
    /// Picks not yet made: the caller's numbers and pixels.
    picks: Vec<(u64, (u32, u32))>,
}

/// What the render thread does next for a view.
enum Work {
    Frame(Plan),
    Picks(Vec<(u64, (u32, u32))>),
}

struct State {
    views: BTreeMap<ViewId, Slot>,
    next_id: ViewId,
    /// The view whose frame was rendered last: the next turn starts after it.
    turn: ViewId,
    shutdown: bool,
}

struct Shared {
    state: Mutex<State>,
    wake: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        // Every critical section is a few field writes: a panic cannot leave one half done.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The render thread and its views ([module documentation](self)). Dropping it stops the
/// thread after the frame it is rendering.
pub struct Viewer {
    shared: Arc<Shared>,
    scene: Arc<Scene>,
    base: RenderOptions,
    opts: LiveOptions,
    thread: Option<JoinHandle<()>>,
}

impl Viewer {
    /// Starts the render thread over `scene` and `cache` (from [`Cache::open`]); views render
    /// with `base` (background, lighting) and refine by `opts`.
    pub fn start(
        scene: Arc<Scene>,
        cache: Cache,
        base: RenderOptions,
        opts: LiveOptions,
    ) -> Result<Viewer, TraceError> {
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                views: BTreeMap::new(),
                next_id: 1,
                turn: 0,
                shutdown: false,
            }),
            wake: Condvar::new(),
        });
        let (s, sc) = (Arc::clone(&shared), Arc::clone(&scene));
        let thread = std::thread::Builder::new()
            .name("oocfmt-live".into())
            .spawn(move || render_loop(&s, &sc, &cache))
            .map_err(|e| TraceError::Options(format!("cannot start the render thread: {e}")))?;
        Ok(Viewer {
            shared,
            scene,
            base,
            opts,
            thread: Some(thread),
        })
    }

    /// The scene the views show.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    /// The options views refine by.
    pub fn options(&self) -> LiveOptions {
        self.opts
    }

    /// A new view refining to `quality`, its frames given to `sink`.
    pub fn connect(&self, quality: Quality, sink: Sink) -> Result<ViewId, TraceError> {
        let view = LiveView::new(self.opts, self.base, quality)?;
        let mut st = self.shared.lock();
        let id = st.next_id;
        st.next_id += 1;
        st.views.insert(
            id,
            Slot {
                view: Some((view, sink)),
                camera: None,
                quality: None,
                section: None,
                parts: None,
                picks: Vec::new(),
            },
        );
        Ok(id)
    }

    /// The view's camera, in world coordinates, numbered `seq`: it replaces any camera the
    /// view has not taken up yet. A camera that cannot make rays (or is too large) is refused
    /// and changes nothing.
    pub fn camera(&self, id: ViewId, world: Camera, seq: u64) -> Result<(), TraceError> {
        let camera = Camera {
            eye: stored_point(&self.scene, world.eye),
            look_at: stored_point(&self.scene, world.look_at),
            ..world
        };
        // The view's own check, made here so that the caller hears of a refusal.
        check_camera(&camera)?;
        let mut st = self.shared.lock();
        if let Some(slot) = st.views.get_mut(&id) {
            slot.camera = Some((camera, seq, Instant::now()));
        }
        drop(st);
        self.shared.wake.notify_all();
        Ok(())
    }

    /// The quality the view refines to; refused (changing nothing) when out of range.
    pub fn quality(&self, id: ViewId, quality: Quality) -> Result<(), TraceError> {
        check_quality(&quality)?;
        let mut st = self.shared.lock();
        if let Some(slot) = st.views.get_mut(&id) {
            slot.quality = Some(quality);
        }
        drop(st);
        self.shared.wake.notify_all();
        Ok(())
    }

    /// The view's section plane, world coordinates (None: no cut; [`crate::section`]): it
    /// replaces any plane the view has not taken up yet, and the picture refines again.
    pub fn section(&self, id: ViewId, section: Option<Section>) {
        let mut st = self.shared.lock();
        if let Some(slot) = st.views.get_mut(&id) {
            slot.section = Some(section);
        }
        drop(st);
        self.shared.wake.notify_all();
    }

    /// The view's part filter (made for the scene's part table, [`PartFilter::from_ids`]): it
    /// replaces any filter the view has not taken up yet, and the picture refines again.
    pub fn parts(&self, id: ViewId, filter: PartFilter) {
        let mut st = self.shared.lock();
        if let Some(slot) = st.views.get_mut(&id) {
            slot.parts = Some(Arc::new(filter));
        }
        drop(st);
        self.shared.wake.notify_all();
    }

    /// Asks what pixel `pixel` of the view's full-size image shows (after the camera and
    /// quality posted before it); the answer, numbered `seq`, goes to the sink between two
    /// frames. A view without a camera answers with an error.
    pub fn pick(&self, id: ViewId, seq: u64, pixel: (u32, u32)) {
        let mut st = self.shared.lock();
        if let Some(slot) = st.views.get_mut(&id) {
            if slot.picks.len() >= MAX_PENDING_PICKS {
                slot.picks.remove(0);
            }
            slot.picks.push((seq, pixel));
        }
        drop(st);
        self.shared.wake.notify_all();
    }

    /// Forgets the view; a frame of it being rendered still goes to its sink.
    pub fn disconnect(&self, id: ViewId) {
        self.shared.lock().views.remove(&id);
    }

    /// How many views are connected.
    pub fn views(&self) -> usize {
        self.shared.lock().views.len()
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        self.shared.lock().shutdown = true;
        self.shared.wake.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Gives a slot's inbox to its view.
fn take_inbox(slot: &mut Slot) {
    let Some((view, sink)) = &mut slot.view else {
        return;
    };
    if let Some(q) = slot.quality.take() {
        if let Err(e) = view.set_quality(q) {
            sink(Event::Error(e.to_string()));
        }
    }
    if let Some(section) = slot.section.take() {
        view.set_section(section, Instant::now());
    }
    if let Some(filter) = slot.parts.take() {
        view.set_parts(filter, Instant::now());
    }
    if let Some((camera, seq, at)) = slot.camera.take() {
        if let Err(e) = view.set_camera(camera, seq, at) {
            sink(Event::Error(e.to_string()));
        }
    }
}

/// The next view with work (picks first, then a frame to render), taking turns after `turn`,
/// or the earliest instant a sleeping one wakes.
fn next_work(st: &mut State, now: Instant) -> Result<(ViewId, Work), Option<Instant>> {
    let turn = st.turn;
    let later = st.views.range(turn + 1..).map(|(&id, _)| id);
    let order: Vec<ViewId> = later
        .chain(st.views.range(..=turn).map(|(&id, _)| id))
        .collect();
    let mut wake: Option<Instant> = None;
    for id in order {
        let Some(slot) = st.views.get_mut(&id) else {
            continue;
        };
        take_inbox(slot);
        let Some((view, _)) = &mut slot.view else {
            continue;
        };
        if !slot.picks.is_empty() {
            return Ok((id, Work::Picks(std::mem::take(&mut slot.picks))));
        }
        match view.next(now) {
            Next::Render(plan) => return Ok((id, Work::Frame(plan))),
            Next::Sleep(t) => wake = Some(wake.map_or(t, |w| w.min(t))),
            Next::Idle => {}
        }
    }
    Err(wake)
}

fn render_loop(shared: &Shared, scene: &Scene, cache: &Cache) {
    let mut rate = LoadRate::new();
    let mut st = shared.lock();
    while !st.shutdown {
        let now = Instant::now();
        let (id, work) = match next_work(&mut st, now) {
            Ok(found) => found,
            Err(Some(t)) => {
                let wait = t.saturating_duration_since(now);
                st = shared
                    .wake
                    .wait_timeout(st, wait)
                    .map_or_else(|e| e.into_inner().0, |(g, _)| g);
                continue;
            }
            Err(None) => {
                st = shared.wake.wait(st).unwrap_or_else(|e| e.into_inner());
                continue;
            }
        };
        st.turn = id;
        let Some((mut view, mut sink)) = st.views.get_mut(&id).and_then(|s| s.view.take()) else {
            continue;
        };
        drop(st);
        match work {
            Work::Frame(plan) => sink(match view.render(plan, scene, cache, &mut rate) {
                Ok(frame) => Event::Frame(Arc::new(frame)),
                Err(e) => Event::Error(e.to_string()),
            }),
            Work::Picks(picks) => {
                for (seq, pixel) in picks {
                    sink(match view.pick(scene, cache, pixel) {
                        Ok(hit) => Event::Pick(Picked { seq, pixel, hit }),
                        Err(e) => Event::Error(format!("pick {seq}: {e}")),
                    });
                }
            }
        }
        st = shared.lock();
        if let Some(slot) = st.views.get_mut(&id) {
            slot.view = Some((view, sink));
        }
    }
}
