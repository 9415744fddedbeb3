//! A build split into subsets: the merge of the subsets, built in any order on any thread
//! count, is byte for byte the one-process `convert --plan`; it holds the triangles a plain
//! convert holds and passes the deep verifier; a missing, repeated, damaged or foreign subset,
//! or a changed input, is refused with nothing written.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use oocfmt::records::LodKinds;
use oocfmt::{BlockKind, ReadOptions, Reader};
use oocfmt_build::convert::{convert, ConvertOptions, BYTES_PER_TRIANGLE_IN_CORE};
use oocfmt_build::progress::NoProgress;
use oocfmt_build::subsets::{
    build_subset, convert_plan, make_plan, merge, update_plan, Plan, SubsetError,
};
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

fn options(chunk_triangles: u64) -> ConvertOptions {
    ConvertOptions {
        mem_limit: chunk_triangles * BYTES_PER_TRIANGLE_IN_CORE,
        ..ConvertOptions::default()
    }
}

fn mandelbulb_obj(path: &Path, triangles: u64) {
    let opts = MandelbulbOptions {
        triangles,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(path, &opts, &mut |_, _| {}).unwrap();
}

fn plan(inputs: &[PathBuf], subsets: u32, opts: &ConvertOptions) -> Plan {
    let settings = vec!["--mem-limit".to_string(), "test".to_string()];
    make_plan(inputs, subsets, settings, opts, &mut NoProgress)
        .unwrap()
        .0
}

/// Builds every subset of `plan` into `dir`, in reverse order, each in a pool of 1 to 3
/// threads; returns the files in a scrambled order.
fn build_all(plan: &Plan, dir: &Path, opts: &ConvertOptions) -> Vec<PathBuf> {
    let mut parts = Vec::new();
    for i in (0..plan.subsets).rev() {
        let part = dir.join(format!("part-{i}.oocfp"));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1 + i as usize % 3)
            .build()
            .unwrap();
        pool.install(|| build_subset(plan, i, &part, opts, &mut NoProgress))
            .unwrap();
        parts.push(part);
    }
    let half = parts.len() / 2;
    parts.rotate_left(half);
    parts
}

/// Every distinct triangle the container stores, by its corners' bits.
fn stored_triangles(file: &Path) -> BTreeSet<[[u32; 3]; 3]> {
    let r = Reader::open(file, ReadOptions::default()).unwrap();
    let attrs = r.metadata().triangle_attributes();
    let mut out = BTreeSet::new();
    for (id, e) in r.entries().iter().enumerate() {
        if e.kind != BlockKind::Triangle {
            continue;
        }
        let block = r.read_block(id as u32).unwrap();
        let t = block.triangles(attrs).unwrap();
        for i in 0..t.triangle_count() {
            out.insert(t.positions(i).unwrap().map(|p| p.map(f32::to_bits)));
        }
    }
    out
}

fn deep_verify(path: &Path) {
    use oocfmt::verify::{verify, Depth, VerifyOptions};
    let src = oocfmt::FileSource::open(path).unwrap();
    let opts = VerifyOptions {
        depth: Depth::Deep,
        ..VerifyOptions::default()
    };
    let report = verify(&src, "merged", &opts, &|_| {}).unwrap();
    assert!(
        report.valid && report.issues.is_empty(),
        "{:#?}",
        report.issues
    );
}

/// Every block of the container as the directory describes it (its place aside).
fn blocks(file: &Path) -> Vec<(BlockKind, u16, u32, u32, u32, u32)> {
    let r = Reader::open(file, ReadOptions::default()).unwrap();
    let e = r.entries();
    e.iter()
        .map(|e| {
            (
                e.kind,
                e.level,
                e.item_count,
                e.raw_length,
                e.stored_length,
                e.crc,
            )
        })
        .collect()
}

#[test]
fn merged_subsets_are_the_one_process_build_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("mb.obj");
    mandelbulb_obj(&obj, 20_000);
    // R-LODs (the CLI's default) and voxels: the cuts' LOD records come from plane pieces
    // and from answered rays.
    for lod in [LodKinds::RLOD, LodKinds::VOXEL] {
        let mut opts = options(2500);
        opts.layout.write.lod = lod.filtered();
        let dir = dir.path().join(lod.name());
        std::fs::create_dir(&dir).unwrap();
        split_builds_match(&obj, &dir, &opts);
    }
}

