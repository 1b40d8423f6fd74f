//! Tests of the 2016 method as a whole: rigid frames under rigid motion,
//! receiver selection, the falloff on receivers, layer order, sinks,
//! coverage, stillness, thread independence and state round trips.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::falloff::{PatchMask, angle_between};
use super::receivers::ReceiverContext;
use super::trackers::{Frame, Tracker};
use super::*;
use crate::exemplar::{Exemplar, builtin_pebbles};
use crate::mesh::{Topology, TriMesh};
use crate::methods::test_clip::{Clip, grid, scene};
use crate::methods::{FrameContext, FrameResult, Method, PreviousFrame, SOURCE_UNCOVERED};
use crate::surface::SurfaceIndex;

fn exemplar() -> Arc<Exemplar> {
    Arc::new(builtin_pebbles(64, 1))
}

fn step_all(method: &mut LappedRigid, clip: &Clip) -> Vec<FrameResult> {
    (0..clip.meshes.len())
        .map(|k| method.step(&clip.ctx(k)).expect("step"))
        .collect()
}

fn stat(r: &FrameResult, key: &str) -> u64 {
    r.stats[key].as_u64().expect("count")
}

/// Rotation about z through (0.5, 0.5, 0.5) by `angle`, the rigid-rotation scene's.
fn rotate(p: Vec3, angle: f32, about_point: bool) -> Vec3 {
    let c = if about_point {
        Vec3::splat(0.5)
    } else {
        Vec3::ZERO
    };
    let d = p - c;
    let (s, co) = angle.sin_cos();
    c + Vec3::new(co * d.x - s * d.y, s * d.x + co * d.y, d.z)
}

#[test]
fn a_rigid_rotation_keeps_every_frame_rigid_and_turns_it_with_the_flow() {
    let frames = 10;
    let c = scene("rigid-rotation", 20, frames, 96);
    let mut m = LappedRigid::new(LappedRigidParams::default(), exemplar(), 3).expect("params");
    let omega = 0.5 * std::f32::consts::PI;
    let mut first: Option<Vec<Tracker>> = None;
    let mut worst_turn = 0.0f32;
    let mut worst_drift = 0.0f32;
    let mut compared = 0;
    for k in 0..frames as usize {
        m.step(&c.ctx(k)).expect("step");
        let r = m.state().radius.expect("resolved");
        for t in &m.state().trackers {
            let d = t.tangent_tracker - t.position;
            // T at r/2 from P, perpendicular to the unit normal.
            assert!((t.normal.length() - 1.0).abs() < 1e-5);
            assert!(
                (d.length() - 0.5 * r).abs() <= 1e-4 * r,
                "tracker {} at {} r",
                t.id,
                d.length() / r
            );
            assert!(d.dot(t.normal).abs() <= 1e-4 * r, "tracker {}", t.id);
        }
        match &first {
            None => first = Some(m.state().trackers.clone()),
            Some(initial) => {
                let angle = omega * k as f32 / 24.0;
                for t in &m.state().trackers {
                    let Some(t0) = initial.iter().find(|s| s.id == t.id) else {
                        continue;
                    };
                    // P rides the rotation, and t turns with it.
                    let p = rotate(t0.position, angle, true);
                    worst_drift = worst_drift.max(p.distance(t.position) / r);
                    let want = rotate(t0.tangent(), angle, false);
                    worst_turn = worst_turn.max(angle_between(want, t.tangent()));
                    compared += 1;
                }
            }
        }
    }
    assert!(compared > 50, "only {compared} tracker frames compared");
    // Unturned, the tangent would be off by the rotation angle itself
    // (0.59 rad at frame 9). Carried, it is off by the polyhedral normal
    // and by T's velocity being read at its closest surface point
    // (measured: 0.027 rad at frame 1 growing to 0.053 at frame 9).
    assert!(worst_turn < 0.08, "tangent off by {worst_turn} rad");
    assert!(worst_drift < 0.02, "P off by {worst_drift} r");
}

/// Receivers of a frame at `p` (normal +z) on `mesh`, with radius `r`.
fn receivers_at(mesh: &TriMesh, p: Vec3, r: f32, phi_max: f32) -> Receivers {
    let topology = Topology::new(mesh.vertex_count(), &mesh.triangles);
    let normals = mesh.vertex_normals();
    let index = SurfaceIndex::new(mesh);
    let rc = ReceiverContext {
        mesh,
        topology: &topology,
        index: &index,
        vertex_normals: &normals,
        radius: r,
        phi_max: phi_max.to_radians(),
    };
    let frame = Frame {
        origin: p,
        tangent: Vec3::X,
        binormal: Vec3::Y,
        normal: Vec3::Z,
        exemplar_size: 2.6 * r,
    };
    rc.receivers(&frame)
}

