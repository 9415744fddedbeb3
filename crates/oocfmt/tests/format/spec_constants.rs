//! Cross-checks spec/oocfmt.md against the code: every field-table offset and size, every magic,
//! every issue code. If this fails, the spec and the code disagree; fix whichever is wrong.

use std::collections::BTreeSet;

use oocfmt::{directory, header, trailer, Code, Severity};

fn spec() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/oocfmt.md");
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The rows `| offset | size | type | field | ...` of the table under `heading`.
fn table(spec: &str, heading: &str) -> Vec<(usize, usize, String)> {
    let start = spec
        .find(heading)
        .unwrap_or_else(|| panic!("no section {heading}"));
    let mut rows = Vec::new();
    let mut seen_table = false;
    for line in spec[start..].lines().skip(1) {
        if line.starts_with("## ") {
            break;
        }
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 5 {
            if seen_table && !line.starts_with('|') {
                break;
            }
            continue;
        }
        seen_table = true;
        if let (Ok(off), Ok(size)) = (cells[1].parse::<usize>(), cells[2].parse::<usize>()) {
            rows.push((off, size, cells[4].to_string()));
        }
    }
    rows
}

fn check_contiguous(rows: &[(usize, usize, String)], total: usize, what: &str) {
    let mut at = 0;
    for (off, size, name) in rows {
        assert_eq!(*off, at, "{what}: field {name} at {off}, expected {at}");
        at += size;
    }
    assert_eq!(
        at, total,
        "{what}: fields add up to {at}, the code says {total}"
    );
}

#[test]
fn header_table_matches_the_code() {
    let rows = table(&spec(), "## 3. Header");
    check_contiguous(&rows, header::HEADER_LEN, "header");
    let want = [
        ("magic", header::OFF_MAGIC),
        ("major", header::OFF_MAJOR),
        ("minor", header::OFF_MINOR),
        ("block_size_log2", header::OFF_BLOCK_SIZE_LOG2),
        ("incompatible_features", header::OFF_INCOMPAT),
        ("compatible_features", header::OFF_COMPAT),
        ("directory_offset", header::OFF_DIRECTORY_OFFSET),
        ("block_count", header::OFF_BLOCK_COUNT),
        ("metadata_length", header::OFF_METADATA_LENGTH),
        ("metadata_offset", header::OFF_METADATA_OFFSET),
        ("header_crc", header::OFF_HEADER_CRC),
    ];
    for (name, off) in want {
        assert!(
            rows.iter().any(|(o, _, n)| n == name && *o == off),
            "header field {name} is not at {off} in the spec"
        );
    }
}

#[test]
fn trailer_table_matches_the_code() {
    let rows = table(&spec(), "## 10. Trailer");
    check_contiguous(&rows, trailer::TRAILER_LEN, "trailer");
    for (name, off) in [
        ("directory_crc", trailer::OFF_DIRECTORY_CRC),
        ("metadata_crc", trailer::OFF_METADATA_CRC),
        ("root_checksum", trailer::OFF_ROOT_CHECKSUM),
        ("trailer_crc", trailer::OFF_TRAILER_CRC),
    ] {
        assert!(
            rows.iter().any(|(o, _, n)| n == name && *o == off),
            "trailer field {name} is not at {off} in the spec"
        );
    }
}

#[test]
fn directory_table_matches_the_code() {
    let rows = table(&spec(), "## 4. Blocks and the directory");
    check_contiguous(&rows, directory::ENTRY_LEN, "directory entry");
    for (name, off) in [
        ("offset", directory::OFF_OFFSET),
        ("stored_length", directory::OFF_STORED_LENGTH),
        ("raw_length", directory::OFF_RAW_LENGTH),
        ("crc", directory::OFF_CRC),
        ("kind", directory::OFF_KIND),
        ("codec", directory::OFF_CODEC),
        ("level", directory::OFF_LEVEL),
        ("item_count", directory::OFF_ITEM_COUNT),
    ] {
        assert!(
            rows.iter().any(|(o, _, n)| n == name && *o == off),
            "entry field {name} is not at {off} in the spec"
        );
    }
}