fn split_builds_match(obj: &Path, dir: &Path, opts: &ConvertOptions) {
    let (obj, opts) = (obj.to_path_buf(), opts.clone());
    let plain = dir.join("plain.oocf");
    convert(std::slice::from_ref(&obj), &plain, &opts, &mut NoProgress).unwrap();
    let triangles = stored_triangles(&plain);
    let plain_blocks = blocks(&plain);
    for n in [1, 3, 8] {
        let plan = plan(std::slice::from_ref(&obj), n, &opts);
        assert_eq!(plan.subsets, n, "the mandelbulb fills every cell");
        // Eight cells put cuts at the LOD depth (2, with treelets of height 3).
        let rlod = opts.layout.write.lod.rlod;
        assert_eq!(plan.planes.is_empty(), n < 8 || !rlod, "{n} subsets");
        let one = dir.join(format!("one-{n}.oocf"));
        convert_plan(&plan, &one, &opts, &mut NoProgress).unwrap();
        let parts_dir = dir.join(format!("parts-{n}"));
        std::fs::create_dir(&parts_dir).unwrap();
        let parts = build_all(&plan, &parts_dir, &opts);
        let merged = dir.join(format!("merged-{n}.oocf"));
        let report = merge(&parts, &merged, &opts, None, &mut NoProgress).unwrap();
        assert!(report.copied_blocks > 0);
        let (a, b) = (
            std::fs::read(&one).unwrap(),
            std::fs::read(&merged).unwrap(),
        );
        assert!(a == b, "{n} subsets: merge and convert --plan differ");
        deep_verify(&merged);
        assert_eq!(stored_triangles(&merged), triangles, "{n} subsets");
        let count = |p: &Path| {
            let r = Reader::open(p, ReadOptions::default()).unwrap();
            r.metadata().counts.triangles
        };
        assert_eq!(count(&merged), count(&plain), "{n} subsets");
        // The plan's cuts are cuts the plain out-of-core build makes too (each of its cells
        // holds more than a chunk's budget): the LOD records of the cuts, pieced together
        // from the subsets, and every block are the plain build's.
        assert!(
            blocks(&merged) == plain_blocks,
            "{n} subsets: blocks differ"
        );
    }
    // Nothing is left behind but what the test wrote.
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// Two files with named parts, as an assembly: each file a part.
fn assembly(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for (f, shift) in [("wing.obj", 0.0f32), ("tail.obj", 6.0)] {
        let mut text = String::new();
        let mut faces = String::new();
        for k in 0..300 {
            let x = shift + k as f32 * 0.02;
            text += &format!(
                "v {x} 0 0\nv {} 0 {}\nv {x} 1 0.5\n",
                x + 0.3,
                (k % 5) as f32 * 0.1
            );
            if k == 150 {
                faces += "o flap\n";
            }
            faces += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
        }
        let path = dir.join(f);
        std::fs::write(&path, text + &faces).unwrap();
        files.push(path);
    }
    files
}

#[test]
fn an_assembly_keeps_its_parts_when_split() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = assembly(dir.path());
    let opts = options(100);
    let plain = dir.path().join("plain.oocf");
    convert(&inputs, &plain, &opts, &mut NoProgress).unwrap();
    let plan = plan(&inputs, 4, &opts);
    let parts = build_all(&plan, dir.path(), &opts);
    let merged = dir.path().join("merged.oocf");
    merge(&parts, &merged, &opts, None, &mut NoProgress).unwrap();
    deep_verify(&merged);
    let read = |p: &Path| {
        Reader::open(p, ReadOptions::default())
            .unwrap()
            .metadata()
            .clone()
    };
    let (a, b) = (read(&plain), read(&merged));
    assert_eq!(a.parts, b.parts);
    assert_eq!(a.counts.triangles, b.counts.triangles);
    assert_eq!(stored_triangles(&plain), stored_triangles(&merged));
}

fn expect_err(r: Result<oocfmt_build::subsets::MergeReport, SubsetError>, out: &Path) -> String {
    let e = r.expect_err("the merge must fail").to_string();
    assert!(!out.exists(), "a failed merge wrote {}", out.display());
    e
}

