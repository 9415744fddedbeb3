//! The free-space check `convert` makes before any work: the disk the conversion will need,
//! estimated from the inputs' sizes, against what the spill folder's and the output folder's
//! file systems have free. Inputs of unknown size (standard input) skip the check.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use crate::convert::InputFormat;

/// Spill record bytes per triangle, positions only (the flag byte and 36 bytes of positions).
const RECORD_BYTES: u64 = 37;
/// What per-corner normals, per-corner colours, and a material and part number add.
const NORMAL_BYTES: u64 = 36;
const COLOUR_BYTES: u64 = 12;
const NUMBER_BYTES: u64 = 4;
/// Raw block bytes per triangle: treelet plus triangle blocks (34.2 measured on a 1M
/// Mandelbulb, positions only; 97.0 on 1M triangles of generated CAD, with normals, whose thin
/// overlapping parts make a deep tree). Normals stand for "a scene like the CAD one".
const BLOCK_BYTES: u64 = 40;
const BLOCK_NORMAL_BYTES: u64 = 60;
/// Spill segments on disk beyond one copy of the data: those being read, not yet freed.
const OPEN_SEGMENTS: u64 = 4;
/// OBJ sample windows and their size: an estimate from a few megabytes of any file.
const WINDOWS: u64 = 64;
const WINDOW_BYTES: u64 = 64 << 10;

/// The inputs are estimated to need more space than the file system has free.
#[derive(Debug, thiserror::Error)]
#[error(
    "not enough free disk space in {dir}: the conversion needs about {} ({what}), {} are free; \
     free some space, or put spill files on another disk with --tmp-dir",
    mib(*needed),
    mib(*free)
)]
pub struct NoSpace {
    /// The folder whose file system is short.
    pub dir: String,
    /// What it must hold.
    pub what: &'static str,
    /// Bytes estimated.
    pub needed: u64,
    /// Bytes free to this process.
    pub free: u64,
}

fn mib(b: u64) -> String {
    format!("{:.1} MiB", b as f64 / 1048576.0)
}

/// What the scene of some inputs is estimated to take on disk.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Triangles, estimated from the inputs' sizes.
    pub triangles: u64,
    /// The most the spill files take at once (records, then blocks).
    pub spill_bytes: u64,
    /// The output file (no larger than its raw blocks).
    pub output_bytes: u64,
}

/// Per-input facts an estimate is built from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Guess {
    triangles: u64,
    normals: bool,
    colours: bool,
}

impl Estimate {
    /// The estimate for `inputs`, or `None` when one of them has no size known in advance
    /// (standard input, a pipe) or cannot be read.
    pub fn of(inputs: &[PathBuf]) -> Option<Estimate> {
        let mut e = Estimate::default();
        for path in inputs {
            let g = guess(path)?;
            let record = RECORD_BYTES
                + NUMBER_BYTES
                + if g.normals { NORMAL_BYTES } else { 0 }
                + if g.colours { COLOUR_BYTES } else { 0 };
            let blocks = BLOCK_BYTES + if g.normals { BLOCK_NORMAL_BYTES } else { 0 };
            // Splits copy a few per cent of the triangles; a tenth is the margin.
            let t = g.triangles.saturating_add(g.triangles / 10);
            e.triangles = e.triangles.saturating_add(g.triangles);
            e.spill_bytes = e
                .spill_bytes
                .saturating_add(t.saturating_mul(record.max(blocks)));
            e.output_bytes = e.output_bytes.saturating_add(t.saturating_mul(blocks));
        }
        let segment = super::disk::SpillDisk::with_segments(super::disk::SEGMENT_BYTES, None)
            .segment_limit(e.spill_bytes);
        e.spill_bytes = e.spill_bytes.saturating_add(OPEN_SEGMENTS * segment);
        Some(e)
    }

    /// Bytes the spill files and the output take at once at most, were they on one file
    /// system: the spill shrinks as the output grows, so the larger of the two.
    pub fn peak_bytes(&self) -> u64 {
        self.spill_bytes.max(self.output_bytes)
    }

