//! Built-in scene generators (deterministic, no input files needed).

pub mod cad;
pub mod demo;
pub mod mandelbulb;
pub mod obj_writer;
pub mod rng;

pub use demo::demo_scene;
