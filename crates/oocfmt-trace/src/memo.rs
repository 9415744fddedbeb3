//! What one group of rays (a tile) has looked up and wanted, and each thread's memo kept
//! between tiles and frames.

use std::cell::{Cell, OnceCell, RefCell};
use std::ops::{Deref, DerefMut};
use std::sync::Arc;

use rustc_hash::FxHashMap as HashMap;

use crate::blocks::{TreeletData, TriangleData};
use crate::cache::{BlockCache, Wish};
use crate::parts::{BlockMask, PartFilter};
use crate::scene::Scene;

/// A block as one group of rays (a tile) saw it.
enum Slot {
    Treelets(Arc<TreeletData>),
    Triangles(Arc<TriangleData>),
    /// Not available to this tile: not loaded yet, missing for good, or not of the kind asked.
    Missing,
}

/// Blocks one group of rays (a tile) has looked up: the shared cache is asked once per block
/// per tile rather than once per ray, and the rays borrow the blocks from here, so the hot loop
/// never touches a reference count. Slots are indexed by block id (one per directory entry), so
/// a lookup is an index, not a hash. The blocks the rays wanted and did not get are gathered
/// here too, with their priorities, and handed to the cache once per tile by [`Memo::flush`].
pub struct Memo {
    slots: Vec<OnceCell<Slot>>,
    /// Slots filled since the last [`Memo::clear`].
    touched: RefCell<Vec<u32>>,
    wanted: RefCell<HashMap<u32, Wish>>,
    flushed: Vec<(u32, Wish)>,
    /// Nodes the rays traced with this memo visited (inner, LOD and leaf), since the last
    /// [`Memo::take_visited`].
    pub(crate) visited: Cell<u64>,
    /// While set, [`Memo::want`] logs under this key instead of adding at once.
    defer_key: Cell<Option<u32>>,
    /// Deferred wants: key, block, radius, distance; in the order the rays made them.
    deferred: RefCell<Vec<(u32, u32, f32, f32)>>,
    /// The visible entries of a leaf of a block that a part filter hides part of, rebuilt
    /// for each such leaf (kept to spare an allocation per leaf).
    pub(crate) visible: RefCell<Vec<u16>>,
    /// By block id, what the part filter `mask_for` makes of each triangle block looked up
    /// under it ([`Memo::masked`]): 0 not yet, else 1 + the index of its [`BlockMask`]. Made
    /// the first time a ray under a filter asks, so a memo that never sees one pays nothing.
    masks: OnceCell<Vec<Cell<u8>>>,
    /// The id of the filter `masks` are for.
    mask_for: Cell<u64>,
    /// How many of `deferred` (sorted by key) have been released.
    released: Cell<usize>,
}

thread_local! {
    /// This thread's memo, kept between tiles and frames: see [`Memo::pooled`].
    static KEPT: RefCell<Option<Memo>> = const { RefCell::new(None) };
}

/// A memo borrowed from its thread ([`Memo::pooled`]): cleared and handed back when dropped.
pub struct PooledMemo(Memo);

impl Deref for PooledMemo {
    type Target = Memo;
    fn deref(&self) -> &Memo {
        &self.0
    }
}

impl DerefMut for PooledMemo {
    fn deref_mut(&mut self) -> &mut Memo {
        &mut self.0
    }
}

impl Drop for PooledMemo {
    fn drop(&mut self) {
        // A memo for no blocks allocates nothing.
        let mut memo = std::mem::replace(&mut self.0, Memo::with_blocks(0));
        // The next user finds no block borrowed (the cache may evict it) and no want of ours.
        memo.clear();
        memo.visited.set(0);
        let _ = KEPT.try_with(|kept| {
            if let Ok(mut kept) = kept.try_borrow_mut() {
                *kept = Some(memo);
            }
        });
    }
}

