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

/// A test hook called by [`Staging::write`] for every file, once its
/// temporary holds all its bytes (flushed, not yet synced or renamed), with
/// the target and the temporary path. Returning an error makes that write
/// fail as the OS would (e.g. `ENOSPC`); blocking in it holds the run inside
/// a write so that a test can kill it there. Front ends leave it unset.
pub type WriteHook = std::sync::Arc<dyn Fn(&Path, &Path) -> std::io::Result<()> + Send + Sync>;

/// Writes `path` atomically: `write` fills a buffered temp file that then
/// replaces `path`. The writer is seekable (EXR needs that).
pub fn write_atomic<F>(path: &Path, write: F) -> Result<(), IoError>
where
    F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
{
    let mut files = Staging::new(None, None);
    files.write(path, write)?;
    files.commit()
}

/// A group of files that appear together or not at all: each
/// [`Staging::write`] fills and syncs a temporary beside its target;
/// [`Staging::commit`] renames them all, in the order written. Dropping a
/// staging that was not committed removes its temporaries, so a failed
/// write (a full disk) leaves none of the group's files behind, and the
/// old versions of the targets stay as they were.
///
/// The pipeline stages every file of a frame, commits, and only then
/// records the frame as finished in `state.bin`; a run that stops between
/// the renames has not counted the frame, so `--resume` redoes it.
pub struct Staging<'a> {
    guard: Option<&'a InputGuard>,
    hook: Option<&'a WriteHook>,
    staged: Vec<(tempfile::TempPath, PathBuf)>,
}

impl<'a> Staging<'a> {
    /// An empty group; `guard` refuses targets that are inputs of the run,
    /// `hook` is the test hook (see [`WriteHook`]).
    pub fn new(guard: Option<&'a InputGuard>, hook: Option<&'a WriteHook>) -> Staging<'a> {
        Staging {
            guard,
            hook,
            staged: Vec::new(),
        }
    }

    /// Writes `path`'s temporary through `write`, synced, not yet renamed.
    pub fn write<F>(&mut self, path: &Path, write: F) -> Result<(), IoError>
    where
        F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
    {
        if let Some(guard) = self.guard {
            guard.check(path)?;
        }
        let os = |e: std::io::Error| IoError::Io {
            path: path.to_path_buf(),
            source: e,
        };
        let dir = parent_dir(path);
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
        // tempfile creates 0600 files by default and the rename keeps the
        // mode; asking for 0666 lets the umask decide, as for any new file,
        // so that others on a render farm can read the outputs.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let tmp = builder.tempfile_in(dir).map_err(os)?;
        let (file, tmp_path) = tmp.into_parts();
        // From here on the temporary is removed on any error (TempPath's drop).
        let mut w = BufWriter::with_capacity(1 << 20, file);
        write(&mut w).map_err(os)?;
        w.flush().map_err(os)?;
        let file = w.into_inner().map_err(|e| os(e.into_error()))?;
        if let Some(hook) = self.hook {
            hook(path, &tmp_path).map_err(os)?;
        }
        file.sync_all().map_err(os)?;
        drop(file);
        self.staged.push((tmp_path, path.to_path_buf()));
        Ok(())
    }

    /// Renames every staged temporary over its target, in order, then
    /// makes the renames durable. A failure part-way leaves the targets
    /// renamed so far and removes the other temporaries.
    pub fn commit(self) -> Result<(), IoError> {
        let mut dirs: Vec<PathBuf> = Vec::new();
        for (tmp, path) in self.staged {
            tmp.persist(&path).map_err(|e| IoError::Io {
                path: path.clone(),
                source: e.error,
            })?;
            let dir = parent_dir(&path).to_path_buf();
            if !dirs.contains(&dir) {
                dirs.push(dir);
            }
        }
        // Not all platforms can sync a directory; the data is synced anyway.
        for dir in dirs {
            if let Ok(d) = File::open(&dir) {
                let _ = d.sync_all();
            }
        }
        Ok(())
    }
}

/// The folder a temporary for `path` goes in: the target's own.
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Removes the temporaries that a killed [`write_atomic`] left in `dir`
/// (`.<name>.<random>.tmp`); returns how many. Only names of that exact
/// shape are touched, and never one of `guard`'s inputs.
pub fn remove_stale_temporaries(dir: &Path, guard: &InputGuard) -> Result<usize, IoError> {
    remove_stale_temporaries_of(dir, guard, |_| true)
}

/// [`remove_stale_temporaries`] of the files whose name `of` accepts
/// only (`of` gets the name of the file a temporary was to replace): a
/// run that shares its folder with others (the phases of a two-phase
/// run) removes what it left itself, never another's files in flight.
pub fn remove_stale_temporaries_of(
    dir: &Path,
    guard: &InputGuard,
    of: impl Fn(&str) -> bool,
) -> Result<usize, IoError> {
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
            && name[1..name.len() - 4]
                .rsplit_once('.')
                .is_some_and(|(target, _)| of(target));
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
    fn a_run_sharing_its_folder_removes_only_its_own_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let names = [
            ".colour.0003.png.Xa9k2Q.tmp",
            ".colour.0004.png.b7.tmp",
            ".selection.0003.bin.q1.tmp",
        ];
        for n in names {
            std::fs::write(dir.path().join(n), b"x").unwrap();
        }
        let guard = InputGuard::default();
        let mine = |target: &str| target.contains(".0003.") && !target.starts_with("selection.");
        assert_eq!(
            remove_stale_temporaries_of(dir.path(), &guard, mine).unwrap(),
            1
        );
        assert!(!dir.path().join(names[0]).exists());
        assert!(dir.path().join(names[1]).exists());
        assert!(dir.path().join(names[2]).exists());
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
    fn a_group_appears_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.png"), dir.path().join("b.obj"));
        std::fs::write(&a, b"old a").unwrap();
        let listing = || {
            let mut n: Vec<String> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect();
            n.sort();
            n
        };
        // The second write fails as on a full disk: nothing of the group
        // appears, the old file stays, no temporary is left.
        let fail_second: WriteHook = std::sync::Arc::new(|target: &Path, tmp: &Path| {
            assert!(tmp.is_file(), "the hook sees the temporary");
            if target.ends_with("b.obj") {
                return Err(std::io::Error::from(std::io::ErrorKind::StorageFull));
            }
            Ok(())
        });
        let mut files = Staging::new(None, Some(&fail_second));
        files.write(&a, |w| w.write_all(b"new a")).unwrap();
        assert_eq!(
            std::fs::read(&a).unwrap(),
            b"old a",
            "not renamed before commit"
        );
        let err = files.write(&b, |w| w.write_all(b"new b")).unwrap_err();
        assert!(
            err.to_string().starts_with(&format!("{}: ", b.display())),
            "{err}"
        );
        drop(files);
        assert_eq!(listing(), ["a.png"]);
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        // Without the fault both appear on commit.
        let mut files = Staging::new(None, None);
        files.write(&a, |w| w.write_all(b"new a")).unwrap();
        files.write(&b, |w| w.write_all(b"new b")).unwrap();
        files.commit().unwrap();
        assert_eq!(listing(), ["a.png", "b.obj"]);
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
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
