//! Flattening of atlas charts: LSCM per chart, a check that the map is
//! injective, and splitting of charts whose map folds.
//!
//! LSCM preserves orientation triangle by triangle but is not guaranteed to
//! be injective: a flipped triangle, a vertex whose one-ring wraps around
//! twice, or a boundary that crosses itself all make two surface points share
//! a texel. A map of a disc is injective exactly when every triangle keeps its
//! orientation, every interior vertex's angles sum to 2π (one turn), every
//! boundary vertex's to less than 2π, and the boundary polygon is simple
//! (a locally injective map of a disc with a simple boundary is globally
//! injective). [`is_injective`] checks these four conditions; a chart that
//! fails them is split ([`super::charts::split`]) and each piece flattened
//! again, down to single triangles if need be (always injective).
//!
//! **Blown-up triangles.** LSCM weights each triangle's conformality by its
//! area, so a near-degenerate sliver (a needle that a mesher left, 3-D
//! area ~10⁻⁶ of its neighbours') barely constrains its corners: the map
//! stays injective, but the sliver's far corner can land anywhere. On a
//! Mantaflow splash frame one such triangle, 0.033 long, was mapped 6.1
//! long, longer than the rest of the surface's charts together, and the
//! packer's one scale had to fit it: the atlas was 46 % full where its
//! neighbours were 53 %. A triangle whose uv scale exceeds
//! [`MAX_TRIANGLE_SCALE`] times the chart's is therefore taken out and
//! flattened on its own (an isometric chart of one triangle), and the rest
//! of the chart flattened again.
//!
//! Output coordinates follow the image convention (x right, y down) and are
//! scaled so that each chart's uv area equals its 3-D area, which gives every
//! chart the same mean texel density once packed.

use std::collections::HashMap;

use glam::{DVec2, Vec2, Vec3};

use super::charts::{ChartParams, split};
use super::{is_degenerate, lscm};

/// One flattened chart.
#[derive(Clone, Debug, PartialEq)]
pub struct FlatChart {
    /// Input triangles of the chart, ascending.
    pub triangles: Vec<u32>,
    /// Input vertex of each chart vertex, in first-use order over `triangles`.
    pub vertices: Vec<u32>,
    /// The chart's triangles in chart-vertex indices, input corner order.
    pub local_triangles: Vec<[u32; 3]>,
    /// Chart-vertex coordinates in world units, image orientation (x right,
    /// y down): a triangle counter-clockwise around its normal has negative
    /// signed area here, so the texture is not mirrored when seen from the
    /// side the normal points to. A degenerate triangle (a chart of its own)
    /// collapses to the point (0, 0): it has no area to texture.
    pub uv: Vec<Vec2>,
}

/// Flattens chart `chart` (ascending input triangle indices) of the mesh
/// `(positions, triangles)`, splitting it until every piece maps injectively.
/// Returns the pieces in a deterministic order.
pub fn flatten_chart(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    chart: &[u32],
    params: &ChartParams,
) -> Vec<FlatChart> {
    let mut out = Vec::new();
    flatten_into(positions, triangles, chart.to_vec(), params, &mut out);
    out
}

fn flatten_into(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    chart: Vec<u32>,
    params: &ChartParams,
    out: &mut Vec<FlatChart>,
) {
    let (vertices, local_triangles) = local_mesh(triangles, &chart);
    let local_pos: Vec<Vec3> = vertices.iter().map(|&v| positions[v as usize]).collect();

    if let [t] = local_triangles[..] {
        let [a, b, c] = t.map(|v| local_pos[v as usize]);
        if is_degenerate(a, b, c) {
            out.push(FlatChart {
                uv: vec![Vec2::ZERO; local_pos.len()],
                triangles: chart,
                vertices,
                local_triangles,
            });
            return;
        }
    }

    if let Ok(uv) = lscm(&local_pos, &local_triangles)
        && is_injective(&uv, &local_triangles)
    {
        let uv = normalised_image_uv(&local_pos, &local_triangles, &uv);
        let blown = blown_up(&local_pos, &local_triangles, &uv);
        if blown.is_empty() || blown.len() == chart.len() {
            out.push(FlatChart {
                uv,
                triangles: chart,
                vertices,
                local_triangles,
            });
            return;
        }
        // The blown-up triangles become charts of their own and the rest is
        // flattened again without them (module doc).
        let mut is_blown = vec![false; chart.len()];
        for &t in &blown {
            is_blown[t] = true;
        }
        let rest: Vec<u32> = (0..chart.len())
            .filter(|&t| !is_blown[t])
            .map(|t| chart[t])
            .collect();
        flatten_into(positions, triangles, rest, params, out);
        for t in blown {
            flatten_into(positions, triangles, vec![chart[t]], params, out);
        }
        return;
    }

    let pieces = split(&local_pos, &local_triangles, params).charts;
    if pieces.len() < 2 {
        // Cannot happen for two or more triangles (split halves the size
        // cap); a lone non-degenerate triangle always flattens above.
        for t in chart {
            flatten_into(positions, triangles, vec![t], params, out);
        }
        return;
    }
    for piece in pieces {
        let global: Vec<u32> = piece.iter().map(|&l| chart[l as usize]).collect();
        flatten_into(positions, triangles, global, params, out);
    }
}

