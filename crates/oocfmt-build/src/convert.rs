//! The conversion pipeline behind `oocfmt convert`: import every input into one scene, build the
//! kd-tree, compute LOD data and lay it out, write the container, then re-open it to report what
//! was written. Each phase is timed and reported.

use std::path::{Path, PathBuf};
use std::time::Instant;

use oocfmt::{BlockKind, ReadOptions, Reader, WriteSummary};

use crate::interrupt::{self, Interrupt, WatchedProgress, WatchedSink};
use crate::kdtree::{self, KdBuildOptions, KdError};
use crate::layout::{build_blocks, write_blocks, LayoutError, LayoutOptions};
use crate::ooc::soup::{finish_soup, soup_sink, Soup};
use crate::ooc::{self, OocError};
use crate::progress::Progress;
use crate::report::{peak_memory, BlockStats, ConvertReport, PhaseClock};
use crate::spill_dir::{self, SpillDir};
use oocfmt_meshio::import::spill_table::VertexSpill;
use oocfmt_meshio::import::{self, ImportError, Recentre, TriangleSink};

/// Bytes of memory the in-core build needs per input triangle, for the worst scene measured:
/// peak RSS over triangle count of release `oocfmt convert` runs was 336–369 B on generated
/// Mandelbulbs (1M–10M triangles) and 1 114 B on 1M triangles of generated CAD clutter, whose
/// thin overlapping parts are referenced by many leaves. A scene over `--mem-limit` at this
/// rate is built out of core, in chunks of at most half `--mem-limit` / this many triangles,
/// two built at once.
pub const BYTES_PER_TRIANGLE_IN_CORE: u64 = 1152;

/// The input name that stands for standard input.
pub const STDIN: &str = "-";

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
    /// How `.ply` inputs are read.
    pub ply: import::ply::PlyOptions,
    /// How `.gltf` and `.glb` inputs are read.
    pub gltf: import::gltf::GltfOptions,
    /// The scene origin positions are stored relative to.
    pub recentre: Recentre,
    /// The folder spill files go to (`--tmp-dir`); `None`: next to the output.
    pub tmp_dir: Option<PathBuf>,
    /// The format of every input (`--format`); `None`: each file's extension tells. Standard
    /// input ([`STDIN`]) has no extension, so it needs one.
    pub format: Option<InputFormat>,
    /// Asked, the build stops at its next check and removes what it made
    /// ([`ConvertError::Interrupted`]).
    pub interrupt: Interrupt,
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
            ply: Default::default(),
            gltf: Default::default(),
            recentre: Recentre::default(),
            tmp_dir: None,
            format: None,
            interrupt: Interrupt::default(),
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
    /// The temporary folder for spill files could not be made (beside the output, or in
    /// `--tmp-dir`).
    #[error("cannot make a folder for spill files in {path}: {source}")]
    SpillDir {
        /// The folder it was to be made in.
        path: String,
        /// The I/O error creating it.
        source: std::io::Error,
    },
    /// A stop was requested ([`ConvertOptions::interrupt`]); the spill folder and the
    /// temporary output were removed, an existing output left as it was.
    #[error(
        "interrupted: removed {} of spill files; {output} was not written",
        spill_dir::mib(*spill_bytes)
    )]
    Interrupted {
        /// The output, as its path displays.
        output: String,
        /// The bytes the removed spill files took.
        spill_bytes: u64,
    },
    /// Standard input is an input, with no [`ConvertOptions::format`] to say what it holds.
    #[error("standard input (`-`) needs `--format obj|ply|stl`: no file name tells its format")]
    StdinFormat,
    /// Standard input is an input and the format is glTF, which is not read from a stream.
    #[error(
        "glTF cannot be read from standard input: its buffers are other files or need random \
         access; save it to a file first (standard input takes obj, ply or stl)"
    )]
    StdinGltf,
    /// Standard input is named more than once.
    #[error("standard input (`-`) can be an input only once")]
    StdinTwice,
    /// Standard input with `--recentre auto`, which reads every input twice.
    #[error(
        "`--recentre auto` reads the inputs twice, and standard input can be read only once: \
         pass `--recentre none` or `--recentre X,Y,Z` (a point near the model)"
    )]
    StdinRecentre,
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

