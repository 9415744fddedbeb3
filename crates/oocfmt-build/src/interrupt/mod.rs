//! Stopping a build from outside (the CLI's Ctrl-C and SIGTERM handler) at the next check.
//!
//! The importers run through a [`TriangleSink`], which can fail: `WatchedSink` checks the
//! request every [`SINK_CHECK_EVERY`] triangles and returns [`ImportError::Interrupted`]. The
//! build phases after it only report through [`Progress`], which cannot fail, so
//! `WatchedProgress` checks at each phase start and advance (every split pass, chunk and
//! written batch) and unwinds the stack to `catch` with a private payload, as salsa's
//! `Cancelled` does: the panic hook is not run (`resume_unwind`), and on the way out the
//! drop guards remove what the build made (the writer's temporary file, spill runs), exactly
//! as on an error. Where panics abort instead of unwinding, only the typed checks stop a
//! build.

use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use oocfmt::metadata::Material;
use oocfmt_meshio::import::{
    DropReason, ImportError, InputTriangle, Location, PartDef, Skipped, TriangleSink,
};

use crate::progress::Progress;

/// How many triangles `WatchedSink` lets through between two looks at the request.
pub const SINK_CHECK_EVERY: u32 = 1 << 12;

/// A request to stop a build, shared with whoever may make it (a signal handler sets the
/// flag). The default is never requested.
#[derive(Clone, Debug, Default)]
pub struct Interrupt(Arc<AtomicBool>);

impl Interrupt {
    /// A request not made yet.
    pub fn new() -> Interrupt {
        Interrupt::default()
    }

    /// The flag behind the request, for a signal handler to set.
    pub fn flag(&self) -> &Arc<AtomicBool> {
        &self.0
    }

    /// Asks the build to stop at its next check.
    pub fn request(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether a stop was asked for.
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// The payload `WatchedProgress` unwinds with; only `catch` stops it.
struct Unwound;

/// Runs `f`; `None` when a `WatchedProgress` inside it unwound on a request. Any other
/// panic goes on unwinding.
pub(crate) fn catch<T>(f: impl FnOnce() -> T) -> Option<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(v) => Some(v),
        Err(payload) if payload.is::<Unwound>() => None,
        Err(payload) => resume_unwind(payload),
    }
}

/// A [`Progress`] that stops the build (unwinding to `catch`) once a stop is requested.
pub(crate) struct WatchedProgress<'a> {
    pub inner: &'a mut dyn Progress,
    pub interrupt: &'a Interrupt,
}

impl WatchedProgress<'_> {
    fn check(&self) {
        if cfg!(panic = "unwind") && self.interrupt.requested() {
            resume_unwind(Box::new(Unwound));
        }
    }
}

impl Progress for WatchedProgress<'_> {
    fn phase(&mut self, name: &str, total: Option<u64>) {
        self.check();
        self.inner.phase(name, total);
    }

    fn advance(&mut self, done: u64) {
        self.check();
        self.inner.advance(done);
    }

    /// Never stops: a phase ends after its work, and the writer's last phase ends after the
    /// output was renamed into place, which an interruption must not then deny.
    fn finish_phase(&mut self) {
        self.inner.finish_phase();
    }

    fn warn(&mut self, message: &str) {
        self.inner.warn(message);
    }
}

/// A [`TriangleSink`] that fails with [`ImportError::Interrupted`] once a stop is requested.
pub(crate) struct WatchedSink<'a> {
    inner: &'a mut dyn TriangleSink,
    interrupt: &'a Interrupt,
    /// Triangles (or, in a bounds pass, positions) until the next look at the request.
    countdown: u32,
    /// The inner sink only wants positions (a bounds pass): `place` is all it gets.
    positions_only: bool,
}

impl<'a> WatchedSink<'a> {
    pub(crate) fn new(inner: &'a mut dyn TriangleSink, interrupt: &'a Interrupt) -> Self {
        WatchedSink {
            positions_only: inner.positions_only(),
            inner,
            interrupt,
            countdown: SINK_CHECK_EVERY,
        }
    }

    /// Whether it is time to look at the request, and it was made.
    fn due(&mut self) -> bool {
        self.countdown -= 1;
        if self.countdown > 0 {
            return false;
        }
        self.countdown = SINK_CHECK_EVERY;
        self.interrupt.requested()
    }

    fn check(&mut self, at: &Location) -> Result<(), ImportError> {
        match self.due() {
            true => Err(ImportError::Interrupted { at: at.clone() }),
            false => Ok(()),
        }
    }
}

impl TriangleSink for WatchedSink<'_> {
    fn add_material(&mut self, material: Material) -> Result<u32, ImportError> {
        self.inner.add_material(material)
    }

    fn add_part(&mut self, part: PartDef) -> Result<u32, ImportError> {
        self.inner.add_part(part)
    }

    fn push(&mut self, triangle: InputTriangle, at: &Location) -> Result<(), ImportError> {
        self.check(at)?;
        self.inner.push(triangle, at)
    }

    fn reject(&mut self, reason: DropReason, at: &Location) -> Result<(), ImportError> {
        self.check(at)?;
        self.inner.reject(reason, at)
    }

    fn skip(&mut self, what: Skipped, count: u64) {
        self.inner.skip(what, count);
    }

    fn warn(&mut self, at: &Location, message: String) {
        self.inner.warn(at, message);
    }

    fn begin_file(&mut self, path: &str) {
        self.inner.begin_file(path);
    }

    /// In a bounds pass, which pushes nothing, a stop unwinds from here as from
    /// `WatchedProgress` (placing cannot fail).
    fn place(&mut self, exact: [f64; 3]) -> [f32; 3] {
        if self.positions_only && cfg!(panic = "unwind") && self.due() {
            resume_unwind(Box::new(Unwound));
        }
        self.inner.place(exact)
    }

    fn charge_disk(&mut self, bytes: u64) -> std::io::Result<()> {
        self.inner.charge_disk(bytes)
    }

    fn release_disk(&mut self, bytes: u64) {
        self.inner.release_disk(bytes);
    }

    fn positions_only(&self) -> bool {
        self.inner.positions_only()
    }
}

#[cfg(test)]
mod tests;
