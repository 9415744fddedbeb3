//! Counting the times a render thread waits on I/O: the measure behind "rays never wait on the
//! disk" (design.md §7). A render thread is a thread of the rayon pool frames are traced on
//! ([`crate::render`]); a block read made on one is a wait, counted where caches read blocks.
//! The blocking and mmap caches read every miss that way. The asynchronous cache never does:
//! its render threads take no lock a fetcher holds across a read (fetchers hold none while they
//! read) and receive from no channel, so the reads its fetchers make, and the one the cache's
//! constructor makes for the root, are not counted, and its count stays 0.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// A cache's count of block reads made on render threads.
#[derive(Debug, Default)]
pub(crate) struct Waits(AtomicU64);

impl Waits {
    /// Runs `read`, a block read, counting it when the calling thread is a render thread.
    pub(crate) fn read<T>(&self, read: impl FnOnce() -> T) -> T {
        if on_render_thread() {
            self.0.fetch_add(1, Relaxed);
        }
        read()
    }

    /// The reads counted so far.
    pub(crate) fn count(&self) -> u64 {
        self.0.load(Relaxed)
    }
}

/// Whether the calling thread is one of a rayon pool's: where frames trace their tiles.
fn on_render_thread() -> bool {
    rayon::current_thread_index().is_some()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn only_reads_on_pool_threads_count() {
        let waits = Waits::default();
        assert_eq!(waits.read(|| 7), 7);
        std::thread::scope(|s| {
            s.spawn(|| waits.read(|| ()));
        });
        assert_eq!(
            waits.count(),
            0,
            "reads off the pool are no render thread's"
        );
        rayon::scope(|_| waits.read(|| ()));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| waits.read(|| ()));
        assert_eq!(waits.count(), 2);
    }
}
