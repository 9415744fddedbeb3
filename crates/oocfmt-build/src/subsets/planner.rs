//! `oocfmt plan`: the inputs' checksums, then two passes over them (a sample, then every
//! triangle routed down the cuts), then the plan.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::cells::{CellTree, RouteStore, SampleStore};
use super::plan::{plan_nodes, Plan, PlanInput, PlanNode, MAX_SUBSETS, PLAN_FORMAT, PLAN_VERSION};
use super::route::import_all;
use super::{watched, SubsetError};
use crate::convert::{import_one, is_stdin, ConvertOptions};
use crate::interrupt::WatchedSink;
use crate::ooc::disk::SpillDisk;
use crate::ooc::{Chunking, OocBuild};
use crate::progress::Progress;

/// What planning found, for the report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PlanReport {
    /// The plan's identity.
    pub identity: String,
    /// Subsets asked for.
    pub asked: u32,
    /// Subsets planned: the cells some triangle reaches.
    pub subsets: u32,
    /// Triangles the import keeps.
    pub triangles: u64,
    /// Triangle records each subset will build (straddling triangles count in each).
    pub records: Vec<u64>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// Plans a build of `inputs` in (at most) `subsets` subsets, under `opts`, whose flags
/// `settings` records for every subset and the merge to use.
pub fn make_plan(
    inputs: &[PathBuf],
    subsets: u32,
    settings: Vec<String>,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<(Plan, PlanReport), SubsetError> {
    if subsets == 0 || subsets > MAX_SUBSETS {
        return Err(SubsetError::TooManySubsets);
    }
    if inputs.iter().any(|p| is_stdin(p)) {
        return Err(SubsetError::Stdin);
    }
    let start = Instant::now();
    watched(opts, progress, "the plan", |progress| {
        let planned = checksums(inputs, progress)?;
        let plan = passes(inputs, subsets, planned, settings, opts, progress)?;
        let report = PlanReport {
            identity: plan.identity.clone(),
            asked: subsets,
            subsets: plan.subsets,
            triangles: plan.triangles,
            records: plan
                .nodes
                .iter()
                .filter_map(|n| match n {
                    PlanNode::Subset { records, .. } => Some(*records),
                    PlanNode::Cut { .. } => None,
                })
                .collect(),
            seconds: start.elapsed().as_secs_f64(),
        };
        Ok((plan, report))
    })
}

/// The plan from the two passes over the inputs.
fn passes(
    inputs: &[PathBuf],
    subsets: u32,
    planned: Vec<PlanInput>,
    settings: Vec<String>,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<Plan, SubsetError> {
    let origin = opts
        .recentre
        .origin(|sink| {
            let mut sink = WatchedSink::new(sink, &opts.interrupt);
            inputs
                .iter()
                .try_for_each(|p| import_one(p, &mut sink, opts))
        })
        .map_err(Box::new)?;
    let first = import_all(inputs, SampleStore::new(), origin, opts, "sample", progress)?;
    let scene = first.store.tally.scene(&first);
    let tree = CellTree::grow(scene.bounds, &first.store.sample, subsets);
    drop(first);
    let disk = Arc::new(SpillDisk::new());
    let chunking = Chunking {
        chunk_triangles: 1,
        dir: Path::new("."),
    };
    let b = OocBuild::new(&scene, &disk, &opts.kd, &opts.layout, &chunking)?;
    let lod = &opts.layout;
    let rlod_height = lod.write.lod.rlod.then_some(lod.treelet_height);
    let store = RouteStore::new(tree, rlod_height, b.facts());
    let second = import_all(inputs, store, origin, opts, "route", progress)?;
    let (tree, tally) = second.store.finish();
    if tally.count != scene.count || tally.bounds != scene.bounds {
        return Err(SubsetError::InputChanged {
            path: inputs
                .first()
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            what: "the inputs changed between the plan's two passes".into(),
        });
    }
    let (nodes, planes, subsets) = plan_nodes(&tree)?;
    let b = scene.bounds;
    let mut plan = Plan {
        format: PLAN_FORMAT.into(),
        version: PLAN_VERSION,
        identity: String::new(),
        subsets,
        inputs: planned,
        settings,
        origin_bits: origin.map(f64::to_bits),
        triangles: scene.count,
        bounds_bits: [b.min.map(f32::to_bits), b.max.map(f32::to_bits)],
        nodes,
        planes,
    };
    plan.seal()?;
    plan.check()?;
    Ok(plan)
}

/// Each input's length and CRC-32C.
fn checksums(
    inputs: &[PathBuf],
    progress: &mut dyn Progress,
) -> Result<Vec<PlanInput>, SubsetError> {
    progress.phase("checksums", Some(inputs.len() as u64));
    let mut out = Vec::with_capacity(inputs.len());
    for (i, p) in inputs.iter().enumerate() {
        let (bytes, crc) = checksum(p)?;
        out.push(PlanInput {
            path: p.display().to_string(),
            bytes,
            crc32c: format!("{crc:08x}"),
        });
        progress.advance(i as u64 + 1);
    }
    progress.finish_phase();
    Ok(out)
}

/// The length and CRC-32C of the file at `path`.
pub(super) fn checksum(path: &Path) -> Result<(u64, u32), SubsetError> {
    let io = |source| SubsetError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut buf = vec![0u8; 1 << 20];
    let (mut crc, mut bytes) = (0u32, 0u64);
    loop {
        let n = f.read(&mut buf).map_err(io)?;
        if n == 0 {
            return Ok((bytes, crc));
        }
        let chunk = buf.get(..n).unwrap_or(&buf);
        crc = crc32c::crc32c_append(crc, chunk);
        bytes += n as u64;
    }
}