/// Imports `inputs` into one scene and writes the container `output`; an input [`STDIN`]
/// (`-`) is read from standard input. A failure or an interruption leaves no file under
/// `output` and never touches an existing one (the writer renames a finished file into
/// place), and removes the spill folder. Spill folders of builds that no longer run, found
/// where this one's goes, are removed first and reported through [`Progress::warn`].
pub fn convert(
    inputs: &[PathBuf],
    output: &Path,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<ConvertReport, ConvertError> {
    let start = Instant::now();
    check_stdin(inputs, opts)?;
    // Before any work: refuse a conversion the disk cannot hold (skipped for an input of
    // unknown size).
    let output_dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let estimate = ooc::space::Estimate::of(inputs);
    // Spill files live next to the output (the same disk, and room for a model's worth)
    // unless `--tmp-dir` puts them elsewhere.
    let parent = opts.tmp_dir.as_deref().unwrap_or(output_dir);
    if let Some(e) = &estimate {
        e.check(parent, output_dir).map_err(OocError::from)?;
    }
    for stale in spill_dir::clear_stale(parent) {
        progress.warn(&stale.to_string());
    }
    let spill = SpillDir::create(parent).map_err(|source| ConvertError::SpillDir {
        path: parent.display().to_string(),
        source,
    })?;
    let mut watched = WatchedProgress {
        inner: progress,
        interrupt: &opts.interrupt,
    };
    let run = Run {
        inputs,
        output,
        opts,
        spill: spill.path(),
        estimate,
    };
    match interrupt::catch(|| run_convert(run, start, &mut watched)) {
        Some(Ok(report)) => Ok(report),
        Some(Err(e)) if !e.is_interruption() => Err(e),
        _ => Err(ConvertError::Interrupted {
            output: output.display().to_string(),
            spill_bytes: spill.remove(),
        }),
    }
}

/// Refuses what standard input cannot do: be read twice, or without a format, or as glTF.
fn check_stdin(inputs: &[PathBuf], opts: &ConvertOptions) -> Result<(), ConvertError> {
    match inputs.iter().filter(|p| is_stdin(p)).count() {
        0 => return Ok(()),
        1 => {}
        _ => return Err(ConvertError::StdinTwice),
    }
    match opts.format {
        None => Err(ConvertError::StdinFormat),
        Some(InputFormat::Gltf) => Err(ConvertError::StdinGltf),
        Some(_) if opts.recentre.needs_scan() => Err(ConvertError::StdinRecentre),
        Some(_) => Ok(()),
    }
}

/// Whether the input `path` stands for standard input.
pub(crate) fn is_stdin(path: &Path) -> bool {
    path.as_os_str() == STDIN
}

impl ConvertError {
    /// Whether this is a stop on request, however deep it was raised.
    fn is_interruption(&self) -> bool {
        matches!(
            self,
            ConvertError::Interrupted { .. }
                | ConvertError::Import(ImportError::Interrupted { .. })
                | ConvertError::OutOfCore(OocError::Import(ImportError::Interrupted { .. }))
        )
    }
}

/// One conversion's inputs, output and settings, with its spill folder made.
struct Run<'a> {
    inputs: &'a [PathBuf],
    output: &'a Path,
    opts: &'a ConvertOptions,
    spill: &'a Path,
    estimate: Option<ooc::space::Estimate>,
}

/// Imports, builds and writes, then describes what was written.
fn run_convert(
    run: Run<'_>,
    start: Instant,
    progress: &mut dyn Progress,
) -> Result<ConvertReport, ConvertError> {
    let Run {
        inputs,
        output,
        opts,
        spill,
        estimate,
    } = run;
    let mut phases = PhaseClock::new(start);
    // `--recentre auto` first reads the positions alone, for their bounds.
    let scan = opts.recentre.needs_scan();
    if scan {
        progress.phase("bounds", None);
    }
    let origin = opts.recentre.origin(|sink| {
        let mut sink = WatchedSink::new(sink, &opts.interrupt);
        inputs
            .iter()
            .try_for_each(|p| import_one(p, &mut sink, opts))
    })?;
    if scan {
        progress.finish_phase();
        phases.done("bounds");
    }
    let chunk_triangles = opts.mem_limit / BYTES_PER_TRIANGLE_IN_CORE;
    let soup = import_soup(inputs, opts, spill, chunk_triangles, origin, progress)?;
    phases.done("import");
    let disk = soup.disk.clone();
    let spill_bytes_per_triangle = soup.bytes_per_triangle();
    let mut import_report = soup.report.clone();
    if let Some(w) = precision_warning(&import_report, &soup.scene.bounds) {
        import_report.warnings.push(w);
    }
    let mut layout = opts.layout.clone();
    layout.sources = inputs.iter().map(|p| source_name(p)).collect();
    layout.origin = origin;
    layout.params.extend(opts.recentre.params(origin));

    let (written, out_of_core) = if soup.scene.count <= chunk_triangles {
        let written = build_in_core(soup, output, &opts.kd, &layout, &mut phases, progress)?;
        (written, None)
    } else {
        let (written, stats) = ooc::build(
            soup,
            output,
            &opts.kd,
            &layout,
            ooc::Chunking::new(chunk_triangles, spill),
            &mut phases,
            progress,
        )?;
        (written, Some(stats))
    };

    let mut report = describe(output, written.identity)?;
    report.import = import_report;
    report.out_of_core = out_of_core;
    report.phases = phases.into_list();
    report.seconds = start.elapsed().as_secs_f64();
    report.triangles_per_second = report.import.triangles_in as f64 / report.seconds.max(1e-9);
    report.peak_memory_bytes = peak_memory();
    report.mem_limit_bytes = opts.mem_limit;
    // The finished output outlives the spill files.
    report.peak_disk_bytes = disk.peak().max(report.file_bytes);
    report.spill_bytes_per_triangle = spill_bytes_per_triangle;
    report.disk_estimate_bytes = estimate.map(|e| e.peak_bytes());
    Ok(report)
}