/// Chart vertices in first-use order and the chart's triangles in them.
fn local_mesh(triangles: &[[u32; 3]], chart: &[u32]) -> (Vec<u32>, Vec<[u32; 3]>) {
    // A map sized by the chart, not a mesh-sized scratch array per chart;
    // only looked up, so its iteration order never matters.
    let mut index: HashMap<u32, u32> = HashMap::with_capacity(chart.len());
    let mut vertices: Vec<u32> = Vec::with_capacity(chart.len() / 2 + 2);
    let local_tris = chart
        .iter()
        .map(|&t| {
            triangles[t as usize].map(|v| {
                *index.entry(v).or_insert_with(|| {
                    vertices.push(v);
                    (vertices.len() - 1) as u32
                })
            })
        })
        .collect();
    (vertices, local_tris)
}

/// Largest scale σ (uv length per 3-D length, the chart's mean being 1) a
/// triangle may have in its chart's map before it is flattened on its own
/// (module doc). On 48 frames of a Mantaflow splash, 19 727 of 19 845 charts
/// had every triangle below σ = 2 and 98 below 8; the 20 above 8 were one
/// near-degenerate sliver each, at σ up to 185.
pub const MAX_TRIANGLE_SCALE: f64 = 8.0;

/// Local indices of the triangles whose uv area exceeds their 3-D area by
/// more than [`MAX_TRIANGLE_SCALE`]², ascending; `uv` as
/// [`normalised_image_uv`] returns it.
fn blown_up(pos: &[Vec3], tris: &[[u32; 3]], uv: &[Vec2]) -> Vec<usize> {
    let limit = MAX_TRIANGLE_SCALE * MAX_TRIANGLE_SCALE;
    tris.iter()
        .enumerate()
        .filter(|(_, t)| {
            let [a, b, c] = t.map(|v| pos[v as usize].as_dvec3());
            let area3 = 0.5 * (b - a).cross(c - a).length();
            let [p, q, r] = t.map(|v| uv[v as usize].as_dvec2());
            let area2 = 0.5 * (q - p).perp_dot(r - p).abs();
            area2 > limit * area3
        })
        .map(|(i, _)| i)
        .collect()
}

/// LSCM uv → image orientation (y = −v), scaled to the 3-D area.
fn normalised_image_uv(pos: &[Vec3], tris: &[[u32; 3]], uv: &[Vec2]) -> Vec<Vec2> {
    let (mut area3, mut area2) = (0.0f64, 0.0f64);
    for t in tris {
        let [a, b, c] = t.map(|v| pos[v as usize].as_dvec3());
        area3 += 0.5 * (b - a).cross(c - a).length();
        let [p, q, r] = t.map(|v| uv[v as usize].as_dvec2());
        area2 += 0.5 * (q - p).perp_dot(r - p);
    }
    let scale = if area2 > 0.0 {
        (area3 / area2).sqrt()
    } else {
        1.0
    };
    uv.iter()
        .map(|p| (DVec2::new(p.x as f64, -(p.y as f64)) * scale).as_vec2())
        .collect()
}

