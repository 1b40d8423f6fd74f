//! The per-texel buffers of a frame, owned by whoever drives the method
//! (the driver of a run) and lent to the method through the frame's
//! context ([`super::FrameContext::arena`]).
//!
//! **Why.** At 6144² a per-texel buffer is 150–450 MB. Mapping fresh pages
//! for every frame's uv and values costs page faults that a run can avoid
//! by filling last frame's buffers again once its files are written. The
//! driver knows when a buffer is spent (the sink has what it needs) and
//! what the frame's results must carry (the uv and levels only an
//! evaluation reads, the renewal only the switch measurement reads); the
//! method only takes what the arena holds and fills it. Methods neither
//! recycle nor know what the sinks read.
//!
//! A buffer taken from the arena is refilled whole, with the value a fresh
//! one would hold, so frames are bit-identical whether or not buffers come
//! back (tested in `erosion/tests.rs`).
//!
//! The arena also lends the frame's memory budget ([`super::budget`]):
//! the driver knows the run's limit, the stages that grow count against it.

use std::sync::Mutex;

use glam::Vec2;

/// Per-texel buffers nothing reads any more: the uv and levels that only
/// an evaluation reads, and the channel values once the sink has them in
/// the form it writes.
#[derive(Debug, Default)]
pub struct SpentBuffers {
    pub uv: Option<Vec<Vec2>>,
    pub exemplar_lod: Option<Vec<f32>>,
    /// The interleaved channel values the fill wrote (the colour atlas when
    /// the exemplar has no extra channel).
    pub values: Option<Vec<f32>>,
}

/// What the results of the next frames must carry beyond the channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wants {
    /// The per-texel uv and exemplar levels
    /// ([`super::FrameResult::uv`], [`super::FrameResult::exemplar_lod`]).
    pub levels: bool,
    /// The per-texel renewal ([`super::FrameResult::renewal`]): recording
    /// it costs the erosion fill about a sixth of its time.
    pub renewal: bool,
}

impl Wants {
    /// Everything: what a method gives when nobody says otherwise.
    pub const ALL: Wants = Wants {
        levels: true,
        renewal: true,
    };
}

/// The buffers lent to a method's frame steps, and what their results must
/// carry.
#[derive(Debug)]
pub struct FrameArena {
    spare: Mutex<SpentBuffers>,
    /// Whether buffers handed back are kept for the next take; a
    /// [`FrameArena::fresh`] one (the shared [`FRESH`]) keeps none.
    keeps: bool,
    wants: Wants,
    /// The memory the frame's stages may grow to ([`super::budget`]).
    memory: super::budget::MemoryBudget,
}

/// The arena of every context built without one (tests, tools, one-off
/// frames): each frame's buffers are fresh.
pub static FRESH: FrameArena = FrameArena::fresh();

impl Default for FrameArena {
    fn default() -> FrameArena {
        FrameArena::new()
    }
}

impl FrameArena {
    /// An arena that lends nothing, keeps nothing and wants everything:
    /// [`FRESH`], the arena of a context built without one.
    pub const fn fresh() -> FrameArena {
        FrameArena {
            spare: Mutex::new(SpentBuffers {
                uv: None,
                exemplar_lod: None,
                values: None,
            }),
            keeps: false,
            wants: Wants::ALL,
            memory: super::budget::MemoryBudget::unlimited(),
        }
    }

    /// An empty arena that keeps what is handed back and wants everything.
    pub fn new() -> FrameArena {
        FrameArena {
            spare: Mutex::new(SpentBuffers::default()),
            keeps: true,
            wants: Wants::ALL,
            memory: super::budget::MemoryBudget::unlimited(),
        }
    }

    /// Sets the memory budget of the next frames' stages.
    pub fn set_memory(&mut self, memory: super::budget::MemoryBudget) {
        self.memory = memory;
    }

    /// The memory budget of this frame's stages: what the stages that grow
    /// with the patches count against ([`super::budget`]).
    pub fn memory(&self) -> &super::budget::MemoryBudget {
        &self.memory
    }

    /// Sets what the next frames' results must carry.
    pub fn set_wants(&mut self, wants: Wants) {
        self.wants = wants;
    }

    /// What this frame's result must carry.
    pub fn wants(&self) -> Wants {
        self.wants
    }

    /// Takes every spare buffer (none where none was handed back).
    pub fn take(&self) -> SpentBuffers {
        std::mem::take(&mut *self.lock())
    }

    /// Keeps `spent` for the next take, replacing what was spare of each
    /// kind it holds.
    pub fn hand_back(&self, spent: SpentBuffers) {
        if !self.keeps {
            return;
        }
        let mut spare = self.lock();
        let SpentBuffers {
            uv,
            exemplar_lod,
            values,
        } = spent;
        if uv.is_some() {
            spare.uv = uv;
        }
        if exemplar_lod.is_some() {
            spare.exemplar_lod = exemplar_lod;
        }
        if values.is_some() {
            spare.values = values;
        }
    }

    /// The spare buffers. A poisoned lock (a method that panicked while it
    /// held it) still holds buffers that any value may refill.
    fn lock(&self) -> std::sync::MutexGuard<'_, SpentBuffers> {
        self.spare.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What is handed back is what the next take gets, each kind replaced
    /// only by a buffer of its kind; a take empties the arena; the fresh
    /// arena keeps nothing (the control).
    #[test]
    fn the_arena_lends_back_what_it_was_handed() {
        let arena = FrameArena::new();
        arena.hand_back(SpentBuffers {
            uv: Some(vec![Vec2::ONE; 3]),
            exemplar_lod: None,
            values: Some(vec![1.0; 5]),
        });
        arena.hand_back(SpentBuffers {
            values: Some(vec![2.0; 7]),
            ..SpentBuffers::default()
        });
        let got = arena.take();
        assert_eq!(got.uv, Some(vec![Vec2::ONE; 3]));
        assert_eq!(got.values, Some(vec![2.0; 7]));
        assert_eq!(got.exemplar_lod, None);
        let again = arena.take();
        assert!(again.uv.is_none() && again.values.is_none());
        let fresh = FrameArena::fresh();
        fresh.hand_back(SpentBuffers {
            values: Some(vec![1.0]),
            ..SpentBuffers::default()
        });
        assert!(fresh.take().values.is_none());
        assert_eq!(fresh.wants(), Wants::ALL);
    }
}
