//! The conversion report: one struct, filled phase by phase, printed by the CLI and serialised
//! for `--report-json`. Every figure the converter prints comes from here.

use std::collections::BTreeMap;

use serde::Serialize;

use oocfmt_meshio::import::ImportReport;

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct PhaseTime {
    pub phase: String,
    pub seconds: f64,
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct BlockStats {
    pub blocks: u64,
    pub raw_bytes: u64,
    pub stored_bytes: u64,
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct ConvertReport {
    pub output: String,
    pub import: ImportReport,
    pub triangles_stored: u64,
    pub basic_nodes: u64,
    pub lod_nodes: u64,
    pub leaves: u64,
    pub depth: u32,
    pub voxels_single: u64,
    pub voxels_six: u64,
    /// What the LOD nodes carry: `voxel`, `rlod` or `voxel+rlod`.
    pub lod_kinds: String,
    pub proxies: u64,
    pub blocks: BTreeMap<String, BlockStats>,
    pub file_bytes: u64,
    pub identity: String,
    pub phases: Vec<PhaseTime>,
    pub seconds: f64,
    pub triangles_per_second: f64,
    /// Peak resident memory of the process, where the platform reports it.
    pub peak_memory_bytes: Option<u64>,
    pub mem_limit_bytes: u64,
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
