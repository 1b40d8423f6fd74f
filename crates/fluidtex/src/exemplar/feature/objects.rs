//! Per-object normalisation of a distance field.
//!
//! Dividing a distance transform by its global maximum makes small stones
//! look like crevices; dividing each connected component by its own maximum
//! is better, but two stones that touch after thresholding form one
//! component and the smaller one never reaches 1. We split components at
//! their necks instead: the objects are the peaks of the distance field that
//! survive a persistence filter (0-dimensional persistent homology of the
//! superlevel sets, as in Edelsbrunner, Letscher & Zomorodian 2002).
//! Texels are added from the highest distance down; each joins the component
//! of its highest already-added 4-neighbour; when two components meet at a
//! texel of distance `s`, the one with the lower peak `p` is merged into the
//! other only if its prominence `p − s` is small (`< max(min, rel · p)`),
//! i.e. it was a bump on the ridge, not a separate stone. Each texel is then
//! divided by the peak of its final component, so every stone's centre is 1.

/// Prominence below which a peak is not an object of its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prominence {
    /// Absolute part, texels.
    pub min: f32,
    /// Part relative to the lower peak's height.
    pub relative: f32,
}

/// `dist / peak(object)` per texel, on the `width × height` torus; texels
/// with `dist <= 0` (background) stay 0. Deterministic: ties in distance are
/// broken by texel index.
pub fn normalise_per_object(dist: &[f32], width: usize, height: usize, p: Prominence) -> Vec<f32> {
    let n = dist.len();
    if n != width * height || n == 0 {
        return vec![0.0; n];
    }
    let mut order: Vec<u32> = (0..n as u32).filter(|&i| dist[i as usize] > 0.0).collect();
    order.sort_by(|&a, &b| {
        dist[b as usize]
            .total_cmp(&dist[a as usize])
            .then(a.cmp(&b))
    });
    const NONE: u32 = u32::MAX;
    let mut parent = vec![NONE; n];
    let mut peak = vec![0.0f32; n];
    let find = |parent: &mut [u32], mut i: u32| {
        let mut root = i;
        while parent[root as usize] != root {
            root = parent[root as usize];
        }
        // Path compression keeps later finds near O(1).
        while parent[i as usize] != root {
            let next = parent[i as usize];
            parent[i as usize] = root;
            i = next;
        }
        root
    };
    let mut roots: Vec<u32> = Vec::with_capacity(4);
    for &i in &order {
        let (x, y) = (i as usize % width, i as usize / width);
        let neighbours = [
            y * width + (x + 1) % width,
            y * width + (x + width - 1) % width,
            ((y + 1) % height) * width + x,
            ((y + height - 1) % height) * width + x,
        ];
        roots.clear();
        for &j in &neighbours {
            if parent[j] != NONE {
                let r = find(&mut parent, j as u32);
                if !roots.contains(&r) {
                    roots.push(r);
                }
            }
        }
        let level = dist[i as usize];
        // Highest peak first; ties by index so the result never depends on
        // neighbour order.
        roots.sort_by(|&a, &b| {
            peak[b as usize]
                .total_cmp(&peak[a as usize])
                .then(a.cmp(&b))
        });
        match roots.first() {
            None => {
                parent[i as usize] = i;
                peak[i as usize] = level;
            }
            Some(&top) => {
                parent[i as usize] = top;
                for &r in &roots[1..] {
                    let pr = peak[r as usize];
                    if pr - level < p.min.max(p.relative * pr) {
                        parent[r as usize] = top;
                    }
                }
            }
        }
    }
    (0..n)
        .map(|i| {
            if parent[i] == NONE {
                0.0
            } else {
                let r = find(&mut parent, i as u32);
                (dist[i] / peak[r as usize]).clamp(0.0, 1.0)
            }
        })
        .collect()
}

/// Share of the `true` texels that lie in the largest 4-connected
/// component of `mask` on the `width × height` torus (0 when none is true).
/// The crevices or mortar of a texture form one network that spans the
/// image (share near 1); its objects are many separate pieces.
pub fn largest_component_share(mask: &[bool], width: usize, height: usize) -> f32 {
    let n = mask.len();
    if n != width * height || n == 0 {
        return 0.0;
    }
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let up = parent[parent[i as usize] as usize];
            parent[i as usize] = up;
            i = up;
        }
        i
    }
    for i in 0..n {
        if !mask[i] {
            continue;
        }
        let (x, y) = (i % width, i / width);
        for j in [y * width + (x + 1) % width, ((y + 1) % height) * width + x] {
            if mask[j] {
                let (a, b) = (root(&mut parent, i as u32), root(&mut parent, j as u32));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
    }
    let mut size = vec![0u32; n];
    let mut total = 0u32;
    for i in 0..n {
        if mask[i] {
            size[root(&mut parent, i as u32) as usize] += 1;
            total += 1;
        }
    }
    match size.iter().max() {
        Some(&m) if total > 0 => m as f32 / total as f32,
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn network_versus_pieces() {
        // A 6×6 torus with a grid of lines (network) and 4 separate blocks.
        let mask: Vec<bool> = (0..36).map(|i| i % 6 == 0 || i / 6 == 0).collect();
        let blocks: Vec<bool> = mask.iter().map(|b| !b).collect();
        assert_eq!(largest_component_share(&mask, 6, 6), 1.0);
        // The complement of a cross on a torus is one 5×5 block.
        assert_eq!(largest_component_share(&blocks, 6, 6), 1.0);
        let grid: Vec<bool> = (0..36).map(|i| i % 3 == 0 || (i / 6) % 3 == 0).collect();
        let pieces: Vec<bool> = grid.iter().map(|b| !b).collect();
        assert_eq!(largest_component_share(&grid, 6, 6), 1.0);
        assert_eq!(largest_component_share(&pieces, 6, 6), 0.25);
        assert_eq!(largest_component_share(&[false; 4], 2, 2), 0.0);
    }

    /// Two separate peaks of different height each normalise to 1; a small
    /// bump on a ridge is merged into its bigger neighbour.
    #[test]
    fn peaks_and_bumps() {
        // 1-D profile on a 1-row torus.
        let d = [0.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 1.0, 2.0, 1.0, 0.0];
        let f = normalise_per_object(
            &d,
            d.len(),
            1,
            Prominence {
                min: 0.5,
                relative: 0.0,
            },
        );
        assert_eq!(f[3], 1.0);
        assert_eq!(f[8], 1.0);
        assert_eq!(f[1], 1.0 / 3.0);
        assert_eq!(f[7], 0.5);
        assert_eq!(f[0], 0.0);

        let ridge = [0.0, 1.0, 2.0, 3.0, 4.0, 3.5, 3.7, 3.0, 1.0, 0.0];
        let f = normalise_per_object(
            &ridge,
            ridge.len(),
            1,
            Prominence {
                min: 0.5,
                relative: 0.0,
            },
        );
        assert_eq!(f[6], 3.7 / 4.0, "bump of prominence 0.2 must merge");
        let f = normalise_per_object(
            &ridge,
            ridge.len(),
            1,
            Prominence {
                min: 0.1,
                relative: 0.0,
            },
        );
        assert_eq!(f[6], 1.0, "bump above the threshold stays a peak");
    }
}
