//! The memory a frame's stages may grow to, checked inside the stages
//! ([`MemoryBudget`], lent through [`super::FrameArena::memory`]).
//!
//! **Why.** The run checks its resident memory after each frame
//! (`--max-memory`), but a frame's own growth can pass the whole machine
//! before that check: on a dam break at a large radius, `advect`'s
//! splitting and candidate building went from 12 GB to the kernel's
//! out-of-memory kill within one frame, with no message. The stages that
//! can grow with the patches (the advection's carry table, the splitting of
//! stretched edges, the fill's candidate pairs, lapped-rigid's receivers)
//! count the bytes they are about to hold; the budget adds them to the
//! resident set read at the frame's start, re-reads the resident set every
//! [`READ_STEP`] bytes counted, and trips once either passes the limit.
//! A tripped stage stops growing, and the method ends the frame with
//! [`super::MethodError::Memory`], which names the stage: the frame is not
//! written and `state.bin` still holds the frame before, so `--resume` with
//! a larger limit goes on from there.
//!
//! The count is an upper bound of what the stages add (transient buffers
//! are counted as if they stayed); the re-reading catches what they do
//! not count.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Bytes counted between two readings of the resident set: a reading
/// costs a read of `/proc/self/status` (tens of microseconds), so the
/// stages may count per patch and per split round.
pub const READ_STEP: u64 = 32 << 20;

/// Where a budget reads the process's resident set.
#[derive(Clone, Copy, Debug)]
pub enum Resident {
    /// Not read: the stages' own count alone (the budget of a context built
    /// without a run, which has no limit anyway).
    Unread,
    /// A reader, the process's `VmRSS` in a run.
    Read(fn() -> Option<u64>),
    /// A fixed value (a test hook): the stages' count is what grows.
    Fixed(u64),
}

/// Where a frame's growth passed the limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trip {
    /// The frame being computed.
    pub frame: i32,
    /// The stage that was growing.
    pub stage: &'static str,
    /// The resident set the budget reckoned, in bytes.
    pub resident: u64,
    /// The limit, in bytes.
    pub limit: u64,
}

/// The memory budget of a frame's stages (see the module docs).
#[derive(Debug)]
pub struct MemoryBudget {
    /// The limit in bytes; 0: none.
    limit: u64,
    resident: Resident,
    frame: AtomicU64,
    /// The resident set at the last reading.
    read: AtomicU64,
    /// Bytes counted since that reading.
    since_read: AtomicU64,
    /// Whether the frame started under the limit: one that starts above
    /// it is the after-frame check's to stop (its message says so).
    armed: AtomicU64,
    tripped: Mutex<Option<Trip>>,
}

/// The budget of a context built without a run: no limit.
pub static UNLIMITED: MemoryBudget = MemoryBudget::unlimited();

impl Default for MemoryBudget {
    fn default() -> MemoryBudget {
        MemoryBudget::unlimited()
    }
}

impl MemoryBudget {
    /// No limit: every count is accepted.
    pub const fn unlimited() -> MemoryBudget {
        MemoryBudget::new(None, Resident::Unread)
    }

    /// A budget of `limit` bytes (`None`: none), reading the resident set
    /// from `resident`.
    pub const fn new(limit: Option<u64>, resident: Resident) -> MemoryBudget {
        MemoryBudget {
            limit: match limit {
                Some(l) => l,
                None => 0,
            },
            resident,
            frame: AtomicU64::new(0),
            read: AtomicU64::new(0),
            since_read: AtomicU64::new(0),
            armed: AtomicU64::new(0),
            tripped: Mutex::new(None),
        }
    }

    /// The limit in bytes, if any.
    pub fn limit(&self) -> Option<u64> {
        (self.limit > 0).then_some(self.limit)
    }

    fn reading(&self) -> u64 {
        match self.resident {
            Resident::Unread => 0,
            Resident::Read(read) => read().unwrap_or(0),
            Resident::Fixed(bytes) => bytes,
        }
    }

    /// Starts frame `frame`: reads the resident set and forgets the last
    /// frame's count and trip.
    pub fn start_frame(&self, frame: i32) {
        if self.limit == 0 {
            return;
        }
        let now = self.reading();
        self.frame.store(frame as i64 as u64, Ordering::Relaxed);
        self.read.store(now, Ordering::Relaxed);
        self.since_read.store(0, Ordering::Relaxed);
        self.armed
            .store(u64::from(now <= self.limit), Ordering::Relaxed);
        *self.lock() = None;
    }

