//! The importers' tests, one binary: glTF and OBJ.

mod import_gltf;
mod import_obj;
