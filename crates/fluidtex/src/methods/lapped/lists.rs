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
        TriangleLists::from_groups(std::slice::from_ref(&pairs), triangle_count, |_, e| e)
    }

    /// [`TriangleLists::build`] of the pairs of `groups` one group after
    /// another, the entries made by `entry(group index, value)`: the same
    /// lists as concatenating the groups first, without that flat copy of
    /// every pair (at 300k triangles the candidate pairs of the erosion
    /// fill are ~10 M, and the copy was the frame's peak of memory).
    pub fn from_groups<G, J>(
        groups: &[G],
        triangle_count: usize,
        entry: impl Fn(usize, J) -> T,
    ) -> TriangleLists<T>
    where
        G: AsRef<[(u32, J)]>,
        J: Copy,
    {
        let pairs = || {
            groups
                .iter()
                .enumerate()
                .flat_map(|(g, pairs)| pairs.as_ref().iter().map(move |&(f, j)| (g, f, j)))
                .filter(|&(_, f, _)| (f as usize) < triangle_count)
        };
        let mut offsets = vec![0u32; triangle_count + 1];
        for (_, f, _) in pairs() {
            offsets[f as usize + 1] += 1;
        }
        for k in 0..triangle_count {
            offsets[k + 1] += offsets[k];
        }
        let mut cursor = offsets.clone();
        let mut entries = Vec::with_capacity(offsets[triangle_count] as usize);
        // Every slot is written exactly once below; start from copies of
        // the first entry so no `T: Default` bound is needed.
        if let Some((g, _, j)) = pairs().next() {
            entries.resize(offsets[triangle_count] as usize, entry(g, j));
        }
        for (g, f, j) in pairs() {
            let c = &mut cursor[f as usize];
            entries[*c as usize] = entry(g, j);
            *c += 1;
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

    #[test]
    fn groups_give_the_lists_of_their_concatenation() {
        // Seeded random groups of (triangle, value) pairs, some outside
        // the mesh and some groups empty: the entries are (group, value).
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
        for case in 0..50 {
            let triangles = rng.random_range(1..20usize);
            let groups: Vec<Vec<(u32, u16)>> = (0..rng.random_range(0..8))
                .map(|_| {
                    (0..rng.random_range(0..30))
                        .map(|_| (rng.random_range(0..triangles as u32 + 3), rng.random()))
                        .collect()
                })
                .collect();
            let flat: Vec<(u32, (usize, u16))> = groups
                .iter()
                .enumerate()
                .flat_map(|(g, pairs)| pairs.iter().map(move |&(f, v)| (f, (g, v))))
                .collect();
            let grouped = TriangleLists::from_groups(&groups, triangles, |g, v| (g, v));
            assert_eq!(
                grouped,
                TriangleLists::build(&flat, triangles),
                "case {case}"
            );
            let inside = flat.iter().filter(|p| (p.0 as usize) < triangles).count();
            assert_eq!(grouped.len(), inside, "case {case}");
        }
    }
}
