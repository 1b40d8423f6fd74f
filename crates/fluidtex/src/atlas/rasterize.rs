//! Scan conversion of the atlas's uv triangles into row spans.
//!
//! Vertices are snapped to a fixed-point grid of 1/256 texel ([`SUBTEXEL`]),
//! as GPUs do, so edge functions are exact integers: a texel centre on an
//! edge shared by two triangles evaluates to exactly zero in both, and the
//! tie-break below gives it to exactly one of them. A texel centre
//! `(x + 0.5, y + 0.5)` belongs to a triangle when it is strictly inside, or
//! on an edge whose direction d (after orienting the triangle positively in
//! x-right, y-down coordinates) satisfies `d.y > 0 || (d.y == 0 && d.x < 0)`
//! — a half-open half-plane of directions, so of the two triangles sharing
//! an edge (which traverse it in opposite directions) exactly one owns it,
//! and a vertex in the middle of a fan is owned by exactly one triangle of
//! the fan (the same argument as the top-left rule of GPU rasterizers).
//!
//! Chart triangles are negatively oriented in texel coordinates (see
//! [`crate::param::flatten::FlatChart::uv`]); a triangle that snapping made
//! zero-area or positive (a sub-1/256-texel sliver) is skipped rather than
//! flipped, so it can never claim texels of its neighbours.

use rayon::prelude::*;

use super::{BAND_HEIGHT, Band, Span};

/// Fixed-point subdivisions per texel.
pub const SUBTEXEL: i64 = 256;
const HALF: i64 = SUBTEXEL / 2;

#[inline]
fn floor_div(a: i64, b: i64) -> i64 {
    a.div_euclid(b)
}

#[inline]
fn ceil_div(a: i64, b: i64) -> i64 {
    -(-a).div_euclid(b)
}

#[inline]
fn owns_edge(dx: i64, dy: i64) -> bool {
    dy > 0 || (dy == 0 && dx < 0)
}

