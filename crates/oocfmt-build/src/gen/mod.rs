//! Built-in scene generators (deterministic, no input files needed).

pub mod demo;

pub use demo::demo_scene;
