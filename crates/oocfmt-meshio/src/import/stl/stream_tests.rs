//! STL from a stream: binary or ASCII by its first bytes (not by a size it does not have),
//! the same triangles as from a file, and what a stream cannot give said in its errors.

use std::io::Cursor;

use super::{ascii_stream_note, import_from, import_stream, StlOptions};
use crate::import::{ImportError, ImportReport, MeshSink};
use crate::mesh::Mesh;

type Tri = [[f32; 3]; 3];

fn tris() -> Vec<Tri> {
    vec![
        [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]],
        [[1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
        [[0., 0., 1.], [1., 0., 1.], [0., 1., 1.]],
    ]
}

/// A binary STL of `t` whose header starts with `header` (padded with NULs).
fn binary(header: &[u8], t: &[Tri]) -> Vec<u8> {
    let mut b = header.to_vec();
    b.resize(80, 0);
    b.extend_from_slice(&(t.len() as u32).to_le_bytes());
    for tri in t {
        b.extend_from_slice(&[0u8; 12]);
        for c in tri.iter().flatten() {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

fn ascii(name: &str, t: &[Tri]) -> String {
    let mut s = format!("solid {name}\n");
    for tri in t {
        s.push_str("facet normal 0 0 0\n outer loop\n");
        for p in tri {
            s.push_str(&format!("  vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str(" endloop\nendfacet\n");
    }
    s.push_str("endsolid\n");
    s
}

/// Imports `bytes` as a stream (a plain slice: it cannot seek).
fn stream(bytes: &[u8]) -> Result<(Mesh, ImportReport), ImportError> {
    let mut sink = MeshSink::new(false);
    import_stream(bytes, "<stdin>", &mut sink, &StlOptions::default())?;
    sink.finish()
}

fn file(bytes: &[u8]) -> Result<(Mesh, ImportReport), ImportError> {
    let mut sink = MeshSink::new(false);
    import_from(
        Cursor::new(bytes),
        "<stdin>",
        &mut sink,
        &StlOptions::default(),
    )?;
    sink.finish()
}

#[test]
fn a_stream_reads_as_the_same_file_would() -> Result<(), ImportError> {
    for bytes in [
        binary(b"solid but binary", &tris()),
        binary(b"", &tris()),
        ascii("", &tris()).into_bytes(),
        ascii("named", &tris()).into_bytes(),
    ] {
        let (m, r) = stream(&bytes)?;
        assert_eq!(m.triangles.len(), 3);
        assert_eq!((m, r), file(&bytes)?);
    }
    Ok(())
}

#[test]
fn the_first_bytes_decide_the_kind() {
    let text = ascii("", &tris());
    assert!(
        ascii_stream_note(b"solid x\n").is_some(),
        "too short for binary"
    );
    assert!(ascii_stream_note(&text.as_bytes()[..84]).is_some());
    assert!(ascii_stream_note(&binary(b"solid x", &tris())[..84]).is_none());
    let mut spaces = binary(b"", &tris());
    spaces[..80].copy_from_slice(&[b' '; 80]);
    assert!(ascii_stream_note(&spaces[..84]).is_none(), "no `solid`");
    assert!(ascii_stream_note(&text.replace("solid ", "solidx ").as_bytes()[..84]).is_none());
}

#[test]
fn what_a_stream_cannot_say_is_said() -> Result<(), ImportError> {
    // Bytes after the declared facets: a warning, the facets kept.
    let mut longer = binary(b"", &tris());
    longer.extend_from_slice(&[7u8; 30]);
    let (m, r) = stream(&longer)?;
    assert_eq!(m.triangles.len(), 3);
    assert!(r
        .warnings
        .iter()
        .any(|w| w.contains("goes on after the 3 facets")));
    // Fewer facets than declared: an error at the facet, saying the stream ended.
    let short = binary(b"", &tris());
    let e = stream(&short[..short.len() - 10])
        .err()
        .map(|e| e.to_string());
    let e = e.unwrap_or_default();
    assert!(e.contains("<stdin> (facet 2 at byte 184)"), "{e}");
    assert!(e.contains("stream ends before the facets"), "{e}");
    // Text that is not STL says why it is not binary either.
    let e = stream(b"hello, this is no model at all, just a line of text long enough: 84 bytes.\n")
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(e.contains("neither binary nor ASCII STL"), "{e}");
    Ok(())
}

#[test]
fn an_unnamed_first_solid_of_a_stream_is_no_part() -> Result<(), ImportError> {
    let two = format!("{}{}", ascii("", &tris()), ascii("second", &tris()));
    let (m, _) = stream(two.as_bytes())?;
    let names: Vec<&str> = m.parts.iter().map(|p| p.name.as_str()).collect();
    assert!(names.contains(&"second"), "{names:?}");
    assert!(!names.contains(&"solid 1"), "{names:?}");
    let (f, _) = file(two.as_bytes())?;
    assert!(f.parts.iter().any(|p| p.name == "solid 1"));
    Ok(())
}