#[test]
fn a_missing_repeated_damaged_or_foreign_subset_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("mb.obj");
    mandelbulb_obj(&obj, 6_000);
    let opts = options(1000);
    let plan3 = plan(std::slice::from_ref(&obj), 3, &opts);
    let parts = build_all(&plan3, dir.path(), &opts);
    let out = dir.path().join("out.oocf");
    let mut sorted = parts.clone();
    sorted.sort();

    let e = expect_err(
        merge(&sorted[..2], &out, &opts, None, &mut NoProgress),
        &out,
    );
    assert!(e.contains("missing subsets 2 of 3"), "{e}");

    let mut twice = sorted.clone();
    twice.push(sorted[1].clone());
    let e = expect_err(merge(&twice, &out, &opts, None, &mut NoProgress), &out);
    assert!(e.contains("subset 1 is given twice"), "{e}");

    // Another plan of the same model (two subsets): its subset 0 is foreign here.
    let other_dir = dir.path().join("other");
    std::fs::create_dir(&other_dir).unwrap();
    let plan2 = plan(std::slice::from_ref(&obj), 2, &opts);
    let other = build_all(&plan2, &other_dir, &opts);
    let mut mixed = sorted.clone();
    mixed[0] = other
        .iter()
        .find(|p| p.ends_with("part-0.oocfp"))
        .unwrap()
        .clone();
    let e = expect_err(merge(&mixed, &out, &opts, None, &mut NoProgress), &out);
    assert!(e.contains("another plan"), "{e}");

    // One byte changed in a block, in the body, in the header: each is found.
    let bytes = std::fs::read(&sorted[1]).unwrap();
    for (at, what) in [
        (100, "block checksum"),
        (bytes.len() - 10, "body checksum"),
        (13, "header checksum"),
    ] {
        let mut bad = bytes.clone();
        bad[at] ^= 0x40;
        let damaged = dir.path().join("damaged.oocfp");
        std::fs::write(&damaged, &bad).unwrap();
        let mut set = sorted.clone();
        set[1] = damaged;
        let e = expect_err(merge(&set, &out, &opts, None, &mut NoProgress), &out);
        assert!(e.contains(what), "byte {at}: {e}");
    }
    // A truncated file.
    let cut = dir.path().join("cut.oocfp");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let mut set = sorted.clone();
    set[1] = cut;
    let e = expect_err(merge(&set, &out, &opts, None, &mut NoProgress), &out);
    assert!(e.contains("cut.oocfp"), "{e}");

    // An input changed after planning: the subset refuses to build.
    let mut text = std::fs::read(&obj).unwrap();
    text.extend_from_slice(b"# edited\n");
    std::fs::write(&obj, text).unwrap();
    let part = dir.path().join("late.oocfp");
    let e = build_subset(&plan3, 0, &part, &opts, &mut NoProgress)
        .expect_err("a changed input is refused")
        .to_string();
    assert!(e.contains("changed") && e.contains("mb.obj"), "{e}");
    assert!(!part.exists());
    let e = build_subset(&plan3, 3, &part, &opts, &mut NoProgress)
        .expect_err("no subset 3")
        .to_string();
    assert!(e.contains("subset 3 is not in the plan"), "{e}");
}

#[test]
fn an_edited_plan_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("mb.obj");
    mandelbulb_obj(&obj, 2_000);
    let opts = options(1000);
    let p = plan(&[obj], 2, &opts);
    let text = p.to_json().unwrap();
    assert_eq!(Plan::parse(&text, "p.json").unwrap(), p);
    let edited = text.replacen("\"subsets\": 2", "\"subsets\": 3", 1);
    let e = Plan::parse(&edited, "p.json").unwrap_err().to_string();
    assert!(e.contains("identity"), "{e}");
    let e = Plan::parse("{\"format\": 1}", "p.json")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("plan p.json:"), "{e}");
    let stdin = make_plan(&[PathBuf::from("-")], 2, Vec::new(), &opts, &mut NoProgress);
    assert!(matches!(stdin, Err(SubsetError::Stdin)));
}

#[test]
fn the_subset_header_is_the_specs() {
    use oocfmt_build::subsets::{SUBSET_HEADER_LEN, SUBSET_MAGIC, SUBSET_VERSION};
    let spec =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/oocfmt.md"))
            .unwrap();
    let at = spec.find("### 16.2").expect("spec §16.2");
    let section = &spec[at..];
    let hex: Vec<String> = SUBSET_MAGIC.iter().map(|b| format!("{b:02X}")).collect();
    assert!(section.contains(&format!("`{}`", hex.join(" "))), "magic");
    assert!(
        section.contains(&format!("| 8 | 2 | version | {SUBSET_VERSION}.")),
        "version"
    );
    assert!(
        section.contains(&format!("from byte {SUBSET_HEADER_LEN}")),
        "header length"
    );
    assert!(
        section.contains("| 60 | 4 | header CRC |"),
        "header CRC place"
    );
}

