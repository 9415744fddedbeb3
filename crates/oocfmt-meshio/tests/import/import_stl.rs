//! The STL importer on hand-built files: ASCII and binary cubes agree, binary is told by size
//! (not by a header starting with `solid`), truncated files say why they are neither kind,
//! solids become parts, flipped normals are counted, both colour conventions, and every
//! error names its line or facet.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::Cursor;
use std::path::PathBuf;

use oocfmt_meshio::import::stl::{import, import_from, StlOptions};
use oocfmt_meshio::import::{
    DropReason, ImportError, ImportReport, MeshSink, PartDef, Recentre, TriangleSink,
};
use oocfmt_meshio::mesh::Mesh;
use tempfile::TempDir;

pub(crate) type Tri = [[f32; 3]; 3];

/// A unit cube from `o`, 12 triangles wound counter-clockwise seen from outside.
pub(crate) fn cube_at(o: [f32; 3]) -> Vec<Tri> {
    let quads: [[[f32; 3]; 4]; 6] = [
        [[0., 0., 0.], [0., 1., 0.], [1., 1., 0.], [1., 0., 0.]],
        [[0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]],
        [[0., 0., 0.], [1., 0., 0.], [1., 0., 1.], [0., 0., 1.]],
        [[0., 1., 0.], [0., 1., 1.], [1., 1., 1.], [1., 1., 0.]],
        [[0., 0., 0.], [0., 0., 1.], [0., 1., 1.], [0., 1., 0.]],
        [[1., 0., 0.], [1., 1., 0.], [1., 1., 1.], [1., 0., 1.]],
    ];
    let shift = |p: [f32; 3]| [p[0] + o[0], p[1] + o[1], p[2] + o[2]];
    quads
        .iter()
        .flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]])
        .map(|t| t.map(shift))
        .collect()
}

pub(crate) fn cube() -> Vec<Tri> {
    cube_at([0.0; 3])
}

/// The unit normal of the winding.
fn normal(t: &Tri) -> [f32; 3] {
    let d = |a: [f32; 3], b: [f32; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let (u, v) = (d(t[0], t[1]), d(t[0], t[2]));
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if l == 0.0 {
        return [0.0; 3];
    }
    n.map(|c| c / l)
}

/// An ASCII STL of `solids` (name, facets, which facets get their normal negated).
pub(crate) fn ascii(solids: &[(&str, &[Tri], &[usize])]) -> String {
    let mut s = String::new();
    for (name, tris, flipped) in solids {
        s += &format!("solid {name}\n");
        for (i, t) in tris.iter().enumerate() {
            let mut n = normal(t);
            if flipped.contains(&i) {
                n = n.map(|c| -c);
            }
            s += &format!(
                "  facet normal {} {} {}\n    outer loop\n",
                n[0], n[1], n[2]
            );
            for p in t {
                s += &format!("      vertex {} {} {}\n", p[0], p[1], p[2]);
            }
            s += "    endloop\n  endfacet\n";
        }
        s += &format!("endsolid {name}\n");
    }
    s
}

/// A binary STL: `header` (padded with zeros to 80 bytes), then each facet with its
/// attribute word; `flip` negates the stored normal.
pub(crate) fn binary(header: &[u8], facets: &[(Tri, u16, bool)]) -> Vec<u8> {
    let mut b = header.to_vec();
    b.resize(80, 0);
    b.extend_from_slice(&(facets.len() as u32).to_le_bytes());
    for (t, attribute, flip) in facets {
        let n = normal(t).map(|c| if *flip { -c } else { c });
        for c in n.iter().chain(t.iter().flatten()) {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&attribute.to_le_bytes());
    }
    b
}

pub(crate) fn plain(tris: &[Tri]) -> Vec<(Tri, u16, bool)> {
    tris.iter().map(|t| (*t, 0, false)).collect()
}

fn file(bytes: impl AsRef<[u8]>) -> (TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.stl");
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

fn load_with(
    bytes: impl AsRef<[u8]>,
    strict: bool,
    opts: &StlOptions,
) -> Result<(Mesh, ImportReport), ImportError> {
    let (_dir, path) = file(bytes);
    let mut sink = MeshSink::new(strict);
    import(&path, &mut sink, opts)?;
    let (mesh, report) = sink.finish()?;
    mesh.validate().unwrap();
    assert_eq!(
        report.triangles_in,
        report.triangles_out + report.dropped_total()
    );
    assert_eq!(report.triangles_out, mesh.triangles.len() as u64);
    Ok((mesh, report))
}

fn load(bytes: impl AsRef<[u8]>) -> Result<(Mesh, ImportReport), ImportError> {
    load_with(bytes, false, &StlOptions::default())
}

fn error(bytes: impl AsRef<[u8]>) -> String {
    match load(bytes) {
        Ok((m, _)) => panic!("expected an error, got {} triangles", m.triangles.len()),
        Err(e) => e.to_string(),
    }
}

/// The corners of every triangle of `mesh`, in order.
fn corners(mesh: &Mesh) -> Vec<Tri> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize]))
        .collect()
}

