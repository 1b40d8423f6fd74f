//! Controls of the sampler on real atlases: a sphere turning rigidly whose
//! texture turns with it (follows), stays in world space (glued), or has
//! its patch ids replaced in a known region at frame t+1.

use glam::{Mat3, Vec3};

use super::*;
use crate::atlas::AtlasParams;
use crate::atlas::fixtures::icosphere;
use crate::metrics::{Metric, SOURCE_UNCOVERED, Verdict};

/// Rotation per frame (rad) and frame time (s): 0.06 rad moves the equator
/// by 0.06 world units, ≈ 6 texels of the 512² atlas of the unit sphere.
const THETA: f32 = 0.06;
const DT: f32 = 1.0 / 24.0;

fn turned(angle: f32) -> TriMesh {
    let base = icosphere(16);
    let rot = Mat3::from_rotation_z(angle);
    let omega = Vec3::Z * (THETA / DT);
    let positions: Vec<Vec3> = base.positions.iter().map(|&p| rot * p).collect();
    let velocity = positions.iter().map(|&p| omega.cross(p)).collect();
    TriMesh::new(positions, base.triangles).with_velocity(velocity)
}

/// A smooth grey pattern and 0.3-unit cells of patch ids, both functions
/// of a point in the texture's own frame.
fn grey_of(b: Vec3) -> f32 {
    0.5 + 0.4 * (9.0 * b.x).sin() * (11.0 * b.y + 2.0 * b.z).sin() * (7.0 * b.z + 1.0).cos()
}

fn id_of(b: Vec3) -> u32 {
    let c = (b / 0.3).floor() + 8.0;
    1 + c.x as u32 + 20 * c.y as u32 + 400 * c.z as u32
}

struct Frame {
    mesh: TriMesh,
    index: SurfaceIndex,
    atlas: Atlas,
    source: Vec<u32>,
    grey: Vec<f32>,
}

impl Frame {
    /// Frame of `mesh`, the texture's frame given per world point by
    /// `body`, and an id override for a world point.
    fn new(
        mesh: TriMesh,
        body: impl Fn(Vec3) -> Vec3,
        reshuffle: impl Fn(Vec3, u32) -> u32,
    ) -> Frame {
        let atlas = Atlas::build(&mesh, &AtlasParams::square(512)).expect("atlas");
        let w = atlas.width as usize;
        let mut source = vec![SOURCE_OUTSIDE; w * atlas.height as usize];
        let mut grey = Texture::filled(atlas.width, atlas.height, 1, 0.0);
        for band in atlas.bands() {
            for span in &band.spans {
                for (x, bary) in atlas.span_barycentrics(span) {
                    let i = span.y as usize * w + x as usize;
                    let p = SurfacePoint::new(span.triangle, bary).position(&mesh);
                    source[i] = reshuffle(p, id_of(body(p)));
                    grey.data[i] = grey_of(body(p));
                }
            }
        }
        atlas.dilate(&mut grey, 8).expect("same size");
        Frame {
            index: SurfaceIndex::new(&mesh),
            mesh,
            atlas,
            source,
            grey: grey.data,
        }
    }

    fn texels(&self) -> TexelFrame<'_> {
        TexelFrame {
            atlas: &self.atlas,
            source: &self.source,
            grey: &self.grey,
            renewal: &[],
        }
    }

    fn flow(&self) -> FlowFrame<'_> {
        FlowFrame {
            mesh: &self.mesh,
            index: &self.index,
            velocity: self.mesh.velocity().expect("velocity"),
        }
    }
}

fn settings() -> CoherenceSettings {
    CoherenceSettings::from_thresholds(&Thresholds::committed().expect("committed"))
}

fn carry(a: &Frame, b: &Frame) -> Carried {
    let s = settings();
    let points = sample_surface(&a.mesh, s.samples, s.seed);
    carry_by_velocity(
        &a.mesh,
        a.mesh.velocity().expect("velocity"),
        b.flow(),
        DT,
        points,
    )
}

