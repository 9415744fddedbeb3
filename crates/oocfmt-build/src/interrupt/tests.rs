//! A stop requested in each phase of a real conversion, in core and out of core: the build
//! ends with [`ConvertError::Interrupted`], leaves no spill folder or temporary output, and
//! an existing output is untouched. Also the spill folders of dead builds removed on the way
//! in, and what standard input cannot do, refused before anything is read.

use std::path::{Path, PathBuf};

use crate::convert::{convert, ConvertError, ConvertOptions, InputFormat, MIN_MEM_LIMIT};
use crate::progress::Progress;
use crate::Interrupt;
use oocfmt_meshio::import::Recentre;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

/// Requests `interrupt` when the phase `at` starts; keeps the warnings it is given.
struct StopAt<'a> {
    at: &'a str,
    interrupt: Interrupt,
    phases: Vec<String>,
    warnings: Vec<String>,
}

impl Progress for StopAt<'_> {
    fn phase(&mut self, name: &str, _total: Option<u64>) {
        self.phases.push(name.to_string());
        if name == self.at {
            self.interrupt.request();
        }
    }
    fn advance(&mut self, _done: u64) {}
    fn finish_phase(&mut self) {}
    fn warn(&mut self, message: &str) {
        self.warnings.push(message.to_string());
    }
}

/// A folder with a 30 000-triangle Mandelbulb `m.obj` and an old `out.oocf`.
fn folder() -> Result<(tempfile::TempDir, PathBuf, PathBuf), String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let obj = dir.path().join("m.obj");
    let opts = MandelbulbOptions {
        triangles: 30_000,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).map_err(|e| e.to_string())?;
    let out = dir.path().join("out.oocf");
    std::fs::write(&out, b"the old output").map_err(|e| e.to_string())?;
    Ok((dir, obj, out))
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

fn options(mem_limit: u64, interrupt: &Interrupt) -> ConvertOptions {
    ConvertOptions {
        mem_limit,
        interrupt: interrupt.clone(),
        ..ConvertOptions::default()
    }
}

#[test]
fn a_stop_in_any_phase_leaves_nothing_behind() -> Result<(), String> {
    let (dir, obj, out) = folder()?;
    let cases = [
        (MIN_MEM_LIMIT, "import"),
        (MIN_MEM_LIMIT, "split"),
        (MIN_MEM_LIMIT, "chunks"),
        (MIN_MEM_LIMIT, "write"),
        (4 << 30, "kd-tree"),
        (4 << 30, "write"),
    ];
    for (limit, at) in cases {
        let interrupt = Interrupt::new();
        let mut progress = StopAt {
            at,
            interrupt: interrupt.clone(),
            phases: Vec::new(),
            warnings: Vec::new(),
        };
        let r = convert(
            std::slice::from_ref(&obj),
            &out,
            &options(limit, &interrupt),
            &mut progress,
        );
        let case = format!("{at} at {limit} bytes: {:?}", progress.phases);
        match r {
            Err(ConvertError::Interrupted { spill_bytes, .. }) => {
                assert!(spill_bytes > 0 || at != "chunks", "{case}")
            }
            other => panic!("{case}: {other:?}"),
        }
        assert!(progress.phases.iter().any(|p| p == at), "{case}");
        assert_eq!(names(dir.path()), ["m.obj", "out.oocf"], "{case}");
        let old = std::fs::read(&out).map_err(|e| e.to_string())?;
        assert_eq!(old, b"the old output", "{case}");
    }
    // Unasked, the same build succeeds and replaces the output.
    let interrupt = Interrupt::new();
    let mut progress = StopAt {
        at: "none",
        interrupt: interrupt.clone(),
        phases: Vec::new(),
        warnings: Vec::new(),
    };
    convert(
        &[obj],
        &out,
        &options(MIN_MEM_LIMIT, &interrupt),
        &mut progress,
    )
    .map_err(|e| e.to_string())?;
    assert_eq!(names(dir.path()), ["m.obj", "out.oocf"]);
    Ok(())
}

#[test]
fn a_dead_builds_spill_folder_is_removed_and_reported() -> Result<(), String> {
    let (dir, obj, out) = folder()?;
    let dead = dir.path().join(".oocfmt-spill-dead");
    std::fs::create_dir(&dead).map_err(|e| e.to_string())?;
    std::fs::write(dead.join("lock"), b"").map_err(|e| e.to_string())?;
    std::fs::write(dead.join("import.soup"), vec![0u8; 1 << 20]).map_err(|e| e.to_string())?;
    let mut progress = StopAt {
        at: "none",
        interrupt: Interrupt::new(),
        phases: Vec::new(),
        warnings: Vec::new(),
    };
    convert(&[obj], &out, &ConvertOptions::default(), &mut progress).map_err(|e| e.to_string())?;
    assert!(!dead.exists());
    let w = progress.warnings.join("\n");
    assert!(
        w.contains(".oocfmt-spill-dead (1.0 MiB) left by a build that no longer runs"),
        "{w}"
    );
    Ok(())
}

#[test]
fn standard_input_is_refused_where_it_cannot_serve() {
    let stdin = PathBuf::from("-");
    let out = Path::new("never.oocf");
    let run = |inputs: &[PathBuf], format: Option<InputFormat>, recentre: Recentre| {
        let opts = ConvertOptions {
            format,
            recentre,
            ..ConvertOptions::default()
        };
        convert(inputs, out, &opts, &mut crate::progress::NoProgress).err()
    };
    let one = std::slice::from_ref(&stdin);
    let none = Recentre::default();
    assert!(matches!(
        run(one, None, none),
        Some(ConvertError::StdinFormat)
    ));
    let gltf = Some(InputFormat::Gltf);
    assert!(matches!(
        run(one, gltf, none),
        Some(ConvertError::StdinGltf)
    ));
    let obj = Some(InputFormat::Obj);
    let two = [stdin.clone(), stdin.clone()];
    assert!(matches!(
        run(&two, obj, none),
        Some(ConvertError::StdinTwice)
    ));
    let auto = Recentre::Auto;
    assert!(matches!(
        run(one, obj, auto),
        Some(ConvertError::StdinRecentre)
    ));
    assert!(!out.exists());
}
