//! Tracker distribution update (Gagnon, Dagenais, Paquette 2016,
//! Sec. 3.1.3): new trackers where the atlas is uncovered, fading sinks.
//!
//! **Coverage.** A texel whose composite α stays below the coverage
//! threshold seeds a new tracker at its surface point, *below* every
//! existing patch; the new patch continues the composite of the uncovered
//! texels on its receivers, and the next uncovered texel (in texel order)
//! seeds the next tracker, until none is left. Covered texels are never
//! touched again this frame: a new patch only shows where its elders leave
//! the surface bare. The seed texel sits at the new patch's centre, where
//! mask and falloff are 1, so it is covered by its own patch; should a
//! strange surface still leave it short, it is closed with what it has and
//! counted as `forced`, so the loop ends after at most as many trackers as
//! there were uncovered texels. With the paper's rule
//! ([`super::SeedTexel::Paper`]) it is left open for the trackers still to
//! come but seeds no other, so the same bound holds.
//!
//! **Placement** ([`Placement`]): the next seed is the first open texel in
//! texel order, or, as the paper has it, a random one (uniform over the
//! open texels, which an atlas spreads evenly over the surface, so uniform
//! over the uncovered area), drawn from a generator seeded per frame.
//!
//! **Sinks.** Where the flow converges, the patch on top never leaves and
//! the layering would keep it forever. A tracker whose four frame corners
//! all move toward its centre faster than a threshold starts to fade: its
//! opacity falls each frame in proportion to the inward speed (relative to
//! the corner distance, so `sink_fade_rate` = 1 fades it out in the time
//! the flow needs to carry the corners to the centre), and it is deleted
//! once it can no longer be seen. A sink stays marked; it fades while the
//! flow still converges on it and holds where the flow stops.

use super::composite::{CompositeBuffers, CompositeContext, Heaviest, Layer, TexelOut, Uncovered};
use super::receivers::ReceiverContext;
use super::trackers::Tracker;
use crate::exemplar::set::Chooser;
use crate::methods::lapped::Pending;
use crate::surface::SurfacePoint;
use crate::surface::velocity::FlowFrame;

/// Where new trackers go.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Placement {
    /// At the first uncovered texel in texel order (the 2021 paper's rule):
    /// the same layout for the same uncovered texels, whatever the seed.
    #[default]
    First,
    /// The 2016 paper's: at a random uncovered texel, seeded per frame.
    Random,
}

crate::named!(Placement {
    First => "first",
    Random => "random",
});

/// What the coverage update did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CoverStats {
    pub created: usize,
    /// Seed texels closed below the coverage threshold.
    pub forced: usize,
}

/// Inputs of [`cover`] besides the buffers.
pub struct CoverInputs<'a> {
    pub receivers: &'a ReceiverContext<'a>,
    pub exemplar_size: f32,
    /// Rotation of the tracker created at a surface point.
    pub rotation: &'a (dyn Fn(SurfacePoint) -> f32 + Sync),
    /// [`Placement::Random`]: the frame's generator; `None`: the first
    /// open texel.
    pub placement: Option<rand_pcg::Pcg64>,
    /// A seed texel its patch leaves short is closed anyway (module doc).
    pub force_seed: bool,
}

/// Covers every texel of `uncovered` with new trackers appended to
/// `trackers` (module doc). `template` is the fill's context; its layer
/// list is replaced by the new patches one at a time.
pub fn cover(
    template: &CompositeContext<'_>,
    inputs: CoverInputs<'_>,
    trackers: &mut Vec<Tracker>,
    next_id: &mut u32,
    mut uncovered: Vec<Uncovered>,
    out: &mut CompositeBuffers,
    mut chooser: Option<&mut Chooser<'_>>,
) -> CoverStats {
    let mut stats = CoverStats::default();
    let rc = inputs.receivers;
    let mut pending = Pending::new(uncovered.iter().map(|u| u.triangle));
    let mut rng = inputs.placement;
    let mut next = |pending: &mut Pending| match rng.as_mut() {
        Some(rng) => pending.random_open(rng),
        None => pending.next_open(),
    };
    while let Some(seed) = next(&mut pending) {
        let at = SurfacePoint::new(uncovered[seed].triangle, uncovered[seed].bary);
        let id = *next_id;
        *next_id += 1;
        let angle = (inputs.rotation)(at);
        let mut tracker = Tracker::create(id, rc.mesh, rc.vertex_normals, at, rc.radius, angle);
        if let Some(c) = chooser.as_deref_mut() {
            tracker.exemplar = c.choose(at, super::location_key(at));
        }
        let layer = [Layer {
            id,
            frame: tracker.frame(inputs.exemplar_size),
            fade: tracker.fade,
            exemplar: template
                .multi
                .map_or(tracker.exemplar, |m| m.slot(tracker.exemplar, id)),
            feature: template
                .multi
                .map_or(tracker.exemplar, |m| m.feature_slot(tracker.exemplar, id)),
        }];
        let ctx = template.with_layers(&layer);
        let mut shown = composite_below(&ctx, rc, &mut pending, &mut uncovered, out);
        if !pending.is_closed(seed) {
            if inputs.force_seed {
                shown += force_seed(&ctx, &tracker, &mut uncovered[seed], out);
                pending.close(seed);
                stats.forced += 1;
            } else {
                pending.retire(seed);
            }
        }
        stats.created += 1;
        if let Some(c) = chooser.as_deref_mut() {
            c.coverage.push(tracker.position, tracker.exemplar, shown);
        }
        trackers.push(tracker);
    }
    // The paper's rule: what no tracker completed keeps what it has.
    for k in pending.open() {
        close(template, &uncovered[k], out);
    }
    stats
}