// ---------------------------------------------------------------- the two kinds

#[test]
fn binary_and_ascii_cubes_give_the_same_mesh() -> Result<(), ImportError> {
    let (a, ra) = load(ascii(&[("", &cube(), &[])]))?;
    let (b, rb) = load(binary(b"a binary cube", &plain(&cube())))?;
    assert_eq!(a.triangles.len(), 12);
    assert_eq!(a.positions.len(), 8, "corners are shared");
    assert_eq!(corners(&a), cube());
    assert_eq!(a, b);
    assert!(
        a.parts.is_empty() && a.part_ids.is_none(),
        "one unnamed solid is no part"
    );
    assert!(a.normals.is_none() && a.colours.is_none());
    assert_eq!((ra.triangles_in, rb.triangles_in), (12, 12));
    assert!(
        ra.warnings.is_empty() && rb.warnings.is_empty(),
        "{ra:?} {rb:?}"
    );
    Ok(())
}

#[test]
fn a_binary_file_whose_header_starts_with_solid_is_read_as_binary() -> Result<(), ImportError> {
    let (m, _) = load(binary(
        b"solid cube exported by a CAD tool",
        &plain(&cube()),
    ))?;
    assert_eq!(corners(&m), cube());
    assert!(m.parts.is_empty(), "binary files have no parts");
    Ok(())
}

#[test]
fn keywords_in_any_case_crlf_and_polygon_loops_are_read() -> Result<(), ImportError> {
    let text = "SOLID\r\n FACET NORMAL 0 0 1\r\n OUTER LOOP\r\n VERTEX 0 0 0\r\n VERTEX 1 0 0\r\n \
                VERTEX 1 1 0\r\n VERTEX 0 1 0\r\n ENDLOOP\r\n ENDFACET\r\nENDSOLID\r\n";
    let (m, r) = load(text)?;
    assert_eq!(
        m.triangles.len(),
        2,
        "a loop of four corners is two triangles"
    );
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    Ok(())
}

#[test]
fn a_truncated_binary_stl_says_why_it_is_neither_kind() {
    let mut b = binary(b"binary cube", &plain(&cube()));
    b.truncate(b.len() - 7);
    let e = error(&b);
    assert!(e.contains("neither binary nor ASCII STL"), "{e}");
    assert!(
        e.contains("declares 12 facets, which take 84 + 50 × 12 = 684 bytes, but the file has 677"),
        "{e}"
    );
    assert!(e.contains("does not start with `solid`"), "{e}");
    // With a header that starts with `solid` (zero-padded, as binary headers are).
    let mut b = binary(b"solid cube", &plain(&cube()));
    b.truncate(b.len() - 50);
    let e = error(&b);
    assert!(e.contains("neither binary nor ASCII STL"), "{e}");
    assert!(e.contains("holds bytes that are not text"), "{e}");
    assert!(e.contains("the file has 634 bytes"), "{e}");
    // Too short for a binary header.
    let e = error(b"sol");
    assert!(e.contains("too short for binary STL (3 bytes"), "{e}");
    let e = error(b"");
    assert!(e.contains("holds no `solid`"), "{e}");
}

