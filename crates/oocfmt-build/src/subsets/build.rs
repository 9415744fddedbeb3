//! `oocfmt convert --plan P --subset I`: one subset, built as the out-of-core build builds the
//! cells below a cut, into a subset file.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::file::{self, Body, ChunkRecord, Header, TopLodRecord};
use super::plan::{Plan, PlanTop, SubsetCell};
use super::planner::checksum;
use super::route::{import_all, CellStore};
use super::{watched, SubsetError};
use crate::convert::{ConvertOptions, BYTES_PER_TRIANGLE_IN_CORE};
use crate::layout::LayoutOptions;
use crate::ooc::disk::SpillDisk;
use crate::ooc::space::Estimate;
use crate::ooc::{Chunking, OocBuild, OocError};
use crate::progress::Progress;
use crate::report::peak_memory;
use crate::spill_dir::{self, SpillDir};

/// What building one subset did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SubsetReport {
    /// The subset file written.
    pub output: String,
    /// Its index.
    pub index: u32,
    /// The plan's subsets.
    pub subsets: u32,
    /// Bytes of the subset file.
    pub file_bytes: u64,
    /// Triangle records of the subset's cell (copies of straddling triangles included).
    pub records: u64,
    /// Chunks it was built in.
    pub chunks: u64,
    /// Blocks it holds.
    pub blocks: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Peak resident memory of the process, where known.
    pub peak_memory_bytes: Option<u64>,
    /// Most bytes its spill files took at once.
    pub peak_disk_bytes: u64,
}

/// The folder `path` is in ("." for a bare name).
pub(super) fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The layout options of every subset and the merge of `plan`: `opts`' own, with the inputs,
/// the origin and the plan named as the container records them.
pub(super) fn plan_layout(plan: &Plan, opts: &ConvertOptions) -> LayoutOptions {
    let mut layout = opts.layout.clone();
    layout.sources = plan.inputs.iter().map(|i| i.path.clone()).collect();
    layout.origin = plan.origin();
    layout.params.extend(opts.recentre.params(layout.origin));
    layout.params.push((
        "plan".into(),
        format!("{} subsets, plan {}", plan.subsets, plan.identity),
    ));
    layout
}

