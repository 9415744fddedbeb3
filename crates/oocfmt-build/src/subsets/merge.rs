//! `oocfmt merge`: every subset of one plan, joined under the plan's cuts and finished as the
//! out-of-core build finishes: the LOD nodes among the cuts from the rays the subsets
//! answered and the plane pieces they measured, the top laid out, the subsets' blocks copied
//! with their references made final.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use super::build::{folder_of, plan_layout};
use super::file::{Body, ChunkRecord, SubsetFile, TopLodRecord};
use super::plan::{Plan, PlanTop};
use super::{watched, SubsetError};
use crate::convert::{describe, ConvertOptions, BYTES_PER_TRIANGLE_IN_CORE};
use crate::layout::LayoutOptions;
use crate::lod::Seen;
use crate::ooc::assemble::BlockSource;
use crate::ooc::chunk::SpilledBlock;
use crate::ooc::chunk::UpperNode;
use crate::ooc::disk::SpillDisk;
use crate::ooc::split::{Chunk, TopNode, TopTree, MAX_SPLIT_DEPTH};
use crate::ooc::top::{record_rays, top_lod_nodes, TopLod};
use crate::ooc::{Chunking, Chunks, OocBuild, OocError, SceneInfo};
use crate::progress::Progress;
use crate::report::{peak_memory, ConvertReport, PhaseClock};

/// What a merge did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct MergeReport {
    /// The container written, as `convert` reports it.
    pub convert: ConvertReport,
    /// Subsets merged.
    pub subsets: u32,
    /// Blocks copied from the subsets (their references rewritten, nothing rebuilt).
    pub copied_blocks: u64,
    /// Raw bytes of those blocks.
    pub copied_bytes: u64,
}

/// The plan a subset file was built from, checked against the file's header.
pub fn plan_of_subset(path: &Path) -> Result<Plan, SubsetError> {
    let f = SubsetFile::open(path)?;
    plan_of(&f)
}

pub(super) fn plan_of(f: &SubsetFile) -> Result<Plan, SubsetError> {
    let plan = Plan::parse(&f.body.plan, &f.path.display().to_string())?;
    if plan.identity_number()? != f.header.plan_identity || plan.subsets != f.header.subsets {
        return Err(foreign(f, "its header and its plan disagree"));
    }
    Ok(plan)
}

fn foreign(f: &SubsetFile, what: &str) -> SubsetError {
    SubsetError::Foreign {
        path: f.path.display().to_string(),
        what: what.to_string(),
    }
}

/// Merges the subset files `parts` (every subset of one plan, once, in any order) into the
/// container `output`. The plan is `plan` when given (an updated plan names the subsets it
/// takes from earlier builds), else the one the files were built from. `opts` must be the
/// plan's settings. On failure nothing is written.
pub fn merge(
    parts: &[PathBuf],
    output: &Path,
    opts: &ConvertOptions,
    plan: Option<&Plan>,
    progress: &mut dyn Progress,
) -> Result<MergeReport, SubsetError> {
    let start = Instant::now();
    let (plan, mut files) = open_all(parts, plan)?;
    let top = plan.top()?;
    let joined = join(&plan, &top, &mut files, &opts.layout)?;
    // The scene's tables are every file's (checked); its count is the plan's, which a file
    // reused from an earlier plan does not know.
    let first = files.first().ok_or(SubsetError::NoSubsets)?;
    let scene = SceneInfo {
        count: plan.triangles,
        bounds: plan.scene_bounds(),
        ..first.body.scene.clone()
    };
    let disk = Arc::new(SpillDisk::new());
    let layout = plan_layout(&plan, opts);
    let chunking = Chunking::new(
        opts.mem_limit / BYTES_PER_TRIANGLE_IN_CORE,
        folder_of(output),
    );
    let b = OocBuild::new(&scene, &disk, &opts.kd, &layout, &chunking)?;
    let (copied_blocks, copied_bytes) = joined.chunks.outs.iter().fold((0, 0), |(n, bytes), o| {
        let all = o.treelet_blocks.iter().chain(&o.triangle_blocks);
        all.fold((n, bytes), |(n, bytes), b| (n + 1, bytes + b.len))
    });
    let mut source = SubsetBlocks {
        files: &files,
        chunk_file: joined.chunk_file,
    };
    let mut clock = PhaseClock::new(start);
    clock.done("open");
    let name = output.display().to_string();
    let (written, stats) = watched(opts, progress, &name, |p| {
        Ok(b.finish(
            &joined.tree,
            joined.chunks,
            &mut source,
            output,
            &mut clock,
            p,
        )?)
    })?;
    let mut convert = describe(output, written.identity).map_err(Box::new)?;
    import_figures(&mut convert, &plan, &files);
    convert.out_of_core = Some(stats);
    convert.phases = clock.into_list();
    convert.seconds = start.elapsed().as_secs_f64();
    convert.triangles_per_second = convert.import.triangles_in as f64 / convert.seconds.max(1e-9);
    convert.peak_memory_bytes = peak_memory();
    convert.mem_limit_bytes = opts.mem_limit;
    convert.peak_disk_bytes = convert.file_bytes;
    Ok(MergeReport {
        convert,
        subsets: plan.subsets,
        copied_blocks,
        copied_bytes,
    })
}

