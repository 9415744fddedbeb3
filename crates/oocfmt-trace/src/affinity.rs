//! Which cores the render threads run on.
//!
//! With as many render threads as cores, the scheduler can still put two of them on one core
//! while another core runs something less urgent, such as a fetcher 10 nice levels below: it
//! then counts that core as busy and may leave both render threads sharing the first for tens
//! of milliseconds (24 ms in one cold frame of a traced walkthrough:
//! docs/notes/2026-12-01-cold-start-frame-bound.md). Bound each to its own core, two render
//! threads never wait for the same core; the fetchers, unbound, run wherever a render thread
//! leaves time.

/// The cores this process may run on, in increasing order (Linux: its affinity mask); `None`
/// where the system does not say.
#[cfg(target_os = "linux")]
pub fn usable_cores() -> Option<Vec<usize>> {
    use rustix::thread::{sched_getaffinity, CpuSet};
    let set = sched_getaffinity(None).ok()?;
    Some((0..CpuSet::MAX_CPU).filter(|&c| set.is_set(c)).collect())
}

#[cfg(not(target_os = "linux"))]
pub fn usable_cores() -> Option<Vec<usize>> {
    None
}

/// Binds the calling thread to `core`; false where the system refused or cannot.
#[cfg(target_os = "linux")]
pub fn bind_this_thread(core: usize) -> bool {
    use rustix::thread::{sched_setaffinity, CpuSet};
    if core >= CpuSet::MAX_CPU {
        return false;
    }
    let mut set = CpuSet::new();
    set.set(core);
    sched_setaffinity(None, &set).is_ok()
}

#[cfg(not(target_os = "linux"))]
pub fn bind_this_thread(_core: usize) -> bool {
    false
}

fn all_distinct(cores: &[usize]) -> bool {
    let mut sorted = cores.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    sorted.len() == cores.len()
}

/// Binds each thread of the current rayon pool to its own core of `cores`, in order, and
/// returns the cores it bound them to: empty, with every thread left as it was, where there
/// are fewer than 2 threads, fewer distinct cores than threads, or the system refused one.
pub fn bind_pool(cores: &[usize]) -> Vec<usize> {
    let threads = rayon::current_num_threads();
    if threads < 2 || !all_distinct(cores) || cores.len() < threads {
        return Vec::new();
    }
    let tried = rayon::broadcast(|ctx| {
        let before = usable_cores();
        let bound = cores
            .get(ctx.index())
            .is_some_and(|&core| bind_this_thread(core));
        (before, bound)
    });
    if tried.iter().all(|&(_, bound)| bound) {
        return cores
            .get(..threads)
            .map(<[usize]>::to_vec)
            .unwrap_or_default();
    }
    // All or none: a pool with some threads bound and some not could still stack two.
    rayon::broadcast(|ctx| {
        if let Some((Some(before), _)) = tried.get(ctx.index()) {
            allow_this_thread(before);
        }
    });
    Vec::new()
}

/// Lets the calling thread run on any of `cores`.
#[cfg(target_os = "linux")]
fn allow_this_thread(cores: &[usize]) -> bool {
    use rustix::thread::{sched_setaffinity, CpuSet};
    let mut set = CpuSet::new();
    for &c in cores.iter().filter(|&&c| c < CpuSet::MAX_CPU) {
        set.set(c);
    }
    sched_setaffinity(None, &set).is_ok()
}

#[cfg(not(target_os = "linux"))]
fn allow_this_thread(_cores: &[usize]) -> bool {
    false
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The one core the calling thread may run on, if it is bound to one.
    fn bound_core() -> Option<usize> {
        match usable_cores()?.as_slice() {
            [core] => Some(*core),
            _ => None,
        }
    }

    #[test]
    fn a_pool_binds_each_thread_to_its_own_core_or_none() {
        let Some(cores) = usable_cores() else {
            return;
        };
        assert!(!cores.is_empty());
        assert!(cores.windows(2).all(|w| w[0] < w[1]));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        // Each thread's one core, if it is bound to one.
        let bound = || rayon::broadcast(|_| bound_core());
        // A process allowed one core has its threads on it from the start.
        let alone = (cores.len() == 1).then_some(cores[0]);
        pool.install(|| {
            assert_eq!(
                bound(),
                [alone, alone],
                "a new pool's threads are not bound"
            );
            // One core for two threads: nothing is bound.
            assert!(bind_pool(&cores[..1]).is_empty());
            // The same core twice: refused as well.
            assert!(bind_pool(&[cores[0], cores[0]]).is_empty());
            assert_eq!(bound(), [alone, alone]);
            // A core that is not there: the other thread is let go again.
            assert!(bind_pool(&[cores[0], usize::MAX]).is_empty());
            let each = rayon::broadcast(|_| usable_cores());
            assert!(each.iter().all(|c| c.as_ref() == Some(&cores)), "{each:?}");
            if cores.len() >= 2 {
                let want = vec![cores[1], cores[0]];
                assert_eq!(bind_pool(&want), want);
                assert_eq!(bound(), [Some(cores[1]), Some(cores[0])]);
            }
        });
        // The test's own thread was never bound.
        assert_eq!(usable_cores(), Some(cores));
    }
}
