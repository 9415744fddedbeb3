//! A build split into subsets that separate processes (or machines, or the tasks of a batch
//! engine such as Slurm) run, then merged (spec §16). The out-of-core build already cuts the
//! scene at spatial medians and builds each chunk on its own; a plan fixes the top cuts for
//! every process, each subset builds the cells below one cut as the out-of-core build would,
//! and the merge lays out the top over them and copies their blocks.
//!
//! - [`make_plan`] reads the inputs twice: bounds and a sample of centroids choose the cuts,
//!   then every triangle is routed down them to count the cells and fit the R-LOD planes of
//!   the LOD nodes among the cuts ([`plan`]).
//! - [`build_subset`] reads every input again, keeps the triangles that reach its cell with
//!   the primary flags the split would give them, splits and builds them, answers the rays of
//!   the LOD cuts above it and measures their planes, and writes a subset file ([`file`]).
//! - [`merge`] checks that every subset of one plan is there once, joins their trees under
//!   the plan's cuts, and finishes as the out-of-core build finishes.
//!
//! [`convert_plan`] does all of it in one process: the same subset files and the same merge,
//! so its output is the merge's, byte for byte.

mod build;
mod cells;
pub(crate) mod file;
mod merge;
pub mod plan;
mod planner;
mod route;

use std::path::{Path, PathBuf};

pub use build::{build_subset, SubsetReport};
pub use file::{HEADER_LEN as SUBSET_HEADER_LEN, MAGIC as SUBSET_MAGIC, VERSION as SUBSET_VERSION};
pub use merge::{merge, plan_of_subset, MergeReport};
pub use plan::Plan;
pub use planner::{make_plan, update_plan, PlanReport};

use crate::convert::{ConvertError, ConvertOptions};
use crate::interrupt::{self, WatchedProgress};
use crate::layout::LayoutError;
use crate::ooc::OocError;
use crate::progress::Progress;
use crate::report::ConvertReport;
use oocfmt_meshio::import::ImportError;

