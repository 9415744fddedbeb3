//! How the asynchronous cache orders its fetches and picks what to evict, after the two designs
//! it follows:
//!
//! - fetch order: Áfra (2012) ranks a block by the rays that wanted it, each weighted by the
//!   angular size of the region; Wald et al. (2004, §4.3) rank it by the size of the region over
//!   its distance alone (a stand-in for the rays it affects, with no per-ray counting), mapped
//!   linearly to [`WALD_QUEUES`] discrete queues between the smallest and largest priority of
//!   the previous frame, the fetchers always serving the highest non-empty queue first;
//! - eviction: least recently used (Áfra), or Wald's second chance (§4.4): a clock hand cycles
//!   through the resident blocks once the cache is above [`HIGH_WATER`] of its budget, clearing
//!   each block's referenced bit, and evicts a block whose bit is still clear when the hand
//!   comes round again.
//!
//! Either way a block the current frame used is never evicted.

use std::collections::VecDeque;
use std::fmt;

use super::Wish;

/// How the fetchers order the blocks a frame asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FetchOrder {
    /// By the summed weight of the rays that wanted a block (Áfra 2012).
    #[default]
    Afra,
    /// By region size over distance, in [`WALD_QUEUES`] discrete queues (Wald et al. 2004).
    Wald,
}

/// What the asynchronous cache evicts when it needs room.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Eviction {
    /// The least recently used blocks first, when a fetch needs room.
    #[default]
    Lru,
    /// A clock sweep with a referenced bit per block, once above [`HIGH_WATER`] of the budget.
    SecondChance,
}

impl FetchOrder {
    /// The names [`FetchOrder::parse`] accepts, in variant order.
    pub const NAMES: [&'static str; 2] = ["afra", "wald"];

    /// The order's name on the command line and in the stats: `afra` or `wald`.
    pub fn name(self) -> &'static str {
        match self {
            FetchOrder::Afra => "afra",
            FetchOrder::Wald => "wald",
        }
    }

    /// The order named `s` (exactly one of [`FetchOrder::NAMES`]), or None.
    pub fn parse(s: &str) -> Option<FetchOrder> {
        match s {
            "afra" => Some(FetchOrder::Afra),
            "wald" => Some(FetchOrder::Wald),
            _ => None,
        }
    }
}

impl Eviction {
    /// The names [`Eviction::parse`] accepts, in variant order.
    pub const NAMES: [&'static str; 2] = ["lru", "second-chance"];

    /// The policy's name on the command line and in the stats: `lru` or `second-chance`.
    pub fn name(self) -> &'static str {
        match self {
            Eviction::Lru => "lru",
            Eviction::SecondChance => "second-chance",
        }
    }

    /// The policy named `s` (exactly one of [`Eviction::NAMES`]), or None.
    pub fn parse(s: &str) -> Option<Eviction> {
        match s {
            "lru" => Some(Eviction::Lru),
            "second-chance" => Some(Eviction::SecondChance),
            _ => None,
        }
    }
}

impl fmt::Display for FetchOrder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl fmt::Display for Eviction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Wald's discrete priority queues.
pub const WALD_QUEUES: u8 = 8;

/// The share of the budget above which the second-chance sweep starts evicting (Wald: "once
/// memory gets scarce, currently at a memory utilization of ~80%").
pub const HIGH_WATER: f64 = 0.8;

/// The smallest and largest finite Wald priority of a frame's requests: the range the next
/// frame's priorities are mapped over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// The smallest finite priority (size over distance); maps to queue 0.
    pub lo: f32,
    /// The largest finite priority; maps to the top queue. `lo <= hi`.
    pub hi: f32,
}