/// Composites the one new layer of `ctx` under every open texel of its
/// receivers, closing those it completes; returns what it showed.
fn composite_below(
    ctx: &CompositeContext<'_>,
    rc: &ReceiverContext<'_>,
    pending: &mut Pending,
    uncovered: &mut [Uncovered],
    out: &mut CompositeBuffers,
) -> f32 {
    let mesh = rc.mesh;
    let c = out.channels;
    let mut sample = vec![0.0f32; c];
    let mut shown = 0.0f32;
    let receivers = rc.receivers(&ctx.layers[0].frame);
    for &f in &receivers.triangles {
        let [a, b, cc] = mesh.corners(f as usize);
        let n = (b - a).cross(cc - a).normalize_or_zero();
        pending.visit_open(f, |k| {
            let u = &mut uncovered[k];
            let t = u.texel as usize;
            let x = a * u.bary[0] + b * u.bary[1] + cc * u.bary[2];
            let values = &mut out.values[t * c..(t + 1) * c];
            let shading = ctx.shading(f, u.bary, n);
            shown += ctx.add_layer(0, &shading, x, n, &mut u.sum, values, &mut sample);
            let complete = u.sum.alpha >= ctx.coverage;
            if complete {
                close(ctx, u, out);
            }
            complete
        });
    }
    shown
}

/// Closes a seed texel its own patch left short (module doc): with what
/// it has, or, where nothing showed at all, with the new patch's centre,
/// opaque. Returns what the patch showed there.
fn force_seed(
    ctx: &CompositeContext<'_>,
    tracker: &Tracker,
    u: &mut Uncovered,
    out: &mut CompositeBuffers,
) -> f32 {
    let mut shown = 0.0;
    if u.sum.alpha <= 0.0 {
        let c = out.channels;
        let t = u.texel as usize;
        let values = &mut out.values[t * c..(t + 1) * c];
        let exemplar = ctx
            .multi
            .and_then(|m| {
                let slot = m.slot(tracker.exemplar, tracker.id);
                m.exemplars.get(slot as usize)
            })
            .map_or(ctx.exemplar, |e| &**e);
        exemplar.sample_all(0.5, 0.5, values);
        shown = 1.0;
        u.sum.alpha = 1.0;
        u.sum.contributions.push(1.0);
        u.sum.heaviest = Some(Heaviest {
            id: tracker.id,
            uv: glam::Vec2::splat(0.5),
            weight: 1.0,
            lod: 0.0,
        });
    }
    close(ctx, u, out);
    shown
}

fn close(ctx: &CompositeContext<'_>, u: &Uncovered, out: &mut CompositeBuffers) {
    let t = u.texel as usize;
    let c = out.channels;
    ctx.finish(
        &u.sum,
        TexelOut {
            values: &mut out.values[t * c..(t + 1) * c],
            source: &mut out.source[t],
            uv: &mut out.uv[t],
            layers: &mut out.layers[t],
            lod: &mut out.lod[t],
        },
    );
}

/// The sink test's settings.
#[derive(Clone, Copy, Debug)]
pub struct SinkRule {
    pub radius: f32,
    /// Every corner must move toward the centre faster than this (world
    /// units per second).
    pub min_speed: f32,
    /// Fade per second per unit of (mean inward speed / corner distance).
    pub fade_rate: f32,
    pub dt: f32,
}

/// The speeds (world units per second) at which the flow carries the four
/// frame corners of `tracker` toward its centre, in the frame's plane;
/// `None` where no velocity can be sampled.
pub fn inward_speeds(tracker: &Tracker, flow: &FlowFrame<'_>, radius: f32) -> Option<[f32; 4]> {
    let n = tracker.normal;
    let mut out = [0.0; 4];
    for (o, corner) in out.iter_mut().zip(tracker.corners(radius)) {
        let dir = (corner - tracker.position).normalize_or_zero();
        let v = flow.sample(corner, radius)?;
        let v = v - n * v.dot(n);
        *o = -v.dot(dir);
    }
    Some(out)
}

/// Applies one frame of the sink rule to `tracker`: it becomes a sink when
/// every corner moves inward faster than `rule.min_speed`; a sink fades
/// by `fade_rate · dt · (mean inward speed) / (corner distance)`, so it
/// fades while the flow converges on it and holds still when the flow
/// stops (a fluid at rest must give identical frames). Returns true when
/// the tracker is a sink.
pub fn apply_sink(tracker: &mut Tracker, flow: &FlowFrame<'_>, rule: &SinkRule) -> bool {
    let Some(speeds) = inward_speeds(tracker, flow, rule.radius) else {
        return tracker.sinking;
    };
    if speeds.iter().all(|&s| s > rule.min_speed) {
        tracker.sinking = true;
    }
    let mean = speeds.iter().sum::<f32>() / 4.0;
    if tracker.sinking && mean > 0.0 {
        let corner_distance = rule.radius * std::f32::consts::FRAC_1_SQRT_2;
        let drop = rule.fade_rate * rule.dt * mean / corner_distance.max(f32::MIN_POSITIVE);
        tracker.fade = (tracker.fade - drop).max(0.0);
    }
    tracker.sinking
}
