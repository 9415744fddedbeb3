//! An append-only table of fixed-size records (an importer's vertex positions, normals or
//! colours) that keeps at most a budget of them in memory and moves the oldest to an unnamed
//! temporary file beyond it: a billion-triangle OBJ file has half a billion vertices, 6 GB of
//! positions. Faces of real exports name vertices written shortly before them, so reads of
//! moved pages are rare; they go through a small cache of pages.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::PathBuf;

/// Records per page: the unit moved to the file and read back.
const PAGE: usize = 1 << 16;
/// Pages read back from the file that are kept (least recently used replaced).
const CACHED_PAGES: usize = 8;

/// A record of a fixed number of bytes, written little-endian.
pub trait Record: Copy + Default {
    /// Its size in the file.
    const LEN: usize;
    /// Writes it to `out`, of [`Record::LEN`] bytes.
    fn put(&self, out: &mut [u8]);
    /// Reads it back from `bytes`, of [`Record::LEN`] bytes.
    fn get(bytes: &[u8]) -> Self;
}

impl Record for [f32; 3] {
    const LEN: usize = 12;

    fn put(&self, out: &mut [u8]) {
        for (c, o) in self.iter().zip(out.chunks_exact_mut(4)) {
            o.copy_from_slice(&c.to_le_bytes());
        }
    }

    fn get(bytes: &[u8]) -> Self {
        let mut v = [0f32; 3];
        for (c, b) in v.iter_mut().zip(bytes.chunks_exact(4)) {
            *c = b.try_into().map_or(0.0, f32::from_le_bytes);
        }
        v
    }
}

impl Record for Option<[u8; 4]> {
    const LEN: usize = 5;

    fn put(&self, out: &mut [u8]) {
        if let (Some(c), [flag, rest @ ..]) = (self, out) {
            *flag = 1;
            rest.copy_from_slice(c);
        }
    }

    fn get(bytes: &[u8]) -> Self {
        match bytes {
            [1, r, g, b, a] => Some([*r, *g, *b, *a]),
            _ => None,
        }
    }
}

/// Where a table may move records it cannot keep, and how many it keeps.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SpillTo {
    /// The folder of the unnamed temporary file (gone when the table is dropped, or when the
    /// process dies).
    pub dir: PathBuf,
    /// Bytes of records kept in memory, at least one page.
    pub resident_bytes: usize,
}

/// Vertex tables larger than memory, for the importers that index vertices (OBJ, PLY): each of
/// positions, normals and colours keeps `to.resident_bytes` in memory and moves older pages
/// to an unnamed file in `to.dir`, whose bytes the sink is told of
/// ([`super::TriangleSink::charge_disk`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VertexSpill {
    /// The folder and the memory budget of each table.
    pub to: SpillTo,
    /// Most vertices in all.
    pub max_vertices: usize,
}

impl VertexSpill {
    /// Room for 2^33 vertices: 96 GiB of positions on disk, beyond any file of a few hundred
    /// GB.
    pub const MAX_VERTICES: usize = 1 << 33;
}

/// The file of moved pages, and the pages read back from it.
struct Moved {
    file: File,
    /// Pages in the file; page `i` starts at byte `i × PAGE × LEN`.
    pages: usize,
    /// Recently read pages, the most recent last.
    cache: Vec<(usize, Vec<u8>)>,
}

/// The table. Without [`SpillTo`] it is a plain vector in pages.
pub struct SpillTable<T> {
    /// The newest pages, in memory; the first is page `first`.
    resident: VecDeque<Vec<T>>,
    first: usize,
    len: usize,
    spill: Option<SpillTo>,
    moved: Option<Moved>,
}

impl<T: Record> SpillTable<T> {
    /// An empty table; `spill` says where records beyond its budget go (`None`: nowhere).
    pub fn new(spill: Option<SpillTo>) -> SpillTable<T> {
        SpillTable {
            resident: VecDeque::new(),
            first: 0,
            len: 0,
            spill,
            moved: None,
        }
    }

    /// Records pushed.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether none was pushed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes of the temporary file.
    pub fn file_bytes(&self) -> u64 {
        self.moved
            .as_ref()
            .map_or(0, |m| (m.pages * PAGE * T::LEN) as u64)
    }

    /// Appends `v`; may move the oldest resident page to the file first (an I/O error then).
    pub fn push(&mut self, v: T) -> std::io::Result<()> {
        let full = self.resident.back().is_none_or(|p| p.len() == PAGE);
        if full {
            if self.over_budget() {
                self.move_oldest()?;
            }
            self.resident.push_back(Vec::with_capacity(PAGE));
        }
        if let Some(page) = self.resident.back_mut() {
            page.push(v);
            self.len += 1;
        }
        Ok(())
    }

    /// Appends `n` default records.
    pub fn extend_default(&mut self, n: usize) -> std::io::Result<()> {
        (0..n).try_for_each(|_| self.push(T::default()))
    }