/// The import's figures in the report: the inputs, and the triangles read and kept as a subset
/// built from `plan` itself counted them (a file reused from an earlier plan read other
/// inputs; with none built from this plan, the plan's count stands for both).
fn import_figures(report: &mut ConvertReport, plan: &Plan, files: &[SubsetFile]) {
    let current = files
        .iter()
        .find(|f| format!("{:08x}", f.header.plan_identity) == plan.identity);
    let (read, kept) = current.map_or((plan.triangles, plan.triangles), |f| {
        (f.body.triangles_in, f.body.triangles_out)
    });
    report.import.files = plan.inputs.iter().map(|i| i.path.clone()).collect();
    report.import.triangles_in = read;
    report.import.triangles_out = kept;
}

/// Opens every subset file and checks that they are the subsets of one plan, each once;
/// returns the plan and the files in subset order.
fn open_all(
    parts: &[PathBuf],
    given: Option<&Plan>,
) -> Result<(Plan, Vec<SubsetFile>), SubsetError> {
    let mut files = parts
        .iter()
        .map(|p| SubsetFile::open(p))
        .collect::<Result<Vec<_>, _>>()?;
    let first = files.first().ok_or(SubsetError::NoSubsets)?;
    let plan = match given {
        Some(p) => p.clone(),
        None => newest_plan(&files)?,
    };
    let mut slots: Vec<Option<&SubsetFile>> = vec![None; plan.subsets as usize];
    for f in &files {
        let own = plan_of(f)?;
        let expected = plan.identity_for(f.header.index);
        if !plan.takes(f.header.index, &own.identity) || !own.same_cuts(&plan) {
            let what = format!(
                "a subset of another plan (plan {}, where plan {} takes subset {} from plan {expected})",
                own.identity, plan.identity, f.header.index
            );
            return Err(foreign(f, &what));
        }
        if !same_tables(&f.body.scene, &first.body.scene) {
            return Err(foreign(
                f,
                "its scene tables differ from the other subsets'",
            ));
        }
        match slots.get_mut(f.header.index as usize) {
            Some(Some(other)) => {
                return Err(SubsetError::Duplicate {
                    index: f.header.index,
                    first: other.path.display().to_string(),
                    second: f.path.display().to_string(),
                })
            }
            Some(slot) => *slot = Some(f),
            None => return Err(foreign(f, "its index is outside the plan")),
        }
    }
    let missing: Vec<String> = slots
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_none())
        .map(|(i, _)| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(SubsetError::Missing {
            missing: missing.join(", "),
            subsets: plan.subsets,
            plan: plan.identity.clone(),
        });
    }
    files.sort_by_key(|f| f.header.index);
    Ok((plan, files))
}