#[test]
fn ascii_errors_name_their_line() {
    let head = "solid x\n facet normal 0 0 1\n";
    for (text, line, needle) in [
        (
            format!("{head} outer loop\n vertex 0 0\n"),
            4,
            "`vertex` has 2 numbers",
        ),
        (
            format!("{head} outer loop\n vertex 0 0 a\n"),
            4,
            "`a` is not a number",
        ),
        (format!("{head} endloop\n"), 3, "expected `outer loop`"),
        (
            format!("{head} outer loop\n vertex 0 0 0\n vertex 1 0 0\n endloop\n"),
            6,
            "a loop of 2 vertices",
        ),
        (
            "solid x\n bogus\n".to_string(),
            2,
            "expected `facet` or `endsolid`, found `bogus`",
        ),
        (
            format!("{}trailing\n", ascii(&[("", &cube(), &[])])),
            87,
            "expected `solid` or the end of the file",
        ),
        (
            format!("{head} outer loop\n vertex 0 0 0\n"),
            4,
            "ends inside a facet",
        ),
    ] {
        let e = load(&text).unwrap_err();
        assert!(matches!(e, ImportError::Parse { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains(&format!("m.stl:{line}:")), "{msg}");
        assert!(msg.contains(needle), "{msg}");
    }
    let e = error("hello\n");
    assert!(
        e.contains("neither binary nor ASCII STL") && e.contains("does not start with `solid`")
    );
    let long = format!("solid {}\n", "x".repeat(64));
    let opts = StlOptions {
        max_line_bytes: 16,
        ..StlOptions::default()
    };
    let e = load_with(long, false, &opts).unwrap_err().to_string();
    assert!(e.contains("first line is longer than 16 bytes"), "{e}");
}

#[test]
fn a_missing_endsolid_is_a_warning_when_every_facet_is_complete() -> Result<(), ImportError> {
    let text = ascii(&[("", &cube(), &[])]);
    let (m, r) = load(text.trim_end().trim_end_matches("endsolid"))?;
    assert_eq!(m.triangles.len(), 12);
    assert_eq!(r.warnings.len(), 1);
    assert!(
        r.warnings[0].contains("without `endsolid`"),
        "{:?}",
        r.warnings
    );
    Ok(())
}

// ---------------------------------------------------------------- parts

#[test]
fn several_solids_become_parts_with_their_names() -> Result<(), ImportError> {
    let c = cube();
    let (left, right) = c.split_at(4);
    let (m, _) = load(ascii(&[("left", left, &[]), ("right side", right, &[])]))?;
    let names: Vec<&str> = m.parts.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["left", "right side"]);
    assert!(m
        .parts
        .iter()
        .all(|p| p.parent.is_none() && p.source == Some(0)));
    let ids = m.part_ids.clone().unwrap();
    assert_eq!(ids, [vec![0; 4], vec![1; 8]].concat());
    // Unnamed solids are numbered, whether the first is unnamed or a later one.
    let (m, _) = load(ascii(&[("", left, &[]), ("", right, &[])]))?;
    let names: Vec<&str> = m.parts.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["solid 1", "solid 2"]);
    let (m, _) = load(ascii(&[("a", left, &[]), ("", right, &[])]))?;
    let names: Vec<&str> = m.parts.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["a", "solid 2"]);
    // One named solid is one part (its name survives; no ids are stored).
    let (m, _) = load(ascii(&[("bracket", &c, &[])]))?;
    assert_eq!(
        m.parts,
        [PartDef {
            name: "bracket".into(),
            parent: None,
            source: Some(0)
        }]
    );
    assert!(m.part_ids.is_none());
    Ok(())
}

// ---------------------------------------------------------------- normals

#[test]
fn normals_against_the_winding_are_counted_once_per_file() -> Result<(), ImportError> {
    let (good, _) = load(ascii(&[("", &cube(), &[])]))?;
    let (m, r) = load(ascii(&[("", &cube(), &[1, 4, 9])]))?;
    assert_eq!(m, good, "the winding wins");
    assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
    let w = &r.warnings[0];
    assert!(
        w.contains("3 facets have a stored normal pointing against their winding"),
        "{w}"
    );
    assert!(
        w.contains("m.stl:15"),
        "the first is facet 1, ending on line 15: {w}"
    );
    // The same in binary, where the place is the facet and its byte.
    let mut facets = plain(&cube());
    facets[2].2 = true;
    let (m, r) = load(binary(b"", &facets))?;
    assert_eq!(m, good);
    assert!(r.warnings[0].contains("1 facets") && r.warnings[0].contains("facet 2 at byte 184"));
    // Zero normals are fine.
    let zero = ascii(&[("", &cube(), &[])]).replace("facet normal 0 0 -1", "facet normal 0 0 0");
    let (_, r) = load(zero)?;
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    Ok(())
}

// ---------------------------------------------------------------- colours

/// Two triangles that share no corner.
pub(crate) fn two() -> [Tri; 2] {
    [
        [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]],
        [[5., 0., 0.], [6., 0., 0.], [5., 1., 0.]],
    ]
}