    /// Checks the estimate against the free space of `spill_dir`'s and `output_dir`'s file
    /// systems (one check when they are the same).
    pub fn check(&self, spill_dir: &Path, output_dir: &Path) -> Result<(), NoSpace> {
        let same = device(spill_dir).is_some() && device(spill_dir) == device(output_dir);
        if same {
            return fits(spill_dir, self.peak_bytes(), "spill files and output");
        }
        fits(spill_dir, self.spill_bytes, "spill files")?;
        fits(output_dir, self.output_bytes, "the output")
    }
}

fn device(dir: &Path) -> Option<u64> {
    std::fs::metadata(dir).ok().map(|m| m.dev())
}

/// Fails when `dir`'s file system has less than `needed` bytes free; a file system that does
/// not say passes.
fn fits(dir: &Path, needed: u64, what: &'static str) -> Result<(), NoSpace> {
    let Some(free) = free_bytes(dir) else {
        return Ok(());
    };
    if needed <= free {
        return Ok(());
    }
    Err(NoSpace {
        dir: dir.display().to_string(),
        what,
        needed,
        free,
    })
}

/// Bytes an unprivileged process may still write on `dir`'s file system.
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let s = rustix::fs::statvfs(dir).ok()?;
    Some(s.f_bavail.saturating_mul(s.f_frsize))
}

/// The input's triangle count and attributes, from its size and what a glance shows.
fn guess(path: &Path) -> Option<Guess> {
    let meta = std::fs::metadata(path).ok()?;
    if !meta.is_file() {
        return None;
    }
    let len = meta.len();
    match InputFormat::of(path)? {
        InputFormat::Obj => sample_obj(path, len),
        InputFormat::Stl => stl(path, len),
        InputFormat::Ply => ply(path),
        InputFormat::Gltf => gltf(path, len),
    }
}

/// Binary STL says its count; ASCII STL takes at least 200 bytes a facet.
fn stl(path: &Path, len: u64) -> Option<Guess> {
    let mut head = [0u8; 84];
    File::open(path).ok()?.read_exact(&mut head).ok()?;
    let n = u64::from(u32::from_le_bytes([head[80], head[81], head[82], head[83]]));
    let triangles = match 84 + 50 * n == len {
        true => n,
        false => len / 200 + 1,
    };
    Some(Guess {
        triangles,
        ..Guess::default()
    })
}

/// PLY's header says its face count (triangles assumed) and its vertex properties.
fn ply(path: &Path) -> Option<Guess> {
    let mut head = Vec::new();
    File::open(path)
        .ok()?
        .take(64 << 10)
        .read_to_end(&mut head)
        .ok()?;
    let text = String::from_utf8_lossy(&head);
    let header = text.split("end_header").next()?;
    let mut g = Guess::default();
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", "face", n] => g.triangles = n.parse().ok()?,
            ["property", .., "nx"] => g.normals = true,
            ["property", .., "red"] => g.colours = true,
            _ => {}
        }
    }
    Some(g)
}

/// glTF: at least 12 bytes of buffer a triangle (16-bit indices, shared vertices), normals
/// assumed. A `.gltf` file's buffers are the files its `buffers` name.
fn gltf(path: &Path, len: u64) -> Option<Guess> {
    let is_text = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"));
    let bytes = match is_text {
        true => len.saturating_add(gltf_buffers(path).unwrap_or(0)),
        false => len,
    };
    Some(Guess {
        triangles: bytes / 12 + 1,
        normals: true,
        colours: false,
    })
}

/// The summed `byteLength` of a `.gltf` file's buffers.
fn gltf_buffers(path: &Path) -> Option<u64> {
    let text = std::fs::read(path).ok()?;
    let json: serde_json::Value = serde_json::from_slice(&text).ok()?;
    let buffers = json.get("buffers")?.as_array()?;
    Some(
        buffers
            .iter()
            .filter_map(|b| b.get("byteLength")?.as_u64())
            .sum(),
    )
}