impl Range {
    /// The range of the finite sizes among `wishes`, or None when there is none.
    pub fn of<'a>(wishes: impl IntoIterator<Item = &'a Wish>) -> Option<Range> {
        wishes
            .into_iter()
            .map(|w| w.size)
            .filter(|s| s.is_finite())
            .fold(None, |r, s| {
                Some(match r {
                    None => Range { lo: s, hi: s },
                    Some(Range { lo, hi }) => Range {
                        lo: lo.min(s),
                        hi: hi.max(s),
                    },
                })
            })
    }

    /// Wald's queue of a priority: 0 (lowest) to `WALD_QUEUES - 1`, linear over the range;
    /// priorities outside the range go to the end queues, +inf (a region the eye is in) and
    /// NaN-free by construction of [`Wish`] to the top.
    pub fn queue(&self, size: f32) -> u8 {
        let top = WALD_QUEUES - 1;
        if !size.is_finite() || size >= self.hi {
            return top;
        }
        if size <= self.lo || self.hi <= self.lo {
            return 0;
        }
        let u = (size - self.lo) / (self.hi - self.lo);
        ((u * f32::from(WALD_QUEUES)) as u8).min(top)
    }
}

/// Orders blocks for the fetchers, lowest priority first (fetchers pop from the end); ties by
/// id, lower ids served first, so runs repeat. `root` always comes first. `previous`: the
/// Wald range of the frame before; without one the requests' own range is used. Returns the
/// order and the range of these requests (for the next frame).
pub fn rank(
    wanted: Vec<(u32, Wish)>,
    order: FetchOrder,
    previous: Option<Range>,
    root: Option<u32>,
) -> (Vec<u32>, Option<Range>) {
    let range = Range::of(wanted.iter().map(|(_, w)| w));
    let map = previous.or(range);
    let mut keyed: Vec<(f32, u32)> = wanted
        .into_iter()
        .map(|(id, w)| {
            let key = if Some(id) == root {
                f32::INFINITY
            } else {
                match (order, map) {
                    (FetchOrder::Afra, _) => w.weight,
                    (FetchOrder::Wald, Some(r)) => f32::from(r.queue(w.size)),
                    (FetchOrder::Wald, None) => f32::from(WALD_QUEUES - 1),
                }
            };
            (key, id)
        })
        .collect();
    keyed.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
    (keyed.into_iter().map(|(_, id)| id).collect(), range)
}

/// What the clock hand does with the block it points at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The block stays (in use by the frame, or referenced: its bit is now cleared): the hand
    /// moves on and meets it again next round.
    Keep,
    /// The block was evicted, or is no longer resident: it leaves the clock.
    Remove,
}

/// The ring of resident blocks the second-chance hand cycles through; the front is under the
/// hand. New blocks join behind the hand, so they are the last it meets.
#[derive(Debug, Default)]
pub struct Clock {
    ring: VecDeque<u32>,
}

impl Clock {
    /// Adds a newly resident block `id` behind the hand.
    pub fn insert(&mut self, id: u32) {
        self.ring.push_back(id);
    }

    /// How many blocks the ring holds.
    pub fn len(&self) -> usize {
        self.ring.len()
    }

    /// Whether the ring holds no block.
    pub fn is_empty(&self) -> bool {
        self.ring.is_empty()
    }

