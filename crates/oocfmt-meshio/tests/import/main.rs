//! The importers' tests, one binary: glTF, OBJ, STL and PLY, and the replay of the STL and PLY
//! fuzz corpora.

mod fuzz_corpus;
mod import_gltf;
mod import_obj;
mod import_ply;
mod import_stl;
