//! Streaming output for the generators and the exporter: an [`AtomicFile`] that appears under
//! its name only when complete, and an [`ObjWriter`] on top of it (or of a stream, such as
//! standard output) that numbers vertices and normals as it writes them, so a caller never
//! needs the whole model in memory.
//!
//! Floats are printed with Rust's `{}` (the shortest text that parses back to the same value),
//! so positions survive a write and re-read bit for bit.

use std::fmt::Display;
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// An I/O failure on an output file, naming the file the user asked for.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", path.display())]
pub struct WriteError {
    /// The file the caller asked for (not the temporary name written under).
    pub path: PathBuf,
    /// The failure.
    pub source: io::Error,
}

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A file written under a temporary name in the target's folder and renamed into place by
/// [`AtomicFile::commit`]. Dropped uncommitted, it removes the temporary file, so a failure
/// never leaves a partial file under the final name nor touches an existing one.
pub struct AtomicFile {
    out: Option<BufWriter<File>>,
    temp: PathBuf,
    target: PathBuf,
    bytes: u64,
}

impl AtomicFile {
    /// Creates a fresh temporary file beside `target` (named `.NAME.PID-N.partial`); `target`
    /// itself is untouched until [`AtomicFile::commit`].
    pub fn create(target: &Path) -> Result<AtomicFile, WriteError> {
        let fail = |source| WriteError {
            path: target.to_path_buf(),
            source,
        };
        let name = target.file_name().ok_or_else(|| {
            fail(io::Error::new(
                io::ErrorKind::InvalidInput,
                "not a file path",
            ))
        })?;
        let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let temp = target.with_file_name(format!(
            ".{}.{}-{n}.partial",
            name.to_string_lossy(),
            std::process::id()
        ));
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(fail)?;
        Ok(AtomicFile {
            out: Some(BufWriter::with_capacity(1 << 20, file)),
            temp,
            target: target.to_path_buf(),
            bytes: 0,
        })
    }

    /// The path the file takes when committed.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Bytes written so far.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Attaches the target's name to an I/O error.
    pub fn error(&self, source: io::Error) -> WriteError {
        WriteError {
            path: self.target.clone(),
            source,
        }
    }

    /// Overwrites the start of the file with `data`, no longer than what is written: for a
    /// header whose numbers are known only at the end.
    pub fn overwrite_start(&mut self, data: &[u8]) -> Result<(), WriteError> {
        if data.len() as u64 > self.bytes {
            return Err(self.error(io::Error::other(format!(
                "a {}-byte header does not fit the {} bytes written",
                data.len(),
                self.bytes
            ))));
        }
        let result = match self.out.as_mut() {
            Some(out) => out
                .seek(SeekFrom::Start(0))
                .and_then(|_| out.write_all(data))
                .and_then(|()| out.seek(SeekFrom::End(0)).map(|_| ())),
            None => Err(io::Error::other("the file was closed after a failure")),
        };
        result.map_err(|e| self.error(e))
    }

