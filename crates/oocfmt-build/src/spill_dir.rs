//! The spill folder of one build, from its making to its removal, and the folders of builds
//! that died without removing theirs.
//!
//! A build's spill files live in a folder `.oocfmt-spill-PID-N` (beside the output, or in
//! `--tmp-dir`) holding a file `lock` on which the build keeps an exclusive advisory lock
//! (`flock`) for its whole life. The kernel drops the lock when the process ends, however it
//! ends, so a spill folder whose lock can be taken belongs to no running build: after a
//! SIGKILL or a power loss the next build in that folder finds it and removes it
//! ([`clear_stale`]). The folder is made under a staging name and renamed once locked, so no
//! scan ever sees a spill folder before its lock is held. Dropping a [`SpillDir`] removes it,
//! so every way out of a build (success, error, Ctrl-C) leaves nothing behind.

use std::fs::{self, File, OpenOptions};
use std::io;
use std::os::unix::fs::DirBuilderExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use rustix::fs::{flock, FlockOperation};

/// How every spill folder's name starts.
pub const PREFIX: &str = ".oocfmt-spill-";
/// The name a spill folder is made under, until its lock is held.
const STAGING: &str = ".oocfmt-staging-";
/// The lock file inside a spill folder.
const LOCK: &str = "lock";

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// A spill folder, locked while the value lives; dropping it removes the folder.
#[derive(Debug)]
pub struct SpillDir {
    path: PathBuf,
    /// Holds the lock; closed (and the lock released) after the folder is gone.
    lock: Option<File>,
}

impl SpillDir {
    /// Makes a fresh spill folder in `parent` and locks it.
    pub fn create(parent: &Path) -> io::Result<SpillDir> {
        loop {
            let tag = format!(
                "{}-{}",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            );
            let staging = parent.join(format!("{STAGING}{tag}"));
            match fs::DirBuilder::new().mode(0o700).create(&staging) {
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
                other => other?,
            }
            let path = parent.join(format!("{PREFIX}{tag}"));
            let made = lock_new(&staging.join(LOCK)).and_then(|lock| {
                if path.exists() {
                    return Err(io::ErrorKind::AlreadyExists.into());
                }
                fs::rename(&staging, &path)?;
                Ok(lock)
            });
            match made {
                Ok(lock) => {
                    return Ok(SpillDir {
                        path,
                        lock: Some(lock),
                    })
                }
                Err(e) => {
                    let _ = fs::remove_dir_all(&staging);
                    if e.kind() != io::ErrorKind::AlreadyExists {
                        return Err(e);
                    }
                }
            }
        }
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Removes the folder now; returns the bytes its files took.
    pub fn remove(mut self) -> u64 {
        self.remove_now()
    }

    fn remove_now(&mut self) -> u64 {
        let Some(lock) = self.lock.take() else {
            return 0;
        };
        let bytes = size(&self.path);
        let _ = fs::remove_dir_all(&self.path);
        drop(lock);
        bytes
    }
}

impl Drop for SpillDir {
    fn drop(&mut self) {
        self.remove_now();
    }
}

/// Creates the lock file at `path` and takes its lock.
fn lock_new(path: &Path) -> io::Result<File> {
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(path)?;
    flock(&file, FlockOperation::NonBlockingLockExclusive)?;
    Ok(file)
}

/// A spill folder found in a scan that no running build holds, or might not.
#[derive(Debug)]
pub enum Stale {
    /// Its lock was free: its build no longer runs, and it was removed.
    Removed {
        /// The folder.
        path: PathBuf,
        /// The bytes its files took.
        bytes: u64,
    },
    /// It has no lock file (an oocfmt from before the lock made it?), so whether its build
    /// runs cannot be told: left alone.
    Unlocked {
        /// The folder.
        path: PathBuf,
        /// The bytes its files take.
        bytes: u64,
    },
    /// Its lock was free, but removing it failed.
    Failed {
        /// The folder.
        path: PathBuf,
        /// Why.
        error: io::Error,
    },
}

impl std::fmt::Display for Stale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stale::Removed { path, bytes } => write!(
                f,
                "removed stale spill folder {} ({}) left by a build that no longer runs",
                path.display(),
                mib(*bytes)
            ),
            Stale::Unlocked { path, bytes } => write!(
                f,
                "spill folder {} ({}) has no lock file, so whether its build still runs cannot \
                 be told; remove it by hand if none does",
                path.display(),
                mib(*bytes)
            ),
            Stale::Failed { path, error } => write!(
                f,
                "cannot remove stale spill folder {}: {error}",
                path.display()
            ),
        }
    }
}

