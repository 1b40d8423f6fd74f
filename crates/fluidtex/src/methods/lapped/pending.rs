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
    by_triangle: HashMap<u32, Vec<u32>>,
    cursor: usize,
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
            by_triangle,
            cursor: 0,
        }
    }

    /// The first open texel (the next seed); `None` once all are closed.
    pub fn next_open(&mut self) -> Option<usize> {
        while self.cursor < self.closed.len() && self.closed[self.cursor] {
            self.cursor += 1;
        }
        (self.cursor < self.closed.len()).then_some(self.cursor)
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
}
