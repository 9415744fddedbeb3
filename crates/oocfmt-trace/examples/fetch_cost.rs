//! What a fetcher spends on one block, stage by stage, on a real container: reading the stored
//! bytes, checking the CRC, decompressing, and decoding into the traversal's shapes, the last
//! once into memory used before (the decoded block dropped at once) and once into fresh memory
//! (every decoded block kept, as the cache keeps them: each page is faulted in and zeroed by the
//! kernel on first touch). Takes every STRIDE-th block of each kind up to COUNT, runs PASSES
//! passes and prints per block the fastest pass's microseconds, the decoded bytes and, on Linux,
//! the page faults of the fresh-memory pass.
//!
//! cargo run --release -p oocfmt-trace --example fetch_cost -- MODEL.oocf [COUNT [STRIDE [PASSES]]]

use std::io::{Read, Seek, SeekFrom};
use std::path::PathBuf;
use std::time::Instant;

use oocfmt::checksum::crc32c;
use oocfmt::codec::decode_into;
use oocfmt::BlockKind;
use oocfmt_trace::blocks::{TreeletData, TriangleData};
use oocfmt_trace::Scene;

/// Seconds per stage: read, CRC, decompress, load reused, load fresh (the last two read, check,
/// decompress and decode).
type Stages = [f64; 5];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: fetch_cost MODEL.oocf [COUNT [STRIDE [PASSES]]]";
    let model = PathBuf::from(args.get(1).ok_or(usage)?);
    let arg = |i: usize, default: usize| args.get(i).map_or(Ok(default), |s| s.parse());
    let (count, stride, passes) = (arg(2, 400)?, arg(3, 7)?.max(1), arg(4, 5)?.max(1));
    let scene = Scene::open(&model)?;
    let mut file = std::fs::File::open(&model)?;
    println!("{}: fastest of {passes} passes, per block", model.display());
    for kind in [BlockKind::Treelet, BlockKind::Triangle] {
        let ids: Vec<u32> = (0u32..)
            .zip(scene.reader().entries())
            .filter(|(_, e)| e.kind == kind)
            .map(|(id, _)| id)
            .step_by(stride)
            .take(count)
            .collect();
        if ids.is_empty() {
            continue;
        }
        let mut best: Stages = [f64::INFINITY; 5];
        let mut faults = Vec::new();
        // Every pass's blocks stay until the kind is done, so that each pass's are fresh.
        let mut kept = Vec::with_capacity(ids.len() * passes);
        for _ in 0..passes {
            let before = minor_faults();
            let t = pass(&scene, &mut file, kind, &ids, &mut kept)?;
            faults.extend(minor_faults().zip(before).map(|(a, b)| a.saturating_sub(b)));
            for (b, t) in best.iter_mut().zip(t) {
                *b = b.min(t);
            }
        }
        faults.sort_unstable();
        let faults = faults.get(faults.len() / 2);
        let decoded: usize = kept.iter().take(ids.len()).map(Decoded::bytes).sum();
        let n = ids.len() as f64;
        let us = best.map(|t| t / n * 1e6);
        let (stored, raw) = ids.iter().fold((0u64, 0u64), |(s, r), &id| {
            let e = scene.reader().entries().get(id as usize);
            e.map_or((s, r), |e| {
                (s + u64::from(e.stored_length), r + u64::from(e.raw_length))
            })
        });
        println!(
            "{kind:?} blocks: {} of them, stored {:.0} B, raw {:.0} B, decoded {:.0} B",
            ids.len(),
            stored as f64 / n,
            raw as f64 / n,
            decoded as f64 / n
        );
        println!(
            "  read {:.1} us, CRC {:.1} us, decompress {:.1} us; all stages with the decode: {:.1} us into memory used before, {:.1} us into fresh memory{}",
            us[0],
            us[1],
            us[2],
            us[3],
            us[4],
            faults.map_or(String::new(), |&f| format!(
                " (a pass's median page faults: {:.1})",
                f as f64 / n
            ))
        );
    }
    Ok(())
}

/// One pass over `ids`, the blocks decoded into fresh memory appended to `kept`: the stage
/// times.
fn pass(
    scene: &Scene,
    file: &mut std::fs::File,
    kind: BlockKind,
    ids: &[u32],
    kept: &mut Vec<Decoded>,
) -> Result<Stages, Box<dyn std::error::Error>> {
    let mut t: Stages = [0.0; 5];
    for &id in ids {
        let e = *scene.reader().entry(id)?;
        let start = Instant::now();
        let mut stored = vec![0u8; e.stored_length as usize];
        file.seek(SeekFrom::Start(e.offset))?;
        file.read_exact(&mut stored)?;
        let read = Instant::now();
        if crc32c(&stored) != e.crc {
            return Err(format!("block {id}: CRC mismatch").into());
        }
        let checked = Instant::now();
        let mut raw = vec![0u8; e.raw_length as usize];
        decode_into(e.codec, &stored, &mut raw)?;
        let done = Instant::now();
        std::hint::black_box(&raw);
        t[0] += (read - start).as_secs_f64();
        t[1] += (checked - read).as_secs_f64();
        t[2] += (done - checked).as_secs_f64();
    }
    // Each block dropped at once: the next block's arrays reuse its memory.
    for &id in ids {
        let start = Instant::now();
        std::hint::black_box(load(scene, kind, id)?);
        t[3] += start.elapsed().as_secs_f64();
    }
    // Each block kept: its arrays are fresh pages.
    for &id in ids {
        let start = Instant::now();
        let d = load(scene, kind, id)?;
        t[4] += start.elapsed().as_secs_f64();
        kept.push(d);
    }
    Ok(t)
}

enum Decoded {
    Treelets(TreeletData),
    Triangles(TriangleData),
}

impl Decoded {
    fn bytes(&self) -> usize {
        match self {
            Decoded::Treelets(d) => d.bytes(),
            Decoded::Triangles(d) => d.bytes(),
        }
    }
}

/// Reads, checks and decodes block `id`.
fn load(scene: &Scene, kind: BlockKind, id: u32) -> Result<Decoded, Box<dyn std::error::Error>> {
    Ok(match kind {
        BlockKind::Treelet => Decoded::Treelets(scene.load_treelets(id)?),
        _ => Decoded::Triangles(scene.load_triangles(id)?),
    })
}

/// The process's minor page faults so far (Linux, from /proc/self/stat), else None.
fn minor_faults() -> Option<u64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name, which ends at the last ')': state is field 3, minflt 10.
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    rest.split_whitespace().nth(7)?.parse().ok()
}
