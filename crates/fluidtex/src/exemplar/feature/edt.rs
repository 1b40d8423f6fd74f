//! Exact Euclidean distance transform on a torus.
//!
//! Felzenszwalb & Huttenlocher 2012, "Distance Transforms of Sampled
//! Functions" (Theory of Computing 8), Sec. 2.1: the 1-D squared transform is
//! the lower envelope of parabolas rooted at the sites (Algorithm `DT(f)`),
//! and the 2-D transform applies it to rows, then to the columns of the
//! result. Written here (a few dozen lines) rather than taken from a crate
//! because the exemplar tiles: distances must wrap around the edges, which
//! the crates we looked at do not offer. Periodicity is obtained by running
//! each 1-D pass over three copies of the line and keeping the middle one
//! (a site farther than one period is never the nearest).

/// Squared distance of every texel to the nearest texel where `site` is
/// true, on the `width × height` torus; `f64::INFINITY` when there is no site.
pub fn squared_distance_wrap(site: &[bool], width: usize, height: usize) -> Vec<f64> {
    let mut d: Vec<f64> = site
        .iter()
        .map(|&s| if s { 0.0 } else { f64::INFINITY })
        .collect();
    if d.len() != width * height || width == 0 || height == 0 {
        return d;
    }
    let mut line = Vec::new();
    let mut out = Vec::new();
    let mut scratch = Scratch::default();
    for y in 0..height {
        line.clear();
        line.extend_from_slice(&d[y * width..(y + 1) * width]);
        periodic_1d(&line, &mut out, &mut scratch);
        d[y * width..(y + 1) * width].copy_from_slice(&out);
    }
    for x in 0..width {
        line.clear();
        line.extend((0..height).map(|y| d[y * width + x]));
        periodic_1d(&line, &mut out, &mut scratch);
        for (y, &v) in out.iter().enumerate() {
            d[y * width + x] = v;
        }
    }
    d
}

#[derive(Default)]
struct Scratch {
    extended: Vec<f64>,
    result: Vec<f64>,
    sites: Vec<usize>,
    bounds: Vec<f64>,
}

/// 1-D squared transform of `f` on a circle of length `f.len()`.
fn periodic_1d(f: &[f64], out: &mut Vec<f64>, s: &mut Scratch) {
    let n = f.len();
    s.extended.clear();
    for _ in 0..3 {
        s.extended.extend_from_slice(f);
    }
    lower_envelope(&s.extended, &mut s.result, &mut s.sites, &mut s.bounds);
    out.clear();
    out.extend_from_slice(&s.result[n..2 * n]);
}

/// `out[q] = min_p (q − p)² + f[p]` over the finite samples of `f`.
fn lower_envelope(f: &[f64], out: &mut Vec<f64>, v: &mut Vec<usize>, z: &mut Vec<f64>) {
    out.clear();
    v.clear();
    z.clear();
    let n = f.len();
    // Intersection abscissa of the parabolas rooted at q and p (q > p).
    let meet = |q: usize, p: usize| {
        let (qf, pf) = (q as f64, p as f64);
        ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf))
    };
    for q in (0..n).filter(|&q| f[q].is_finite()) {
        loop {
            match (v.last(), z.last()) {
                (Some(&p), Some(&zp)) if meet(q, p) <= zp => {
                    v.pop();
                    z.pop();
                }
                _ => break,
            }
        }
        match v.last() {
            Some(&p) => z.push(meet(q, p)),
            None => z.push(f64::NEG_INFINITY),
        }
        v.push(q);
    }
    if v.is_empty() {
        out.resize(n, f64::INFINITY);
        return;
    }
    let mut k = 0;
    for q in 0..n {
        let qf = q as f64;
        while k + 1 < v.len() && z[k + 1] < qf {
            k += 1;
        }
        let p = v[k];
        out.push((qf - p as f64).powi(2) + f[p]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn brute(site: &[bool], w: usize, h: usize) -> Vec<f64> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                site.iter()
                    .enumerate()
                    .filter(|(_, s)| **s)
                    .map(|(j, _)| {
                        let (sx, sy) = ((j % w) as i64, (j / w) as i64);
                        let dx = (x - sx).abs().min(w as i64 - (x - sx).abs());
                        let dy = (y - sy).abs().min(h as i64 - (y - sy).abs());
                        (dx * dx + dy * dy) as f64
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    /// Exact against brute force on random toroidal site sets, odd and even sizes.
    #[test]
    fn matches_brute_force_on_torus() {
        let mut rng = Pcg64::seed_from_u64(11);
        for case in 0..40 {
            let (w, h) = (rng.random_range(1..24), rng.random_range(1..24));
            let density = [0.01, 0.05, 0.3][case % 3];
            let site: Vec<bool> = (0..w * h).map(|_| rng.random_bool(density)).collect();
            assert_eq!(
                squared_distance_wrap(&site, w, h),
                brute(&site, w, h),
                "case {case}: {w}x{h}"
            );
        }
    }
}