/// True when the piecewise-linear map `uv` (orientation as LSCM returns it:
/// counter-clockwise triangles positive) of the disc `tris` is injective;
/// see the module doc for the four conditions.
pub fn is_injective(uv: &[Vec2], tris: &[[u32; 3]]) -> bool {
    use std::f64::consts::TAU;
    let p: Vec<DVec2> = uv.iter().map(|q| q.as_dvec2()).collect();
    let mut angle_sum = vec![0.0f64; p.len()];
    let mut edges: Vec<(u32, u32, u32, u32)> = Vec::with_capacity(tris.len() * 3);
    for t in tris {
        let [a, b, c] = t.map(|v| p[v as usize]);
        if (b - a).perp_dot(c - a) <= 0.0 {
            return false;
        }
        for k in 0..3 {
            let (o, n1, n2) = (
                t[k] as usize,
                t[(k + 1) % 3] as usize,
                t[(k + 2) % 3] as usize,
            );
            let (e1, e2) = (p[n1] - p[o], p[n2] - p[o]);
            angle_sum[o] += e1.perp_dot(e2).atan2(e1.dot(e2));
            let (u, v) = (t[k], t[(k + 1) % 3]);
            edges.push((u.min(v), u.max(v), u, v));
        }
    }
    edges.sort_unstable();
    let mut boundary: Vec<(u32, u32)> = Vec::new();
    let mut on_boundary = vec![false; p.len()];
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
            j += 1;
        }
        match j - i {
            1 => {
                boundary.push((edges[i].2, edges[i].3));
                on_boundary[edges[i].0 as usize] = true;
                on_boundary[edges[i].1 as usize] = true;
            }
            2 => {}
            _ => return false,
        }
        i = j;
    }
    let used: Vec<bool> = {
        let mut u = vec![false; p.len()];
        for t in tris {
            for &v in t {
                u[v as usize] = true;
            }
        }
        u
    };
    for v in 0..p.len() {
        if !used[v] {
            continue;
        }
        // Interior sums are whole turns (2π k); anything near 4π wraps.
        let limit = if on_boundary[v] {
            TAU - 1e-9
        } else {
            TAU + 1.0
        };
        if angle_sum[v] >= limit {
            return false;
        }
    }
    boundary_is_simple(&p, &boundary)
}

/// No two boundary edges without a common vertex touch or cross. Uniform
/// grid over the boundary's bounding box, about one edge per cell.
fn boundary_is_simple(p: &[DVec2], edges: &[(u32, u32)]) -> bool {
    let m = edges.len();
    if m < 4 {
        return true;
    }
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for &(a, b) in edges {
        for v in [a, b] {
            lo = lo.min(p[v as usize]);
            hi = hi.max(p[v as usize]);
        }
    }
    let ext = (hi - lo).max(DVec2::splat(1e-300));
    let cells = (m as f64).sqrt().ceil().max(1.0);
    let n = DVec2::new(
        (cells * ext.x / ext.max_element()).ceil().max(1.0),
        (cells * ext.y / ext.max_element()).ceil().max(1.0),
    );
    let cell_of = |q: DVec2| -> (i64, i64) {
        let c = (q - lo) / ext * n;
        (
            (c.x.floor() as i64).clamp(0, n.x as i64 - 1),
            (c.y.floor() as i64).clamp(0, n.y as i64 - 1),
        )
    };
    let mut entries: Vec<(i64, u32)> = Vec::new();
    for (e, &(a, b)) in edges.iter().enumerate() {
        let (ca, cb) = (cell_of(p[a as usize]), cell_of(p[b as usize]));
        for cy in ca.1.min(cb.1)..=ca.1.max(cb.1) {
            for cx in ca.0.min(cb.0)..=ca.0.max(cb.0) {
                entries.push((cy * n.x as i64 + cx, e as u32));
            }
        }
    }
    entries.sort_unstable();
    let mut i = 0;
    while i < entries.len() {
        let mut j = i + 1;
        while j < entries.len() && entries[j].0 == entries[i].0 {
            j += 1;
        }
        for x in i..j {
            for y in x + 1..j {
                let (e, f) = (edges[entries[x].1 as usize], edges[entries[y].1 as usize]);
                if e.0 == f.0 || e.0 == f.1 || e.1 == f.0 || e.1 == f.1 {
                    continue;
                }
                if segments_touch(
                    p[e.0 as usize],
                    p[e.1 as usize],
                    p[f.0 as usize],
                    p[f.1 as usize],
                ) {
                    return false;
                }
            }
        }
        i = j;
    }
    true
}