fn keep(_: Vec3, id: u32) -> u32 {
    id
}

/// Frame t, and frame t+1 turned by THETA with the texture turned along
/// (`follows`) or left in world space.
fn pair(follows: bool) -> (Frame, Frame) {
    let a = Frame::new(turned(0.0), |p| p, keep);
    let back = Mat3::from_rotation_z(-THETA);
    let b = if follows {
        Frame::new(turned(THETA), move |p| back * p, keep)
    } else {
        Frame::new(turned(THETA), |p| p, keep)
    };
    (a, b)
}

#[test]
fn samples_are_area_weighted_and_seeded() {
    // Two triangles of areas 1 and 3.
    let mesh = TriMesh::new(
        vec![
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(12.0, 0.0, 0.0),
            Vec3::new(10.0, 3.0, 0.0),
        ],
        vec![[0, 1, 2], [3, 4, 5]],
    );
    let s = sample_surface(&mesh, 20_000, 1);
    let first = s.iter().filter(|p| p.triangle == 0).count() as f64 / 20_000.0;
    // Binomial standard deviation of the share: 0.003.
    assert!((first - 0.25).abs() < 0.012, "{first}");
    assert!(s.iter().all(|p| {
        let sum: f32 = p.bary.iter().sum();
        p.bary.iter().all(|&b| (0.0..=1.0).contains(&b)) && (sum - 1.0).abs() < 1e-5
    }));
    assert_eq!(s, sample_surface(&mesh, 20_000, 1));
    assert_ne!(s, sample_surface(&mesh, 20_000, 2));
    assert!(sample_surface(&TriMesh::default(), 10, 1).is_empty());
}

#[test]
fn velocity_carry_lands_on_the_rigidly_turned_point() {
    let (a, b) = pair(true);
    let c = carry(&a, &b);
    let rot = Mat3::from_rotation_z(THETA);
    let mut errors: Vec<f32> = c
        .from
        .iter()
        .zip(&c.to)
        .map(|(p, q)| {
            let q = q.expect("located").position(&b.mesh);
            (q - rot * p.position(&a.mesh)).length() * b.atlas.scale as f32
        })
        .collect();
    errors.sort_by(f32::total_cmp);
    let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
    eprintln!("velocity carry error (texels): median {median:.4}, worst {worst:.4}");
    // The second-order step on a circle of radius 1 turned by 0.06 rad
    // misses it by ~θ³/6 ≈ 4e-5 units; the chordal sphere adds its flat
    // facets' distance to the exact point. Both far below a texel.
    assert!(median < 0.05 && worst < 0.3, "{median} {worst}");
}

#[test]
fn texture_turning_with_the_sphere_follows_and_glued_texture_does_not() {
    let t = Thresholds::committed().expect("committed");
    let s = settings();
    let (a, b) = pair(true);
    let follows = measure(&carry(&a, &b), &a.texels(), &b.texels(), &s).expect("valid");
    let (a, g) = pair(false);
    let glued = measure(&carry(&a, &g), &a.texels(), &g.texels(), &s).expect("valid");
    eprintln!(
        "sphere 512², 0.06 rad/frame: follows switch {:.4} ({} covered) ratio {:.3} \
         ({} moving); glued switch {:.4} ratio {:.3}",
        follows.switch_share(),
        follows.switch.covered,
        follows.follow_ratio(),
        follows.follow.moving,
        glued.switch_share(),
        glued.follow_ratio()
    );
    // Measured: follows switch 0.0251 (19 856 covered), ratio 0.001;
    // glued switch 0.2008, ratio 286 (the texture is static in world
    // space, so the unmoved colour differs only by resampling).
    // Every sample lies on a chart texel or next to one.
    assert!(
        follows.switch.covered > 19_000,
        "{}",
        follows.switch.covered
    );
    // Texel rounding at cell borders only.
    assert!(follows.switch_share() < 0.03, "{}", follows.switch_share());
    assert_eq!(
        t.verdict(Metric::ColourFollow, follows.follow_ratio()),
        Verdict::Pass
    );
    assert!(glued.switch_share() > 0.15, "{}", glued.switch_share());
    assert_eq!(
        t.switch_verdict(glued.switch_share(), follows.switch_share()),
        Verdict::Fail
    );
    assert_eq!(
        t.verdict(Metric::ColourFollow, glued.follow_ratio()),
        Verdict::Fail
    );
}