#[test]
fn receivers_reject_a_disjoint_parallel_sheet() {
    // Sheet A at z = 0 and an identical, unconnected sheet B at z = 0.05,
    // both facing +z: B lies within r of P but is not connected to it.
    let a = grid(10, 0.1, |_| Vec3::ZERO);
    let mut mesh = a.clone();
    let off = mesh.positions.len() as u32;
    mesh.positions
        .extend(a.positions.iter().map(|p| *p + Vec3::Z * 0.05));
    mesh.triangles
        .extend(a.triangles.iter().map(|t| t.map(|v| v + off)));
    let p = Vec3::new(0.01, 0.02, 0.0);
    let r = 0.25;
    let got = receivers_at(&mesh, p, r, 130.0);
    let within: Vec<u32> = (0..a.triangles.len() as u32)
        .filter(|&t| {
            let [x, y, z] = a.corners(t as usize);
            crate::surface::closest_point_on_triangle(p, x, y, z).distance(p) <= r
        })
        .collect();
    assert!(!within.is_empty());
    assert_eq!(
        got.triangles, within,
        "exactly sheet A's triangles within r"
    );
    // Control: with B connected nothing would keep it out; from B's side
    // (P on B) it is A that is left out.
    let from_b = receivers_at(&mesh, p + Vec3::Z * 0.05, r, 130.0);
    assert!(
        from_b
            .triangles
            .iter()
            .all(|&t| t >= a.triangles.len() as u32)
    );
    assert_eq!(from_b.triangles.len(), within.len());
}

/// Sheet A (z = 0, x ≤ 0) and a flap B hinged on x = 0 whose normal makes
/// `fold` degrees with A's, cells of 0.1.
fn hinged(fold: f32) -> (TriMesh, usize) {
    let n = 6usize;
    let g = fold.to_radians();
    // Direction of B away from the hinge: A goes along −x; B along
    // (cos g, 0, sin g), so its normal (same winding) is +z turned by g.
    let dir = Vec3::new(g.cos(), 0.0, g.sin());
    let mut positions = Vec::new();
    let w = n + 1;
    // Columns −n..=n: negative on A, positive on B.
    let cols = 2 * n + 1;
    for j in 0..w {
        for i in 0..cols {
            let s = (i as f32 - n as f32) * 0.1;
            let y = (j as f32 - n as f32 / 2.0) * 0.1;
            positions.push(if s <= 0.0 {
                Vec3::new(s, y, 0.0)
            } else {
                dir * s + Vec3::Y * y
            });
        }
    }
    let mut triangles = Vec::new();
    let cw = cols as u32;
    for j in 0..(w - 1) as u32 {
        for i in 0..(cols - 1) as u32 {
            let a = j * cw + i;
            triangles.push([a, a + 1, a + cw + 1]);
            triangles.push([a, a + cw + 1, a + cw]);
        }
    }
    let a_triangles = 2 * n * (w - 1);
    let v = vec![Vec3::ZERO; positions.len()];
    (
        TriMesh::new(positions, triangles).with_velocity(v),
        a_triangles,
    )
}

#[test]
fn receivers_honour_phi_max() {
    let p = Vec3::new(-0.25, 0.02, 0.0);
    for (fold, phi_max, keeps_flap) in [
        (120.0f32, 130.0f32, true),
        (140.0, 130.0, false),
        (120.0, 110.0, false),
        (60.0, 130.0, true),
    ] {
        let (mesh, a_count) = hinged(fold);
        let got = receivers_at(&mesh, p, 0.45, phi_max);
        let on_flap = |t: u32| mesh.triangle_normal(t as usize).z < 0.999;
        let flap = got.triangles.iter().filter(|&&t| on_flap(t)).count();
        assert_eq!(flap > 0, keeps_flap, "fold {fold}°, φ_max {phi_max}°");
        // Every flap triangle within r is taken when the flap is.
        let within_flap = (0..mesh.triangle_count() as u32)
            .filter(|&t| on_flap(t))
            .filter(|&t| {
                let [x, y, z] = mesh.corners(t as usize);
                crate::surface::closest_point_on_triangle(p, x, y, z).distance(p) <= 0.45
            })
            .count();
        assert!(within_flap > 0);
        if keeps_flap {
            assert_eq!(flap, within_flap);
        }
        assert!(got.triangles.len() - flap >= a_count / 4);
    }
}