    /// Record `i`, or None past the end; reads it back from the file if it was moved.
    pub fn get(&mut self, i: usize) -> std::io::Result<Option<T>> {
        if i >= self.len {
            return Ok(None);
        }
        let (page, at) = (i / PAGE, i % PAGE);
        if page >= self.first {
            return Ok(self
                .resident
                .get(page - self.first)
                .and_then(|p| p.get(at))
                .copied());
        }
        let Some(moved) = &mut self.moved else {
            return Ok(None);
        };
        let bytes = moved.page(page, T::LEN)?;
        Ok(bytes.get(at * T::LEN..(at + 1) * T::LEN).map(T::get))
    }

    /// Whether one more resident page would pass the budget.
    fn over_budget(&self) -> bool {
        let Some(s) = &self.spill else {
            return false;
        };
        let pages = (s.resident_bytes / (PAGE * std::mem::size_of::<T>()).max(1)).max(1);
        self.resident.len() >= pages
    }

    /// Moves the oldest resident page (always full) to the end of the file.
    fn move_oldest(&mut self) -> std::io::Result<()> {
        let Some(spill) = &self.spill else {
            return Ok(());
        };
        let moved = match &mut self.moved {
            Some(m) => m,
            None => self.moved.insert(Moved {
                file: tempfile::tempfile_in(&spill.dir)?,
                pages: 0,
                cache: Vec::new(),
            }),
        };
        let Some(page) = self.resident.pop_front() else {
            return Ok(());
        };
        let mut bytes = vec![0u8; page.len() * T::LEN];
        for (v, out) in page.iter().zip(bytes.chunks_exact_mut(T::LEN)) {
            v.put(out);
        }
        moved
            .file
            .seek(SeekFrom::Start((moved.pages * PAGE * T::LEN) as u64))?;
        moved.file.write_all(&bytes)?;
        moved.pages += 1;
        self.first += 1;
        Ok(())
    }
}

impl Moved {
    /// The bytes of moved page `page`, of records of `len` bytes.
    fn page(&mut self, page: usize, len: usize) -> std::io::Result<&[u8]> {
        if let Some(k) = self.cache.iter().position(|(p, _)| *p == page) {
            let hit = self.cache.remove(k);
            self.cache.push(hit);
        } else {
            let mut bytes = match self.cache.len() >= CACHED_PAGES {
                true => self.cache.remove(0).1,
                false => vec![0u8; PAGE * len],
            };
            bytes.resize(PAGE * len, 0);
            self.file
                .seek(SeekFrom::Start((page * PAGE * len) as u64))?;
            self.file.read_exact(&mut bytes)?;
            self.cache.push((page, bytes));
        }
        Ok(self.cache.last().map_or(&[][..], |(_, b)| b.as_slice()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(i: usize) -> [f32; 3] {
        let x = i as f32;
        [x, -x * 0.5, x + 0.25]
    }

    /// Random reads over a table of several pages, most of them moved to the file, give what
    /// was pushed; so does the same table kept in memory.
    #[test]
    fn moved_pages_read_back_as_pushed() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let n = 5 * PAGE + 123;
        let spill = SpillTo {
            dir: dir.path().to_path_buf(),
            resident_bytes: 2 * PAGE * 12,
        };
        let mut moved = SpillTable::new(Some(spill));
        let mut kept = SpillTable::new(None);
        for i in 0..n {
            moved.push(point(i))?;
            kept.push(point(i))?;
        }
        assert_eq!((moved.len(), kept.len()), (n, n));
        // Six pages, two of them resident.
        assert_eq!(moved.file_bytes(), (4 * PAGE * 12) as u64);
        assert_eq!(kept.file_bytes(), 0);
        let mut state = 12345u64;
        for _ in 0..20_000 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let i = (state >> 33) as usize % (n + 10);
            let want = (i < n).then(|| point(i));
            assert_eq!(moved.get(i)?, want, "{i}");
            assert_eq!(kept.get(i)?, want, "{i}");
        }
        // The temporary file has no name in the folder.
        assert_eq!(std::fs::read_dir(dir.path())?.count(), 0);
        Ok(())
    }

    #[test]
    fn colours_keep_none_and_some() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let spill = SpillTo {
            dir: dir.path().to_path_buf(),
            resident_bytes: 1,
        };
        let mut t: SpillTable<Option<[u8; 4]>> = SpillTable::new(Some(spill));
        t.extend_default(PAGE + 1)?;
        t.push(Some([1, 2, 3, 4]))?;
        for i in 0..3 * PAGE {
            t.push((i % 3 == 0).then_some([i as u8, 0, 255, 7]))?;
        }
        assert_eq!(t.get(0)?, Some(None));
        assert_eq!(t.get(PAGE + 1)?, Some(Some([1, 2, 3, 4])));
        assert_eq!(t.get(PAGE + 2)?, Some(Some([0, 0, 255, 7])));
        assert_eq!(t.get(PAGE + 3)?, Some(None));
        assert_eq!(t.get(4 * PAGE + 2)?, None);
        assert!(t.file_bytes() > 0);
        Ok(())
    }

    /// A folder the file cannot be made in is an error at the first move, not a panic.
    #[test]
    fn a_missing_folder_is_an_error() {
        let spill = SpillTo {
            dir: PathBuf::from("/nonexistent/oocfmt-spill-table"),
            resident_bytes: 1,
        };
        let mut t = SpillTable::new(Some(spill));
        let r = (0..2 * PAGE + 1).try_for_each(|i| t.push(point(i)));
        assert!(r.is_err());
    }
}