#[test]
fn ids_replaced_in_a_region_switch_by_the_region_s_share() {
    let t = Thresholds::committed().expect("committed");
    let s = settings();
    let a = Frame::new(turned(0.0), |p| p, keep);
    let back = Mat3::from_rotation_z(-THETA);
    let follows = Frame::new(turned(THETA), move |p| back * p, keep);
    // Frame t+1's ids in the cap z > 0.5 belong to other patches.
    let reshuffled = Frame::new(
        turned(THETA),
        move |p| back * p,
        |p, id| if p.z > 0.5 { id + 100_000 } else { id },
    );
    let c = carry(&a, &follows);
    let good = measure(&c, &a.texels(), &follows.texels(), &s).expect("valid");
    let bad = measure(&c, &a.texels(), &reshuffled.texels(), &s).expect("valid");
    // The share of covered samples carried into the cap.
    let in_cap =
        c.to.iter()
            .flatten()
            .filter(|q| q.position(&follows.mesh).z > 0.5)
            .count() as f64
            / c.from.len() as f64;
    // Points carried into the cap switch, and outside it those that
    // switched already (texel rounding at cell borders).
    let expected = in_cap + good.switch_share() * (1.0 - in_cap);
    eprintln!(
        "reshuffled cap: switch {:.4} against {:.4} following; cap share {in_cap:.4}",
        bad.switch_share(),
        good.switch_share()
    );
    // Measured: 0.2763 against 0.0251, cap share 0.2577; switch map: every
    // cap texel switched, 1.7 % of the rest (cell borders).
    // The cap z > 0.5 is a quarter of the sphere; points rounding across
    // its border to a texel on the other side are the only difference.
    assert!((in_cap - 0.25).abs() < 0.015, "{in_cap}");
    assert!(
        (bad.switch_share() - expected).abs() < 0.003,
        "{} vs {expected}",
        bad.switch_share()
    );
    assert_eq!(
        t.switch_verdict(bad.switch_share(), good.switch_share()),
        Verdict::Fail
    );

    // The switch map shows the cap.
    let map = switch_map(
        &a.texels(),
        a.flow(),
        &reshuffled.texels(),
        reshuffled.flow(),
        DT,
    )
    .expect("valid");
    let w = reshuffled.atlas.width as usize;
    let (mut cap, mut cap_switched, mut rest, mut rest_switched) = (0, 0, 0, 0);
    for band in reshuffled.atlas.bands() {
        for span in &band.spans {
            for (x, bary) in reshuffled.atlas.span_barycentrics(span) {
                let i = span.y as usize * w + x as usize;
                let z = SurfacePoint::new(span.triangle, bary)
                    .position(&reshuffled.mesh)
                    .z;
                let switched = match map[i] {
                    SwitchTexel::Switched => 1,
                    SwitchTexel::Same => 0,
                    _ => continue,
                };
                // One texel's width of slack around the cap's border.
                if z > 0.52 {
                    cap += 1;
                    cap_switched += switched;
                } else if z < 0.48 {
                    rest += 1;
                    rest_switched += switched;
                }
            }
        }
    }
    let (cap_share, rest_share) = (
        cap_switched as f64 / cap as f64,
        rest_switched as f64 / rest as f64,
    );
    eprintln!("switch map: cap {cap_share:.4} of {cap}, rest {rest_share:.4} of {rest}");
    assert_eq!(cap_share, 1.0);
    assert!(rest_share < 0.03, "{rest_share}");
    assert!(map.contains(&SwitchTexel::Outside));
    let image = switch_image(&map, reshuffled.atlas.width, reshuffled.atlas.height);
    assert_eq!(image.data.len(), map.len() * 3);
}

