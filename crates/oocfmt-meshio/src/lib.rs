//! `oocfmt-meshio`: the mesh formats outside the container.
//!
//! Importers ([`import::obj`], [`import::gltf`], [`import::stl`], [`import::ply`]) stream
//! triangles into a [`import::TriangleSink`], which applies one bad-input policy for every
//! format; [`export`] writes a container's full-detail triangles back out as OBJ or PLY;
//! [`obj_writer`] is the streaming, atomic OBJ output the exporter and the scene generators
//! share; [`mesh`] is the in-memory indexed mesh they all speak.
//!
//! ```
//! use oocfmt_meshio::import::{obj, MeshSink};
//!
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("tri.obj");
//! std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")?;
//! let mut sink = MeshSink::new(false);
//! obj::import(&path, &mut sink, &obj::ObjOptions::default())?;
//! let (mesh, report) = sink.finish()?;
//! assert_eq!((mesh.triangles.len(), report.triangles_out), (1, 1));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod export;
pub mod import;
pub mod mesh;
pub mod obj_writer;

pub use export::{ExportError, ExportOptions, ExportReport};
pub use import::{ImportError, ImportReport, MeshSink, TriangleSink};
pub use mesh::Mesh;