/// Appends the spans of triangle `t` with fixed-point corners `p` to `out`,
/// in increasing row order.
pub(crate) fn triangle_spans(
    t: u32,
    p: [[i64; 2]; 3],
    width: u32,
    height: u32,
    out: &mut Vec<Span>,
) {
    let area2 =
        (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
    if area2 >= 0 {
        return;
    }
    // Positive orientation: corners 0, 2, 1.
    let q = [p[0], p[2], p[1]];
    let ymin = q.iter().map(|v| v[1]).min().unwrap_or(0);
    let ymax = q.iter().map(|v| v[1]).max().unwrap_or(0);
    let xmin = q.iter().map(|v| v[0]).min().unwrap_or(0);
    let xmax = q.iter().map(|v| v[0]).max().unwrap_or(0);
    let y0 = ceil_div(ymin - HALF, SUBTEXEL).max(0);
    let y1 = floor_div(ymax - HALF, SUBTEXEL).min(height as i64 - 1);
    let bx0 = ceil_div(xmin - HALF, SUBTEXEL).max(0);
    let bx1 = floor_div(xmax - HALF, SUBTEXEL).min(width as i64 - 1);
    for y in y0..=y1 {
        let py = y * SUBTEXEL + HALF;
        let (mut lo, mut hi) = (bx0, bx1);
        for k in 0..3 {
            let (a, b) = (q[k], q[(k + 1) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            // E(x) = A x + B at the centre of texel x in this row.
            let ca = -dy * SUBTEXEL;
            let cb = dx * (py - a[1]) - dy * (HALF - a[0]);
            let owner = owns_edge(dx, dy);
            if ca > 0 {
                let min = if owner {
                    ceil_div(-cb, ca)
                } else {
                    floor_div(-cb, ca) + 1
                };
                lo = lo.max(min);
            } else if ca < 0 {
                let max = if owner {
                    floor_div(cb, -ca)
                } else {
                    ceil_div(cb, -ca) - 1
                };
                hi = hi.min(max);
            } else if cb < 0 || (cb == 0 && !owner) {
                lo = hi + 1;
            }
        }
        if lo <= hi {
            out.push(Span {
                triangle: t,
                y: y as u32,
                x0: lo as u32,
                x1: hi as u32 + 1,
            });
        }
    }
}

/// Rasterizes all triangles into bands of [`BAND_HEIGHT`] rows, spans in
/// each band sorted by (triangle, y).
///
/// Chunks of triangles are rasterized in parallel, each bucketing its spans
/// by band (a stable counting sort, so each bucket stays in (triangle, y)
/// order); each band then concatenates its buckets in chunk order, also in
/// parallel. The result does not depend on the thread count.
pub(crate) fn rasterize(
    fixed: &[[i32; 2]],
    triangles: &[[u32; 3]],
    width: u32,
    height: u32,
) -> Vec<Band> {
    const CHUNK: usize = 2048;
    let band_count = height.div_ceil(BAND_HEIGHT) as usize;
    let chunks: Vec<(Vec<Span>, Vec<u32>)> = triangles
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(ci, tris)| {
            let mut spans = Vec::new();
            for (k, tri) in tris.iter().enumerate() {
                let p = tri.map(|v| {
                    let f = fixed[v as usize];
                    [f[0] as i64, f[1] as i64]
                });
                triangle_spans((ci * CHUNK + k) as u32, p, width, height, &mut spans);
            }
            let mut start = vec![0u32; band_count + 1];
            for s in &spans {
                start[(s.y / BAND_HEIGHT) as usize + 1] += 1;
            }
            for b in 0..band_count {
                start[b + 1] += start[b];
            }
            let mut fill = start.clone();
            let mut sorted = vec![
                Span {
                    triangle: 0,
                    y: 0,
                    x0: 0,
                    x1: 0
                };
                spans.len()
            ];
            for s in spans {
                let slot = &mut fill[(s.y / BAND_HEIGHT) as usize];
                sorted[*slot as usize] = s;
                *slot += 1;
            }
            (sorted, start)
        })
        .collect();
    (0..band_count)
        .into_par_iter()
        .map(|b| {
            let len = chunks
                .iter()
                .map(|(_, st)| (st[b + 1] - st[b]) as usize)
                .sum();
            let mut spans = Vec::with_capacity(len);
            for (sorted, st) in &chunks {
                spans.extend_from_slice(&sorted[st[b] as usize..st[b + 1] as usize]);
            }
            Band {
                y0: b as u32 * BAND_HEIGHT,
                y1: ((b as u32 + 1) * BAND_HEIGHT).min(height),
                spans,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fx(x: f64, y: f64) -> [i64; 2] {
        [
            (x * SUBTEXEL as f64).round() as i64,
            (y * SUBTEXEL as f64).round() as i64,
        ]
    }

    fn texels(p: [[i64; 2]; 3], w: u32, h: u32) -> Vec<(u32, u32)> {
        let mut spans = Vec::new();
        triangle_spans(0, p, w, h, &mut spans);
        spans
            .iter()
            .flat_map(|s| (s.x0..s.x1).map(move |x| (x, s.y)))
            .collect()
    }

    /// Brute-force reference: centre strictly inside or on an owned edge.
    fn reference(p: [[i64; 2]; 3], w: u32, h: u32) -> Vec<(u32, u32)> {
        let e = |a: [i64; 2], b: [i64; 2], c: [i64; 2]| {
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        };
        if e(p[0], p[1], p[2]) >= 0 {
            return Vec::new();
        }
        let q = [p[0], p[2], p[1]];
        let mut out = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let c = [x as i64 * SUBTEXEL + HALF, y as i64 * SUBTEXEL + HALF];
                let inside = (0..3).all(|k| {
                    let (a, b) = (q[k], q[(k + 1) % 3]);
                    let v = e(a, b, c);
                    v > 0 || (v == 0 && owns_edge(b[0] - a[0], b[1] - a[1]))
                });
                if inside {
                    out.push((x, y));
                }
            }
        }
        out
    }

    #[test]
    fn spans_match_a_brute_force_reference() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let mut nonempty = 0;
        for i in 0..2000 {
            // Corners on half-texel positions half of the time, so centres
            // land exactly on edges and vertices; some far outside.
            let span = if i % 4 == 0 { 40.0 } else { 12.0 };
            let mut c = || {
                if rng.random_bool(0.5) {
                    rng.random_range(0..24) as f64 * 0.5
                } else {
                    rng.random_range(-span..span)
                }
            };
            let p = [fx(c(), c()), fx(c(), c()), fx(c(), c())];
            let got = texels(p, 11, 10);
            assert_eq!(got, reference(p, 11, 10), "{p:?}");
            nonempty += !got.is_empty() as u32;
        }
        assert!(nonempty > 500, "too few triangles hit the grid: {nonempty}");
    }

    #[test]
    fn a_square_split_in_two_covers_each_centre_once() {
        // Square with corners on texel centres, split along its diagonal,
        // which passes through texel centres too.
        let (a, b, c, d) = (fx(0.5, 0.5), fx(4.5, 0.5), fx(4.5, 4.5), fx(0.5, 4.5));
        // Both negatively oriented in x-right, y-down coordinates.
        let t1 = [a, d, c];
        let t2 = [a, c, b];
        let mut all = texels(t1, 8, 8);
        all.extend(texels(t2, 8, 8));
        all.sort();
        let n = all.len();
        all.dedup();
        assert_eq!(all.len(), n, "a centre was claimed twice");
        // Centres with x, y in 0.5..=4.5 on or inside the square: owned
        // edges of the square's boundary decide; the interior is full.
        assert!((1..4).all(|y| (1..4).all(|x| all.contains(&(x, y)))));
    }
}