/// The plan of the files that takes every file: the files' own plan, or after an update the
/// newest plan, which names the subsets it takes from earlier ones.
fn newest_plan(files: &[SubsetFile]) -> Result<Plan, SubsetError> {
    let mut plans: Vec<Plan> = Vec::new();
    for f in files {
        let p = plan_of(f)?;
        if !plans.iter().any(|q| q.identity == p.identity) {
            plans.push(p);
        }
    }
    let takes_all = |p: &Plan| {
        files
            .iter()
            .all(|f| p.takes(f.header.index, &format!("{:08x}", f.header.plan_identity)))
    };
    match plans.iter().find(|p| takes_all(p)) {
        Some(p) => Ok(p.clone()),
        None => {
            let a = files.first().ok_or(SubsetError::NoSubsets)?;
            let other = |f: &&SubsetFile| f.header.plan_identity != a.header.plan_identity;
            let b = files.iter().find(other).unwrap_or(a);
            Err(foreign(
                b,
                &format!(
                    "a subset of another plan than {}'s (plan {:08x}, not {:08x})",
                    a.path.display(),
                    b.header.plan_identity,
                    a.header.plan_identity
                ),
            ))
        }
    }
}

/// Whether two subsets number materials and parts alike and have the same attributes.
fn same_tables(a: &SceneInfo, b: &SceneInfo) -> bool {
    (
        &a.materials,
        &a.used_materials,
        &a.parts,
        a.normals,
        a.colours,
    ) == (
        &b.materials,
        &b.used_materials,
        &b.parts,
        b.normals,
        b.colours,
    )
}

/// The subsets joined into the out-of-core build's state after its chunks.
struct Joined {
    tree: TopTree,
    chunks: Chunks,
    /// The subset file of each chunk.
    chunk_file: Vec<usize>,
}

/// Joins the subsets' trees under the plan's cuts, renumbering their own nodes and chunks
/// after those of the subsets before; combines the plan's LOD cuts' rays and planes.
fn join(
    plan: &Plan,
    top: &PlanTop,
    files: &mut [SubsetFile],
    layout: &LayoutOptions,
) -> Result<Joined, SubsetError> {
    let p = top.plan_nodes;
    let threshold = layout.voxel_threshold;
    let mut j = Joined {
        tree: TopTree {
            nodes: top.tree.nodes.clone(),
            ..TopTree::default()
        },
        chunks: Chunks {
            outs: Vec::new(),
            proxies: Vec::new(),
            proxy_count: 0,
            proxy_shift: Vec::new(),
            top_lod: Vec::new(),
            planes: top.tree.planes.clone(),
        },
        chunk_file: Vec::new(),
    };
    let mut answers: BTreeMap<usize, Vec<Option<(f64, Seen)>>> = BTreeMap::new();
    for (s, f) in files.iter_mut().enumerate() {
        let cell = top
            .cells
            .get(s)
            .ok_or(SubsetError::Internal("a subset has no cell"))?;
        // The chunks move into the joined build; the rest of the body stays for the checks.
        let chunks = std::mem::take(&mut f.body.chunks);
        let f = &*f;
        let body = &f.body;
        let number = Renumber {
            plan_nodes: p,
            node_base: j.tree.nodes.len(),
            chunk_base: j.chunks.outs.len(),
            chunks: chunks.len(),
            own: cell.node,
        };
        let bad = |what: &str| foreign(f, what);
        let root = number
            .top_node(&body.root)
            .ok_or_else(|| bad("a node is out of range"))?;
        if let Some(slot) = j.tree.nodes.get_mut(cell.node) {
            *slot = root;
        }
        for n in &body.nodes {
            let n = number
                .top_node(n)
                .ok_or_else(|| bad("a node is out of range"))?;
            j.tree.nodes.push(n);
        }
        add_chunks(&mut j, chunks, body, &number, s)
            .ok_or_else(|| bad("a chunk is out of range"))?;
        for &(node, fit) in &body.planes {
            let node = number
                .own_node(node)
                .ok_or_else(|| bad("a plane is not the subset's"))?;
            j.chunks.planes.insert(node, fit);
        }
        for t in &body.top_lod {
            match number.own_node(t.node) {
                Some(node) => j.chunks.top_lod.push(
                    local_lod(node, t, threshold)
                        .ok_or_else(|| bad("a LOD node's rays do not match its cell"))?,
                ),
                None if cell.ancestors.contains(&t.node) => {
                    nearest(answers.entry(t.node).or_default(), &t.answers)
                }
                None => return Err(bad("it sampled a LOD node that is not above it")),
            }
        }
    }
    check_tree(&j.tree).ok_or_else(|| SubsetError::Foreign {
        path: plan.identity.clone(),
        what: "the subsets do not join into one tree".into(),
    })?;
    // The plan's LOD cuts: their rays as every chunk below answered them, their planes
    // widened by every chunk's piece, in chunk order, as in one out-of-core build.
    let height = layout.treelet_height;
    for mut t in top_lod_nodes(&j.tree, plan.scene_bounds(), height, threshold) {
        if !matches!(top.tree.nodes.get(t.node), Some(TopNode::Inner { .. })) {
            continue;
        }
        if let Some(a) = answers.get(&t.node) {
            if a.len() != t.rays.len() {
                return Err(SubsetError::Internal(
                    "a LOD cut's rays differ between subsets",
                ));
            }
            for (r, a) in t.rays.iter_mut().zip(a) {
                r.best = *a;
            }
        }
        j.chunks.top_lod.push(t);
    }
    for o in &j.chunks.outs {
        for (node, piece) in &o.plane_pieces {
            if *node < p && top.tree.planes.contains_key(node) {
                if let Some(plane) = j.chunks.planes.get_mut(node) {
                    plane.widen(piece);
                }
            }
        }
    }
    Ok(j)
}

