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
    let prefix = format!(".{name}.");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    // tempfile creates 0600 files by default and the rename keeps the mode;
    // asking for 0666 lets the umask decide, as for any new file, so that
    // others on a render farm can read the outputs.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder.tempfile_in(dir).map_err(os)?;
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

/// Removes the temporaries that a killed [`write_atomic`] left in `dir`
/// (`.<name>.<random>.tmp`); returns how many. Only names of that exact
/// shape are touched, and never one of `guard`'s inputs.
pub fn remove_stale_temporaries(dir: &Path, guard: &InputGuard) -> Result<usize, IoError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => {
            return Err(IoError::Io {
                path: dir.to_path_buf(),
                source: e,
            });
        }
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let looks_ours = name.starts_with('.')
            && name.ends_with(".tmp")
            && name[1..name.len() - 4].contains('.');
        let path = entry.path();
        if !looks_ours || !entry.file_type().is_ok_and(|t| t.is_file()) {
            continue;
        }
        if guard.check(&path).is_err() {
            continue;
        }
        std::fs::remove_file(&path).map_err(|e| IoError::Io {
            path: path.clone(),
            source: e,
        })?;
        removed += 1;
    }
    Ok(removed)
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
    fn stale_temporaries_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let keep = [
            "color.0001.png",
            ".hidden",
            "notes.tmp",
            ".input.tmp",
            ".guarded.abc.tmp",
        ];
        for k in keep {
            std::fs::write(dir.path().join(k), b"x").unwrap();
        }
        std::fs::write(dir.path().join(".color.0003.png.Xa9k2Q.tmp"), b"x").unwrap();
        std::fs::write(dir.path().join(".mesh.0002.obj.q1.tmp"), b"x").unwrap();
        let guard = InputGuard::new([dir.path().join(".guarded.abc.tmp")]);
        assert_eq!(remove_stale_temporaries(dir.path(), &guard).unwrap(), 2);
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        let mut want: Vec<String> = keep.iter().map(|s| s.to_string()).collect();
        want.sort();
        assert_eq!(names, want);
        let missing = dir.path().join("nope");
        assert_eq!(remove_stale_temporaries(&missing, &guard).unwrap(), 0);
    }

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
