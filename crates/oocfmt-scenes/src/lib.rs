//! `oocfmt-scenes`: built-in scenes and the spec's test vectors (not published).
//!
//! The generators are deterministic and need no input files: [`mandelbulb`] (a fractal surface,
//! the demo's model) and [`cad`] (pipes, flanges, bolts, plates and panels) stream OBJ files of
//! any size; [`demo_scene`] builds a small mesh in memory for tests; [`rng`] is the seeded
//! generator they use; [`vectors`] writes `spec/vectors/`.
//!
//! ```
//! let mesh = oocfmt_scenes::demo_scene(1000);
//! assert!(!mesh.triangles.is_empty());
//! assert!(mesh.validate().is_ok());
//! ```

#![forbid(unsafe_code)]

pub mod cad;
pub mod demo;
pub mod mandelbulb;
mod report;
pub mod rng;
pub mod vectors;

pub use demo::demo_scene;
pub use report::{GenError, GenReport};
