//! The uncovered texels a coverage-driven insertion still has to close.
//!
//! Both lapped methods insert new patches *below* the existing ones at the
//! first uncovered texel in texel order, then let the new patch close what
//! it can; only uncovered texels on the fluid triangles the new patch
//! reaches need a second look. This is the bookkeeping of that loop: which
//! texels are still open, the next seed, and the texels of one triangle.

use std::collections::HashMap;

/// Open/closed state of a list of uncovered texels (indices into it).
pub struct Pending {
    closed: Vec<bool>,
    /// Open texels that may no longer seed a patch ([`Pending::retire`]).
    retired: Vec<bool>,
    by_triangle: HashMap<u32, Vec<u32>>,
    cursor: usize,
    /// Random seeds: the texels that may still be open and unretired,
    /// pruned lazily as they are drawn.
    candidates: Option<Vec<u32>>,
}

impl Pending {
    /// All open; `triangles` gives each texel's fluid triangle, in the
    /// list's (texel) order.
    pub fn new(triangles: impl IntoIterator<Item = u32>) -> Pending {
        let mut by_triangle: HashMap<u32, Vec<u32>> = HashMap::new();
        let mut n = 0usize;
        for (k, f) in triangles.into_iter().enumerate() {
            by_triangle.entry(f).or_default().push(k as u32);
            n += 1;
        }
        Pending {
            closed: vec![false; n],
            retired: vec![false; n],
            by_triangle,
            cursor: 0,
            candidates: None,
        }
    }

    fn can_seed(&self, k: usize) -> bool {
        !self.closed[k] && !self.retired[k]
    }

    /// The first open texel that may seed (the next seed); `None` once all
    /// are closed or retired.
    pub fn next_open(&mut self) -> Option<usize> {
        while self.cursor < self.closed.len() && !self.can_seed(self.cursor) {
            self.cursor += 1;
        }
        (self.cursor < self.closed.len()).then_some(self.cursor)
    }

    /// An open texel that may seed, drawn uniformly by `rng` among them
    /// (the 2016 paper's random distribution over the uncovered area: the
    /// texels of an atlas chart are spread evenly over the surface);
    /// `None` once all are closed or retired. Each texel is dropped from
    /// the draw once it is found closed, so a frame's draws cost about one
    /// pass over the list.
    pub fn random_open(&mut self, rng: &mut impl rand::Rng) -> Option<usize> {
        let n = self.closed.len() as u32;
        let candidates = self.candidates.get_or_insert_with(|| (0..n).collect());
        while !candidates.is_empty() {
            let i = rng.random_range(0..candidates.len());
            let k = candidates[i] as usize;
            if !self.closed[k] && !self.retired[k] {
                return Some(k);
            }
            candidates.swap_remove(i);
        }
        None
    }

    /// Texel `k` stays open (later patches may still complete it) but no
    /// longer seeds one.
    pub fn retire(&mut self, k: usize) {
        if let Some(r) = self.retired.get_mut(k) {
            *r = true;
        }
    }

    /// The texels still open, in list order.
    pub fn open(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.closed.len()).filter(|&k| !self.closed[k])
    }

    /// Calls `visit` on every open texel of fluid triangle `f`, in texel
    /// order, and closes those for which it returns true.
    pub fn visit_open(&mut self, f: u32, mut visit: impl FnMut(usize) -> bool) {
        let Some(texels) = self.by_triangle.get(&f) else {
            return;
        };
        for &k in texels {
            let k = k as usize;
            if !self.closed[k] && visit(k) {
                self.closed[k] = true;
            }
        }
    }

    /// The fluid triangles that hold any of the texels, open or not, in
    /// increasing order.
    pub fn triangles(&self) -> Vec<u32> {
        let mut t: Vec<u32> = self.by_triangle.keys().copied().collect();
        t.sort_unstable();
        t
    }

    pub fn is_closed(&self, k: usize) -> bool {
        self.closed.get(k).copied().unwrap_or(true)
    }

    pub fn close(&mut self, k: usize) {
        if let Some(c) = self.closed.get_mut(k) {
            *c = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Pending;

    #[test]
    fn hands_out_seeds_in_order_and_groups_by_triangle() {
        let mut p = Pending::new([4, 9, 4, 1]);
        assert_eq!(p.triangles(), vec![1, 4, 9]);
        assert_eq!(p.next_open(), Some(0));
        p.close(0);
        let mut seen = Vec::new();
        p.visit_open(4, |k| {
            seen.push(k);
            true
        });
        assert_eq!(seen, vec![2], "texel 0 is closed, 2 gets closed");
        p.visit_open(5, |_| unreachable!("no texel on triangle 5"));
        assert_eq!(p.next_open(), Some(1));
        assert!(p.is_closed(2) && !p.is_closed(3));
        p.close(1);
        p.close(3);
        assert_eq!(p.next_open(), None);
        assert!(p.is_closed(99), "beyond the list counts as closed");
    }

    /// Random draws hand out every open, unretired texel and nothing else,
    /// the same sequence for the same seed; a retired texel stays open.
    #[test]
    fn random_seeds_are_the_open_unretired_texels() {
        use rand::SeedableRng;
        let draw = |seed: u64| {
            let mut p = Pending::new((0..50).map(|k| k % 7));
            for k in [3, 10, 11] {
                p.close(k);
            }
            p.retire(20);
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let mut order = Vec::new();
            while let Some(k) = p.random_open(&mut rng) {
                assert!(!p.is_closed(k) && k != 20);
                order.push(k);
                p.close(k);
            }
            assert_eq!(p.open().collect::<Vec<_>>(), vec![20]);
            order
        };
        let (a, b) = (draw(1), draw(1));
        assert_eq!(a, b);
        let mut sorted = a.clone();
        sorted.sort_unstable();
        let want: Vec<usize> = (0..50).filter(|k| ![3, 10, 11, 20].contains(k)).collect();
        assert_eq!(sorted, want);
        assert_ne!(a, want, "not texel order");
        assert_ne!(a, draw(2));
        let mut p = Pending::new([1, 1, 1]);
        p.retire(0);
        assert_eq!(p.next_open(), Some(1), "a retired texel seeds nothing");
    }
}
