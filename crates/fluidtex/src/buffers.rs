//! Atlas-sized buffers handed back when a frame is done with them, for the
//! next frame to fill again instead of asking the system for fresh memory.
//!
//! At a 6144² atlas a frame's per-texel buffers (exemplar values, source
//! ids, patch uv, mip levels) are about 1 GB. Allocations that large are
//! fresh pages every frame: the kernel maps and zeroes each 4 KB page on
//! its first touch and unmaps it on free, and on the 2-core machine that
//! page-fault work showed as a tenth of the CPU time of a `run`. A buffer
//! given back here keeps its pages; the next [`Pool::take`] refills it in
//! parallel and hands it out.
//!
//! **Same bits.** [`Pool::take`] returns exactly `n` copies of the value
//! asked for, whatever buffer it reuses, so a frame's results do not depend
//! on whether, or which, buffers were recycled (nor on the thread count).
//!
//! **Bounded.** A pool keeps at most [`KEEP`] buffers per element type and
//! by default only buffers of at least [`MIN_LEN`] elements (small ones cost the
//! allocator nothing worth saving). With write-behind two frames are alive
//! at once, each with its own set; the pool holds what one frame gave back
//! until the next takes it, so memory stays that of two frames.
//!
//! A `Mutex<Vec<Vec<T>>>` per type is the whole mechanism: buffers change
//! hands a few times per frame, so the lock is never contended enough to
//! matter, and no object-pool crate fits buffers whose length changes with
//! the atlas size.

use std::sync::Mutex;

use glam::Vec2;
use rayon::prelude::*;

/// Buffers shorter than this are not kept (1 Mi elements: a 1024² atlas).
pub const MIN_LEN: usize = 1 << 20;
/// Buffers kept per element type, at most.
pub const KEEP: usize = 6;

/// Given-back buffers of one element type.
#[derive(Debug)]
pub struct Pool<T> {
    free: Mutex<Vec<Vec<T>>>,
    min_len: usize,
}

impl<T> Default for Pool<T> {
    fn default() -> Self {
        Pool::keeping(MIN_LEN)
    }
}

impl<T> Pool<T> {
    /// A pool that keeps buffers of at least `min_len` elements (the
    /// default is [`MIN_LEN`]; tests with small atlases set less).
    pub fn keeping(min_len: usize) -> Pool<T> {
        Pool {
            free: Mutex::new(Vec::new()),
            min_len,
        }
    }
}

impl<T: Copy + Send + Sync> Pool<T> {
    /// `n` copies of `value`, in a given-back buffer when one holds at
    /// least `n` (the smallest such), else in a new one.
    pub fn take(&self, n: usize, value: T) -> Vec<T> {
        let reused = (n >= self.min_len)
            .then(|| {
                let mut free = self.free.lock().ok()?;
                let best = free
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| v.capacity() >= n)
                    .min_by_key(|(_, v)| v.capacity())
                    .map(|(i, _)| i)?;
                Some(free.swap_remove(best))
            })
            .flatten();
        match reused {
            Some(mut v) => {
                v.truncate(n);
                v.par_chunks_mut(1 << 16).for_each(|c| c.fill(value));
                // A shorter buffer with room grows into pages it already
                // owns.
                if v.len() < n {
                    let len = v.len();
                    v.par_extend(rayon::iter::repeat_n(value, n - len));
                }
                v
            }
            None => fresh(n, value),
        }
    }

    /// Keeps `buffer` for a later [`Pool::take`] (drops it when it is
    /// small or the pool is full).
    pub fn give(&self, buffer: Vec<T>) {
        if buffer.capacity() < self.min_len || buffer.capacity() == 0 {
            return;
        }
        if let Ok(mut free) = self.free.lock()
            && free.len() < KEEP
        {
            free.push(buffer);
        }
    }

    /// Buffers held now.
    pub fn held(&self) -> usize {
        self.free.lock().map_or(0, |f| f.len())
    }
}

/// One [`Pool`] per element type the per-texel buffers use.
#[derive(Debug, Default)]
pub struct Buffers {
    pub f32: Pool<f32>,
    pub u32: Pool<u32>,
    pub vec2: Pool<Vec2>,
}

impl Buffers {
    /// Pools that keep buffers of at least `min_len` elements.
    pub fn keeping(min_len: usize) -> Buffers {
        Buffers {
            f32: Pool::keeping(min_len),
            u32: Pool::keeping(min_len),
            vec2: Pool::keeping(min_len),
        }
    }
}

/// `n` copies of `value` from `pool` ([`Pool::take`]), or in fresh memory
/// when there is no pool (tests, one-off tools): the same vector either way.
pub fn take_from<T: Copy + Send + Sync>(pool: Option<&Pool<T>>, n: usize, value: T) -> Vec<T> {
    match pool {
        Some(pool) => pool.take(n, value),
        None => fresh(n, value),
    }
}

/// `n` copies of `value` in new memory, written on every core (a 450 MB
/// buffer filled by one thread showed in every frame's time).
fn fresh<T: Copy + Send + Sync>(n: usize, value: T) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    v.par_extend(rayon::iter::repeat_n(value, n));
    v
}

#[cfg(test)]
mod tests;