/// How `path` is named among the container's sources.
fn source_name(path: &Path) -> String {
    match is_stdin(path) {
        true => import::STDIN_NAME.to_string(),
        false => path.display().to_string(),
    }
}

/// Imports `inputs` into a spill file in `dir`, positions relative to `origin`. A scene of at
/// most `chunk_triangles` triangles is also kept in memory as it is read.
pub(crate) fn import_soup(
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
    let opts = &with_vertex_spill(opts, dir);
    for (i, path) in inputs.iter().enumerate() {
        import_one(
            path,
            &mut WatchedSink::new(&mut sink, &opts.interrupt),
            opts,
        )?;
        progress.advance(i as u64 + 1);
    }
    progress.finish_phase();
    Ok(finish_soup(sink)?)
}

/// `opts` with OBJ and PLY vertex tables beyond an eighth of the memory limit each
/// (positions, normals, colours) moved to `dir`, unless the caller chose a spill: a
/// billion-triangle model has half a billion vertices.
fn with_vertex_spill(opts: &ConvertOptions, dir: &Path) -> ConvertOptions {
    let mut opts = opts.clone();
    let spill = |max_vertices: usize| VertexSpill {
        to: import::spill_table::SpillTo {
            dir: dir.to_path_buf(),
            resident_bytes: usize::try_from(opts.mem_limit / 8).unwrap_or(usize::MAX),
        },
        max_vertices: VertexSpill::MAX_VERTICES.max(max_vertices),
    };
    if opts.obj.spill.is_none() {
        opts.obj.spill = Some(spill(opts.obj.max_vertices));
    }
    if opts.ply.spill.is_none() {
        let max = usize::try_from(opts.ply.max_vertices).unwrap_or(usize::MAX);
        opts.ply.spill = Some(spill(max));
    }
    opts
}

/// Builds a scene that fits in memory: its kd-tree, then its LOD data and blocks, then the
/// file.
fn build_in_core(
    soup: Soup,
    output: &Path,
    kd: &KdBuildOptions,
    layout: &LayoutOptions,
    phases: &mut PhaseClock,
    progress: &mut dyn Progress,
) -> Result<WriteSummary, ConvertError> {
    let mesh = soup.into_mesh()?;
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

/// Imports the input `path` (a file, or standard input as [`STDIN`]) into `sink`, in
/// [`ConvertOptions::format`] or the format its extension names.
pub(crate) fn import_one(
    path: &Path,
    sink: &mut dyn TriangleSink,
    opts: &ConvertOptions,
) -> Result<(), ConvertError> {
    let format = opts.format.or_else(|| InputFormat::of(path));
    if is_stdin(path) {
        return import_stdin(format, sink, opts);
    }
    match format {
        Some(InputFormat::Obj) => import::obj::import(path, sink, &opts.obj)?,
        Some(InputFormat::Gltf) => import::gltf::import(path, sink, &opts.gltf)?,
        // Its options only bound what a file can make the importer hold: the defaults.
        Some(InputFormat::Stl) => import::stl::import(path, sink, &Default::default())?,
        Some(InputFormat::Ply) => import::ply::import(path, sink, &opts.ply)?,
        None => return Err(ConvertError::UnknownFormat(path.display().to_string())),
    }
    Ok(())
}

/// Imports standard input, in `format`, into `sink`: read once, front to back. OBJ material
/// libraries are looked up in the current folder.
fn import_stdin(
    format: Option<InputFormat>,
    sink: &mut dyn TriangleSink,
    opts: &ConvertOptions,
) -> Result<(), ConvertError> {
    let input = std::io::BufReader::with_capacity(1 << 16, std::io::stdin());
    let name = import::STDIN_NAME;
    match format {
        Some(InputFormat::Obj) => {
            import::obj::import_from(input, name, Path::new("."), sink, &opts.obj)?
        }
        Some(InputFormat::Stl) => {
            import::stl::import_stream(input, name, sink, &Default::default())?
        }
        Some(InputFormat::Ply) => import::ply::import_stream(input, name, sink, &opts.ply)?,
        Some(InputFormat::Gltf) => return Err(ConvertError::StdinGltf),
        None => return Err(ConvertError::StdinFormat),
    }
    Ok(())
}

/// The report's figures about the written file, read back from it.
pub(crate) fn describe(output: &Path, identity: u32) -> Result<ConvertReport, ConvertError> {
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