/// `bytes` in MiB, for messages.
pub fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / 1048576.0)
}

/// Removes the spill folders in `parent` whose builds no longer run (their lock can be
/// taken), and reports them with those that cannot be judged; folders whose lock is held are
/// left alone and not reported. A folder that cannot be listed reports nothing.
pub fn clear_stale(parent: &Path) -> Vec<Stale> {
    let Ok(entries) = fs::read_dir(parent) else {
        return Vec::new();
    };
    let mut found = Vec::new();
    for entry in entries.flatten() {
        let named = entry
            .file_name()
            .to_str()
            .is_some_and(|n| n.starts_with(PREFIX));
        if named && entry.file_type().is_ok_and(|t| t.is_dir()) {
            found.extend(judge(&entry.path()));
        }
    }
    found.sort_by(|a, b| key(a).cmp(key(b)));
    found
}

fn key(s: &Stale) -> &Path {
    match s {
        Stale::Removed { path, .. } | Stale::Unlocked { path, .. } | Stale::Failed { path, .. } => {
            path
        }
    }
}

/// What to do with the spill folder `dir`: `None` while its build runs (or it vanished).
fn judge(dir: &Path) -> Option<Stale> {
    let lock = match File::open(dir.join(LOCK)) {
        Ok(f) => f,
        // Gone meanwhile: its own build removed it.
        Err(_) if !dir.exists() => return None,
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            let bytes = size(dir);
            return Some(Stale::Unlocked {
                path: dir.to_path_buf(),
                bytes,
            });
        }
        Err(_) => return None,
    };
    // Held: a live build's. Other failures (no locks on this file system): not ours to judge.
    flock(&lock, FlockOperation::NonBlockingLockExclusive).ok()?;
    let bytes = size(dir);
    let path = dir.to_path_buf();
    match fs::remove_dir_all(dir) {
        Ok(()) => Some(Stale::Removed { path, bytes }),
        // Another build's scan removed it first.
        Err(e) if e.kind() == io::ErrorKind::NotFound => None,
        Err(error) => Some(Stale::Failed { path, error }),
    }
}

/// The bytes of the files under `dir` (links not followed).
fn size(dir: &Path) -> u64 {
    let Ok(entries) = fs::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => size(&e.path()),
            Ok(t) if t.is_file() => e.metadata().map_or(0, |m| m.len()),
            _ => 0,
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .map(|r| {
                r.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    }

    #[test]
    fn a_live_folder_is_kept_and_a_dead_one_removed() -> io::Result<()> {
        let tmp = tempfile::tempdir()?;
        let live = SpillDir::create(tmp.path())?;
        fs::write(live.path().join("import.soup"), [0u8; 1000])?;
        assert!(names(tmp.path()).iter().all(|n| n.starts_with(PREFIX)));
        // A dead build's folder: its lock file, unlocked, and 3 MiB of spill.
        let dead = tmp.path().join(format!("{PREFIX}dead"));
        fs::create_dir(&dead)?;
        fs::write(dead.join(LOCK), b"")?;
        fs::write(dead.join("run"), vec![0u8; 3 << 20])?;
        // An older build's, without a lock file.
        let old = tmp.path().join(format!("{PREFIX}old"));
        fs::create_dir(&old)?;
        fs::write(old.join("run"), [0u8; 10])?;
        let found = clear_stale(tmp.path());
        let text: Vec<String> = found.iter().map(ToString::to_string).collect();
        assert_eq!(found.len(), 2, "{text:?}");
        assert!(
            matches!(&found[0], Stale::Removed { path, bytes } if *path == dead && *bytes == 3 << 20),
            "{text:?}"
        );
        assert!(text[0].contains("(3.0 MiB) left by a build that no longer runs"));
        assert!(
            matches!(&found[1], Stale::Unlocked { bytes: 10, .. }),
            "{text:?}"
        );
        assert!(!dead.exists() && old.exists() && live.path().exists());
        let path = live.path().to_path_buf();
        assert_eq!(live.remove(), 1000);
        assert!(!path.exists());
        Ok(())
    }

    #[test]
    fn dropping_removes_the_folder() -> io::Result<()> {
        let tmp = tempfile::tempdir()?;
        let (a, b) = (SpillDir::create(tmp.path())?, SpillDir::create(tmp.path())?);
        assert_ne!(a.path(), b.path());
        drop((a, b));
        assert!(names(tmp.path()).is_empty());
        Ok(())
    }
}
