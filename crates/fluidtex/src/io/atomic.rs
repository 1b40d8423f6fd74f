//! Atomic file writing and protection of a run's inputs.
//!
//! Every output is written to a temporary file in the target's directory
//! (same file system, so the rename is atomic), flushed and synced, then
//! renamed over the target. A run killed at any point leaves either the old
//! file or the new one, never half of one; stray temporaries are named
//! `.<name>.<random>.tmp` and removed on error. The temp-file handling is
//! the `tempfile` crate's.

use std::collections::HashSet;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::IoError;

/// Writes `path` atomically: `write` fills a buffered temp file that then
/// replaces `path`. The writer is seekable (EXR needs that).
pub fn write_atomic<F>(path: &Path, write: F) -> Result<(), IoError>
where
    F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
{
    let os = |e: std::io::Error| IoError::Io {
        path: path.to_path_buf(),
        source: e,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| IoError::Unwritable {
            path: path.to_path_buf(),
            reason: "not a file name".into(),
        })?
        .to_string_lossy();
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".{name}."))
        .suffix(".tmp")
        .tempfile_in(dir)
        .map_err(os)?;
    let (file, tmp_path) = tmp.into_parts();
    let mut w = BufWriter::with_capacity(1 << 20, file);
    write(&mut w).map_err(os)?;
    w.flush().map_err(os)?;
    let file = w.into_inner().map_err(|e| os(e.into_error()))?;
    file.sync_all().map_err(os)?;
    drop(file);
    tmp_path.persist(path).map_err(|e| os(e.error))?;
    // Make the rename itself durable; not all platforms can sync a directory.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// The set of a run's input files; outputs must not be any of them.
#[derive(Clone, Debug, Default)]
pub struct InputGuard {
    inputs: HashSet<PathBuf>,
}

impl InputGuard {
    /// Guards the given input paths (canonicalized; symlinks resolved).
    pub fn new<P: AsRef<Path>>(inputs: impl IntoIterator<Item = P>) -> InputGuard {
        let mut g = InputGuard::default();
        for p in inputs {
            g.add(p.as_ref());
        }
        g
    }

    /// Adds one more input.
    pub fn add(&mut self, input: &Path) {
        self.inputs.insert(canonical(input));
    }

    /// Number of guarded inputs.
    pub fn len(&self) -> usize {
        self.inputs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty()
    }

    /// Errors when writing `output` would replace one of the inputs.
    pub fn check(&self, output: &Path) -> Result<(), IoError> {
        if self.inputs.contains(&canonical(output)) {
            return Err(IoError::OverwritesInput {
                path: output.to_path_buf(),
            });
        }
        Ok(())
    }

    /// [`InputGuard::check`], then [`write_atomic`].
    pub fn write_atomic<F>(&self, path: &Path, write: F) -> Result<(), IoError>
    where
        F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
    {
        self.check(path)?;
        write_atomic(path, write)
    }
}

/// Canonical form of a path that may not exist yet: the canonical parent
/// joined with the file name (or the absolute path if the parent is missing).
fn canonical(p: &Path) -> PathBuf {
    if let Ok(c) = p.canonicalize() {
        return c;
    }
    let parent = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (parent.canonicalize(), p.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_and_replaces_without_leaving_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.txt");
        write_atomic(&out, |w| w.write_all(b"one")).unwrap();
        write_atomic(&out, |w| w.write_all(b"two")).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.txt")]);
    }

    #[test]
    fn a_failing_writer_keeps_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.txt");
        std::fs::write(&out, b"old").unwrap();
        let err = write_atomic(&out, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("killed"))
        })
        .unwrap_err();
        assert!(err.to_string().ends_with("a.txt: killed"), "{err}");
        assert_eq!(std::fs::read(&out).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn guard_refuses_inputs_through_other_spellings_and_symlinks() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("fluid.0001.ply");
        std::fs::write(&input, b"x").unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let guard = InputGuard::new([&input]);
        let spelled = sub.join("..").join("fluid.0001.ply");
        assert!(matches!(
            guard.check(&spelled),
            Err(IoError::OverwritesInput { .. })
        ));
        #[cfg(unix)]
        {
            let link = dir.path().join("link.ply");
            std::os::unix::fs::symlink(&input, &link).unwrap();
            assert!(guard.check(&link).is_err());
        }
        assert!(guard.check(&dir.path().join("fluid.0001.obj")).is_ok());
        assert!(guard.check(&dir.path().join("new/x.obj")).is_ok());
        let err = guard
            .write_atomic(&input, |w| w.write_all(b"y"))
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "{}: refusing to overwrite an input of this run",
                input.display()
            )
        );
        assert_eq!(std::fs::read(&input).unwrap(), b"x");
    }
}