/// A compositing context for the falloff tests: ψ = 30° and 60°, nothing
/// dropped, one exemplar read at level 0.
fn falloff_context<'a>(
    mesh: &'a TriMesh,
    normals: &'a [Vec3],
    layers: &'a [composite::Layer],
    ex: &'a Exemplar,
    mask: &'a PatchMask,
    falloff_at: falloff::FalloffAt,
) -> composite::CompositeContext<'a> {
    composite::CompositeContext {
        mesh,
        vertex_normals: normals,
        opaque: 30f32.to_radians(),
        transparent: 60f32.to_radians(),
        falloff_at,
        composite: composite::Composite::Over,
        layers,
        exemplar: ex,
        mask,
        feature: ex.feature.sampler(),
        base_lod: None,
        coverage: 0.99,
        keep_weight: 0.0,
        multi: None,
    }
}

/// A flat grid at z = 0, its vertex normals, the test exemplar and a
/// derived mask of reach 0.4 whose feature weight and softness are both
/// `soft` (0: a hard disc).
fn flat_texels(soft: f32) -> (TriMesh, Vec<Vec3>, Arc<Exemplar>, PatchMask) {
    let mesh = grid(4, 0.25, |_| Vec3::ZERO);
    let normals = mesh.vertex_normals();
    let mask = PatchMask::Derived {
        reach: 0.4,
        feature_weight: soft,
        softness: soft,
    };
    (mesh, normals, exemplar(), mask)
}

/// An opaque, unfaded layer of exemplar size 1 centred at `origin`, its
/// frame normal turned by `tilt` (radians) from +z about the y axis, its
/// tangent +y.
fn tilted_layer(id: u32, origin: Vec3, tilt: f32) -> composite::Layer {
    let normal = Vec3::new(tilt.sin(), 0.0, tilt.cos());
    composite::Layer {
        id,
        frame: Frame {
            origin,
            tangent: Vec3::Y,
            binormal: normal.cross(Vec3::Y),
            normal,
            exemplar_size: 1.0,
        },
        fade: 1.0,
        exemplar: 0,
        feature: 0,
    }
}

#[test]
fn the_falloff_at_a_texel_equals_its_formula() {
    // One patch centred on a flat texel, its frame normal tilted by θ from
    // the surface's: the layer's contribution there is falloff(θ) (mask and
    // fade are 1 at the centre, nothing above it).
    let (mesh, normals, ex, mask) = flat_texels(0.2);
    let (psi1, psi0) = (30f32, 60f32);
    for deg in [0.0f32, 20.0, 30.0, 37.5, 45.0, 52.5, 59.0, 60.0, 75.0] {
        let layers = [tilted_layer(
            0,
            Vec3::new(0.01, 0.02, 0.0),
            deg.to_radians(),
        )];
        let ctx = falloff_context(
            &mesh,
            &normals,
            &layers,
            &ex,
            &mask,
            falloff::FalloffAt::Texel,
        );
        let mut sum = composite::TexelSum::default();
        let (mut values, mut sample) = (vec![0.0; 3], vec![0.0; 3]);
        let shading = ctx.shading(0, [1.0 / 3.0; 3], Vec3::Z);
        assert_eq!(shading.normal, Vec3::Z);
        let w = ctx.add_layer(
            0,
            &shading,
            layers[0].frame.origin,
            Vec3::Z,
            &mut sum,
            &mut values,
            &mut sample,
        );
        let want = if deg <= psi1 {
            1.0
        } else if deg >= psi0 {
            0.0
        } else {
            (psi0 - deg) / (psi0 - psi1)
        };
        assert!((w - want).abs() < 1e-4, "{deg}°: {w} != {want}");
    }
}