fn colour_of(m: &Mesh, t: usize) -> [u8; 4] {
    let c = m.colours.as_ref().unwrap();
    let v = m.triangles[t];
    assert!(v.iter().all(|&i| c[i as usize] == c[v[0] as usize]));
    c[v[0] as usize]
}

#[test]
fn viscam_colours_have_bit_15_set_and_red_in_the_high_bits() -> Result<(), ImportError> {
    let [a, b] = two();
    let red = 0x8000 | (31 << 10);
    let (m, _) = load(binary(b"viscam", &[(a, red, false), (b, 0x7fff, false)]))?;
    assert_eq!(colour_of(&m, 0), [255, 0, 0, 255]);
    assert_eq!(
        colour_of(&m, 1),
        [255; 4],
        "bit 15 clear: no colour (white)"
    );
    let blue_green = 0x8000 | (16 << 5) | 31;
    let (m, _) = load(binary(b"", &[(a, blue_green, false)]))?;
    assert_eq!(colour_of(&m, 0), [0, 132, 255, 255]);
    // No facet with bit 15: no colours at all.
    let (m, _) = load(binary(b"", &[(a, 0x1234, false)]))?;
    assert!(m.colours.is_none());
    Ok(())
}

#[test]
fn magics_colours_come_from_the_header_and_bit_15_clear() -> Result<(), ImportError> {
    let [a, b] = two();
    let header = b"exported COLOR=\x0a\x14\x1e\x28,MATERIAL=...";
    let own_red = 31;
    let (m, _) = load(binary(header, &[(a, own_red, false), (b, 0x8000, false)]))?;
    assert_eq!(
        colour_of(&m, 0),
        [255, 0, 0, 255],
        "bit 15 clear: own colour, red low"
    );
    assert_eq!(
        colour_of(&m, 1),
        [10, 20, 30, 40],
        "bit 15 set: the header's RGBA"
    );
    // Off, the attribute words are ignored.
    let opts = StlOptions {
        colours: false,
        ..StlOptions::default()
    };
    let (m, _) = load_with(binary(header, &[(a, own_red, false)]), false, &opts)?;
    assert!(m.colours.is_none());
    Ok(())
}

// ---------------------------------------------------------------- the sink's policy

#[test]
fn degenerate_facets_are_dropped_and_counted_or_refused_with_their_place() {
    let mut facets = plain(&cube());
    facets[1].0 = [[0.0; 3], [0.0; 3], [1.0, 0.0, 0.0]];
    let (m, r) = load(binary(b"", &facets)).unwrap();
    assert_eq!(m.triangles.len(), 11);
    assert_eq!(r.dropped.get(&DropReason::ZeroArea), Some(&1));
    let e = load_with(binary(b"", &facets), true, &StlOptions::default()).unwrap_err();
    assert!(matches!(e, ImportError::Strict { .. }), "{e}");
    assert!(e.to_string().contains("facet 1 at byte 134"), "{e}");
    let mut tris = cube();
    tris[3][2][0] = f32::NAN;
    let (_, r) = load(ascii(&[("", &tris, &[])])).unwrap();
    assert_eq!(r.dropped.get(&DropReason::NonFinite), Some(&1));
    // No facet at all: the sink says so.
    assert!(matches!(
        load(binary(b"", &[])),
        Err(ImportError::Empty { .. })
    ));
}

#[test]
fn input_that_is_not_a_file_and_the_bounds_pass_read_the_same() -> Result<(), ImportError> {
    let bytes = binary(b"", &plain(&cube_at([1e7, 0.0, 0.0])));
    let mut sink = MeshSink::new(false);
    import_from(
        Cursor::new(&bytes),
        "mem.stl",
        &mut sink,
        &StlOptions::default(),
    )?;
    let (m, r) = sink.finish()?;
    assert_eq!(
        (m.triangles.len(), r.files.as_slice()),
        (12, &["mem.stl".to_string()][..])
    );
    // `--recentre auto`'s first pass only places positions.
    let text = ascii(&[("", &cube_at([1e7, 0.0, 0.0]), &[])]);
    for input in [bytes, text.into_bytes()] {
        let origin = Recentre::Auto.origin(|s: &mut dyn TriangleSink| {
            import_from(Cursor::new(&input), "mem.stl", s, &StlOptions::default())
        })?;
        assert_eq!(origin, [1e7 + 0.5, 0.5, 0.5]);
    }
    Ok(())
}
