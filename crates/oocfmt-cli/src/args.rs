//! What the subcommands share on the command line: the value parsers (one of each), the
//! choices as clap `ValueEnum`s (each mapped onto the library's own type, which knows no
//! clap), the view flags of `render` and `curve`, and `--threads`.

use std::path::Path;
use std::sync::Arc;

use clap::ValueEnum;

use oocfmt::records::LodKinds;
use oocfmt::{Codec, Io, ReadOptions, Reader};
use oocfmt_trace::blocks::LodKind;
use oocfmt_trace::cache::{Eviction, FetchOrder};
use oocfmt_trace::session::CacheKind;
use oocfmt_trace::{Camera, Scene};

use crate::error::CliError;

/// `--cache`: the block cache to render with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CacheArg {
    Async,
    Blocking,
    Mmap,
}

impl From<CacheArg> for CacheKind {
    fn from(c: CacheArg) -> CacheKind {
        match c {
            CacheArg::Async => CacheKind::Async,
            CacheArg::Blocking => CacheKind::Blocking,
            CacheArg::Mmap => CacheKind::Mmap,
        }
    }
}

/// `--io`: how the async and blocking caches read blocks from the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum IoArg {
    Buffered,
    Direct,
}

impl From<IoArg> for Io {
    fn from(i: IoArg) -> Io {
        match i {
            IoArg::Buffered => Io::Buffered,
            IoArg::Direct => Io::Direct,
        }
    }
}

/// The container at `model` read as `--io` asks, stopping on `lod` (None: the file's default).
pub fn open_scene(model: &Path, lod: Option<LodKind>, io: IoArg) -> Result<Scene, CliError> {
    let scene = Scene::from_reader(Reader::open_with(model, ReadOptions::default(), io.into())?);
    Ok(match lod {
        Some(l) => scene.with_lod(l)?,
        None => scene,
    })
}

/// The scene a cache of `kind` renders ([`open_scene`]); None for the mmap cache, which maps
/// the file itself, through the page cache: with `--io direct` a usage error.
pub fn scene_for(
    model: &Path,
    kind: CacheKind,
    lod: Option<LodKind>,
    io: IoArg,
) -> Result<Option<Arc<Scene>>, CliError> {
    check_io(kind, io)?;
    if kind == CacheKind::Mmap {
        return Ok(None);
    }
    Ok(Some(Arc::new(open_scene(model, lod, io)?)))
}

/// With `--io direct`, a line saying what is in effect: `O_DIRECT`, or the fallback where the
/// file system refused it.
pub fn io_note(io: IoArg, scene: &Scene) -> Option<String> {
    if io == IoArg::Buffered {
        return None;
    }
    Some(match scene.reader().io_mode() {
        oocfmt::IoMode::Direct => "reads: direct (O_DIRECT, past the page cache)".to_string(),
        oocfmt::IoMode::DontNeed => "reads: dontneed (the file system refused O_DIRECT: buffered \
             reads, each dropped from the page cache after it)"
            .to_string(),
        oocfmt::IoMode::Buffered => {
            "reads: buffered (direct reads are not available on this system)".to_string()
        }
    })
}

/// Refuses `--io direct` with the mmap cache, whose map is the page cache.
pub fn check_io(kind: CacheKind, io: IoArg) -> Result<(), CliError> {
    if kind == CacheKind::Mmap && io == IoArg::Direct {
        return Err(CliError::Usage(
            "--io direct reads past the page cache, and --cache mmap reads through it (the \
             operating system pages the map in): use --io direct with --cache async or blocking"
                .into(),
        ));
    }
    Ok(())
}

/// `--lod` of `render` and `curve`: the LOD representation rays stop on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LodArg {
    Voxel,
    Rlod,
}

impl From<LodArg> for LodKind {
    fn from(l: LodArg) -> LodKind {
        match l {
            LodArg::Voxel => LodKind::Voxel,
            LodArg::Rlod => LodKind::Rlod,
        }
    }
}

/// `--lod` of `convert`: the LOD representations to store.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LodKindsArg {
    Voxel,
    Rlod,
    Both,
}

impl From<LodKindsArg> for LodKinds {
    fn from(l: LodKindsArg) -> LodKinds {
        match l {
            LodKindsArg::Voxel => LodKinds::VOXEL,
            LodKindsArg::Rlod => LodKinds::RLOD,
            LodKindsArg::Both => LodKinds::BOTH,
        }
    }
}

/// `--fetch-order` of the async cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FetchOrderArg {
    Afra,
    Wald,
}

impl From<FetchOrderArg> for FetchOrder {
    fn from(f: FetchOrderArg) -> FetchOrder {
        match f {
            FetchOrderArg::Afra => FetchOrder::Afra,
            FetchOrderArg::Wald => FetchOrder::Wald,
        }
    }
}

/// `--eviction` of the async cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EvictionArg {
    Lru,
    SecondChance,
}

impl From<EvictionArg> for Eviction {
    fn from(e: EvictionArg) -> Eviction {
        match e {
            EvictionArg::Lru => Eviction::Lru,
            EvictionArg::SecondChance => Eviction::SecondChance,
        }
    }
}