    /// Moves the hand until `enough()` holds, letting `visit` decide on each block (clear its
    /// bit and keep it, or evict it), for one round at most: a block whose bit the hand
    /// clears is evicted only if it is still clear when the hand comes round in a later
    /// sweep, so a block used since the last step always survives this one (the steps between
    /// frames are Wald's evictor cycling "slowly but continuously"). When every block is
    /// referenced or in use, a sweep frees nothing and the fetches wait for the next step.
    pub fn sweep(
        &mut self,
        mut visit: impl FnMut(u32) -> Verdict,
        mut enough: impl FnMut() -> bool,
    ) {
        let mut budget = self.ring.len();
        while budget > 0 && !enough() {
            budget -= 1;
            let Some(id) = self.ring.pop_front() else {
                return;
            };
            if visit(id) == Verdict::Keep {
                self.ring.push_back(id);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use std::collections::{HashMap, HashSet};

    use super::*;

    /// A cache of blocks with referenced bits, swept until `evictions` blocks went.
    fn sweep_evicting(
        clock: &mut Clock,
        referenced: &mut HashMap<u32, bool>,
        in_use: &HashSet<u32>,
        evictions: usize,
    ) -> Vec<u32> {
        let gone = std::cell::RefCell::new(Vec::new());
        clock.sweep(
            |id| {
                if in_use.contains(&id) {
                    return Verdict::Keep;
                }
                let r = referenced.get_mut(&id).unwrap();
                if std::mem::replace(r, false) {
                    Verdict::Keep
                } else {
                    gone.borrow_mut().push(id);
                    Verdict::Remove
                }
            },
            || gone.borrow().len() >= evictions,
        );
        gone.into_inner()
    }

    #[test]
    fn a_used_block_gets_a_second_chance() {
        let mut clock = Clock::default();
        let mut referenced = HashMap::new();
        for id in 1..=4 {
            clock.insert(id);
            referenced.insert(id, false);
        }
        // Block 1, first under the hand, was used since the hand last passed.
        referenced.insert(1, true);
        let none = HashSet::new();
        assert_eq!(sweep_evicting(&mut clock, &mut referenced, &none, 1), [2]);
        assert!(
            !referenced[&1],
            "the hand cleared the bit of the block it spared"
        );
        assert_eq!(sweep_evicting(&mut clock, &mut referenced, &none, 1), [3]);
        // Not used again: the next time round it goes.
        assert_eq!(
            sweep_evicting(&mut clock, &mut referenced, &none, 2),
            [4, 1]
        );
        assert!(clock.is_empty());
    }

    #[test]
    fn blocks_in_use_are_never_evicted_and_a_sweep_is_one_round_at_most() {
        let mut clock = Clock::default();
        let mut referenced = HashMap::new();
        for id in 0..5 {
            clock.insert(id);
            referenced.insert(id, true);
        }
        let in_use: HashSet<u32> = [0, 2, 4].into();
        // Asks for more evictions than can be made: one round clears the bits, evicts
        // nothing, and stops; the next round evicts what the frame did not use since.
        let evicted = sweep_evicting(&mut clock, &mut referenced, &in_use, 10);
        assert!(evicted.is_empty(), "{evicted:?}");
        assert_eq!(clock.len(), 5);
        let evicted = sweep_evicting(&mut clock, &mut referenced, &in_use, 10);
        assert_eq!(evicted, [1, 3]);
        assert_eq!(clock.len(), 3);
    }

    fn wish(weight: f32, size: f32) -> Wish {
        Wish { weight, size }
    }

    #[test]
    fn wald_maps_priorities_linearly_to_eight_queues() {
        let r = Range { lo: 1.0, hi: 9.0 };
        assert_eq!(r.queue(1.0), 0);
        assert_eq!(r.queue(0.5), 0);
        assert_eq!(r.queue(2.0), 1);
        assert_eq!(r.queue(4.99), 3);
        assert_eq!(r.queue(5.0), 4);
        assert_eq!(r.queue(8.99), 7);
        assert_eq!(r.queue(100.0), 7);
        assert_eq!(r.queue(f32::INFINITY), 7);
        let flat = Range { lo: 2.0, hi: 2.0 };
        assert_eq!(flat.queue(1.0), 0);
        assert_eq!(flat.queue(2.0), 7);
    }

    #[test]
    fn wald_ranks_by_size_over_distance_in_queues_and_afra_by_rays() {
        // Block 10: many rays, a small far region; block 20: one ray, a big near region;
        // blocks 30 and 31: the same middle queue, served by id; block 5: the root.
        let wanted = vec![
            (10, wish(500.0, 0.01)),
            (20, wish(1.5, 0.8)),
            (31, wish(3.0, 0.41)),
            (30, wish(2.0, 0.42)),
            (5, wish(1.0, 0.001)),
        ];
        // Fetchers pop from the end: reverse for the order served.
        let served = |v: Vec<u32>| v.into_iter().rev().collect::<Vec<_>>();
        let (afra, _) = rank(wanted.clone(), FetchOrder::Afra, None, Some(5));
        assert_eq!(served(afra), [5, 10, 31, 30, 20]);
        let (wald, range) = rank(wanted.clone(), FetchOrder::Wald, None, Some(5));
        assert_eq!(served(wald), [5, 20, 30, 31, 10]);
        assert_eq!(range, Some(Range { lo: 0.001, hi: 0.8 }));
        // The previous frame's range maps this one's: all of these above it share the top
        // queue and are served by id.
        let before = Range { lo: 0.0, hi: 0.005 };
        let (wald, _) = rank(wanted, FetchOrder::Wald, Some(before), Some(5));
        assert_eq!(served(wald), [5, 10, 20, 30, 31]);
    }
}