#[test]
fn same_result_for_one_and_two_threads() {
    let (a, b) = pair(true);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| {
                let c = carry(&a, &b);
                let m = measure(&c, &a.texels(), &b.texels(), &settings()).expect("valid");
                let map =
                    switch_map(&a.texels(), a.flow(), &b.texels(), b.flow(), DT).expect("valid");
                (c, m, map)
            })
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn mismatched_inputs_are_errors() {
    let (a, b) = pair(true);
    let c = carry(&a, &b);
    let short = &b.grey[..10];
    let bad = TexelFrame {
        grey: short,
        ..b.texels()
    };
    assert!(matches!(
        measure(&c, &a.texels(), &bad, &settings()),
        Err(MetricsError::Length { what: "grey", .. })
    ));
    let mut c2 = c.clone();
    c2.moved.pop();
    assert!(measure(&c2, &a.texels(), &b.texels(), &settings()).is_err());
    // Uncovered texels are not measured.
    let mut holes = b.source.clone();
    for s in holes.iter_mut().filter(|s| **s != SOURCE_OUTSIDE) {
        *s = SOURCE_UNCOVERED;
    }
    let none = TexelFrame {
        source: &holes,
        ..b.texels()
    };
    let m = measure(&c, &a.texels(), &none, &settings()).expect("valid");
    assert_eq!(m.switch.covered, 0);
    assert!(m.switch_share().is_nan());
}

/// The frame job's path (frame t looked up at its sample points when it is
/// written, frame t+1 a frame later) gives exactly what [`measure`] gives.
#[test]
fn values_kept_from_frame_t_measure_the_same() {
    let (a, b) = pair(true);
    let c = carry(&a, &b);
    let whole = measure(&c, &a.texels(), &b.texels(), &settings()).expect("valid");
    let values = point_values(&c.from, &a.texels()).expect("valid");
    let kept = measure_from(&c, &values, &b.texels(), &settings()).expect("valid");
    assert_eq!(whole, kept);
    assert!(whole.switch_share() < 0.05, "{}", whole.switch_share());
    // Values for other points are refused.
    assert!(measure_from(&c, &values[1..], &b.texels(), &settings()).is_err());
}

/// A departure taken of frame t carries its points as the step of the
/// module doc does, written out here per point, after frame t's mesh is
/// gone, and as often as asked.
#[test]
fn departure_outlives_its_frame_and_carries_by_the_second_order_step() {
    let (a, b) = pair(true);
    let s = settings();
    let points = sample_surface(&a.mesh, s.samples, s.seed);
    let velocity = a.mesh.velocity().expect("velocity");
    let hint = search_hint(&a.mesh);
    let carried: Vec<Option<Vec3>> = points
        .iter()
        .map(|sp| {
            let p = position(&a.mesh, sp)?;
            let v0 = interpolate(&a.mesh, velocity, sp)?;
            let v1 = b.flow().sample(p + v0 * DT, hint)?;
            Some(p + (v0 + v1) * (0.5 * DT))
        })
        .collect();
    let want = Carried::locate(&a.mesh, points.clone(), &carried, &b.index);
    let departure = Departure::of(&a.mesh, velocity, points.clone());
    drop(a);
    assert_eq!(departure.points(), points.as_slice());
    let first = departure.carry(b.flow(), DT);
    assert_eq!(first, want);
    assert_eq!(departure.carry(b.flow(), DT), first);
    assert!(first.to.iter().all(Option::is_some));
}

