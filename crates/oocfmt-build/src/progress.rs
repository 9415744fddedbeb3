//! Progress reporting for long phases, without tying the library to a terminal: the CLI shows
//! bars, tests and benches pass [`NoProgress`].

/// Receives phase starts and advances. `total` is in the phase's own unit (bytes, triangles).
pub trait Progress {
    /// A phase named `name` starts; `total` is its amount of work, None when unknown.
    fn phase(&mut self, name: &str, total: Option<u64>);
    /// `done` units of the current phase are complete so far (a running total, not a step).
    fn advance(&mut self, done: u64);
    /// The current phase is over.
    fn finish_phase(&mut self);
    /// Something the user should know that does not stop the work (a stale spill folder
    /// removed, say), as soon as it happens rather than in the final report.
    fn warn(&mut self, _message: &str) {}
}

/// Ignores everything.
pub struct NoProgress;

impl Progress for NoProgress {
    fn phase(&mut self, _name: &str, _total: Option<u64>) {}
    fn advance(&mut self, _done: u64) {}
    fn finish_phase(&mut self) {}
}