#[test]
fn magics_match_the_code() {
    let s = spec();
    let hex = |b: &[u8]| {
        b.iter()
            .map(|x| format!("{x:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    assert!(
        s.contains(&format!("`{}`", hex(&header::MAGIC))),
        "header magic"
    );
    assert!(
        s.contains(&format!("`{}`", hex(&trailer::END_MAGIC))),
        "end magic"
    );
}

#[test]
fn issue_codes_match_the_code() {
    let s = spec();
    let start = s.find("## 13.").unwrap_or(0);
    let end = s.find("## 14.").unwrap_or(s.len());
    let mut in_spec = BTreeSet::new();
    for line in s[start..end].lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let code = cells[1].trim_matches('`').to_string();
        let sev = cells[2].to_string();
        in_spec.insert((code, sev));
    }
    let in_code: BTreeSet<(String, String)> = Code::ALL
        .iter()
        .map(|c| {
            let sev = match c.severity() {
                Severity::Error => "error",
                Severity::Warning => "warning",
                Severity::Info => "info",
            };
            (c.as_str().to_string(), sev.to_string())
        })
        .collect();
    assert_eq!(in_spec, in_code, "spec §13 and Code::ALL disagree");
}

#[test]
fn record_sizes_match_the_spec() {
    use oocfmt::records::{NODE_BASIC_LEN, NODE_LEAF_LEN, NODE_LOD_LEN, PROXY_LEN};
    let s = spec();
    assert!(s.contains(&format!("Basic node (type 0), {NODE_BASIC_LEN} bytes")));
    assert!(s.contains(&format!("LOD node (type 1), {NODE_LOD_LEN} bytes")));
    assert!(s.contains(&format!("Leaf node (type 2), {NODE_LEAF_LEN} bytes")));
    assert!(s.contains(&format!("records of {PROXY_LEN} bytes")));
}

#[test]
fn rlod_table_matches_the_code() {
    let rows = table(&spec(), "### 6.4 R-LOD records");
    check_contiguous(&rows, oocfmt::records::RLOD_LEN, "R-LOD record");
    let s = spec();
    for (name, bit) in [
        ("LOD_RLODS", header::INCOMPAT_LOD_RLODS),
        ("LOD_NO_VOXELS", header::INCOMPAT_LOD_NO_VOXELS),
        ("LOD_FILTERED", header::INCOMPAT_LOD_FILTERED),
        ("PART_IDS", header::INCOMPAT_PART_IDS),
    ] {
        let row = format!("| incompatible | {} | `{name}` |", bit.trailing_zeros());
        assert!(s.contains(&row), "{row}");
    }
    // The first undefined bit follows the last known one.
    let first_free = 64 - header::KNOWN_INCOMPAT.leading_zeros();
    let row = format!("| incompatible | {first_free}–63 | — |");
    assert!(s.contains(&row), "{row}");
    // Coverage and shade where §6.4 puts them.
    for (off, name) in [(19, "coverage"), (22, "shade"), (23, "reserved")] {
        assert!(
            rows.iter()
                .any(|(o, n, f)| *o == off && *n == 1 && f == name),
            "R-LOD byte {off} is not {name} in the spec"
        );
    }
    let r = oocfmt::records::Rlod {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
        colour: [0; 3],
        deviation_code: 0,
        expansion_code: 0,
        coverage: 0x19,
        shade: 0x22,
    };
    let mut v = Vec::new();
    r.encode_into(&mut v, true);
    assert_eq!((v[19], v[22], v[23]), (0x19, 0x22, 0));
}

#[test]
fn version_and_footprint_layout_match_the_spec() {
    use oocfmt::records::{Footprint, Sample, Voxel};
    let s = spec();
    let title = format!(
        "# The `.oocf` container, version {}.{}",
        header::VERSION_MAJOR,
        header::VERSION_MINOR
    );
    assert!(s.starts_with(&title), "{title}");
    let minors: Vec<String> = (0..=header::VERSION_MINOR).map(|m| m.to_string()).collect();
    let (last, rest) = minors.split_last().unwrap_or_else(|| panic!("no minor"));
    let cell = format!("| minor | {} or {last} (§11) |", rest.join(", "));
    assert!(s.contains(&cell), "{cell}");
    // §5.1: the four voxel lengths, and where shade and coverage sit in a footprint.
    let sample = Sample::pack([0.0, 0.0, 1.0], [1.0; 3]);
    let f = Footprint {
        shade: 0x12,
        coverage: 0x34,
    };
    let lens = [
        Voxel::single(sample),
        Voxel::Single(sample, f),
        Voxel::six([sample; 6]),
        Voxel::Six([sample; 6], [f; 6]),
    ]
    .map(|v| {
        let mut b = Vec::new();
        v.encode_into(&mut b, true);
        assert_eq!(b.len(), v.byte_len(true));
        b.len()
    });
    let sentence = format!(
        "So a voxel is {}, {}, {} or {} bytes.",
        lens[0], lens[1], lens[2], lens[3]
    );
    assert!(s.contains(&sentence), "{sentence}");
    let mut b = Vec::new();
    Voxel::Single(sample, f).encode_into(&mut b, true);
    assert_eq!(&b[4..8], &[0x12, 0x34, 0, 0]);
    for row in [
        "| 0–7  | shade *σ* |",
        "| 8–15 | coverage *α* |",
        "| 30    | empty / footprints |",
    ] {
        assert!(s.contains(row), "{row}");
    }
}

/// Every issue code the prose names (a back-quoted upper-case word that is not a feature bit)
/// is a code of `Code::ALL`, so a rule cannot name a code that no verifier reports.
#[test]
fn codes_named_in_the_prose_exist() {
    let s = spec();
    let features = [
        "PROXIES",
        "LOD_VOXELS",
        "LOD_RLODS",
        "LOD_NO_VOXELS",
        "LOD_FILTERED",
        "PART_IDS",
    ];
    let known: BTreeSet<&str> = Code::ALL.iter().map(|c| c.as_str()).collect();
    let mut named = BTreeSet::new();
    for piece in s.split('`').skip(1).step_by(2) {
        let code_like = piece.len() > 1
            && piece
                .chars()
                .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
            && piece.starts_with(|c: char| c.is_ascii_uppercase());
        if code_like && !features.contains(&piece) {
            named.insert(piece.to_string());
        }
    }
    let unknown: Vec<&String> = named
        .iter()
        .filter(|n| !known.contains(n.as_str()))
        .collect();
    assert!(
        unknown.is_empty(),
        "spec names codes that do not exist: {unknown:?}"
    );
    assert!(
        named.len() >= 40,
        "only {} codes found in the prose",
        named.len()
    );
}

/// §8's part-id width code (bits 3–4, its thresholds), §6.2's part word, §12's part limit and §3's
/// minor for parts, as the code has them.
#[test]
fn part_ids_match_the_spec() {
    use oocfmt::metadata::MAX_PARTS;
    use oocfmt::records::triangle::{part_id_width, ATTR_PART_WIDTH, ATTR_PART_WIDTH_SHIFT};
    use oocfmt::records::PART_WORD_LEN;
    let s = spec();
    let (lo, hi) = (
        ATTR_PART_WIDTH_SHIFT,
        ATTR_PART_WIDTH_SHIFT + ATTR_PART_WIDTH.count_ones() as u16 - 1,
    );
    assert_eq!(ATTR_PART_WIDTH >> ATTR_PART_WIDTH_SHIFT, 0b11);
    let cell = format!("bits {lo}–{hi} part-id width code (since 1.3)");
    assert!(s.contains(&cell), "{cell}");
    let reserved = format!("triangle block attribute bits {}–15", hi + 1);
    assert!(s.contains(&reserved), "{reserved}");
    // The thresholds: the last count of each width, and the one after it.
    for (last, code) in [(1usize, 0u16), (256, 1), (65536, 2)] {
        assert_eq!(part_id_width(last), code, "{last} parts");
        assert_eq!(part_id_width(last + 1), code + 1, "{} parts", last + 1);
    }
    for needle in [
        "1 (u8) for *P* ≤ 256, 2 (u16) for",
        "*P* ≤ 65536, else 3 (u32)",
        "(u8, u16 or u32 for *c* = 1, 2, 3)",
    ] {
        assert!(s.contains(needle), "{needle}");
    }
    let word = format!("then {PART_WORD_LEN} bytes of part word where the file has `PART_IDS`");
    assert!(s.contains(&word), "{word}");
    assert_eq!(MAX_PARTS, 1 << 24);
    assert!(s.contains("| parts | 2^24 in the part table (§9)"));
    assert_eq!(header::VERSION_MINOR_PARTS, 3);
    assert!(s.contains("3 when the metadata has a part table"));
}
