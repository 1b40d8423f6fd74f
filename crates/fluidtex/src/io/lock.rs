//! One writer per output folder.
//!
//! A run holds `fluidtex.lock` in its output folder from start to end. The
//! file names the holder (pid, host, start time) so that a refused run can
//! say who writes there; the exclusion itself is the operating system's
//! advisory lock on the open file (`flock` on Unix, `LockFileEx` on
//! Windows, through [`std::fs::File::try_lock`]):
//!
//! - a second run finds the lock held and refuses at once, naming the
//!   folder and the holder;
//! - the kernel drops the lock of a process that dies however it dies
//!   (SIGKILL, power loss of a client on a network file system), so a lock
//!   file left by a killed run is recognised as stale by taking the lock,
//!   with no guess about whether a pid is alive or reused, and taken over:
//!   its content is replaced while we hold the lock, so two runs that find
//!   the same stale file cannot both take it;
//! - on release the file is unlinked *before* it is unlocked, and a run that
//!   gets the lock checks that the path still names the file it locked
//!   (else it opened a file that the previous holder just unlinked, and it
//!   tries again), so unlink and create never race into two holders.
//!
//! Where the file system has no advisory locks (`Unsupported`), the lock
//! falls back to the file's content: a holder on this host whose pid is
//! gone (no `/proc/<pid>`) is stale, any other holder is respected.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use super::IoError;

/// The lock file's name inside the output folder.
pub const LOCK_FILE: &str = "fluidtex.lock";

/// Who holds (or held) a lock, as written in the lock file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LockOwner {
    pub pid: u32,
    pub host: String,
    /// Start of the holding run, seconds since the Unix epoch.
    pub started: u64,
}

impl LockOwner {
    /// This process.
    pub fn this_process() -> LockOwner {
        LockOwner {
            pid: std::process::id(),
            host: hostname(),
            started: now_seconds(),
        }
    }

    fn to_text(&self) -> String {
        format!(
            "pid {}\nhost {}\nstarted {}\n",
            self.pid, self.host, self.started
        )
    }

    /// Parses the lock file's text; `None` for an empty or foreign file.
    fn parse(text: &str) -> Option<LockOwner> {
        let mut pid = None;
        let mut host = None;
        let mut started = None;
        for line in text.lines() {
            match line.split_once(' ') {
                Some(("pid", v)) => pid = v.trim().parse().ok(),
                Some(("host", v)) => host = Some(v.trim().to_string()),
                Some(("started", v)) => started = v.trim().parse().ok(),
                _ => {}
            }
        }
        Some(LockOwner {
            pid: pid?,
            host: host?,
            started: started.unwrap_or(0),
        })
    }

    /// "pid 4242 on host farm07, started 37 s ago".
    pub fn describe(&self) -> String {
        let age = now_seconds().saturating_sub(self.started);
        format!(
            "pid {} on host {}, started {age} s ago",
            self.pid, self.host
        )
    }
}

/// The held lock of an output folder; released (file removed, lock dropped)
/// when dropped, on success and on error alike.
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
    file: Option<File>,
}

/// What [`OutputLock::acquire`] found.
#[derive(Debug)]
pub struct Acquired {
    pub lock: OutputLock,
    /// The holder named in a lock file that a killed run left behind, now
    /// taken over.
    pub stale: Option<LockOwner>,
}

impl OutputLock {
    /// Takes the lock of `dir` (which must exist), or refuses with
    /// [`IoError::Locked`] naming the run that holds it.
    pub fn acquire(dir: &Path) -> Result<Acquired, IoError> {
        OutputLock::acquire_named(dir, LOCK_FILE)
    }

    /// [`OutputLock::acquire`] of the lock file `name` in `dir`: a lock of
    /// part of the folder's work (the resampling of a range of frames),
    /// which runs beside other parts.
    pub fn acquire_named(dir: &Path, name: &str) -> Result<Acquired, IoError> {
        let path = dir.join(name);
        let os = |e: std::io::Error| IoError::Io {
            path: path.clone(),
            source: e,
        };
        // A few rounds only cover a holder that releases while we open.
        for _ in 0..8 {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(os)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(IoError::Locked {
                        dir: dir.to_path_buf(),
                        holder: read_owner(&mut file)
                            .map(|o| o.describe())
                            .unwrap_or_else(|| "a run that is starting".into()),
                    });
                }
                Err(std::fs::TryLockError::Error(e))
                    if e.kind() == std::io::ErrorKind::Unsupported =>
                {
                    return acquire_without_os_lock(dir, &path, file);
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(os(e)),
            }
            if !same_file(&file, &path) {
                continue; // the previous holder unlinked it meanwhile
            }
            let stale = read_owner(&mut file);
            write_owner(&mut file).map_err(os)?;
            return Ok(Acquired {
                lock: OutputLock {
                    path,
                    file: Some(file),
                },
                stale,
            });
        }
        Err(IoError::Locked {
            dir: dir.to_path_buf(),
            holder: "runs that keep starting and ending".into(),
        })
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Unlink first, unlock second (see the module notes).
        let _ = std::fs::remove_file(&self.path);
        if let Some(f) = self.file.take() {
            let _ = f.unlock();
        }
    }
}