    /// Flushes, syncs and renames the file into place; returns its length.
    pub fn commit(mut self) -> Result<u64, WriteError> {
        let out = self
            .out
            .take()
            .ok_or_else(|| self.error(io::Error::other("the file was closed after a failure")))?;
        let file = out.into_inner().map_err(|e| self.error(e.into_error()))?;
        file.sync_all().map_err(|e| self.error(e))?;
        drop(file);
        std::fs::rename(&self.temp, &self.target).map_err(|e| self.error(e))?;
        Ok(self.bytes)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let out = self
            .out
            .as_mut()
            .ok_or_else(|| io::Error::other("the file was closed after a failure"))?;
        let n = out.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        match self.out.as_mut() {
            Some(out) => out.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.out.take().is_some() {
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Counts of what an [`ObjWriter`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObjStats {
    /// `v` lines written.
    pub vertices: u64,
    /// `vn` lines written.
    pub normals: u64,
    /// `f` lines written.
    pub faces: u64,
    /// Bytes written, the file's size once finished.
    pub bytes: u64,
}

/// Where an [`ObjWriter`] writes.
enum Target {
    /// A file, renamed into place when finished.
    File(AtomicFile),
    /// A stream (standard output), named in errors by `name`; `bytes` written so far.
    Stream {
        out: BufWriter<Box<dyn Write>>,
        name: PathBuf,
        bytes: u64,
    },
}

impl Target {
    fn bytes(&self) -> u64 {
        match self {
            Target::File(f) => f.bytes(),
            Target::Stream { bytes, .. } => *bytes,
        }
    }

    fn error(&self, source: io::Error) -> WriteError {
        match self {
            Target::File(f) => f.error(source),
            Target::Stream { name, .. } => WriteError {
                path: name.clone(),
                source,
            },
        }
    }

    fn write_fmt(&mut self, args: std::fmt::Arguments<'_>) -> io::Result<()> {
        match self {
            Target::File(f) => f.write_fmt(args),
            Target::Stream { out, bytes, .. } => {
                let mut counted = Counted { out, bytes };
                counted.write_fmt(args)
            }
        }
    }

    /// Commits the file, or flushes the stream; returns the bytes written.
    fn finish(self) -> Result<u64, WriteError> {
        match self {
            Target::File(f) => f.commit(),
            Target::Stream {
                mut out,
                name,
                bytes,
            } => out
                .flush()
                .map(|()| bytes)
                .map_err(|source| WriteError { path: name, source }),
        }
    }
}

/// A writer that counts what goes through it.
struct Counted<'a, W> {
    out: &'a mut W,
    bytes: &'a mut u64,
}

impl<W: Write> Write for Counted<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.out.write(buf)?;
        *self.bytes += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// Writes a Wavefront OBJ file line by line. Vertex and normal indices are the 1-based
/// numbers OBJ uses, returned as each element is written.
pub struct ObjWriter {
    out: Target,
    stats: ObjStats,
}

impl ObjWriter {
    /// Starts an OBJ file that appears at `path` only when [`ObjWriter::finish`] succeeds.
    pub fn create(path: &Path) -> Result<ObjWriter, WriteError> {
        Ok(ObjWriter {
            out: Target::File(AtomicFile::create(path)?),
            stats: ObjStats::default(),
        })
    }

    /// Writes OBJ text to the stream `out` (standard output, say), buffered, named `name` in
    /// errors. What is written reaches the reader as it goes: a failure leaves it a partial
    /// file.
    pub fn stream(out: Box<dyn Write>, name: &str) -> ObjWriter {
        ObjWriter {
            out: Target::Stream {
                out: BufWriter::with_capacity(1 << 20, out),
                name: PathBuf::from(name),
                bytes: 0,
            },
            stats: ObjStats::default(),
        }
    }

    /// What has been written so far.
    pub fn stats(&self) -> ObjStats {
        ObjStats {
            bytes: self.out.bytes(),
            ..self.stats
        }
    }

    /// The vertex count so far: the index of the last vertex written.
    pub fn vertex_count(&self) -> u64 {
        self.stats.vertices
    }

    fn put(&mut self, args: std::fmt::Arguments<'_>) -> Result<(), WriteError> {
        self.out.write_fmt(args).map_err(|e| self.out.error(e))
    }

    /// One `# …` line per line of `text`.
    pub fn comment(&mut self, text: &str) -> Result<(), WriteError> {
        for line in text.lines() {
            self.put(format_args!("# {line}\n"))?;
        }
        Ok(())
    }

    /// `mtllib NAME`: the material library the faces' `usemtl` names come from.
    pub fn mtllib(&mut self, file_name: &str) -> Result<(), WriteError> {
        self.put(format_args!("mtllib {file_name}\n"))
    }

    /// `usemtl NAME`: the faces after it use that material.
    pub fn usemtl(&mut self, name: &str) -> Result<(), WriteError> {
        self.put(format_args!("usemtl {name}\n"))
    }

    /// `o NAME`: starts a named object.
    pub fn object(&mut self, name: &str) -> Result<(), WriteError> {
        self.put(format_args!("o {name}\n"))
    }

    /// `g NAME`: starts a named group (a part under the current object).
    pub fn group(&mut self, name: &str) -> Result<(), WriteError> {
        self.put(format_args!("g {name}\n"))
    }

    fn next_vertex(&mut self) -> u64 {
        self.stats.vertices += 1;
        self.stats.vertices
    }

    /// `v x y z`; generic so f64 world coordinates print at their own precision.
    pub fn vertex<T: Display>(&mut self, p: [T; 3]) -> Result<u64, WriteError> {
        let [x, y, z] = p;
        self.put(format_args!("v {x} {y} {z}\n"))?;
        Ok(self.next_vertex())
    }

    /// `v x y z r g b`, the common vertex-colour extension (colour channels 0 ..= 1).
    pub fn vertex_rgb<T: Display>(&mut self, p: [T; 3], rgb: [f32; 3]) -> Result<u64, WriteError> {
        let [x, y, z] = p;
        let [r, g, b] = rgb;
        self.put(format_args!("v {x} {y} {z} {r} {g} {b}\n"))?;
        Ok(self.next_vertex())
    }

    /// `vn x y z`; returns the normal's 1-based number.
    pub fn normal(&mut self, n: [f32; 3]) -> Result<u64, WriteError> {
        let [x, y, z] = n;
        self.put(format_args!("vn {x} {y} {z}\n"))?;
        self.stats.normals += 1;
        Ok(self.stats.normals)
    }

    /// `f a b c`: a triangle of the 1-based vertex numbers `v`.
    pub fn face(&mut self, v: [u64; 3]) -> Result<(), WriteError> {
        let [a, b, c] = v;
        self.put(format_args!("f {a} {b} {c}\n"))?;
        self.stats.faces += 1;
        Ok(())
    }

    /// `f v//n …`: a face whose corners have normals.
    pub fn face_normals(&mut self, v: [u64; 3], n: [u64; 3]) -> Result<(), WriteError> {
        let ([a, b, c], [na, nb, nc]) = (v, n);
        self.put(format_args!("f {a}//{na} {b}//{nb} {c}//{nc}\n"))?;
        self.stats.faces += 1;
        Ok(())
    }

    /// Renames the file into place (or flushes the stream); returns what was written.
    pub fn finish(self) -> Result<ObjStats, WriteError> {
        let stats = self.stats;
        let bytes = self.out.finish()?;
        Ok(ObjStats { bytes, ..stats })
    }
}

/// Writes a `.mtl` file of diffuse colours, atomically.
pub fn write_mtl<'a>(
    path: &Path,
    materials: impl IntoIterator<Item = (&'a str, [f32; 3])>,
) -> Result<AtomicFile, WriteError> {
    let mut out = AtomicFile::create(path)?;
    for (name, [r, g, b]) in materials {
        writeln!(out, "newmtl {name}\nKd {r} {g} {b}\n").map_err(|e| out.error(e))?;
    }
    Ok(out)
}

/// The `.mtl` path beside `obj` and the name an `mtllib` line uses for it.
pub fn mtl_beside(obj: &Path) -> Result<(PathBuf, String), WriteError> {
    let mtl = obj.with_extension("mtl");
    if mtl == obj {
        return Err(WriteError {
            path: obj.to_path_buf(),
            source: io::Error::new(
                io::ErrorKind::InvalidInput,
                "the model file must not have the extension .mtl (its materials go there)",
            ),
        });
    }
    let name = mtl
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok((mtl, name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_print_so_they_parse_back_bit_for_bit() -> Result<(), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let path = dir.path().join("t.obj");
        let values = [
            0.1f32,
            -0.0,
            1.0e-38,
            f32::MIN_POSITIVE / 3.0,
            3.402_823_5e38,
            16_777_217.0,
            1.0 / 3.0,
        ];
        let mut w = ObjWriter::create(&path).map_err(|e| e.to_string())?;
        for v in values {
            w.vertex([v, -v, v * 0.5]).map_err(|e| e.to_string())?;
        }
        let stats = w.finish().map_err(|e| e.to_string())?;
        let text = std::fs::read_to_string(&path).map_err(|e| e.to_string())?;
        assert_eq!(stats.bytes, text.len() as u64);
        assert_eq!(stats.vertices, values.len() as u64);
        for (line, v) in text.lines().zip(values) {
            let parsed: Vec<f32> = line
                .split_whitespace()
                .skip(1)
                .filter_map(|t| t.parse().ok())
                .collect();
            let want = [v, -v, v * 0.5];
            assert_eq!(
                parsed.iter().map(|c| c.to_bits()).collect::<Vec<_>>(),
                want.iter().map(|c| c.to_bits()).collect::<Vec<_>>(),
                "{line}"
            );
        }
        Ok(())
    }

    #[test]
    fn an_unfinished_file_leaves_nothing_and_keeps_the_old_one() -> Result<(), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let path = dir.path().join("m.obj");
        std::fs::write(&path, "old").map_err(|e| e.to_string())?;
        {
            let mut w = ObjWriter::create(&path).map_err(|e| e.to_string())?;
            w.vertex([1.0f32, 2.0, 3.0]).map_err(|e| e.to_string())?;
        }
        assert_eq!(std::fs::read_to_string(&path).ok().as_deref(), Some("old"));
        let leftovers = std::fs::read_dir(dir.path())
            .map_err(|e| e.to_string())?
            .count();
        assert_eq!(leftovers, 1);
        Ok(())
    }

    #[test]
    fn a_stream_counts_its_bytes_and_names_itself_in_errors() {
        let mut w = ObjWriter::stream(Box::new(io::sink()), "standard output");
        let v = w.vertex([1.0f32, 2.0, 3.0]).ok();
        assert_eq!(v, Some(1));
        assert_eq!(
            w.finish().ok().map(|s| s.bytes),
            Some("v 1 2 3\n".len() as u64)
        );
        struct Closed;
        impl Write for Closed {
            fn write(&mut self, _: &[u8]) -> io::Result<usize> {
                Err(io::ErrorKind::BrokenPipe.into())
            }
            fn flush(&mut self) -> io::Result<()> {
                Err(io::ErrorKind::BrokenPipe.into())
            }
        }
        let mut w = ObjWriter::stream(Box::new(Closed), "standard output");
        let e = w
            .comment("buffered")
            .and_then(|()| w.finish().map(|_| ()))
            .err();
        let e = e.map(|e| (e.source.kind(), e.to_string()));
        assert_eq!(e.as_ref().map(|e| e.0), Some(io::ErrorKind::BrokenPipe));
        assert!(e.is_some_and(|e| e.1.starts_with("standard output: ")));
    }

    #[test]
    fn a_model_named_mtl_is_refused() {
        assert!(mtl_beside(Path::new("x.mtl")).is_err());
        assert_eq!(
            mtl_beside(Path::new("dir/x.obj")).ok().map(|(_, n)| n),
            Some("x.mtl".to_string())
        );
    }
}