/// Adds a subset's chunks, their proxies numbered on from the subsets' before.
fn add_chunks(
    j: &mut Joined,
    chunks: Vec<ChunkRecord>,
    body: &Body,
    number: &Renumber,
    file: usize,
) -> Option<()> {
    for c in chunks {
        if !upper_is_a_tree(&c.out.upper) {
            return None;
        }
        let ancestors = c
            .ancestors
            .iter()
            .map(|&a| number.any_node(a))
            .collect::<Option<Vec<_>>>()?;
        j.tree.chunks.push(Chunk {
            run: Default::default(),
            count: c.count,
            cell: c.cell,
            depth: c.depth,
            ancestors,
        });
        let mut out = c.out;
        j.chunks.proxies.push(std::mem::take(&mut out.proxies));
        j.chunks.outs.push(out);
        j.chunks.proxy_shift.push(j.chunks.proxy_count);
        j.chunk_file.push(file);
    }
    for &k in &body.oversized {
        j.tree.oversized.push(number.chunk(k)?);
    }
    j.chunks.proxy_count = j.chunks.proxy_count.checked_add(body.proxy_count)?;
    Some(())
}

/// A LOD node of the subset's own, its rays answered.
fn local_lod(node: usize, t: &TopLodRecord, threshold: f32) -> Option<TopLod> {
    let mut rays = record_rays(t.cell, threshold);
    if rays.len() != t.answers.len() {
        return None;
    }
    for (r, a) in rays.iter_mut().zip(&t.answers) {
        r.best = *a;
    }
    Some(TopLod {
        node,
        cell: t.cell,
        rays,
    })
}

/// Keeps, ray by ray, the nearer hit: an earlier subset's on a tie, as an earlier chunk's
/// wins in one build.
fn nearest(best: &mut Vec<Option<(f64, Seen)>>, answers: &[Option<(f64, Seen)>]) {
    if best.is_empty() {
        best.resize(answers.len(), None);
    }
    for (b, a) in best.iter_mut().zip(answers) {
        if let Some((t, _)) = a {
            if b.is_none_or(|(bt, _)| bt > *t) {
                *b = *a;
            }
        }
    }
}