#[test]
fn the_papers_falloff_interpolates_the_vertex_alphas() {
    // One triangle whose corner normals lie 0°, 0° and 70° from the frame
    // normal (ψ = 30°, 60°: vertex alphas 1, 1, 0). Per vertex (the
    // paper's) the alpha at barycentrics b is b₀ + b₁; per texel it is the
    // falloff of the interpolated normal's angle, 1 at the centroid, where
    // that normal is 22° from the frame's.
    let mesh = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
    let tilt = 70f32.to_radians();
    let normals = vec![Vec3::Z, Vec3::Z, Vec3::new(tilt.sin(), 0.0, tilt.cos())];
    let ex = exemplar();
    let mask = PatchMask::Derived {
        reach: 0.4,
        feature_weight: 0.2,
        softness: 0.2,
    };
    let layers = [composite::Layer {
        id: 0,
        frame: Frame {
            origin: Vec3::new(0.3, 0.3, 0.0),
            tangent: Vec3::X,
            binormal: Vec3::Y,
            normal: Vec3::Z,
            exemplar_size: 1.0,
        },
        fade: 1.0,
        exemplar: 0,
        feature: 0,
    }];
    let ctx = |at| falloff_context(&mesh, &normals, &layers, &ex, &mask, at);
    let (texel, vertex) = (
        ctx(falloff::FalloffAt::Texel),
        ctx(falloff::FalloffAt::Vertex),
    );
    for bary in [
        [1.0 / 3.0; 3],
        [0.5, 0.25, 0.25],
        [0.1, 0.1, 0.8],
        [0.0, 0.0, 1.0],
    ] {
        let at = vertex.shading(0, bary, Vec3::Z);
        let a = vertex.falloff_alpha(0, &at);
        assert!((a - (bary[0] + bary[1])).abs() < 1e-5, "{bary:?}: {a}");
    }
    let centre = texel.shading(0, [1.0 / 3.0; 3], Vec3::Z);
    assert_eq!(texel.falloff_alpha(0, &centre), 1.0);
    assert!((vertex.falloff_alpha(0, &centre) - 2.0 / 3.0).abs() < 1e-5);
}

#[test]
fn as_printed_a_clear_mask_hides_what_lies_beneath() {
    // Two layers at one flat texel x. On top, a patch whose hard mask is
    // clear at x (x lies 0.45 from its centre, past its 0.4 reach), its
    // frame tilted by `tilt` (falloff 1 at 0°, 0.5 at 45°); beneath, a
    // patch centred at x, opaque. Over (ours): the clear mask shows the
    // patch beneath whole. As printed: the top layer scales what lies
    // beneath by 1 − falloff, so the texel shows 1 − falloff of it, and
    // nothing at all (uncovered, black) where the falloff is 1.
    let (mesh, normals, ex, mask) = flat_texels(0.0);
    let x = Vec3::new(0.4, 0.4, 0.0);
    let mut beneath = vec![0.0f32; 3];
    let below = tilted_layer(1, x, 0.0);
    let uv = below.frame.uv(x);
    ex.sample_all_lod(uv.x, uv.y, 0.0, &mut beneath);
    assert!(beneath.iter().any(|&v| v > 0.05), "a dark exemplar texel");
    for (tilt, shown) in [(0f32, 0.0f32), (45.0, 0.5)] {
        let layers = [
            tilted_layer(0, x + Vec3::new(0.0, 0.45, 0.0), tilt.to_radians()),
            below,
        ];
        let over = falloff_context(
            &mesh,
            &normals,
            &layers,
            &ex,
            &mask,
            falloff::FalloffAt::Texel,
        );
        let printed = composite::CompositeContext {
            composite: composite::Composite::Paper,
            ..over.with_layers(&layers)
        };
        for (ctx, want) in [(&over, 1.0f32), (&printed, shown)] {
            let mut sum = composite::TexelSum::default();
            let (mut values, mut sample) = (vec![0.0; 3], vec![0.0; 3]);
            let shading = ctx.shading(0, [1.0 / 3.0; 3], Vec3::Z);
            for i in 0..2 {
                ctx.add_layer(i, &shading, x, Vec3::Z, &mut sum, &mut values, &mut sample);
            }
            assert!((sum.alpha - 1.0).abs() < 1e-5, "{tilt}°: α {}", sum.alpha);
            let (mut source, mut uv, mut layers_seen, mut lod) = (0u32, glam::Vec2::ZERO, 0u8, 0.0);
            ctx.finish(
                &sum,
                composite::TexelOut {
                    values: &mut values,
                    source: &mut source,
                    uv: &mut uv,
                    layers: &mut layers_seen,
                    lod: &mut lod,
                },
            );
            for (v, b) in values.iter().zip(&beneath) {
                assert!((v - want * b).abs() < 1e-5, "{tilt}°: {v} != {want} × {b}");
            }
            let want_source = if want > 0.0 { 2 } else { SOURCE_UNCOVERED };
            assert_eq!(source, want_source, "{tilt}°, shown {want}");
        }
    }
}