/// The fallback where the file system has no advisory locks.
fn acquire_without_os_lock(dir: &Path, path: &Path, mut file: File) -> Result<Acquired, IoError> {
    let stale = read_owner(&mut file);
    if let Some(owner) = &stale {
        let alive = owner.host != hostname() || pid_alive(owner.pid) != Some(false);
        if alive && owner.pid != std::process::id() {
            return Err(IoError::Locked {
                dir: dir.to_path_buf(),
                holder: owner.describe(),
            });
        }
    }
    write_owner(&mut file).map_err(|e| IoError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    Ok(Acquired {
        lock: OutputLock {
            path: path.to_path_buf(),
            file: Some(file),
        },
        stale,
    })
}

fn read_owner(file: &mut File) -> Option<LockOwner> {
    let mut text = String::new();
    file.rewind().ok()?;
    // A lock file is a few dozen bytes; never read an odd large one whole.
    file.take(4096).read_to_string(&mut text).ok()?;
    LockOwner::parse(&text)
}

fn write_owner(file: &mut File) -> std::io::Result<()> {
    file.set_len(0)?;
    file.rewind()?;
    file.write_all(LockOwner::this_process().to_text().as_bytes())?;
    file.sync_all()
}

/// Whether `file` is still the file at `path`.
fn same_file(file: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (file.metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        // Windows cannot unlink an open file, so the path cannot move away.
        let _ = (file, path);
        true
    }
}

/// Whether process `pid` of this host is alive: `None` where it cannot be
/// told (no `/proc`).
pub fn pid_alive(pid: u32) -> Option<bool> {
    if !Path::new("/proc/self").exists() {
        return None;
    }
    Some(Path::new(&format!("/proc/{pid}")).exists())
}

/// This machine's name: the kernel's on Linux, else the usual variables.
pub fn hostname() -> String {
    let from_kernel = std::fs::read_to_string("/proc/sys/kernel/hostname").ok();
    let name = from_kernel
        .or_else(|| std::env::var("HOSTNAME").ok())
        .or_else(|| std::env::var("COMPUTERNAME").ok())
        .unwrap_or_default();
    // One token: the lock file is `key value` lines.
    let name: String = name.split_whitespace().collect::<Vec<_>>().join("_");
    if name.is_empty() {
        "unknown".into()
    } else {
        name
    }
}

fn now_seconds() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_with_the_first_named() {
        let dir = tempfile::tempdir().unwrap();
        let first = OutputLock::acquire(dir.path()).unwrap();
        assert!(first.stale.is_none());
        let text = std::fs::read_to_string(dir.path().join(LOCK_FILE)).unwrap();
        let owner = LockOwner::parse(&text).unwrap();
        assert_eq!(owner.pid, std::process::id());
        assert_eq!(owner.host, hostname());
        // The OS lock is per open file, so this refuses within one process too.
        let err = OutputLock::acquire(dir.path()).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!(
                "{}: another fluidtex run is writing here (pid {} on host {}, started ",
                dir.path().display(),
                std::process::id(),
                hostname()
            )),
            "{msg}"
        );
        drop(first);
        assert!(!dir.path().join(LOCK_FILE).exists(), "released on drop");
        let again = OutputLock::acquire(dir.path()).unwrap();
        assert!(again.stale.is_none());
    }

    #[test]
    fn a_lock_file_left_by_a_dead_run_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        // What a SIGKILLed run leaves: the file, no OS lock.
        std::fs::write(
            dir.path().join(LOCK_FILE),
            "pid 999999999\nhost elsewhere\nstarted 12\n",
        )
        .unwrap();
        let got = OutputLock::acquire(dir.path()).unwrap();
        assert_eq!(
            got.stale,
            Some(LockOwner {
                pid: 999_999_999,
                host: "elsewhere".into(),
                started: 12
            })
        );
        let text = std::fs::read_to_string(got.lock.path()).unwrap();
        assert_eq!(
            LockOwner::parse(&text).map(|o| o.pid),
            Some(std::process::id())
        );
        // A damaged lock file is taken over too, with no holder to name.
        drop(got);
        std::fs::write(dir.path().join(LOCK_FILE), b"\xff\x00garbage").unwrap();
        assert!(OutputLock::acquire(dir.path()).unwrap().stale.is_none());
    }

    #[test]
    fn pid_liveness_on_linux() {
        if pid_alive(1).is_none() {
            return; // no /proc here
        }
        assert_eq!(pid_alive(std::process::id()), Some(true));
        assert_eq!(pid_alive(u32::MAX), Some(false));
    }
}