/// A switch spelled `on` or `off` (`--prefetch`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    On,
    Off,
}

impl Switch {
    pub fn is_on(self) -> bool {
        self == Switch::On
    }
}

/// The view flags `render` and `curve` share.
#[derive(clap::Args, Clone, Copy)]
pub struct View {
    /// Image size, WIDTHxHEIGHT
    #[arg(long, default_value = "1024x768", value_parser = parse_image_size)]
    pub size: (u32, u32),
    /// Eye position X,Y,Z in world coordinates (default: framing the whole model)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<[f64; 3]>,
    /// The point looked at, X,Y,Z in world coordinates (default: the model's centre)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<[f64; 3]>,
    /// Up direction X,Y,Z
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<[f64; 3]>,
    /// Vertical field of view in degrees
    #[arg(long, default_value_t = oocfmt_trace::camera::DEFAULT_FOV_Y)]
    pub fov_y: f64,
}

impl View {
    /// The camera of this still view in stored coordinates: framing the whole model, with the
    /// eye, look-at point (world coordinates) and up direction given on the command line.
    pub fn camera(&self, scene: &Scene) -> Camera {
        let View {
            size: (w, h),
            eye,
            look_at,
            up,
            fov_y,
        } = *self;
        let m = scene.metadata();
        let stored = |p| oocfmt_trace::session::stored_point(scene, p);
        let mut camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h);
        if let Some(e) = eye {
            camera.eye = stored(e);
        }
        if let Some(l) = look_at {
            camera.look_at = stored(l);
        }
        if let Some(u) = up {
            camera.up = u;
        }
        camera.fov_y = fov_y;
        camera
    }
}

/// Half the cores, at least one: the default of `--fetchers`. Reading, decompressing and
/// decoding blocks competes with rendering for the cores (docs/benchmarks.md measures it).
pub fn default_fetchers() -> u64 {
    std::thread::available_parallelism().map_or(1, |n| (n.get() as u64 / 2).max(1))
}

/// A `--cache-mb` in bytes.
pub fn budget_bytes(mb: u64) -> usize {
    usize::try_from(mb << 20).unwrap_or(usize::MAX)
}

/// Sets the worker (render) threads of `--threads`; None: all cores.
pub fn use_threads(threads: Option<usize>) -> Result<(), CliError> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| CliError::Usage(format!("--threads {n}: {e}")))?;
    }
    Ok(())
}

/// A block codec: `none`, `lz4`, `zstd` or `zstd:LEVEL` (a level is not a plain choice).
pub fn parse_codec(s: &str) -> Result<Codec, String> {
    Codec::parse(s).map_err(|e| e.to_string())
}

/// An image size `WIDTHxHEIGHT`, each 1 ..= 16384.
pub fn parse_image_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: expected WIDTHxHEIGHT, each 1 to 16384, e.g. 1024x768");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

/// A byte count with an optional binary suffix: `512M`, `2G`, `1.5G`, `64k` or `1000`.
pub fn parse_byte_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((at, c)) => match c.to_ascii_uppercase() {
            'K' => (&t[..at], 1u64 << 10),
            'M' => (&t[..at], 1 << 20),
            'G' => (&t[..at], 1 << 30),
            'T' => (&t[..at], 1 << 40),
            _ => (t, 1),
        },
        None => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("`{s}`: expected a size like 512M or 2G"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("`{s}`: the size must be positive"));
    }
    Ok((v * mult as f64) as u64)
}

/// A count of things >= 1: a whole number (`1000000`, `1_000_000`) or in scientific notation
/// (`1e9`, `2.5e8`) when that is a whole number at most 2^53 (where every whole f64 is exact).
pub fn parse_count(s: &str) -> Result<u64, String> {
    let bad = || format!("`{s}`: expected a whole number >= 1, e.g. 1000000 or 1e9");
    let t = s.trim().replace('_', "");
    if let Ok(n) = t.parse::<u64>() {
        return if n >= 1 { Ok(n) } else { Err(bad()) };
    }
    let v: f64 = t.parse().map_err(|_| bad())?;
    // 2^53: beyond it an f64 no longer names every whole number.
    let exact = 9_007_199_254_740_992.0;
    if v.is_finite() && v >= 1.0 && v <= exact && v.fract() == 0.0 {
        Ok(v as u64)
    } else {
        Err(bad())
    }
}

/// MiB as a number: finite, > 0 and at most 2^30.
pub fn parse_mb(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(m) if m.is_finite() && m > 0.0 && m <= f64::from(1u32 << 30) => Ok(m),
        _ => Err(format!(
            "`{s}`: expected MiB, a number > 0 and at most 2^30"
        )),
    }
}

/// A share of a frame: a number > 0, or `inf`.
pub fn parse_share(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(x) if x > 0.0 => Ok(x),
        _ => Err(format!(
            "`{s}`: expected a share of a frame, a number > 0 or `inf`"
        )),
    }
}

