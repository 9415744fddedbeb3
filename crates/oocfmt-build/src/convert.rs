//! The conversion pipeline behind `oocfmt convert`: import every input into one scene, build the
//! kd-tree, compute LOD data and lay it out, write the container, then re-open it to report what
//! was written. Each phase is timed and reported.

use std::path::{Path, PathBuf};
use std::time::Instant;

use oocfmt::{BlockKind, ReadOptions, Reader, WriteSummary};

use crate::kdtree::{self, KdBuildOptions, KdError};
use crate::layout::{build_blocks, write_blocks, LayoutError, LayoutOptions};
use crate::ooc::soup::{finish_soup, soup_sink, Soup};
use crate::ooc::{self, OocError};
use crate::progress::Progress;
use crate::report::{peak_memory, BlockStats, ConvertReport, PhaseTime};
use oocfmt_meshio::import::{self, ImportError, Recentre, TriangleSink};

/// Bytes of memory the in-core build needs per input triangle, for the worst scene measured:
/// peak RSS over triangle count of release `oocfmt convert` runs was 336–369 B on generated
/// Mandelbulbs (1M–10M triangles) and 1 114 B on 1M triangles of generated CAD clutter, whose
/// thin overlapping parts are referenced by many leaves. A scene over `--mem-limit` at this
/// rate is built out of core, in chunks of at most `--mem-limit` / this many triangles.
pub const BYTES_PER_TRIANGLE_IN_CORE: u64 = 1152;

/// The smallest `--mem-limit` the CLI accepts: the process itself, the importers' vertex
/// arrays and a useful chunk need about this much.
pub const MIN_MEM_LIMIT: u64 = 16 << 20;

/// Everything [`convert`] needs besides its inputs and output.
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    /// LOD, treelet, block and write settings; `sources`, `origin` and `params` are filled in by
    /// [`convert`] from the inputs and `recentre`.
    pub layout: LayoutOptions,
    /// kd-tree build settings (SAH costs, leaf size, depth limit).
    pub kd: KdBuildOptions,
    /// Refuse the first bad triangle instead of dropping and counting it.
    pub strict: bool,
    /// Bytes of memory the build may use: a scene over this at [`BYTES_PER_TRIANGLE_IN_CORE`]
    /// is built out of core, in chunks that fit.
    pub mem_limit: u64,
    /// How `.obj` inputs are read.
    pub obj: import::obj::ObjOptions,
    /// How `.gltf` and `.glb` inputs are read.
    pub gltf: import::gltf::GltfOptions,
    /// The scene origin positions are stored relative to.
    pub recentre: Recentre,
}

impl Default for ConvertOptions {
    /// Default options, with half the physical memory (4 GiB where it is unknown) as the limit.
    fn default() -> Self {
        ConvertOptions {
            layout: LayoutOptions::default(),
            kd: KdBuildOptions::default(),
            strict: false,
            mem_limit: crate::report::total_memory().map_or(4 << 30, |m| m / 2),
            obj: Default::default(),
            gltf: Default::default(),
            recentre: Recentre::default(),
        }
    }
}

/// Why [`convert`] failed, by phase.
#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    /// An input could not be read or held a bad triangle under `strict`.
    #[error(transparent)]
    Import(#[from] ImportError),
    /// The in-core kd-tree build failed.
    #[error(transparent)]
    Tree(#[from] KdError),
    /// Computing LOD data, laying out blocks or writing them failed.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// The written file could not be re-opened to describe it.
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
    /// The out-of-core build, or a spill file, failed.
    #[error(transparent)]
    OutOfCore(#[from] OocError),
    /// An input's extension is none of `.obj`, `.gltf`, `.glb`, `.stl`, `.ply`; holds the
    /// input's path.
    #[error("{0}: unknown input format (expected .obj, .gltf, .glb, .stl or .ply)")]
    UnknownFormat(String),
    /// The temporary folder for spill files could not be made beside the output.
    #[error("cannot make a folder for spill files next to {path}: {source}")]
    SpillDir {
        /// The output file the folder was to sit beside.
        path: String,
        /// The I/O error creating it.
        source: std::io::Error,
    },
}

/// Input formats, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputFormat {
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// glTF 2.0, text (`.gltf`) or binary (`.glb`).
    Gltf,
    /// STL, ASCII or binary (`.stl`).
    Stl,
    /// PLY, ASCII or binary (`.ply`).
    Ply,
}

impl InputFormat {
    /// The format `path`'s extension names (case-insensitive), or None for any other extension.
    pub fn of(path: &Path) -> Option<InputFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(InputFormat::Obj),
            "gltf" | "glb" => Some(InputFormat::Gltf),
            "stl" => Some(InputFormat::Stl),
            "ply" => Some(InputFormat::Ply),
            _ => None,
        }
    }
}

