//! Test-only hooks, set through environment variables, that stop a run at
//! an exact point so that the command-line tests of killing, resuming and
//! full disks are deterministic instead of racing a running process.
//! Users never need them; with none set, a run is unchanged.
//!
//! - `FLUIDTEX_TEST_FAIL_WRITE=N`: the Nth atomic write of the run (1-based,
//!   counted in the run's fixed write order) fails with `ENOSPC`, as on a
//!   full disk, after its temporary holds all its bytes.
//! - `FLUIDTEX_TEST_PAUSE_IN_WRITE=N`: in the Nth write, with its temporary
//!   on disk, print `fluidtex-test: paused in write N: <temporary>` on
//!   stderr and wait until standard input ends; a test kills the process
//!   there.
//! - `FLUIDTEX_TEST_PAUSE_AFTER_FRAME=F`: once frame F is counted finished
//!   (its files and `state.bin` written), print
//!   `fluidtex-test: paused after frame F` and wait the same way. The
//!   thread that writes frames pauses, so no later frame's file appears.
//! - `FLUIDTEX_TEST_WRITE_IN_PLACE` (any value): write each frame before
//!   computing the next, as a run without the memory for write-behind does.
//! - `FLUIDTEX_TEST_MEMORY_AVAILABLE=BYTES`: the memory available to the
//!   up-front memory check, instead of the machine's.
//! - `FLUIDTEX_TEST_RESIDENT_MEMORY=BYTES`: the resident memory the
//!   per-frame memory limit (`--max-memory`) is checked against, instead
//!   of the process's.

use std::io::BufRead;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{Context, Result};
use fluidtex::pipeline::TestHooks;

/// A positive integer from the variable `name`, if set.
fn number(name: &str) -> Result<Option<u64>> {
    match std::env::var(name) {
        Ok(v) => {
            Ok(Some(v.trim().parse().with_context(|| {
                format!("{name}={v}: expected a whole number")
            })?))
        }
        Err(_) => Ok(None),
    }
}

/// Waits until standard input ends (the test closes it or kills us).
fn wait_for_stdin_to_end() {
    let mut line = String::new();
    let stdin = std::io::stdin();
    let mut lock = stdin.lock();
    while matches!(lock.read_line(&mut line), Ok(n) if n > 0) {
        line.clear();
    }
}

/// The library hooks the variables ask for.
pub fn from_env() -> Result<TestHooks> {
    let fail = number("FLUIDTEX_TEST_FAIL_WRITE")?;
    let pause = number("FLUIDTEX_TEST_PAUSE_IN_WRITE")?;
    let write: Option<fluidtex::io::WriteHook> = if fail.is_some() || pause.is_some() {
        let count = Arc::new(AtomicU64::new(0));
        Some(Arc::new(move |_target: &Path, temporary: &Path| {
            let n = count.fetch_add(1, Ordering::SeqCst) + 1;
            if pause == Some(n) {
                eprintln!(
                    "fluidtex-test: paused in write {n}: {}",
                    temporary.display()
                );
                wait_for_stdin_to_end();
            }
            if fail == Some(n) {
                return Err(disk_full());
            }
            Ok(())
        }))
    } else {
        None
    };
    let after_frame: Option<fluidtex::pipeline::FrameHook> =
        pause_after_frame()?.map(|asked| -> fluidtex::pipeline::FrameHook {
            Arc::new(move |frame| maybe_pause_after(frame, Some(asked)))
        });
    Ok(TestHooks {
        write,
        available_memory: number("FLUIDTEX_TEST_MEMORY_AVAILABLE")?,
        after_frame,
        write_in_place: std::env::var_os("FLUIDTEX_TEST_WRITE_IN_PLACE").is_some(),
        resident_memory: number("FLUIDTEX_TEST_RESIDENT_MEMORY")?,
    })
}

/// The frame after which to pause, if asked.
fn pause_after_frame() -> Result<Option<i32>> {
    let name = "FLUIDTEX_TEST_PAUSE_AFTER_FRAME";
    match std::env::var(name) {
        Ok(v) => {
            Ok(Some(v.trim().parse().with_context(|| {
                format!("{name}={v}: expected a frame number")
            })?))
        }
        Err(_) => Ok(None),
    }
}

/// Pauses after `frame` when it is the one asked for.
fn maybe_pause_after(frame: i32, asked: Option<i32>) {
    if asked == Some(frame) {
        eprintln!("fluidtex-test: paused after frame {frame}");
        wait_for_stdin_to_end();
    }
}

/// The error a full disk gives: ENOSPC where the OS numbers it so.
fn disk_full() -> std::io::Error {
    #[cfg(unix)]
    {
        std::io::Error::from_raw_os_error(28)
    }
    #[cfg(not(unix))]
    {
        std::io::Error::new(std::io::ErrorKind::StorageFull, "No space left on device")
    }
}