/// A finite distance > 0 that fits an f32.
pub fn parse_distance(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok(d),
        _ => Err(format!("`{s}`: expected a finite distance > 0")),
    }
}

/// A pixel `X,Y` of an image (0,0 the top left): two whole numbers; the image size is checked
/// where the view is known.
pub fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: expected a pixel X,Y of whole numbers, e.g. 512,384");
    let (x, y) = s.split_once(',').ok_or_else(bad)?;
    let x = x.trim().parse().map_err(|_| bad())?;
    let y = y.trim().parse().map_err(|_| bad())?;
    Ok((x, y))
}

/// `X,Y,Z`, finite numbers.
pub fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let bad = || format!("`{s}`: expected three finite numbers X,Y,Z");
    let parts: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    match parts[..] {
        [x, y, z] if parts.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(bad()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_sizes_parse() {
        assert_eq!(parse_byte_size("2G"), Ok(2 << 30));
        assert_eq!(parse_byte_size("512m"), Ok(512 << 20));
        assert_eq!(parse_byte_size("1.5k"), Ok(1536));
        assert_eq!(parse_byte_size("1000"), Ok(1000));
        assert!(parse_byte_size("-1G").is_err());
        assert!(parse_byte_size("lots").is_err());
        assert!(parse_byte_size("").is_err());
        // A multi-byte last character is no suffix, and no panic.
        assert!(parse_byte_size("1é").is_err());
    }

    #[test]
    fn image_sizes_and_vectors_parse() {
        assert_eq!(parse_image_size("640x480"), Ok((640, 480)));
        assert_eq!(parse_image_size("8X 4"), Ok((8, 4)));
        assert!(parse_image_size("0x4").is_err());
        assert!(parse_image_size("16385x1").is_err());
        assert!(parse_image_size("640").is_err());
        assert_eq!(parse_vec3("1,-2, 3.5"), Ok([1.0, -2.0, 3.5]));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,inf").is_err());
        assert_eq!(parse_pixel("3, 40"), Ok((3, 40)));
        assert!(parse_pixel("3").is_err());
        assert!(parse_pixel("-1,2").is_err());
        assert!(parse_pixel("1,2,3").is_err());
    }

    #[test]
    fn counts_parse_plain_or_scientific() {
        assert_eq!(parse_count("1000000"), Ok(1_000_000));
        assert_eq!(parse_count("1_000_000"), Ok(1_000_000));
        assert_eq!(parse_count("1e9"), Ok(1_000_000_000));
        assert_eq!(parse_count("2.5E8"), Ok(250_000_000));
        assert_eq!(parse_count(&u64::MAX.to_string()), Ok(u64::MAX));
        for bad in [
            "0", "0e3", "1.5", "1e-3", "-1", "1e300", "inf", "nan", "", "lots",
        ] {
            assert!(parse_count(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn numbers_parse_within_their_ranges() {
        assert_eq!(parse_mb("4"), Ok(4.0));
        assert!(parse_mb("0").is_err());
        assert!(parse_mb("nan").is_err());
        assert_eq!(parse_share("inf"), Ok(f64::INFINITY));
        assert!(parse_share("0").is_err());
        assert_eq!(parse_distance("0.5"), Ok(0.5));
        assert!(parse_distance("inf").is_err());
    }

    /// The spelling clap accepts for `v`.
    fn name(v: impl ValueEnum) -> String {
        v.to_possible_value()
            .map(|p| p.get_name().to_string())
            .unwrap_or_default()
    }

    #[test]
    fn choices_keep_their_spellings_and_map_onto_the_library() {
        assert_eq!(name(LodKindsArg::Both), "both");
        assert_eq!(LodKinds::from(LodKindsArg::Both), LodKinds::BOTH);
        assert_eq!(name(Switch::On), "on");
        assert!(Switch::On.is_on() && !Switch::Off.is_on());
        for arg in [FetchOrderArg::Afra, FetchOrderArg::Wald] {
            assert_eq!(name(arg), FetchOrder::from(arg).name());
        }
        for arg in [EvictionArg::Lru, EvictionArg::SecondChance] {
            assert_eq!(name(arg), Eviction::from(arg).name());
        }
        assert_eq!(name(EvictionArg::SecondChance), "second-chance");
        for arg in [CacheArg::Async, CacheArg::Blocking, CacheArg::Mmap] {
            assert_eq!(name(arg), CacheKind::from(arg).name());
        }
        for arg in [LodArg::Voxel, LodArg::Rlod] {
            assert_eq!(name(arg), LodKind::from(arg).name());
        }
        assert_eq!(name(IoArg::Direct), "direct");
        assert_eq!(Io::from(IoArg::Direct), Io::Direct);
    }

    #[test]
    fn direct_io_is_refused_with_the_mmap_cache_only() {
        assert!(check_io(CacheKind::Mmap, IoArg::Direct).is_err());
        assert!(check_io(CacheKind::Mmap, IoArg::Buffered).is_ok());
        assert!(check_io(CacheKind::Async, IoArg::Direct).is_ok());
        assert!(check_io(CacheKind::Blocking, IoArg::Direct).is_ok());
    }
}
