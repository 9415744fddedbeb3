//! PLY from a stream: every encoding reads as the same file would, without the size checks a
//! file gets, and faces stored before the vertices are refused, saying why.

use std::io::Cursor;

use super::{import_from, import_stream, PlyOptions};
use crate::import::{ImportError, ImportReport, MeshSink};
use crate::mesh::Mesh;

/// A square of two triangles as PLY in `encoding`; `faces_first` stores the faces first.
fn square(encoding: &str, faces_first: bool) -> Vec<u8> {
    let vertex = "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n";
    let face = "element face 1\nproperty list uchar int vertex_indices\n";
    let (a, b) = if faces_first {
        (face, vertex)
    } else {
        (vertex, face)
    };
    let mut out = format!("ply\nformat {encoding} 1.0\n{a}{b}end_header\n").into_bytes();
    let corners: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let big = encoding == "binary_big_endian";
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    if encoding == "ascii" {
        for c in corners {
            vertices.extend_from_slice(format!("{} {} {}\n", c[0], c[1], c[2]).as_bytes());
        }
        faces.extend_from_slice(b"4 0 1 2 3\n");
    } else {
        for c in corners.iter().flatten() {
            vertices.extend(if big {
                c.to_be_bytes()
            } else {
                c.to_le_bytes()
            });
        }
        faces.push(4);
        for i in 0..4i32 {
            faces.extend(if big {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
    }
    let (a, b) = if faces_first {
        (faces, vertices)
    } else {
        (vertices, faces)
    };
    out.extend(a);
    out.extend(b);
    out
}

fn stream(bytes: &[u8]) -> Result<(Mesh, ImportReport), ImportError> {
    let mut sink = MeshSink::new(false);
    import_stream(bytes, "<stdin>", &mut sink, &PlyOptions::default())?;
    sink.finish()
}

fn file(bytes: &[u8]) -> Result<(Mesh, ImportReport), ImportError> {
    let mut sink = MeshSink::new(false);
    import_from(
        Cursor::new(bytes),
        "<stdin>",
        &mut sink,
        &PlyOptions::default(),
    )?;
    sink.finish()
}

#[test]
fn every_encoding_streams_as_its_file_reads() -> Result<(), ImportError> {
    for encoding in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let bytes = square(encoding, false);
        let (m, r) = stream(&bytes)?;
        assert_eq!(m.triangles.len(), 2, "{encoding}");
        assert_eq!((m, r), file(&bytes)?, "{encoding}");
    }
    Ok(())
}

#[test]
fn faces_before_the_vertices_are_refused_from_a_stream() -> Result<(), ImportError> {
    for encoding in ["ascii", "binary_little_endian"] {
        let bytes = square(encoding, true);
        assert_eq!(file(&bytes)?.0.triangles.len(), 2, "{encoding}");
        let e = stream(&bytes)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.starts_with("<stdin>:3: unsupported: element `face`"),
            "{e}"
        );
        assert!(e.contains("save it to a file first"), "{e}");
    }
    Ok(())
}

#[test]
fn a_stream_is_held_to_the_limits_not_to_a_size() -> Result<(), ImportError> {
    // A file would refuse these counts before reading (the bytes cannot hold them); a stream
    // reads on and fails where the data ends, having reserved little.
    let mut big = square("binary_little_endian", false);
    let from = b"element vertex 4\n";
    let at = big.windows(from.len()).position(|w| w == from).unwrap_or(0);
    big.splice(
        at..at + from.len(),
        b"element vertex 9000000\n".iter().copied(),
    );
    let e = file(&big).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("more than the"), "{e}");
    let e = stream(&big)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(e.contains("the stream ends inside property"), "{e}");
    Ok(())
}
