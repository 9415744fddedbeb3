//! Disk accounting for one conversion's spill files: bytes on disk now, the output file's bytes
//! so far, and the peak of their sum, for the report's `peak_disk_bytes`. Every spill write is
//! charged here before it is made, which is also where tests make the disk "fill up".

use std::sync::atomic::{AtomicU64, Ordering};

/// Bytes of one spill segment file: a pass frees its input a segment at a time, so the disk
/// holds about one copy of the data plus a segment per stream being read. (A billion
/// triangles make a few thousand segments at once.)
pub const SEGMENT_BYTES: u64 = 16 << 20;

/// The first segments of a run are this small.
const MIN_SEGMENT_BYTES: u64 = 1 << 20;

/// What one conversion's spill files take on disk. Shared (behind an `Arc`) by every spill
/// writer and reader of that conversion.
#[derive(Debug)]
pub struct SpillDisk {
    /// Bytes a segment file may hold before a writer starts the next one.
    segment_bytes: u64,
    /// Spill bytes on disk now.
    now: AtomicU64,
    /// Bytes of the output file written so far.
    output: AtomicU64,
    /// The most `now + output` has been.
    peak: AtomicU64,
    /// Spill bytes past which a write fails as on a full disk (tests only).
    budget: Option<u64>,
}

impl Default for SpillDisk {
    fn default() -> Self {
        SpillDisk::new()
    }
}

impl SpillDisk {
    /// Accounting for a new conversion, with [`SEGMENT_BYTES`] segments (in this crate's tests,
    /// the segment size and byte budget `with_test_disk` set).
    pub fn new() -> SpillDisk {
        #[cfg(test)]
        let (segment_bytes, budget) = TEST_DISK.with(std::cell::Cell::get);
        #[cfg(not(test))]
        let (segment_bytes, budget) = (SEGMENT_BYTES, None);
        SpillDisk::with_segments(segment_bytes, budget)
    }

    /// Accounting with segments of `segment_bytes` (at least 1) and, when given, a `budget` of
    /// spill bytes past which writes fail with [`std::io::ErrorKind::StorageFull`].
    pub fn with_segments(segment_bytes: u64, budget: Option<u64>) -> SpillDisk {
        SpillDisk {
            segment_bytes: segment_bytes.max(1),
            now: AtomicU64::new(0),
            output: AtomicU64::new(0),
            peak: AtomicU64::new(0),
            budget,
        }
    }

    /// Bytes the next segment of a run (or stream) that holds `run_bytes` so far may hold: a
    /// 64th of the run, at least 1 MiB, at most the segment size. A segment being read is
    /// still on disk when its records are already in the next pass's output, so small
    /// segments keep that overlap small; growing ones keep a billion triangles to a few
    /// thousand files.
    pub fn segment_limit(&self, run_bytes: u64) -> u64 {
        (run_bytes / 64)
            .max(MIN_SEGMENT_BYTES)
            .min(self.segment_bytes)
    }

    /// Records `bytes` about to be written to a spill file; refuses them as a full disk would
    /// when they would pass the budget.
    pub fn charge(&self, bytes: u64) -> std::io::Result<()> {
        let before = self.now.fetch_add(bytes, Ordering::Relaxed);
        if let Some(budget) = self.budget {
            if before.saturating_add(bytes) > budget {
                self.now.fetch_sub(bytes, Ordering::Relaxed);
                return Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    format!("no space left on device (a test budget of {budget} spill bytes)"),
                ));
            }
        }
        self.note_peak();
        Ok(())
    }

    /// Records that spill files of `bytes` in all were deleted.
    pub fn release(&self, bytes: u64) {
        let _ = self
            .now
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
                Some(n.saturating_sub(bytes))
            });
    }

    /// Records that the output file has reached `bytes`.
    pub fn set_output(&self, bytes: u64) {
        self.output.store(bytes, Ordering::Relaxed);
        self.note_peak();
    }

    /// Spill bytes on disk now.
    pub fn spill_bytes(&self) -> u64 {
        self.now.load(Ordering::Relaxed)
    }

    /// The most bytes spill files and the output took at once, so far.
    pub fn peak(&self) -> u64 {
        self.peak.load(Ordering::Relaxed)
    }

    fn note_peak(&self) {
        let total = self
            .now
            .load(Ordering::Relaxed)
            .saturating_add(self.output.load(Ordering::Relaxed));
        self.peak.fetch_max(total, Ordering::Relaxed);
    }
}

#[cfg(test)]
thread_local! {
    /// Segment size and spill byte budget of the [`SpillDisk`]s made on this thread.
    static TEST_DISK: std::cell::Cell<(u64, Option<u64>)> =
        const { std::cell::Cell::new((SEGMENT_BYTES, None)) };
}

/// Runs `f` with every [`SpillDisk`] it makes on this thread using `segment_bytes` segments
/// and failing writes past `budget` spill bytes: how tests fill the disk of a whole
/// conversion.
#[cfg(test)]
pub fn with_test_disk<R>(segment_bytes: u64, budget: Option<u64>, f: impl FnOnce() -> R) -> R {
    let before = TEST_DISK.with(|c| c.replace((segment_bytes, budget)));
    let r = f();
    TEST_DISK.with(|c| c.set(before));
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_peak_counts_spill_and_output_together() {
        let d = SpillDisk::with_segments(10, None);
        d.charge(100).unwrap_or_else(|e| panic!("{e}"));
        d.release(60);
        d.set_output(50);
        assert_eq!((d.spill_bytes(), d.peak()), (40, 100));
        d.charge(30).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(d.peak(), 120);
    }

    #[test]
    fn segments_grow_with_their_run_up_to_the_segment_size() {
        let d = SpillDisk::with_segments(SEGMENT_BYTES, None);
        assert_eq!(d.segment_limit(0), MIN_SEGMENT_BYTES);
        assert_eq!(d.segment_limit(200 << 20), (200 << 20) / 64);
        assert_eq!(d.segment_limit(u64::MAX), SEGMENT_BYTES);
        // Tests make tiny segments.
        assert_eq!(
            SpillDisk::with_segments(80, None).segment_limit(1 << 30),
            80
        );
    }

    #[test]
    fn a_budget_refuses_the_write_that_passes_it() {
        let d = SpillDisk::with_segments(10, Some(100));
        assert!(d.charge(100).is_ok());
        let e = d.charge(1).err().map(|e| e.kind());
        assert_eq!(e, Some(std::io::ErrorKind::StorageFull));
        assert_eq!(d.spill_bytes(), 100);
    }
}