/// Six files side by side along x, each a part; `bump` changes the depths of file 4's
/// triangles, within the scene's bounds.
fn row_of_parts(dir: &Path, bump: u32) -> Vec<PathBuf> {
    (0..6)
        .map(|f| {
            let mut text = String::new();
            for k in 0..400u32 {
                let x = f as f32 * 2.0 + (k % 40) as f32 * 0.04;
                let y = (k / 40) as f32 * 0.1;
                let z = match f {
                    4 => ((k + bump) % 5) as f32 * 0.1,
                    _ => (k % 5) as f32 * 0.1,
                };
                text += &format!(
                    "v {x} {y} {z}\nv {} {y} 0.2\nv {x} {} 0.1\n",
                    x + 0.05,
                    y + 0.08
                );
            }
            for k in 0..400 {
                text += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
            }
            let path = dir.join(format!("part{f}.obj"));
            std::fs::write(&path, text).unwrap();
            path
        })
        .collect()
}

#[test]
fn an_update_rebuilds_only_the_subsets_a_changed_part_reaches() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = row_of_parts(dir.path(), 0);
    let mut opts = options(150);
    opts.layout.write.lod = LodKinds::RLOD.filtered();
    let old = plan(&inputs, 8, &opts);
    assert_eq!(old.subsets, 8);
    let old_dir = dir.path().join("old");
    std::fs::create_dir(&old_dir).unwrap();
    let old_parts = build_all(&old, &old_dir, &opts);
    // File 4 changes; the scene's bounds and tables do not.
    row_of_parts(dir.path(), 2);
    let (new, report) = update_plan(&old, &opts, &mut NoProgress).unwrap();
    assert_eq!(report.replanned, None, "{report:?}");
    assert!(new.same_cuts(&old));
    let reused: Vec<u32> = new.reuse.iter().map(|r| r.index).collect();
    assert!(!reused.is_empty() && report.rebuild.len() < 8, "{report:?}");
    assert!(new.reuse.iter().all(|r| r.plan == old.identity));
    // The subsets file 4 reaches, and those below a LOD cut whose plane it moved.
    let changed = &new.inputs[4].subsets;
    assert!(
        changed.iter().all(|i| report.rebuild.contains(i)),
        "{changed:?} {report:?}"
    );
    assert!(
        report.rebuild.len() > changed.len(),
        "{changed:?} {report:?}"
    );
    // Rebuild what the plan says, take the rest from the old build.
    let new_dir = dir.path().join("new");
    std::fs::create_dir(&new_dir).unwrap();
    let mut parts = Vec::new();
    for i in 0..8u32 {
        let name = format!("part-{i}.oocfp");
        if reused.contains(&i) {
            parts.push(
                old_parts
                    .iter()
                    .find(|p| p.ends_with(&name))
                    .unwrap()
                    .clone(),
            );
        } else {
            let part = new_dir.join(&name);
            build_subset(&new, i, &part, &opts, &mut NoProgress).unwrap();
            parts.push(part);
        }
    }
    let full = dir.path().join("full.oocf");
    convert_plan(&new, &full, &opts, &mut NoProgress).unwrap();
    let full = std::fs::read(&full).unwrap();
    for given in [Some(&new), None] {
        let merged = dir.path().join("merged.oocf");
        merge(&parts, &merged, &opts, given, &mut NoProgress).unwrap();
        assert!(
            std::fs::read(&merged).unwrap() == full,
            "the update differs from a full rebuild"
        );
        deep_verify(&merged);
    }
    // An old file where the update needs a new one is foreign.
    let stale = report.rebuild[0];
    let name = format!("part-{stale}.oocfp");
    let mut wrong = parts.clone();
    wrong[stale as usize] = old_parts
        .iter()
        .find(|p| p.ends_with(&name))
        .unwrap()
        .clone();
    let out = dir.path().join("wrong.oocf");
    let e = expect_err(
        merge(&wrong, &out, &opts, Some(&new), &mut NoProgress),
        &out,
    );
    assert!(e.contains("another plan"), "{e}");
}