impl Memo {
    /// A memo for the blocks of `scene`.
    pub fn new(scene: &Scene) -> Memo {
        Self::with_blocks(scene.block_count())
    }

    fn with_blocks(blocks: usize) -> Memo {
        Memo {
            slots: (0..blocks).map(|_| OnceCell::new()).collect(),
            touched: RefCell::default(),
            wanted: RefCell::default(),
            flushed: Vec::new(),
            visited: Cell::new(0),
            defer_key: Cell::new(None),
            deferred: RefCell::default(),
            released: Cell::new(0),
            visible: RefCell::default(),
            masks: OnceCell::new(),
            mask_for: Cell::new(0),
        }
    }

    /// This thread's kept memo when it has one for as many blocks as `scene`, else a new one;
    /// handed back to the thread when dropped. Rayon runs a frame's tiles as some 25 jobs, each
    /// wanting a memo of 16 bytes per block of the file (794 KiB for the 100M-triangle model):
    /// a new one per job wrote 20 MB a frame, and in a fresh process on fresh pages. A thread
    /// keeps its memo (empty, outside any cache budget) until it ends or takes one for a file
    /// with another block count.
    pub fn pooled(scene: &Scene) -> PooledMemo {
        Self::pooled_for(scene.block_count())
    }

    fn pooled_for(blocks: usize) -> PooledMemo {
        let kept = KEPT
            .try_with(|kept| kept.try_borrow_mut().ok().and_then(|mut k| k.take()))
            .ok()
            .flatten();
        PooledMemo(match kept {
            // A kept memo is cleared: only its length ties it to a file.
            Some(memo) if memo.slots.len() == blocks => memo,
            _ => Self::with_blocks(blocks),
        })
    }

    /// Forgets the blocks looked up so far (the next tile asks the cache again) and the
    /// unflushed requests.
    pub fn clear(&mut self) {
        let masks = self.masks.get();
        for id in self.touched.get_mut().drain(..) {
            if let Some(slot) = self.slots.get_mut(id as usize) {
                slot.take();
            }
            if let Some(m) = masks.and_then(|m| m.get(id as usize)) {
                m.set(0);
            }
        }
        self.wanted.get_mut().clear();
        self.deferred.get_mut().clear();
        self.released.set(0);
        self.defer_key.set(None);
    }

    /// Nodes visited since the last call, and a fresh count.
    pub fn take_visited(&mut self) -> u64 {
        self.visited.replace(0)
    }

    /// Hands the blocks wanted since the last flush to the cache as requests.
    pub fn flush(&mut self, cache: &dyn BlockCache) {
        self.release_deferred(u32::MAX);
        self.deferred.get_mut().clear();
        self.released.set(0);
        let wanted = self.wanted.get_mut();
        if wanted.is_empty() {
            return;
        }
        self.flushed.clear();
        self.flushed.extend(wanted.drain());
        cache.request(&self.flushed);
    }

    /// One ray wanted block `id` and did not get it: see [`Wish::add`] for the priority.
    pub(crate) fn want(&self, id: u32, radius: f32, t: f32) {
        match self.defer_key.get() {
            Some(key) => self.want_later(key, id, radius, t),
            None => self.want_now(id, radius, t),
        }
    }

    fn want_now(&self, id: u32, radius: f32, t: f32) {
        self.wanted
            .borrow_mut()
            .entry(id)
            .or_default()
            .add(radius, t);
    }

    /// [`Memo::want`] for the ray of `key`, logged until [`Memo::release_deferred`] reaches
    /// the key. Rays traced together in a packet make their wants interleaved; replaying them
    /// ray by ray, in the order the rays would have been traced alone, keeps the sums of the
    /// priorities bit for bit those of the single-ray path.
    pub(crate) fn want_later(&self, key: u32, id: u32, radius: f32, t: f32) {
        self.deferred.borrow_mut().push((key, id, radius, t));
    }