/// Closed segments ab and cd share a point.
fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let o = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (o1, o2, o3, o4) = (o(a, b, c), o(a, b, d), o(c, d, a), o(c, d, b));
    if o1 == 0.0 && o2 == 0.0 {
        // Collinear: overlap of the projections on the longer axis.
        let axis = if (b - a).x.abs() >= (b - a).y.abs() {
            0
        } else {
            1
        };
        let (a0, a1) = (a[axis].min(b[axis]), a[axis].max(b[axis]));
        let (c0, c1) = (c[axis].min(d[axis]), c[axis].max(d[axis]));
        return a0 <= c1 && c0 <= a1;
    }
    o1 * o2 <= 0.0 && o3 * o4 <= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Vec<Vec2>, Vec<[u32; 3]>) {
        (
            vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
                Vec2::new(0.5, 0.5),
            ],
            vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
        )
    }

    /// A helicoid strip of `turns` turns with a small pitch: nearly a flat
    /// annulus covered `turns` times, so any flat map of it overlaps itself.
    fn helicoid(turns: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (nu, nt) = (4u32, (40.0 * turns) as u32);
        let mut pos = Vec::new();
        for j in 0..=nt {
            let th = std::f32::consts::TAU * turns * j as f32 / nt as f32;
            for i in 0..=nu {
                let r = 1.0 + i as f32 / nu as f32;
                pos.push(Vec3::new(r * th.cos(), r * th.sin(), 0.05 * th));
            }
        }
        let mut tris = Vec::new();
        for j in 0..nt {
            for i in 0..nu {
                let a = j * (nu + 1) + i;
                let b = a + nu + 1;
                tris.push([a, a + 1, b + 1]);
                tris.push([a, b + 1, b]);
            }
        }
        (pos, tris)
    }

    #[test]
    fn a_folding_chart_is_split_into_injective_pieces() {
        let (pos, tris) = helicoid(2.0);
        // Control: the whole strip's LSCM map does overlap itself.
        let whole = lscm(&pos, &tris).expect("a valid disc");
        assert!(!is_injective(&whole, &tris));

        let chart: Vec<u32> = (0..tris.len() as u32).collect();
        let pieces = flatten_chart(&pos, &tris, &chart, &ChartParams::default());
        assert!(pieces.len() >= 2);
        let mut all: Vec<u32> = pieces.iter().flat_map(|p| p.triangles.clone()).collect();
        all.sort_unstable();
        assert_eq!(all, chart, "pieces must partition the chart");
        for p in &pieces {
            // Back to LSCM orientation (y up) for the check.
            let up: Vec<Vec2> = p.uv.iter().map(|q| Vec2::new(q.x, -q.y)).collect();
            assert!(is_injective(&up, &p.local_triangles));
            for (k, &t) in p.triangles.iter().enumerate() {
                assert_eq!(
                    p.local_triangles[k].map(|v| p.vertices[v as usize]),
                    tris[t as usize]
                );
            }
        }
    }

    #[test]
    fn a_flat_chart_stays_whole_with_its_area() {
        let (pos, tris) = helicoid(0.5);
        let chart: Vec<u32> = (0..tris.len() as u32).collect();
        let pieces = flatten_chart(&pos, &tris, &chart, &ChartParams::default());
        assert_eq!(pieces.len(), 1);
        let p = &pieces[0];
        let (mut a2, mut a3) = (0.0f64, 0.0f64);
        for (k, t) in p.local_triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| p.uv[v as usize].as_dvec2());
            let signed = 0.5 * (b - a).perp_dot(c - a);
            assert!(signed < 0.0, "triangle {k} not in image orientation");
            a2 -= signed;
            let [x, y, z] = tris[p.triangles[k] as usize].map(|v| pos[v as usize].as_dvec3());
            a3 += 0.5 * (y - x).cross(z - x).length();
        }
        assert!(
            (a2 / a3 - 1.0).abs() < 1e-5,
            "uv area {a2} vs 3-D area {a3}"
        );
    }

    /// `v`/`f` lines of an OBJ file (test fixtures only).
    fn obj(text: &str) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (mut pos, mut tris) = (Vec::new(), Vec::new());
        for line in text.lines() {
            let w: Vec<&str> = line.split_whitespace().collect();
            match w.first() {
                Some(&"v") => {
                    let c: Vec<f32> = w[1..4].iter().map(|x| x.parse().expect("x")).collect();
                    pos.push(Vec3::new(c[0], c[1], c[2]));
                }
                Some(&"f") => {
                    let c: Vec<u32> = w[1..4].iter().map(|x| x.parse().expect("i")).collect();
                    tris.push([c[0] - 1, c[1] - 1, c[2] - 1]);
                }
                _ => {}
            }
        }
        (pos, tris)
    }

    fn extent(uv: &[Vec2]) -> f32 {
        let lo = uv.iter().fold(Vec2::splat(f32::MAX), |a, &p| a.min(p));
        let hi = uv.iter().fold(Vec2::splat(f32::MIN), |a, &p| a.max(p));
        (hi - lo).max_element()
    }

    #[test]
    fn a_sliver_that_lscm_blows_up_is_flattened_on_its_own() {
        // 117 triangles of a Mantaflow splash frame, one of them a needle
        // (edges 0.033, 0.033 and 0.00005).
        let (pos, tris) = obj(include_str!("../../tests/data/sliver_chart.obj"));
        assert_eq!(tris.len(), 117);
        // Control: the chart's own LSCM map is injective, but it maps the
        // needle and its neighbour at the chart's end more than eight times
        // longer than the rest of the chart.
        let whole = lscm(&pos, &tris).expect("a valid disc");
        assert!(is_injective(&whole, &tris));
        let whole = normalised_image_uv(&pos, &tris, &whole);
        let blown = blown_up(&pos, &tris, &whole);
        assert_eq!(blown, vec![115, 116]);

        let chart: Vec<u32> = (0..tris.len() as u32).collect();
        let pieces = flatten_chart(&pos, &tris, &chart, &ChartParams::default());
        for t in blown {
            assert!(pieces.iter().any(|p| p.triangles == vec![t as u32]));
        }
        let mut all: Vec<u32> = pieces.iter().flat_map(|p| p.triangles.clone()).collect();
        all.sort_unstable();
        assert_eq!(all, chart, "pieces must partition the chart");
        let mut longest = 0.0f32;
        for p in &pieces {
            let local: Vec<Vec3> = p.vertices.iter().map(|&v| pos[v as usize]).collect();
            assert!(blown_up(&local, &p.local_triangles, &p.uv).is_empty());
            longest = longest.max(extent(&p.uv));
        }
        assert!(
            longest * 20.0 < extent(&whole),
            "pieces up to {longest} long, the whole map {}",
            extent(&whole)
        );
    }

    #[test]
    fn a_triangle_is_blown_up_beyond_eight_times_its_length() {
        // Two unit right triangles, the second's uv scaled by k: blown up
        // exactly when k > 8.
        let pos = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(6.0, 0.0, 0.0),
            Vec3::new(5.0, 1.0, 0.0),
        ];
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        for (k, expected) in [(7.9f32, 0), (8.1, 1)] {
            let uv = vec![
                Vec2::ZERO,
                Vec2::X,
                Vec2::new(0.0, -1.0),
                Vec2::new(5.0, 0.0),
                Vec2::new(5.0 + k, 0.0),
                Vec2::new(5.0, -k),
            ];
            assert_eq!(blown_up(&pos, &tris, &uv).len(), expected, "k = {k}");
        }
    }

    #[test]
    fn a_convex_fan_is_injective() {
        let (uv, tris) = square();
        assert!(is_injective(&uv, &tris));
    }

    #[test]
    fn a_flipped_triangle_is_caught() {
        let (mut uv, tris) = square();
        uv[4] = Vec2::new(1.5, 0.5); // centre pushed outside: triangle 1 flips
        assert!(!is_injective(&uv, &tris));
    }

    #[test]
    fn a_double_cover_is_caught() {
        // Eight triangles around a centre, each spanning 90°: every triangle
        // is positive but the one-ring turns twice (angle sum 4π).
        let mut uv = vec![Vec2::ZERO];
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::FRAC_PI_2;
            uv.push(Vec2::new(a.cos(), a.sin()));
        }
        let tris: Vec<[u32; 3]> = (0..8).map(|k| [0, 1 + k, 1 + (k + 1) % 8]).collect();
        assert!(!is_injective(&uv, &tris));
    }

    #[test]
    fn a_self_crossing_boundary_is_caught() {
        // A strip of 8 quads bent round so that its two ends overlap, every
        // triangle positive and every vertex angle sum below 2π.
        let mut uv = Vec::new();
        for i in 0..=8 {
            let a = i as f32 * std::f32::consts::TAU / 7.0;
            uv.push(Vec2::new(a.cos(), a.sin()) * 1.0);
            uv.push(Vec2::new(a.cos(), a.sin()) * 2.0);
        }
        let mut tris = Vec::new();
        for i in 0..8u32 {
            let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
        let positive = tris.iter().all(|t| {
            let [a, b, c] = t.map(|v| uv[v as usize]);
            (b - a).perp_dot(c - a) > 0.0
        });
        assert!(positive, "the fixture must pass the orientation test");
        assert!(!is_injective(&uv, &tris));
        // The same strip bent less (6 of 7 sectors) is fine.
        let short: Vec<[u32; 3]> = tris[..12].to_vec();
        assert!(is_injective(&uv, &short));
    }
}