    /// Counts `bytes` that `stage` is about to hold; false once the frame
    /// has passed the limit (this count or an earlier one): the stage then
    /// stops growing and the method ends the frame with
    /// [`MemoryBudget::check`]. Always true without a limit.
    pub fn grow(&self, stage: &'static str, bytes: usize) -> bool {
        if self.limit == 0 {
            return true;
        }
        if self.lock().is_some() {
            return false;
        }
        if self.armed.load(Ordering::Relaxed) == 0 {
            return true;
        }
        let bytes = bytes as u64;
        let mut since = self.since_read.fetch_add(bytes, Ordering::Relaxed) + bytes;
        // A real reading already holds what was counted before it; a fixed
        // one never does, so the count keeps adding to it.
        if since >= READ_STEP && matches!(self.resident, Resident::Read(_)) {
            self.read.store(self.reading(), Ordering::Relaxed);
            self.since_read.store(0, Ordering::Relaxed);
            since = 0;
        }
        let reckoned = self.read.load(Ordering::Relaxed).saturating_add(since);
        if reckoned <= self.limit {
            return true;
        }
        let mut tripped = self.lock();
        tripped.get_or_insert(Trip {
            frame: self.frame.load(Ordering::Relaxed) as i64 as i32,
            stage,
            resident: reckoned,
            limit: self.limit,
        });
        false
    }

    /// The trip of this frame, if a stage passed the limit.
    pub fn tripped(&self) -> Option<Trip> {
        *self.lock()
    }

    /// `Err` once a stage of this frame passed the limit: the frame ends
    /// there, naming the stage.
    pub fn check(&self) -> Result<(), super::MethodError> {
        match self.tripped() {
            Some(trip) => Err(super::MethodError::Memory(trip)),
            None => Ok(()),
        }
    }

    /// The trip, under a lock that a panicking stage may have poisoned (a
    /// trip is a plain value, valid whatever the panic left).
    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Trip>> {
        self.tripped.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn growth_within_a_frame_trips_at_the_limit_and_names_the_stage() {
        let budget = MemoryBudget::new(Some(1000), Resident::Fixed(900));
        budget.start_frame(7);
        assert!(budget.grow("advection", 60));
        assert!(budget.tripped().is_none() && budget.check().is_ok());
        // 900 + 60 + 50 passes 1000.
        assert!(!budget.grow("splitting", 50));
        let trip = budget.tripped().expect("tripped");
        assert_eq!(
            trip,
            Trip {
                frame: 7,
                stage: "splitting",
                resident: 1010,
                limit: 1000
            }
        );
        // Later stages stop at once and the first stage stays named.
        assert!(!budget.grow("candidates", 1));
        assert_eq!(budget.tripped().map(|t| t.stage), Some("splitting"));
        let err = budget.check().expect_err("tripped");
        assert!(err.to_string().contains("splitting"), "{err}");
        // The next frame starts afresh.
        budget.start_frame(8);
        assert!(budget.grow("splitting", 99) && budget.check().is_ok());
    }

    #[test]
    fn no_limit_and_a_frame_started_above_it_never_trip() {
        let none = MemoryBudget::new(None, Resident::Fixed(u64::MAX));
        none.start_frame(0);
        assert!(none.grow("splitting", usize::MAX));
        assert!(UNLIMITED.grow("splitting", usize::MAX));
        // Started above the limit: the after-frame check stops that run.
        let above = MemoryBudget::new(Some(1000), Resident::Fixed(2000));
        above.start_frame(0);
        assert!(above.grow("splitting", 1 << 20) && above.tripped().is_none());
    }

    #[test]
    fn the_resident_set_is_read_again_as_the_count_grows() {
        // The real reader: a budget 64 MiB above what the process holds
        // now trips once 96 MiB more are held, which the stage counts
        // only in part (what it does not count, the reading finds).
        let Some(now) = resident() else {
            return; // no /proc here
        };
        let budget = MemoryBudget::new(Some(now + (64 << 20)), Resident::Read(resident));
        budget.start_frame(1);
        let mut held: Vec<Vec<u8>> = Vec::new();
        let mut tripped_after = None;
        for k in 0..12 {
            // 16 MiB touched, 8 MiB counted: the count alone would take
            // 24 rounds to pass 64 MiB + the reading step.
            held.push(vec![1u8; 16 << 20]);
            if !budget.grow("splitting", 8 << 20) {
                tripped_after = Some(k + 1);
                break;
            }
        }
        let rounds = tripped_after.expect("the held memory passes the limit");
        assert!(rounds <= 10, "{rounds} rounds of 16 MiB");
        assert!(held.iter().all(|h| h[0] == 1));
    }

    /// `VmRSS` of this process (as the run's reader reads it).
    fn resident() -> Option<u64> {
        let text = std::fs::read_to_string("/proc/self/status").ok()?;
        let line = text.lines().find(|l| l.starts_with("VmRSS:"))?;
        let kib: u64 = line
            .trim_start_matches("VmRSS:")
            .trim()
            .trim_end_matches("kB")
            .trim()
            .parse()
            .ok()?;
        Some(kib * 1024)
    }
}