    /// Logs the wants of the rays traced from now on under `key` (None: adds them at once).
    pub fn defer_wants(&self, key: Option<u32>) {
        self.defer_key.set(key);
    }

    /// Adds the logged wants of every key up to `key`, key by key in increasing order, each
    /// key's in the order they were made. Keys must be released in increasing order; a want
    /// logged under a key already released is added at the next release.
    pub fn release_deferred(&self, key: u32) {
        let mut log = self.deferred.borrow_mut();
        let mut at = self.released.get();
        if at == 0 && !log.is_empty() {
            // Stable: each key keeps the order of its wants.
            log.sort_by_key(|e| e.0);
        }
        while let Some(&(k, id, radius, t)) = log.get(at) {
            if k > key {
                break;
            }
            self.want_now(id, radius, t);
            at += 1;
        }
        if at == log.len() {
            log.clear();
            at = 0;
        }
        self.released.set(at);
    }

    fn slot(&self, id: u32, load: impl FnOnce() -> Slot) -> Option<&Slot> {
        let cell = self.slots.get(id as usize)?;
        Some(cell.get_or_init(|| {
            self.touched.borrow_mut().push(id);
            load()
        }))
    }

    pub(crate) fn treelets(&self, cache: &dyn BlockCache, id: u32) -> Option<&TreeletData> {
        let slot = self.slot(id, || {
            cache.treelets(id).map_or(Slot::Missing, Slot::Treelets)
        });
        match slot? {
            Slot::Treelets(d) => Some(d),
            _ => None,
        }
    }

    pub(crate) fn triangles(&self, cache: &dyn BlockCache, id: u32) -> Option<&Arc<TriangleData>> {
        let slot = self.slot(id, || {
            cache.triangles(id).map_or(Slot::Missing, Slot::Triangles)
        });
        match slot? {
            Slot::Triangles(d) => Some(d),
            _ => None,
        }
    }

    /// Triangle block `id` and what `filter` makes of it, worked out from the block's parts
    /// once per tile (the slot is cleared with the tile) and per filter.
    pub(crate) fn masked(
        &self,
        cache: &dyn BlockCache,
        id: u32,
        filter: &PartFilter,
    ) -> Option<(&Arc<TriangleData>, BlockMask)> {
        const MASKS: [BlockMask; 3] = [
            BlockMask::NoneHidden,
            BlockMask::AllHidden,
            BlockMask::Mixed,
        ];
        let d = self.triangles(cache, id)?;
        let masks = self
            .masks
            .get_or_init(|| (0..self.slots.len()).map(|_| Cell::new(0)).collect());
        if self.mask_for.replace(filter.id()) != filter.id() {
            // Another filter than the one these were worked out for (a pooled memo's new
            // frame): rare, and one pass.
            masks.iter().for_each(|m| m.set(0));
        }
        let cell = masks.get(id as usize)?;
        if let Some(&m) = cell
            .get()
            .checked_sub(1)
            .and_then(|i| MASKS.get(usize::from(i)))
        {
            return Some((d, m));
        }
        let m = filter.block_mask(d.parts_present());
        let at = MASKS.iter().position(|&x| x == m).unwrap_or(0);
        cell.set(at as u8 + 1);
        Some((d, m))
    }
}

#[cfg(test)]
mod tests {
    use super::Memo;

    #[test]
    fn a_thread_gets_its_kept_memo_back_when_the_block_count_matches() {
        let first = Memo::pooled_for(10);
        let at = first.slots.as_ptr();
        drop(first);
        let again = Memo::pooled_for(10);
        assert_eq!(again.slots.as_ptr(), at);
        // Taken: a second borrower meanwhile gets a new one.
        let other = Memo::pooled_for(10);
        assert_ne!(other.slots.as_ptr(), at);
        drop(other);
        drop(again);
        let longer = Memo::pooled_for(11);
        assert_eq!(longer.slots.len(), 11);
    }
}