/// OBJ: the triangles of the faces in evenly spaced windows of the file, scaled to its size;
/// normals or colours when a window shows them.
fn sample_obj(path: &Path, len: u64) -> Option<Guess> {
    let mut f = File::open(path).ok()?;
    let mut g = Guess::default();
    let mut sampled = 0u64;
    let mut window = Vec::with_capacity(WINDOW_BYTES as usize);
    // A small file is read whole; a large one in windows from its start to its end.
    let (windows, size) = match len <= WINDOWS * WINDOW_BYTES {
        true => (1, len),
        false => (WINDOWS, WINDOW_BYTES),
    };
    for k in 0..windows {
        let at = (len - size) / (windows - 1).max(1) * k;
        f.seek(SeekFrom::Start(at)).ok()?;
        window.clear();
        (&mut f).take(size).read_to_end(&mut window).ok()?;
        sampled += obj_window(&window, at == 0, &mut g);
    }
    if sampled == 0 {
        return Some(g);
    }
    let scaled = u128::from(g.triangles) * u128::from(len) / u128::from(sampled);
    g.triangles = u64::try_from(scaled).unwrap_or(u64::MAX) + 1;
    Some(g)
}

/// Counts the triangles of the whole lines in `window` (the first one only when the window
/// starts the file); returns the bytes they span.
fn obj_window(window: &[u8], at_start: bool, g: &mut Guess) -> u64 {
    let start = match at_start {
        true => 0,
        false => match window.iter().position(|&b| b == b'\n') {
            Some(i) => i + 1,
            None => return 0,
        },
    };
    let end = window
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    let Some(lines) = window.get(start..end) else {
        return 0;
    };
    for line in lines.split(|&b| b == b'\n') {
        let mut words = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        match words.next() {
            Some(b"f") => g.triangles += (words.count() as u64).saturating_sub(2),
            Some(b"vn") => g.normals = true,
            Some(b"v") => g.colours |= words.count() >= 6,
            _ => {}
        }
    }
    lines.len() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_obj_estimate_is_close_to_its_face_count() -> Result<(), std::io::Error> {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("m.obj");
        // 200 000 triangles of varied line lengths, vertices then faces: far more than the
        // sample windows cover.
        let mut text = String::new();
        for k in 0..100_000u32 {
            text += &format!("v {} {}.5 {}\n", k, k % 977, k * 7 % 13);
        }
        for k in 0..100_000u32 {
            let (a, b, c) = (k % 99_997 + 1, k % 99_989 + 2, k % 13 + 3);
            text += &format!("f {a} {b} {c}\nf {c} {b} {a} {}\n", a + 1);
        }
        std::fs::write(&path, &text)?;
        let g = guess(&path);
        let t = g.map_or(0, |g| g.triangles);
        // Two faces a line pair, the second a quad: 100 000 × 3 triangles.
        assert!((270_000..=330_000).contains(&t), "{t}");
        assert!(g.is_some_and(|g| !g.normals && !g.colours));
        std::fs::write(&path, "v 0 0 0 1 0 0\nvn 0 0 1\nf 1 1 1\n")?;
        assert_eq!(
            guess(&path),
            Some(Guess {
                triangles: 2,
                normals: true,
                colours: true
            })
        );
        Ok(())
    }

    #[test]
    fn binary_stl_and_ply_say_their_counts() -> Result<(), std::io::Error> {
        let dir = tempfile::tempdir()?;
        let stl_path = dir.path().join("a.stl");
        let mut stl_bytes = vec![0u8; 84 + 50 * 3];
        stl_bytes[80] = 3;
        std::fs::write(&stl_path, &stl_bytes)?;
        assert_eq!(guess(&stl_path).map(|g| g.triangles), Some(3));
        let ply_path = dir.path().join("a.ply");
        let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                      property float nx\nelement face 1234\nend_header\n";
        std::fs::write(&ply_path, header)?;
        let g = guess(&ply_path);
        assert_eq!(g.map(|g| (g.triangles, g.normals)), Some((1234, true)));
        assert_eq!(guess(&dir.path().join("missing.obj")), None);
        Ok(())
    }

    #[test]
    fn a_disk_too_small_for_the_estimate_is_refused_naming_the_folder() {
        let dir = Path::new(".");
        let free = free_bytes(dir).unwrap_or(0);
        let fits_easily = Estimate {
            triangles: 1,
            spill_bytes: 1,
            output_bytes: 1,
        };
        assert!(fits_easily.check(dir, dir).is_ok());
        let huge = Estimate {
            spill_bytes: free.saturating_mul(2).max(1 << 60),
            ..fits_easily
        };
        let e = huge.check(dir, dir).err().map(|e| e.to_string());
        assert!(
            e.as_deref()
                .is_some_and(|m| m.contains("not enough free disk space in .")),
            "{e:?}"
        );
    }
}