/// Per texel of `frame`'s atlas, `byte(world point)` on the charts and
/// [`RENEWAL_UNKNOWN`] off them.
fn renewal_of(frame: &Frame, byte: impl Fn(Vec3) -> u8) -> Vec<u8> {
    let w = frame.atlas.width as usize;
    let mut out = vec![RENEWAL_UNKNOWN; frame.source.len()];
    for band in frame.atlas.bands() {
        for span in &band.spans {
            for (x, bary) in frame.atlas.span_barycentrics(span) {
                let p = SurfacePoint::new(span.triangle, bary).position(&frame.mesh);
                out[span.y as usize * w + x as usize] = byte(p);
            }
        }
    }
    out
}

#[test]
fn switches_split_into_forced_and_unforced_by_the_renewal_at_their_end() {
    use crate::provenance::{RENEWAL_DISTORTED, RENEWAL_HELD};
    let s = settings();
    let a = Frame::new(turned(0.0), |p| p, keep);
    let back = Mat3::from_rotation_z(-THETA);
    // The cap z > 0.5 switches; the method says its half x > 0 was forced
    // (a holder past δ_max) and its half x < 0 was not.
    let b = Frame::new(
        turned(THETA),
        move |p| back * p,
        |p, id| if p.z > 0.5 { id + 100_000 } else { id },
    );
    let renewal = renewal_of(&b, |p| {
        if p.z > 0.5 && p.x > 0.0 {
            RENEWAL_HELD | RENEWAL_DISTORTED
        } else {
            RENEWAL_HELD
        }
    });
    let with_renewal = TexelFrame {
        renewal: &renewal,
        ..b.texels()
    };
    let c = carry(&a, &b);
    let m = measure(&c, &a.texels(), &with_renewal, &s).expect("valid");
    // Every covered point is classified, and every switch is one or the other.
    assert_eq!(m.causes.covered, m.switch.covered);
    assert_eq!(m.causes.forced + m.causes.unforced, m.switch.switched);
    // The forced ones are the switched points landing in the cap's x > 0
    // half: about half the cap (an eighth of the sphere).
    let forced_half = (c.to.iter().zip(&c.from))
        .filter(|(to, _)| {
            to.as_ref().is_some_and(|q| {
                let p = q.position(&b.mesh);
                p.z > 0.5 && p.x > 0.0
            })
        })
        .count() as f64
        / c.from.len() as f64;
    assert!((forced_half - 0.125).abs() < 0.015, "{forced_half}");
    assert!(
        (m.causes.forced_share() - forced_half).abs() < 0.005,
        "{} vs {forced_half}",
        m.causes.forced_share()
    );
    assert_eq!(m.causes.forced, m.causes.distorted);
    // Without renewal bytes nothing is classified.
    let plain = measure(&c, &a.texels(), &b.texels(), &s).expect("valid");
    assert_eq!(plain.causes, metrics::SwitchCauses::default());
    assert!(plain.causes.forced_share().is_nan());

    // The switch map paints the forced half amber and the rest red.
    let map = switch_map(&a.texels(), a.flow(), &with_renewal, b.flow(), DT).expect("valid");
    let w = b.atlas.width as usize;
    let (mut forced, mut unforced, mut wrong) = (0, 0, 0);
    for band in b.atlas.bands() {
        for span in &band.spans {
            for (x, bary) in b.atlas.span_barycentrics(span) {
                let p = SurfacePoint::new(span.triangle, bary).position(&b.mesh);
                // A texel's width of slack around the cap and its halves.
                if p.z < 0.52 || p.x.abs() < 0.02 {
                    continue;
                }
                match (map[span.y as usize * w + x as usize], p.x > 0.0) {
                    (SwitchTexel::Forced, true) => forced += 1,
                    (SwitchTexel::Switched, false) => unforced += 1,
                    (SwitchTexel::Forced, false) | (SwitchTexel::Switched, true) => wrong += 1,
                    // Chart borders whose point carried back finds no texel.
                    _ => {}
                }
            }
        }
    }
    assert!(forced > 1000 && unforced > 1000, "{forced} {unforced}");
    assert_eq!(wrong, 0);
    assert_ne!(SwitchTexel::Forced.colour(), SwitchTexel::Switched.colour());
}
