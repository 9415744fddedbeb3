//! `oocfmt plan`: the inputs' checksums, then two passes over them (a sample, then every
//! triangle routed down the cuts), then the plan.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use std::collections::BTreeSet;

use super::cells::{CellTree, RouteStore, SampleStore};
use super::plan::{
    plan_nodes, tables_digest, Plan, PlanInput, PlanNode, PlanReuse, MAX_SUBSETS, PLAN_FORMAT,
    PLAN_VERSION,
};
use super::route::import_all;
use super::{watched, SubsetError};
use crate::convert::{import_one, is_stdin, ConvertOptions};
use crate::interrupt::WatchedSink;
use crate::ooc::disk::SpillDisk;
use crate::ooc::{Chunking, OocBuild, SceneInfo};
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
    /// The subsets to build: all of them, or for an update those it cannot reuse.
    pub rebuild: Vec<u32>,
    /// For an update that had to plan afresh, why.
    pub replanned: Option<String>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl PlanReport {
    fn of(plan: &Plan, asked: u32, start: Instant) -> PlanReport {
        PlanReport {
            identity: plan.identity.clone(),
            asked,
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
            rebuild: (0..plan.subsets)
                .filter(|i| !plan.reuse.iter().any(|r| r.index == *i))
                .collect(),
            replanned: None,
            seconds: start.elapsed().as_secs_f64(),
        }
    }
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
        let origin = opts
            .recentre
            .origin(|sink| {
                let mut sink = WatchedSink::new(sink, &opts.interrupt);
                inputs
                    .iter()
                    .try_for_each(|p| import_one(p, &mut sink, opts))
            })
            .map_err(Box::new)?;
        let passes = Passes {
            inputs,
            origin,
            opts,
        };
        let scene = passes.sample(progress)?;
        let tree = CellTree::grow(scene.0.bounds, &scene.1, subsets);
        let plan = passes.plan(&scene.0, tree, planned, settings, progress)?;
        Ok((plan.clone(), PlanReport::of(&plan, subsets, start)))
    })
}

/// Plans `old`'s inputs again after some of them changed, keeping its cuts where it can: the
/// new plan reuses the subsets no changed input reaches (before or after the change) and no
/// changed plane is above, so only the others are built again before the merge. Where the
/// scene's bounds or tables changed, or a cell was emptied or filled, the cuts cannot stay:
/// the inputs are planned afresh, every subset to build (the report says why). `opts` must be
/// `old`'s settings.
pub fn update_plan(
    old: &Plan,
    opts: &ConvertOptions,
    progress: &mut dyn Progress,
) -> Result<(Plan, PlanReport), SubsetError> {
    let start = Instant::now();
    let inputs: Vec<PathBuf> = old.inputs.iter().map(|i| PathBuf::from(&i.path)).collect();
    watched(opts, progress, "the plan", |progress| {
        let planned = checksums(&inputs, progress)?;
        let passes = Passes {
            inputs: &inputs,
            origin: old.origin(),
            opts,
        };
        let (scene, sample) = passes.sample(progress)?;
        let settings = old.settings.clone();
        let asked = old.subsets;
        let fresh = |why: &str, progress: &mut dyn Progress| {
            let tree = CellTree::grow(scene.bounds, &sample, asked);
            let plan = passes.plan(&scene, tree, planned.clone(), settings.clone(), progress)?;
            let mut report = PlanReport::of(&plan, asked, start);
            report.replanned = Some(why.to_string());
            Ok::<_, SubsetError>((plan, report))
        };
        if scene.bounds != old.scene_bounds() {
            return fresh("the scene's bounds changed", progress);
        }
        if tables_digest(&scene)? != old.tables {
            return fresh(
                "its materials, parts or vertex attributes changed",
                progress,
            );
        }
        let tree = CellTree::from_plan(old)?;
        let mut plan = passes.plan(&scene, tree, planned.clone(), settings.clone(), progress)?;
        if !plan.same_cuts(old) {
            return fresh("a cell was emptied or a new one filled", progress);
        }
        plan.reuse = reusable(old, &plan);
        plan.seal()?;
        plan.check()?;
        Ok((plan.clone(), PlanReport::of(&plan, asked, start)))
    })
}