/// A method holding two opaque-centred trackers on a flat grid at rest.
fn two_layer_stack(older_at: f32, younger_at: f32) -> (LappedRigid, Clip) {
    let mesh = grid(16, 0.0625, |_| Vec3::ZERO);
    let clip = Clip::from_meshes(vec![mesh.clone(), mesh], 128);
    let params = LappedRigidParams {
        radius: Some(0.3),
        // A hard mask: 1 inside the footprint, 0 outside.
        mask_feature_weight: 0.0,
        mask_softness: 0.0,
        ..Default::default()
    };
    let mut m = LappedRigid::new(params, exemplar(), 0).expect("params");
    let tracker = |id: u32, x: f32, turn: f32| {
        let p = Vec3::new(x, 0.01, 0.0);
        let t = Vec3::new(turn.cos(), turn.sin(), 0.0);
        Tracker {
            id,
            position: p,
            tangent_tracker: p + t * 0.15,
            normal: Vec3::Z,
            fade: 1.0,
            sinking: false,
            exemplar: 0,
        }
    };
    m.set_state(LappedRigidState {
        trackers: vec![tracker(0, older_at, 0.3), tracker(1, younger_at, 2.0)],
        next_id: 2,
        radius: Some(0.3),
        exemplar_size: Some(0.78),
    });
    (m, clip)
}

