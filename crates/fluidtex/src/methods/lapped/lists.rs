//! Per-fluid-triangle lists (compressed rows): for every triangle of the
//! fluid mesh, the entries that may show on its texels, in the order they
//! were pushed. Patch methods push patch by patch, so every list is sorted
//! by patch age, which is the order the lapped fills resolve in.

/// Entries of type `T` grouped by fluid triangle.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleLists<T> {
    offsets: Vec<u32>,
    entries: Vec<T>,
}

impl<T: Copy> TriangleLists<T> {
    /// Groups `(fluid triangle, entry)` pairs by triangle, keeping the
    /// order of `pairs` within each triangle (a stable counting sort).
    /// Pairs naming a triangle outside `0..triangle_count` are dropped.
    pub fn build(pairs: &[(u32, T)], triangle_count: usize) -> TriangleLists<T> {
        let mut offsets = vec![0u32; triangle_count + 1];
        for &(f, _) in pairs {
            if (f as usize) < triangle_count {
                offsets[f as usize + 1] += 1;
            }
        }
        for k in 0..triangle_count {
            offsets[k + 1] += offsets[k];
        }
        let mut cursor = offsets.clone();
        let mut entries = Vec::with_capacity(offsets[triangle_count] as usize);
        // Every slot is written exactly once below; start from copies of
        // the first entry so no `T: Default` bound is needed.
        if let Some(&(_, first)) = pairs.first() {
            entries.resize(offsets[triangle_count] as usize, first);
        }
        for &(f, e) in pairs {
            if (f as usize) < triangle_count {
                let c = &mut cursor[f as usize];
                entries[*c as usize] = e;
                *c += 1;
            }
        }
        TriangleLists { offsets, entries }
    }
}

impl<T> TriangleLists<T> {
    /// The entries of fluid triangle `f`, in push order (empty outside).
    #[inline]
    pub fn of(&self, f: u32) -> &[T] {
        let f = f as usize;
        if f + 1 >= self.offsets.len() {
            return &[];
        }
        &self.entries[self.offsets[f] as usize..self.offsets[f + 1] as usize]
    }

    /// The lists with, in each, only the runs of consecutive entries
    /// (`same` holding between neighbours) that `keep` accepts, in order.
    pub fn retain_runs(
        &self,
        same: impl Fn(&T, &T) -> bool,
        keep: impl Fn(&[T]) -> bool,
    ) -> TriangleLists<T>
    where
        T: Copy,
    {
        let mut offsets = Vec::with_capacity(self.offsets.len());
        let mut entries = Vec::with_capacity(self.entries.len());
        offsets.push(0);
        for f in 0..self.offsets.len().saturating_sub(1) {
            for run in self.of(f as u32).chunk_by(&same) {
                if keep(run) {
                    entries.extend_from_slice(run);
                }
            }
            // The lists hold fewer entries than the u32 offsets they came with.
            offsets.push(entries.len() as u32);
        }
        TriangleLists { offsets, entries }
    }

    /// Total number of (triangle, entry) pairs (a cost indicator).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::TriangleLists;

    #[test]
    fn retained_runs_keep_their_order_and_drop_whole() {
        // Entries (patch, triangle); runs are consecutive entries of one patch.
        let pairs = [
            (0, (1, 0)),
            (0, (1, 1)),
            (0, (2, 0)),
            (0, (1, 2)),
            (1, (2, 5)),
            (2, (3, 0)),
        ];
        let lists = TriangleLists::build(&pairs, 3);
        // Drop the runs of patch 1 (both runs in list 0); patch 2 stays.
        let kept = lists.retain_runs(|a, b| a.0 == b.0, |run| run[0].0 != 1);
        assert_eq!(kept.of(0), &[(2, 0)]);
        assert_eq!(kept.of(1), &[(2, 5)]);
        assert_eq!(kept.of(2), &[(3, 0)]);
        assert_eq!(kept.len(), 3);
        // A run is judged whole: keep runs holding any triangle 1.
        let any_one = lists.retain_runs(|a, b| a.0 == b.0, |run| run.iter().any(|e| e.1 == 1));
        assert_eq!(any_one.of(0), &[(1, 0), (1, 1)]);
        assert!(any_one.of(1).is_empty() && any_one.of(2).is_empty());
    }

    #[test]
    fn groups_by_triangle_keeping_push_order() {
        let pairs = [(2, 'a'), (0, 'b'), (2, 'c'), (7, 'x'), (0, 'd'), (1, 'e')];
        let lists = TriangleLists::build(&pairs, 3);
        assert_eq!(lists.of(0), &['b', 'd']);
        assert_eq!(lists.of(1), &['e']);
        assert_eq!(lists.of(2), &['a', 'c']);
        assert!(lists.of(3).is_empty(), "outside the mesh");
        assert_eq!(lists.len(), 5, "the pair beyond the mesh is dropped");
        let empty = TriangleLists::<u32>::build(&[], 4);
        assert!(empty.is_empty() && empty.of(1).is_empty());
    }
}