struct Phases {
    list: Vec<PhaseTime>,
    at: Instant,
}

impl Phases {
    fn done(&mut self, phase: &str) {
        let now = Instant::now();
        self.list.push(PhaseTime {
            phase: phase.to_string(),
            seconds: (now - self.at).as_secs_f64(),
        });
        self.at = now;
    }
}

/// Imports `inputs` into one scene and writes the container `output`. A failure leaves no file
/// under `output` and never touches an existing one (the writer renames a finished file into
/// place).
pub fn convert(
    inputs: &[PathBuf],
    output: &Path,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<ConvertReport, ConvertError> {
    let start = Instant::now();
    let mut phases = Phases {
        list: Vec::new(),
        at: start,
    };
    // `--recentre auto` first reads the positions alone, for their bounds.
    let scan = opts.recentre.needs_scan();
    if scan {
        progress.phase("bounds", None);
    }
    let origin = opts
        .recentre
        .origin(|sink| inputs.iter().try_for_each(|p| import_one(p, sink, opts)))?;
    if scan {
        progress.finish_phase();
        phases.done("bounds");
    }
    // Spill files live next to the output: the same disk, and room for a model's worth.
    let parent = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let spill = tempfile::Builder::new()
        .prefix(".oocfmt-spill-")
        .tempdir_in(parent)
        .map_err(|source| ConvertError::SpillDir {
            path: output.display().to_string(),
            source,
        })?;
    let chunk_triangles = opts.mem_limit / BYTES_PER_TRIANGLE_IN_CORE;
    let soup = import_soup(
        inputs,
        opts,
        spill.path(),
        chunk_triangles,
        origin,
        progress,
    )?;
    phases.done("import");
    let mut import_report = soup.report.clone();
    if let Some(w) = precision_warning(&import_report, &soup.bounds) {
        import_report.warnings.push(w);
    }
    let mut layout = opts.layout.clone();
    layout.sources = inputs.iter().map(|p| p.display().to_string()).collect();
    layout.origin = origin;
    layout.params.extend(opts.recentre.params(origin));

    let (written, out_of_core) = if soup.count <= chunk_triangles {
        let written = build_in_core(soup, output, &opts.kd, &layout, &mut phases, progress)?;
        (written, None)
    } else {
        let (written, stats) = ooc::build(
            soup,
            output,
            &opts.kd,
            &layout,
            chunk_triangles,
            spill.path(),
            progress,
        )?;
        phases.done("out-of-core build");
        (written, Some(stats))
    };
    drop(spill);

    let mut report = describe(output, written.identity)?;
    report.import = import_report;
    report.out_of_core = out_of_core;
    report.phases = phases.list;
    report.seconds = start.elapsed().as_secs_f64();
    report.triangles_per_second = report.import.triangles_in as f64 / report.seconds.max(1e-9);
    report.peak_memory_bytes = peak_memory();
    report.mem_limit_bytes = opts.mem_limit;
    Ok(report)
}

/// Imports `inputs` into a spill file in `dir`, positions relative to `origin`. A scene of at
/// most `chunk_triangles` triangles is also kept in memory as it is read.
fn import_soup(
    inputs: &[PathBuf],
    opts: &ConvertOptions,
    dir: &Path,
    chunk_triangles: u64,
    origin: [f64; 3],
    progress: &mut dyn Progress,
) -> Result<Soup, ConvertError> {
    // Several files: each is a part above its own parts, so the assembly says where it came from.
    let mut sink = soup_sink(&dir.join("import.soup"), opts.strict, Some(chunk_triangles))?
        .with_origin(origin)
        .with_file_parts(inputs.len() > 1);
    progress.phase("import", Some(inputs.len() as u64));
    for (i, path) in inputs.iter().enumerate() {
        import_one(path, &mut sink, opts)?;
        progress.advance(i as u64 + 1);
    }
    progress.finish_phase();
    Ok(finish_soup(sink)?)
}

/// Builds a scene that fits in memory: its kd-tree, then its LOD data and blocks, then the
/// file.
fn build_in_core(
    mut soup: Soup,
    output: &Path,
    kd: &KdBuildOptions,
    layout: &LayoutOptions,
    phases: &mut Phases,
    progress: &mut dyn Progress,
) -> Result<WriteSummary, ConvertError> {
    let mesh = soup.load_mesh()?;
    std::fs::remove_file(&soup.path).map_err(|e| OocError::spill(&soup.path, e))?;
    phases.done("load");
    progress.phase("kd-tree", None);
    let tree = kdtree::build(&mesh, kd)?;
    progress.finish_phase();
    phases.done("kd-tree");

    progress.phase("LOD + layout", None);
    let container = build_blocks(&mesh, &tree, layout)?;
    progress.finish_phase();
    phases.done("lod+layout");
    // Freeing the tree's millions of leaf lists takes a while: beside the writing.
    let freed = std::thread::spawn(move || drop((tree, mesh)));

    progress.phase("write", Some(container.blocks.len() as u64));
    let written = write_blocks(output, &container, layout.write, &mut |n| {
        progress.advance(n)
    });
    drop(freed.join());
    let written = written?;
    progress.finish_phase();
    phases.done("write");
    Ok(written)
}

/// A warning when f32 rounding moved positions by more than about a millionth of the model's
/// size: a model far from its origin, which `--recentre auto` would have kept exact.
fn precision_warning(
    report: &import::ImportReport,
    bounds: &oocfmt_meshio::mesh::Bounds,
) -> Option<String> {
    let extent = (0..3)
        .map(|a| f64::from(bounds.max[a]) - f64::from(bounds.min[a]))
        .fold(0.0, f64::max);
    let error = report.placement.max_abs_error;
    let dropped = report.dropped_total();
    (extent > 0.0 && error > extent * f64::from(f32::EPSILON) * 8.0).then(|| {
        format!(
            "positions were rounded by up to {error:.3e} in f32, {:.1e} of the model's extent \
             {extent:.3e} ({dropped} triangles dropped in all): the model lies far from its \
             origin; `--recentre auto` stores positions relative to a nearby origin",
            error / extent
        )
    })
}

fn import_one(
    path: &Path,
    sink: &mut dyn TriangleSink,
    opts: &ConvertOptions,
) -> Result<(), ConvertError> {
    match InputFormat::of(path) {
        Some(InputFormat::Obj) => import::obj::import(path, sink, &opts.obj)?,
        Some(InputFormat::Gltf) => import::gltf::import(path, sink, &opts.gltf)?,
        // Their options only bound what a file can make the importer hold: the defaults.
        Some(InputFormat::Stl) => import::stl::import(path, sink, &Default::default())?,
        Some(InputFormat::Ply) => import::ply::import(path, sink, &Default::default())?,
        None => return Err(ConvertError::UnknownFormat(path.display().to_string())),
    }
    Ok(())
}

/// The report's figures about the written file, read back from it.
fn describe(output: &Path, identity: u32) -> Result<ConvertReport, ConvertError> {
    let reader = Reader::open(output, ReadOptions::default())?;
    let m = reader.metadata();
    let mut report = ConvertReport {
        output: output.display().to_string(),
        triangles_stored: m.counts.triangles,
        basic_nodes: m.counts.basic_nodes,
        lod_nodes: m.counts.lod_nodes,
        leaves: m.counts.leaves,
        depth: m.counts.depth,
        voxels_single: m.counts.voxels_single,
        voxels_six: m.counts.voxels_six,
        lod_kinds: reader.lod_kinds().name().to_string(),
        proxies: m.counts.proxies,
        parts: m.parts.len() as u64,
        file_bytes: reader.file_len(),
        identity: format!("{identity:08x}"),
        ..ConvertReport::default()
    };
    for e in reader.entries() {
        let kind = match e.kind {
            BlockKind::Treelet => "treelet",
            BlockKind::Triangle => "triangle",
            BlockKind::Proxy => "proxy",
        };
        let s: &mut BlockStats = report.blocks.entry(kind.to_string()).or_default();
        s.blocks += 1;
        s.raw_bytes += u64::from(e.raw_length);
        s.stored_bytes += u64::from(e.stored_length);
    }
    Ok(report)
}