/// Why planning, building a subset or merging failed.
#[derive(Debug, thiserror::Error)]
pub enum SubsetError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A plan file is malformed, of another version, or edited.
    #[error("plan {path}: {what}")]
    Plan {
        /// The plan file.
        path: String,
        /// What is wrong.
        what: String,
    },
    /// Encoding a plan or a subset body failed.
    #[error("encoding failed: {0}")]
    Json(String),
    /// A subset file is damaged: its bytes fail a check.
    #[error("{path}: byte {offset}: {what}")]
    Corrupt {
        /// The subset file.
        path: String,
        /// Where in it.
        offset: u64,
        /// What is wrong.
        what: String,
    },
    /// An input is not what the plan was made from.
    #[error("{path}: {what} since the plan was made; make a new plan")]
    InputChanged {
        /// The input.
        path: String,
        /// What changed.
        what: String,
    },
    /// Standard input among a plan's inputs.
    #[error("a plan reads its inputs several times: standard input (`-`) cannot be planned; save it to a file")]
    Stdin,
    /// A subset count outside 1 ..= [`plan::MAX_SUBSETS`].
    #[error("subsets must be from 1 to {}", plan::MAX_SUBSETS)]
    TooManySubsets,
    /// A subset index the plan does not have.
    #[error("subset {index} is not in the plan, which has {subsets} subsets (0 to {})", subsets.saturating_sub(1))]
    NoSuchSubset {
        /// The index asked for.
        index: u32,
        /// The plan's subsets.
        subsets: u32,
    },
    /// The merge was given no subset file.
    #[error("no subset files to merge")]
    NoSubsets,
    /// Subsets of the plan are missing from the merge.
    #[error("missing subsets {missing} of {subsets} (plan {plan}): every subset is needed once")]
    Missing {
        /// The missing indices, listed.
        missing: String,
        /// The plan's subsets.
        subsets: u32,
        /// The plan's identity.
        plan: String,
    },
    /// The same subset twice.
    #[error("subset {index} is given twice: {first} and {second}")]
    Duplicate {
        /// The index.
        index: u32,
        /// The first file holding it.
        first: String,
        /// The second.
        second: String,
    },
    /// A subset file of another plan, or one that disagrees with the others.
    #[error("{path}: {what}")]
    Foreign {
        /// The subset file.
        path: String,
        /// How it differs.
        what: String,
    },
    /// Reading the inputs failed.
    #[error(transparent)]
    Import(#[from] ImportError),
    /// The build of a subset failed.
    #[error(transparent)]
    OutOfCore(#[from] OocError),
    /// Laying out the top failed.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// A conversion step failed.
    #[error(transparent)]
    Convert(#[from] Box<ConvertError>),
    /// A stop was requested; what was made was removed.
    #[error("interrupted: {output} was not written")]
    Interrupted {
        /// The output not written.
        output: String,
    },
    /// A bug: a structure the build made is inconsistent.
    #[error("internal error: {0}")]
    Internal(&'static str),
}

impl From<oocfmt::Error> for SubsetError {
    fn from(e: oocfmt::Error) -> Self {
        SubsetError::OutOfCore(OocError::Format(e))
    }
}

impl SubsetError {
    /// Whether this is a stop on request.
    fn is_interruption(&self) -> bool {
        matches!(
            self,
            SubsetError::Interrupted { .. }
                | SubsetError::Import(ImportError::Interrupted { .. })
                | SubsetError::OutOfCore(OocError::Import(ImportError::Interrupted { .. }))
        )
    }
}

/// Runs `f` with a progress that stops it when `opts.interrupt` asks; a stop becomes
/// [`SubsetError::Interrupted`] naming `output`.
fn watched<T>(
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
    output: &str,
    f: impl FnOnce(&mut dyn Progress) -> Result<T, SubsetError>,
) -> Result<T, SubsetError> {
    let mut w = WatchedProgress {
        inner: progress,
        interrupt: &opts.interrupt,
    };
    match interrupt::catch(|| f(&mut w)) {
        Some(Ok(v)) => Ok(v),
        Some(Err(e)) if !e.is_interruption() => Err(e),
        _ => Err(SubsetError::Interrupted {
            output: output.to_string(),
        }),
    }
}

/// What checking a subset file found: it is whole.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SubsetCheck {
    /// The subset's index, and the plan's subsets.
    pub index: u32,
    /// The plan's subsets.
    pub subsets: u32,
    /// The plan's identity.
    pub plan: String,
    /// Blocks checked.
    pub blocks: u64,
    /// Bytes of blocks checked.
    pub block_bytes: u64,
}

/// Whether the file at `path` starts as a subset file does.
pub fn is_subset_file(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok_and(|()| magic == file::MAGIC)
}

/// Checks a subset file (spec §16.2): its header, its body's checksum and encoding, its
/// plan (whose identity the header names, and whose cell the index names), and every block's
/// place and checksum.
pub fn verify_subset(path: &Path) -> Result<SubsetCheck, SubsetError> {
    let f = file::SubsetFile::open(path)?;
    let plan = merge::plan_of(&f)?;
    let top = plan.top()?;
    if top.cells.get(f.header.index as usize).is_none() {
        return Err(SubsetError::Internal("a checked plan lacks a cell"));
    }
    let (blocks, block_bytes) = f.check_blocks()?;
    Ok(SubsetCheck {
        index: f.header.index,
        subsets: f.header.subsets,
        plan: plan.identity,
        blocks,
        block_bytes,
    })
}

/// Builds every subset of `plan` in turn into a spill folder, then merges them into
/// `output`: the single-machine form of a split build, byte for byte what merging the same
/// subsets built anywhere gives. `opts` must be the plan's settings.
pub fn convert_plan(
    plan: &Plan,
    output: &Path,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<ConvertReport, SubsetError> {
    let parent = opts
        .tmp_dir
        .clone()
        .unwrap_or_else(|| build::folder_of(output).to_path_buf());
    // A spill folder, locked for the build's life: a later build removes it if this one is
    // killed.
    for stale in crate::spill_dir::clear_stale(&parent) {
        progress.warn(&stale.to_string());
    }
    let dir = crate::spill_dir::SpillDir::create(&parent).map_err(|source| SubsetError::Io {
        path: parent.display().to_string(),
        source,
    })?;
    let start = std::time::Instant::now();
    // The inputs are read for their checksums once, not once a subset.
    build::check_inputs(plan)?;
    let mut parts: Vec<PathBuf> = Vec::new();
    let mut peak_disk = 0u64;
    for index in 0..plan.subsets {
        let part = dir.path().join(format!("part-{index}.oocfp"));
        let built = build::build_checked(plan, index, &part, opts, progress)?;
        // The subset files so far, and this subset's spill files at their peak.
        peak_disk = peak_disk.max(built.peak_disk_bytes + dir_bytes(dir.path()));
        parts.push(part);
    }
    let subsets = start.elapsed().as_secs_f64();
    let mut report = merge(&parts, output, opts, Some(plan), progress)?.convert;
    report.phases.insert(
        0,
        crate::report::PhaseTime {
            phase: "subsets".into(),
            seconds: subsets,
        },
    );
    report.seconds = start.elapsed().as_secs_f64();
    report.triangles_per_second = report.import.triangles_in as f64 / report.seconds.max(1e-9);
    report.peak_disk_bytes = peak_disk.max(dir_bytes(dir.path()) + report.file_bytes);
    report.disk_estimate_bytes = build::space_estimate(plan).map(|e| e.peak_bytes());
    Ok(report)
}

/// Bytes of the files in `dir`.
fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok()?.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}