/// How one subset's node and chunk numbers map into the joined tree.
struct Renumber {
    plan_nodes: usize,
    node_base: usize,
    chunk_base: usize,
    chunks: usize,
    /// The plan node of the subset's cell.
    own: usize,
}

impl Renumber {
    /// A node the subset added (or its cell's).
    fn own_node(&self, n: usize) -> Option<usize> {
        match n {
            n if n == self.own => Some(n),
            n if n >= self.plan_nodes => (n - self.plan_nodes).checked_add(self.node_base),
            _ => None,
        }
    }

    /// Any node: the plan's keep their numbers.
    fn any_node(&self, n: usize) -> Option<usize> {
        match n < self.plan_nodes {
            true => Some(n),
            false => self.own_node(n),
        }
    }

    fn chunk(&self, k: usize) -> Option<usize> {
        (k < self.chunks).then_some(k + self.chunk_base)
    }

    fn top_node(&self, n: &TopNode) -> Option<TopNode> {
        Some(match *n {
            TopNode::Inner {
                axis,
                split,
                children,
            } => {
                let mut kids = [None, None];
                for (slot, c) in kids.iter_mut().zip(children) {
                    if let Some(c) = c {
                        *slot = Some(self.own_node(c).filter(|&c| c >= self.plan_nodes)?);
                    }
                }
                TopNode::Inner {
                    axis,
                    split,
                    children: kids,
                }
            }
            TopNode::Chunk(k) => TopNode::Chunk(self.chunk(k)?),
        })
    }
}

/// Most levels of a chunk's top treelet: far above any treelet height a build uses.
const MAX_UPPER_DEPTH: u32 = 64;

/// A chunk's top treelet in preorder: every child after its parent, in the list, and not too
/// deep, so the layout's walk of it ends.
fn upper_is_a_tree(upper: &[UpperNode]) -> bool {
    let mut depth = vec![0u32; upper.len()];
    for (k, n) in upper.iter().enumerate() {
        let UpperNode::Basic { children, .. } = n else {
            continue;
        };
        let d = depth.get(k).copied().unwrap_or(0) + 1;
        for &c in children.iter().flatten() {
            match depth.get_mut(c) {
                Some(slot) if c > k && d <= MAX_UPPER_DEPTH => *slot = d,
                _ => return false,
            }
        }
    }
    true
}

/// Every node reached once from the root, no deeper than a split goes, every chunk once.
fn check_tree(tree: &TopTree) -> Option<()> {
    let mut seen = vec![false; tree.nodes.len()];
    let mut chunks = vec![false; tree.chunks.len()];
    let mut stack = vec![(0usize, 0u32)];
    while let Some((k, depth)) = stack.pop() {
        let s = seen.get_mut(k)?;
        if *s || depth > MAX_SPLIT_DEPTH {
            return None;
        }
        *s = true;
        match tree.nodes.get(k)? {
            TopNode::Inner { children, .. } => {
                stack.extend(children.iter().flatten().map(|&c| (c, depth + 1)))
            }
            TopNode::Chunk(c) => {
                let s = chunks.get_mut(*c)?;
                if *s {
                    return None;
                }
                *s = true;
            }
        }
    }
    (seen.iter().all(|&s| s) && chunks.iter().all(|&s| s)).then_some(())
}

/// The subset files' blocks, read for the container.
struct SubsetBlocks<'a> {
    files: &'a [SubsetFile],
    chunk_file: Vec<usize>,
}

impl BlockSource for SubsetBlocks<'_> {
    fn read(&mut self, chunk: usize, b: &SpilledBlock) -> Result<Vec<u8>, OocError> {
        let f = self
            .chunk_file
            .get(chunk)
            .and_then(|&k| self.files.get(k))
            .ok_or(OocError::SpillCorrupt {
                path: "subset".into(),
                what: "a chunk has no subset file",
            })?;
        f.read_block(b)
            .map_err(|e| OocError::BlockFile(e.to_string()))
    }
}