#[test]
fn an_older_patch_covers_a_younger_one_where_both_are_opaque() {
    for (older, younger) in [(-0.05f32, 0.05f32), (0.05, -0.05)] {
        let (mut m, clip) = two_layer_stack(older, younger);
        let r = m.step(&clip.ctx(1)).expect("step");
        let atlas = &clip.atlases[1];
        let mesh = &clip.meshes[1];
        let source = r.source.as_deref().expect("source");
        let layers = r.layers.as_deref().expect("layers");
        let colour = &r.channels[0];
        let frame0 = m.state().trackers[0].frame(0.78);
        let mut checked = 0;
        let mut younger_seen = false;
        for band in atlas.bands() {
            for span in &band.spans {
                let [a, b, c] = mesh.corners(span.triangle as usize);
                for (x, bary) in atlas.span_barycentrics(span) {
                    let p = a * bary[0] + b * bary[1] + c * bary[2];
                    let t = (span.y * atlas.width + x) as usize;
                    younger_seen |= source[t] == 2;
                    // Well inside both footprints (r = 0.3 around x = ±0.05):
                    // both opaque, the older alone shows.
                    if p.truncate().distance(Vec2::new(0.0, 0.01)) < 0.1 {
                        assert_eq!(source[t], 1, "older patch on top at {p}");
                        assert_eq!(layers[t], 1);
                        let uv = frame0.uv(p);
                        let mut want = vec![0.0; 3];
                        m.exemplar.sample_all(uv.x, uv.y, &mut want);
                        for (got, want) in colour.data[t * 3..t * 3 + 3].iter().zip(&want) {
                            assert!((got - want).abs() < 1e-5, "{got} vs {want}");
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 20, "{checked}");
        // The younger patch still shows beyond its elder's footprint.
        assert!(younger_seen);
    }
}

/// `frames` frames of one static grid carrying velocity `v`.
fn static_clip(frames: usize, v: impl Fn(Vec3) -> Vec3) -> Clip {
    let mesh = grid(32, 0.0625, v);
    Clip::from_meshes(vec![mesh; frames], 96)
}

#[test]
fn a_sink_field_fades_and_deletes_its_patches_while_a_translation_deletes_none() {
    let params = LappedRigidParams {
        radius: Some(0.25),
        ..Default::default()
    };
    // v = −2 (x, y, 0): every patch near the origin has all four corners
    // moving inward; a uniform translation has none.
    let sink = static_clip(24, |p| Vec3::new(-2.0 * p.x, -2.0 * p.y, 0.0));
    let mut m = LappedRigid::new(params.clone(), exemplar(), 5).expect("params");
    let results = step_all(&mut m, &sink);
    let sinking: u64 = results.iter().map(|r| stat(r, "patches_sinking")).sum();
    let deleted: u64 = results
        .iter()
        .map(|r| stat(r, "patches_deleted_sink"))
        .sum();
    assert!(
        sinking > 0 && deleted > 0,
        "{sinking} sinking, {deleted} deleted"
    );
    // A sink's fade never rises; in this field it falls every frame.
    let mut m = LappedRigid::new(params.clone(), exemplar(), 5).expect("params");
    let mut fades: std::collections::BTreeMap<u32, f32> = Default::default();
    for k in 0..24 {
        m.step(&sink.ctx(k)).expect("step");
        for t in m.state().trackers.iter().filter(|t| t.sinking) {
            if let Some(&before) = fades.get(&t.id) {
                assert!(t.fade < before, "{} -> {}", before, t.fade);
            }
            fades.insert(t.id, t.fade);
        }
    }
    // A patch at the sink centre fades at k·dt = 1/12 per frame: gone
    // within 12 frames of being found; nothing found sinking on frame 1
    // lives past frame 14.
    let mut m = LappedRigid::new(params.clone(), exemplar(), 5).expect("params");
    m.step(&sink.ctx(0)).expect("step");
    m.step(&sink.ctx(1)).expect("step");
    let fading: Vec<u32> = m
        .state()
        .trackers
        .iter()
        .filter(|t| t.sinking)
        .map(|t| t.id)
        .collect();
    assert!(!fading.is_empty());
    assert!(
        m.state()
            .trackers
            .iter()
            .filter(|t| t.sinking)
            .all(|t| t.fade < 1.0)
    );
    for k in 2..=14 {
        m.step(&sink.ctx(k)).expect("step");
    }
    assert!(
        m.state().trackers.iter().all(|t| !fading.contains(&t.id)),
        "sinks of frame 1 still alive at frame 14"
    );

    // The sink stops: what is fading holds still, frames are identical.
    let mut m = LappedRigid::new(params.clone(), exemplar(), 5).expect("params");
    let rest = static_clip(2, |_| Vec3::ZERO);
    for k in 0..4 {
        m.step(&sink.ctx(k)).expect("step");
    }
    assert!(m.state().trackers.iter().any(|t| t.sinking));
    let stopped = |m: &mut LappedRigid| {
        let ctx = FrameContext {
            previous: Some(PreviousFrame {
                mesh: &rest.meshes[0],
                index: &rest.indices[0],
            }),
            ..rest.ctx(1)
        };
        let r = m.step(&ctx).expect("step");
        (bits(&r), m.state().clone())
    };
    let (first, state) = stopped(&mut m);
    for _ in 0..3 {
        let (again, s) = stopped(&mut m);
        assert!(again == first, "a stopped sink changed the frame");
        assert_eq!(s, state);
    }

    let translation = static_clip(24, |_| Vec3::new(0.3, 0.1, 0.0));
    let mut m = LappedRigid::new(params, exemplar(), 5).expect("params");
    for r in step_all(&mut m, &translation) {
        assert_eq!(stat(&r, "patches_sinking"), 0);
        assert_eq!(stat(&r, "patches_deleted_sink"), 0);
    }
}

#[test]
fn every_chart_texel_is_covered_and_layers_are_counted() {
    let c = scene("vortex", 16, 4, 128);
    let mut m = LappedRigid::new(LappedRigidParams::default(), exemplar(), 1).expect("params");
    for (k, r) in step_all(&mut m, &c).iter().enumerate() {
        let source = r.source.as_deref().expect("source");
        let layers = r.layers.as_deref().expect("layers");
        let map = c.atlases[k].triangle_map();
        let alive: Vec<u32> = m.state().trackers.iter().map(|t| t.id).collect();
        for (t, &s) in source.iter().enumerate() {
            let inside = map[t] != u32::MAX;
            assert_eq!(s != crate::methods::SOURCE_OUTSIDE, inside, "texel {t}");
            if inside {
                assert_ne!(s, SOURCE_UNCOVERED, "frame {k} texel {t}");
                assert!(layers[t] >= 1);
                assert!(
                    r.channels[0].data[t * 3..t * 3 + 3]
                        .iter()
                        .all(|v| v.is_finite())
                );
            }
        }
        assert_eq!(stat(r, "uncovered_texels"), 0);
        // The last frame's sources name living patches only.
        if k + 1 == c.meshes.len() {
            for &s in source
                .iter()
                .filter(|&&s| s != crate::methods::SOURCE_OUTSIDE)
            {
                assert!(alive.binary_search(&(s - 1)).is_ok(), "source {s} deleted");
            }
        }
        assert!(
            stat(r, "blended_texels") > 0,
            "a lapped-rigid atlas blends somewhere"
        );
    }
}

#[test]
fn a_fluid_at_rest_gives_bit_identical_frames() {
    let c = static_clip(4, |_| Vec3::ZERO);
    let mut m = LappedRigid::new(LappedRigidParams::default(), exemplar(), 9).expect("params");
    let r = step_all(&mut m, &c);
    for k in 2..4 {
        assert!(r[k].channels[0].data == r[1].channels[0].data, "frame {k}");
        assert_eq!(r[k].source, r[1].source);
        assert_eq!(stat(&r[k], "patches_created"), 0);
    }
}

#[test]
fn frames_after_the_flow_stops_are_bit_identical() {
    // The stop scene ramps its vortex to zero by t = 2 s (frame 48) and
    // holds it; time runs from the scene's first frame, 0.
    let mut params = crate::scenes::default_params("stop").expect("scene");
    params.resolution = 16;
    let mut scene = crate::scenes::by_name("stop", Some(params)).expect("scene");
    let meshes: Vec<TriMesh> = (42..=52).map(|f| scene.frame(f).expect("frame")).collect();
    let c = Clip::from_meshes(meshes, 128);
    let still = (1..c.meshes.len())
        .find(|&k| c.meshes[k].positions == c.meshes[k - 1].positions)
        .expect("the scene stops")
        - 1;
    let mut m = LappedRigid::new(LappedRigidParams::default(), exemplar(), 6).expect("params");
    let r = step_all(&mut m, &c);
    // From the first frame whose mesh is the still one, nothing changes.
    for k in still + 1..r.len() {
        assert!(
            bits(&r[k]) == bits(&r[still]),
            "frame {k} differs from {still}"
        );
    }
    assert!(still + 3 < r.len());
}

fn bits(r: &FrameResult) -> Vec<u32> {
    let mut out: Vec<u32> = r
        .channels
        .iter()
        .flat_map(|c| c.data.iter().map(|v| v.to_bits()))
        .collect();
    out.extend(r.source.iter().flatten());
    out.extend(
        r.uv.iter()
            .flatten()
            .flat_map(|v| [v.x.to_bits(), v.y.to_bits()]),
    );
    out.extend(r.layers.iter().flatten().map(|&l| l as u32));
    out.extend(r.exemplar_lod.iter().flatten().map(|v| v.to_bits()));
    out
}

#[test]
fn one_and_two_threads_give_identical_results() {
    let c = scene("vortex", 16, 4, 128);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut m =
                LappedRigid::new(LappedRigidParams::default(), exemplar(), 4).expect("params");
            let r = step_all(&mut m, &c);
            let mut all: Vec<u32> = r.iter().flat_map(bits).collect();
            all.extend(m.save_state().expect("state").into_iter().map(|b| b as u32));
            all
        })
    };
    let (a, b) = (run(1), run(2));
    assert!(a == b, "outputs differ between 1 and 2 threads");
}

#[test]
fn saved_state_continues_exactly() {
    let c = scene("vortex", 16, 4, 128);
    let mut whole = LappedRigid::new(LappedRigidParams::default(), exemplar(), 2).expect("p");
    let all = step_all(&mut whole, &c);
    let mut first = LappedRigid::new(LappedRigidParams::default(), exemplar(), 2).expect("p");
    for k in 0..2 {
        first.step(&c.ctx(k)).expect("step");
    }
    let bytes = first.save_state().expect("save");
    let mut resumed = LappedRigid::new(LappedRigidParams::default(), exemplar(), 2).expect("p");
    resumed.load_state(&bytes).expect("load");
    for (k, expected) in all.iter().enumerate().skip(2) {
        let r = resumed.step(&c.ctx(k)).expect("step");
        assert!(bits(&r) == bits(expected), "frame {k} differs after resume");
    }
    assert_eq!(resumed.state(), whole.state());
    assert!(resumed.load_state(&bytes[..bytes.len() / 2]).is_err());
}

#[test]
fn bad_parameters_and_missing_velocity_are_errors() {
    let bad = [
        LappedRigidParams {
            alpha_opaque: 70.0,
            ..Default::default()
        },
        LappedRigidParams {
            alpha_transparent: 140.0,
            ..Default::default()
        },
        LappedRigidParams {
            coverage: 0.0,
            ..Default::default()
        },
        LappedRigidParams {
            radius: Some(-1.0),
            ..Default::default()
        },
        LappedRigidParams {
            mask_feature_weight: 0.9,
            mask_softness: 0.2,
            ..Default::default()
        },
    ];
    for p in bad {
        let e = LappedRigid::new(p.clone(), exemplar(), 0).err();
        assert!(e.is_some(), "{p:?} accepted");
    }
    let missing = LappedRigidParams {
        mask: Some("/nonexistent/mask.png".into()),
        ..Default::default()
    };
    let e = LappedRigid::new(missing, exemplar(), 0)
        .err()
        .expect("missing mask")
        .to_string();
    assert!(e.contains("/nonexistent/mask.png"), "{e}");
    assert!(LappedRigid::new(LappedRigidParams::default(), exemplar(), 0).is_ok());

    let mut mesh = grid(4, 0.25, |_| Vec3::ZERO);
    mesh.attributes.clear();
    let c = Clip::from_meshes(vec![mesh], 64);
    let mut m = LappedRigid::new(LappedRigidParams::default(), exemplar(), 0).expect("p");
    assert!(matches!(
        m.step(&c.ctx(0)),
        Err(MethodError::MissingVelocity { frame: 0, .. })
    ));
}

/// The 2016 paper's random placement: every texel is still covered, the
/// trackers it adds are not those of the first-texel rule, and the same
/// seed gives the same frames (another seed, others); a fluid at rest
/// still gives identical frames.
#[test]
fn random_placement_covers_every_texel_and_follows_its_seed() {
    let c = scene("vortex", 16, 4, 128);
    let run = |placement, seed| {
        let params = LappedRigidParams {
            placement,
            ..Default::default()
        };
        let mut m = LappedRigid::new(params, exemplar(), seed).expect("params");
        let results = step_all(&mut m, &c);
        let created: Vec<Vec3> = m
            .state()
            .trackers
            .iter()
            .filter(|t| t.id >= results.first().map_or(0, |r| stat(r, "patches_created")) as u32)
            .map(|t| t.position)
            .collect();
        (results, created)
    };
    use distribution::Placement::{First, Random};
    let (random, created) = run(Random, 1);
    let (again, _) = run(Random, 1);
    let (other, _) = run(Random, 2);
    let (first, first_created) = run(First, 1);
    assert!(!created.is_empty(), "later frames create trackers");
    assert_ne!(created, first_created);
    for (k, r) in random.iter().enumerate() {
        assert_eq!(stat(r, "uncovered_texels"), 0, "frame {k}");
        assert!(bits(r) == bits(&again[k]), "frame {k}: not reproducible");
    }
    let last = random.len() - 1;
    assert!(bits(&random[last]) != bits(&other[last]));
    assert!(bits(&random[last]) != bits(&first[last]));
    let rest = static_clip(3, |_| Vec3::ZERO);
    let params = LappedRigidParams {
        placement: Random,
        ..Default::default()
    };
    let mut m = LappedRigid::new(params, exemplar(), 4).expect("params");
    let r = step_all(&mut m, &rest);
    assert!(bits(&r[2]) == bits(&r[1]));
}

/// `far_fraction = 0` (the paper: no rule) keeps a tracker however far the
/// surface moved from it; the default deletes it past r/4.
#[test]
fn far_fraction_zero_never_deletes_a_tracker_for_its_distance() {
    let near = grid(8, 0.125, |_| Vec3::ZERO);
    let mut far = near.clone();
    for p in &mut far.positions {
        p.z += 0.6;
    }
    let c = Clip::from_meshes(vec![near, far], 64);
    let deleted = |far_fraction| {
        let params = LappedRigidParams {
            far_fraction,
            ..Default::default()
        };
        let mut m = LappedRigid::new(params, exemplar(), 2).expect("params");
        let r = step_all(&mut m, &c);
        let radius = m.state().radius.expect("resolved");
        assert!(0.6 > 0.25 * radius, "r = {radius}");
        (
            stat(&r[0], "patches_alive"),
            stat(&r[1], "patches_deleted_advection"),
        )
    };
    let (alive, gone) = deleted(0.25);
    assert!(alive > 0);
    assert_eq!(gone, alive);
    assert_eq!(deleted(0.0), (alive, 0));
    let bad = LappedRigidParams {
        far_fraction: 0.0005,
        ..Default::default()
    };
    assert!(LappedRigid::new(bad, exemplar(), 0).is_err());
}

/// Coverage 1 leaves seed texels a hair short of opacity (the sum of
/// partial α rounds below 1): ours closes them (`forced_texels`), the
/// paper's rule leaves them to later trackers and keeps what they have.
/// Here every such texel had some α, and no later tracker reached it, so
/// both give the same frames; only the count differs.
#[test]
fn the_papers_seed_texel_is_left_to_later_trackers() {
    let c = scene("vortex", 16, 3, 128);
    let run = |seed_texel| {
        let params = LappedRigidParams {
            coverage: 1.0,
            seed_texel,
            ..Default::default()
        };
        let mut m = LappedRigid::new(params, exemplar(), 1).expect("params");
        step_all(&mut m, &c)
    };
    let forced = run(SeedTexel::Forced);
    let paper = run(SeedTexel::Paper);
    let total = |r: &[FrameResult], key| r.iter().map(|f| stat(f, key)).sum::<u64>();
    assert!(total(&forced, "forced_texels") > 0, "the case arises");
    assert_eq!(total(&paper, "forced_texels"), 0);
    assert_eq!(total(&forced, "uncovered_texels"), 0);
    for r in &paper {
        let holes = r
            .source
            .as_deref()
            .expect("source")
            .iter()
            .filter(|&&s| s == SOURCE_UNCOVERED)
            .count() as u64;
        assert_eq!(holes, stat(r, "uncovered_texels"));
    }
    for (a, b) in forced.iter().zip(&paper) {
        assert!(bits(a) == bits(b));
    }
}