/// Builds subset `index` of `plan` into the subset file `output`. `opts` must be the plan's
/// settings. Every input is checked against the plan first: a changed input is refused.
pub fn build_subset(
    plan: &Plan,
    index: u32,
    output: &Path,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<SubsetReport, SubsetError> {
    // A wrong index is told before the inputs are read for their checksums.
    if index >= plan.subsets {
        return Err(SubsetError::NoSuchSubset {
            index,
            subsets: plan.subsets,
        });
    }
    check_inputs(plan)?;
    build_checked(plan, index, output, opts, progress)
}

/// [`build_subset`] with the inputs already checked against the plan.
pub(super) fn build_checked(
    plan: &Plan,
    index: u32,
    output: &Path,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<SubsetReport, SubsetError> {
    let start = Instant::now();
    let top = plan.top()?;
    let cell = top
        .cells
        .get(index as usize)
        .cloned()
        .ok_or(SubsetError::NoSuchSubset {
            index,
            subsets: plan.subsets,
        })?;
    let parent = opts.tmp_dir.as_deref().unwrap_or(folder_of(output));
    // A subset spills at most the whole scene, as one conversion does.
    if let Some(e) = space_estimate(plan) {
        e.check(parent, folder_of(output)).map_err(OocError::from)?;
    }
    for stale in spill_dir::clear_stale(parent) {
        progress.warn(&stale.to_string());
    }
    let spill = SpillDir::create(parent).map_err(|source| SubsetError::Io {
        path: parent.display().to_string(),
        source,
    })?;
    let job = Job {
        plan,
        top: &top,
        index,
        cell: &cell,
        output,
        opts,
        dir: spill.path(),
    };
    let mut report = watched(opts, progress, &output.display().to_string(), |p| {
        job.run(p)
    })?;
    drop(spill);
    report.seconds = start.elapsed().as_secs_f64();
    report.peak_memory_bytes = peak_memory();
    Ok(report)
}

/// What converting the plan's inputs is estimated to take on disk.
pub(super) fn space_estimate(plan: &Plan) -> Option<Estimate> {
    let inputs: Vec<PathBuf> = plan.inputs.iter().map(|i| PathBuf::from(&i.path)).collect();
    Estimate::of(&inputs)
}

/// Refuses an input whose length or checksum is not the plan's.
pub(super) fn check_inputs(plan: &Plan) -> Result<(), SubsetError> {
    for input in &plan.inputs {
        let (bytes, crc) = checksum(Path::new(&input.path))?;
        let what = if bytes != input.bytes {
            format!("{bytes} bytes, {} when planned", input.bytes)
        } else if format!("{crc:08x}") != input.crc32c {
            format!("CRC-32C {crc:08x}, {} when planned", input.crc32c)
        } else {
            continue;
        };
        return Err(SubsetError::InputChanged {
            path: input.path.clone(),
            what: format!("it changed ({what})"),
        });
    }
    Ok(())
}

/// One subset build with its spill folder made.
struct Job<'a> {
    plan: &'a Plan,
    top: &'a PlanTop,
    index: u32,
    cell: &'a SubsetCell,
    output: &'a Path,
    opts: &'a ConvertOptions,
    dir: &'a Path,
}

impl Job<'_> {
    fn run(&self, progress: &mut dyn Progress) -> Result<SubsetReport, SubsetError> {
        let (plan, opts, cell) = (self.plan, self.opts, self.cell);
        let disk = Arc::new(SpillDisk::new());
        let base = self.dir.join("cell.soup");
        let store = CellStore::new(plan, &self.top.tree.nodes, cell, &base, disk.clone())?;
        let inputs: Vec<PathBuf> = plan.inputs.iter().map(|i| PathBuf::from(&i.path)).collect();
        let origin = plan.origin();
        let intaken = import_all(&inputs, store, origin, opts, "import", progress, |_, _| {})?;
        let (triangles_in, triangles_out) =
            (intaken.report.triangles_in, intaken.report.triangles_out);
        let scene = intaken.store.tally.scene(&intaken);
        let run = intaken.store.finish()?;
        if scene.count != plan.triangles || scene.bounds != plan.scene_bounds() {
            return Err(SubsetError::InputChanged {
                path: plan
                    .inputs
                    .first()
                    .map(|i| i.path.clone())
                    .unwrap_or_default(),
                what: "the inputs read differently (another importer version or options?)".into(),
            });
        }
        let records = run.count;
        let layout = plan_layout(plan, opts);
        let chunking = Chunking::new(opts.mem_limit / BYTES_PER_TRIANGLE_IN_CORE, self.dir);
        let b = OocBuild::new(&scene, &disk, &opts.kd, &layout, &chunking)?;
        let mut tree = b.split(run, self.top.tree.clone(), cell.start(), progress)?;
        let planes = std::mem::take(&mut tree.planes);
        let plan_nodes = self.top.plan_nodes;
        let own = |n: usize| n >= plan_nodes || n == cell.node;
        let top_lod = b
            .top_lod_nodes(&tree)
            .into_iter()
            .filter(|t| own(t.node) || cell.ancestors.contains(&t.node))
            .collect();
        let (chunks, mut spill) = b.build_chunks(&tree, planes, top_lod, progress)?;
        let root = tree
            .nodes
            .get(cell.node)
            .cloned()
            .ok_or(SubsetError::Internal("the subset's cell has no node"))?;
        let mut outs = chunks.outs;
        for (o, p) in outs.iter_mut().zip(chunks.proxies) {
            o.proxies = p;
        }
        let blocks = outs
            .iter()
            .map(|o| (o.treelet_blocks.len() + o.triangle_blocks.len()) as u64)
            .sum();
        let mut body = Body {
            plan: plan.to_json()?,
            scene,
            triangles_in,
            triangles_out,
            root,
            nodes: tree.nodes.get(plan_nodes..).unwrap_or_default().to_vec(),
            chunks: tree
                .chunks
                .into_iter()
                .zip(outs)
                .map(|(c, out)| ChunkRecord {
                    count: c.count,
                    cell: c.cell,
                    depth: c.depth,
                    ancestors: c.ancestors,
                    out,
                })
                .collect(),
            oversized: tree.oversized,
            planes: chunks.planes.into_iter().filter(|(n, _)| own(*n)).collect(),
            top_lod: chunks
                .top_lod
                .into_iter()
                .map(|t| TopLodRecord {
                    node: t.node,
                    cell: t.cell,
                    answers: t.rays.iter().map(|r| r.best).collect(),
                })
                .collect(),
            proxy_count: chunks.proxy_count,
        };
        let header = Header {
            index: self.index,
            subsets: plan.subsets,
            plan_identity: plan.identity_number()?,
            body_offset: 0,
            body_len: 0,
            body_crc: 0,
        };
        progress.phase("write", None);
        let file_bytes = file::write(self.output, header, &mut body, &mut spill)?;
        progress.finish_phase();
        Ok(SubsetReport {
            output: self.output.display().to_string(),
            index: self.index,
            subsets: plan.subsets,
            file_bytes,
            records,
            chunks: body.chunks.len() as u64,
            blocks,
            seconds: 0.0,
            peak_memory_bytes: None,
            peak_disk_bytes: disk.peak(),
        })
    }
}
