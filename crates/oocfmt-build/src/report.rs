//! The conversion report: one struct, filled phase by phase, printed by the CLI and serialised
//! for `--report-json`. Every figure the converter prints comes from here.

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

use oocfmt_meshio::import::ImportReport;

/// Wall time of one conversion phase.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct PhaseTime {
    /// The phase: `bounds`, `import`, then in core `load`, `kd-tree`, `lod+layout`, `write`,
    /// or out of core `split`, `chunks`, `top`, `write`.
    pub phase: String,
    /// Seconds of wall time from the end of the previous phase to the end of this one.
    pub seconds: f64,
}

/// Times the phases of one conversion, each from the end of the one before.
pub(crate) struct PhaseClock {
    list: Vec<PhaseTime>,
    at: Instant,
}

impl PhaseClock {
    /// A clock whose first phase starts at `start`.
    pub(crate) fn new(start: Instant) -> PhaseClock {
        PhaseClock {
            list: Vec::new(),
            at: start,
        }
    }

    /// The phase `phase` ends now.
    pub(crate) fn done(&mut self, phase: &str) {
        let now = Instant::now();
        self.list.push(PhaseTime {
            phase: phase.to_string(),
            seconds: (now - self.at).as_secs_f64(),
        });
        self.at = now;
    }

    /// The phases timed, in the order they ran.
    pub(crate) fn into_list(self) -> Vec<PhaseTime> {
        self.list
    }
}

/// Totals over the blocks of one kind in the written file.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct BlockStats {
    /// Number of blocks.
    pub blocks: u64,
    /// Bytes before compression, summed.
    pub raw_bytes: u64,
    /// Bytes the blocks take in the file, summed; below `raw_bytes` when compressed.
    pub stored_bytes: u64,
}

/// What a conversion read, built and wrote, and how long and how much memory it took.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct ConvertReport {
    /// Path of the written container.
    pub output: String,
    /// What the importers read, dropped and warned about.
    pub import: ImportReport,
    /// Input triangles stored (copies of straddling triangles not counted).
    pub triangles_stored: u64,
    /// Reachable inner nodes without LOD data.
    pub basic_nodes: u64,
    /// Reachable inner nodes with LOD data (a voxel and/or an R-LOD).
    pub lod_nodes: u64,
    /// Reachable leaves.
    pub leaves: u64,
    /// Node levels on the longest root-to-leaf path; a lone leaf has depth 1.
    pub depth: u32,
    /// Voxels with one shading sample.
    pub voxels_single: u64,
    /// Voxels with six shading samples, one per cell face.
    pub voxels_six: u64,
    /// What the LOD nodes carry: `voxel`, `rlod` or `voxel+rlod`.
    pub lod_kinds: String,
    /// Proxy records over all proxy blocks.
    pub proxies: u64,
    /// Parts in the file's part table (0: the input named none).
    pub parts: u64,
    /// Block totals keyed by kind: `treelet`, `triangle`, `proxy`.
    pub blocks: BTreeMap<String, BlockStats>,
    /// Size of the written file in bytes.
    pub file_bytes: u64,
    /// The file's root checksum (its identity) as 8 lowercase hex digits.
    pub identity: String,
    /// Wall time of each phase, in the order they ran.
    pub phases: Vec<PhaseTime>,
    /// Seconds of wall time for the whole conversion.
    pub seconds: f64,
    /// Input triangles read over `seconds`.
    pub triangles_per_second: f64,
    /// Peak resident memory of the process, where the platform reports it.
    pub peak_memory_bytes: Option<u64>,
    /// The memory limit the build ran under, in bytes.
    pub mem_limit_bytes: u64,
    /// The most bytes the spill files and the output took on disk at once.
    pub peak_disk_bytes: u64,
    /// Bytes per triangle of the import's spill records (37 for positions only).
    pub spill_bytes_per_triangle: f64,
    /// The disk use the free-space check estimated before the conversion; `None` when an
    /// input's size was unknown (standard input) and the check was skipped.
    pub disk_estimate_bytes: Option<u64>,
    /// Present when the scene was over the memory limit and built in chunks.
    pub out_of_core: Option<crate::ooc::OocStats>,
}

/// Peak resident set size of this process (Linux: VmHWM), or None elsewhere.
pub fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Physical memory (Linux: MemTotal), or None elsewhere.
pub fn total_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