/// The subsets of `new` (with `old`'s cuts) whose files built for `old` stay valid: no input
/// that changed reaches them in either plan, and every plane above them is the same.
fn reusable(old: &Plan, new: &Plan) -> Vec<PlanReuse> {
    let mut dirty = BTreeSet::new();
    for (o, n) in old.inputs.iter().zip(&new.inputs) {
        if (o.bytes, &o.crc32c) != (n.bytes, &n.crc32c) {
            dirty.extend(o.subsets.iter().chain(&n.subsets).copied());
        }
    }
    let moved: BTreeSet<u32> = new
        .planes
        .iter()
        .filter(|p| !old.planes.contains(p))
        .chain(old.planes.iter().filter(|p| !new.planes.contains(p)))
        .map(|p| p.node)
        .collect();
    let Ok(top) = new.top() else {
        return Vec::new();
    };
    for (i, cell) in top.cells.iter().enumerate() {
        if cell.ancestors.iter().any(|&a| moved.contains(&(a as u32))) {
            dirty.insert(i as u32);
        }
    }
    (0..new.subsets)
        .filter(|i| !dirty.contains(i))
        .map(|index| PlanReuse {
            index,
            plan: old.identity_for(index).to_string(),
        })
        .collect()
}

/// The two passes over the inputs, positions relative to `origin`.
struct Passes<'a> {
    inputs: &'a [PathBuf],
    origin: [f64; 3],
    opts: &'a ConvertOptions,
}

impl Passes<'_> {
    /// The first pass: the scene and a sample of its centroids.
    fn sample(
        &self,
        progress: &mut dyn Progress,
    ) -> Result<(SceneInfo, Vec<[f32; 3]>), SubsetError> {
        let store = SampleStore::new();
        let first = import_all(
            self.inputs,
            store,
            self.origin,
            self.opts,
            "sample",
            progress,
            |_, _| {},
        )?;
        let scene = first.store.tally.scene(&first);
        Ok((scene, first.store.sample))
    }

    /// The second pass over `tree`'s cuts, and the plan of what it found.
    fn plan(
        &self,
        scene: &SceneInfo,
        tree: CellTree,
        mut planned: Vec<PlanInput>,
        settings: Vec<String>,
        progress: &mut dyn Progress,
    ) -> Result<Plan, SubsetError> {
        let opts = self.opts;
        let disk = Arc::new(SpillDisk::new());
        let chunking = Chunking::new(1, Path::new("."));
        let b = OocBuild::new(scene, &disk, &opts.kd, &opts.layout, &chunking)?;
        let lod = &opts.layout;
        let rlod_height = lod.write.lod.rlod.then_some(lod.treelet_height);
        let store = RouteStore::new(tree, rlod_height, b.facts());
        let set_input = |s: &mut RouteStore, k: usize| s.input = k;
        let second = import_all(
            self.inputs,
            store,
            self.origin,
            opts,
            "route",
            progress,
            set_input,
        )?;
        let routed = second.store.finish();
        if routed.tally.count != scene.count || routed.tally.bounds != scene.bounds {
            return Err(SubsetError::InputChanged {
                path: self
                    .inputs
                    .first()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default(),
                what: "the inputs changed between the plan's two passes".into(),
            });
        }
        let e = plan_nodes(&routed.tree)?;
        for (input, reach) in planned.iter_mut().zip(&routed.reach) {
            input.subsets = reach
                .iter()
                .filter_map(|k| e.subset_of.get(k).copied())
                .collect();
        }
        let b = scene.bounds;
        let mut plan = Plan {
            format: PLAN_FORMAT.into(),
            version: PLAN_VERSION,
            identity: String::new(),
            subsets: e.subsets,
            inputs: planned,
            settings,
            origin_bits: self.origin.map(f64::to_bits),
            triangles: scene.count,
            bounds_bits: [b.min.map(f32::to_bits), b.max.map(f32::to_bits)],
            tables: tables_digest(scene)?,
            nodes: e.nodes,
            planes: e.planes,
            reuse: Vec::new(),
        };
        plan.seal()?;
        plan.check()?;
        Ok(plan)
    }
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
            subsets: Vec::new(),
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
