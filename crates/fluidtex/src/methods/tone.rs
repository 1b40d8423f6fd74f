//! Tone matching: per frame, every channel of a lapped composite is moved
//! by one affine map so that its mean and variance over the covered texels
//! are those of the exemplar as shown.
//!
//! **Why.** The 2021 method's compositing is feature-guided: where a patch
//! erodes, it keeps its high-feature texels (stone tops, bright foam) and
//! lets the next patch through in its low-feature ones (crevices). Every
//! eroding layer is one more such draw, so the visible texels are biased
//! towards high features, and with them towards whatever colour the
//! features have: on the built-in pebbles, whose feature map is their
//! height, a dam break's atlas is 4.6 % brighter than the exemplar on its
//! first frame and 15 % brighter once the surface is fragmented, while a
//! texture carried without erosion stays within 0.5 %. An artist picks an
//! exemplar for its look, so the default undoes that drift; the paper's
//! composite, untouched, is [`Tone::Off`]. Texture synthesis has long
//! matched output statistics to the exemplar's (histogram matching); a
//! per-channel affine map is its mildest form: it keeps every texel's rank
//! and every edge, only the level and the contrast of the whole move.
//!
//! **Modes** ([`Tone`]). `mean` (the default) shifts each channel so that
//! its mean is the exemplar's: on the dam break the drift is in the level
//! (+15 %), while the contrast the texels show stays within 2–3 % of the
//! exemplar's as shown. `match` also scales each channel about its mean to
//! the exemplar's variance as shown; that gain scales every frame-to-frame
//! difference too, so it costs a little popping where the contrast was
//! already close. `off` is the paper's composite.
//!
//! **Reference.** The mean of each channel is the exemplar's; the variance
//! is the mean, over the covered texels, of the variance the sampler shows
//! at each texel's mip level ([`ExemplarTone`]): what an unbiased mosaic
//! read at the same levels would have. With several exemplars per surface,
//! each exemplar's texels are matched to its own statistics.
//!
//! **Over time.** The map is computed from each frame's composite: a
//! function of that composite alone, so a frame that repeats (the flow has
//! stopped) repeats bit for bit, and a resumed run gives the same frames.
//! The composite's statistics change slowly (a fraction of a percent per
//! frame on the dam break), so the map does too.
//!
//! **Determinism.** Sums run in f64 over fixed chunks of texels, in
//! parallel, and the chunks' sums are added in chunk order: the same bits
//! for any thread count.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::exemplar::tone::ExemplarTone;
use crate::provenance::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};

/// Whether a method matches its composite's tone to the exemplar's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Tone {
    /// Per frame, each channel's mean over the covered texels is moved to
    /// the exemplar's (a shift; gain 1).
    #[default]
    Mean,
    /// The mean as with `Mean`, and each channel's variance is scaled to
    /// the exemplar's as shown (module doc). The gain scales every
    /// frame-to-frame difference with it, so a composite whose contrast is
    /// already close pays a little popping for it.
    Match,
    /// The composite as the paper's compositing makes it.
    Off,
}

crate::named!(Tone {
    Mean => "mean",
    Match => "match",
    Off => "off",
});

/// Texels per chunk of the statistics pass: a fixed size, so the chunks
/// (and the order their sums are added in) do not depend on the threads.
const CHUNK: usize = 1 << 15;

/// The gain of a channel is kept in this range: a composite whose variance
/// is wildly off its reference (a frame covered by a handful of flat
/// texels) is not stretched into noise.
pub const GAIN_RANGE: (f64, f64) = (0.5, 2.0);

/// The map applied to one exemplar's texels, per channel:
/// `v ← target_mean + (v − mean) · gain`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ToneMap {
    /// Covered texels of this exemplar.
    pub texels: u64,
    /// The composite's mean per channel before the map.
    pub mean: Vec<f64>,
    /// The exemplar's mean per channel.
    pub target_mean: Vec<f64>,
    /// sqrt(reference variance / composite variance), clamped to
    /// [`GAIN_RANGE`] ([`Tone::Match`]); 1 where either variance is 0, and
    /// always 1 with [`Tone::Mean`].
    pub gain: Vec<f64>,
}

/// Running sums of one exemplar's texels.
#[derive(Clone, Debug, PartialEq)]
struct Sums {
    n: u64,
    sum: Vec<f64>,
    sum_sq: Vec<f64>,
    reference: Vec<f64>,
}

impl Sums {
    fn new(c: usize) -> Sums {
        Sums {
            n: 0,
            sum: vec![0.0; c],
            sum_sq: vec![0.0; c],
            reference: vec![0.0; c],
        }
    }

    fn add(&mut self, other: &Sums) {
        self.n += other.n;
        for (a, b) in [
            (&mut self.sum, &other.sum),
            (&mut self.sum_sq, &other.sum_sq),
            (&mut self.reference, &other.reference),
        ] {
            a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
        }
    }

    fn map(&self, tone: &ExemplarTone, contrast: bool) -> ToneMap {
        let n = self.n.max(1) as f64;
        let c = self.sum.len();
        let mean: Vec<f64> = self.sum.iter().map(|s| s / n).collect();
        let gain = (0..c)
            .map(|ch| {
                let var = self.sum_sq[ch] / n - mean[ch] * mean[ch];
                let reference = self.reference[ch] / n;
                if contrast && var > 1e-12 && reference > 1e-12 {
                    (reference / var).sqrt().clamp(GAIN_RANGE.0, GAIN_RANGE.1)
                } else {
                    1.0
                }
            })
            .collect();
        ToneMap {
            texels: self.n,
            mean,
            target_mean: tone.mean.clone(),
            gain,
        }
    }
}

/// Matches the tone of the covered texels of an interleaved composite
/// (`channels` values per texel, `source` per texel as in
/// [`crate::provenance`], `lods` the mip level each texel was read at or
/// `None` for level 0 everywhere) as `mode` says. `exemplar_of(source)` is
/// the index in `tones` of the texel's exemplar. Returns the map applied
/// per exemplar (`texels` 0 and gain 1 for an exemplar no texel shows).
/// Values of texels outside the charts or uncovered are left as they are;
/// so is everything with [`Tone::Off`], or for a composite whose sizes
/// disagree, or whose channel count differs from an exemplar's (then no
/// map is returned).
pub fn match_tone(
    mode: Tone,
    values: &mut [f32],
    channels: usize,
    source: &[u32],
    lods: Option<&[f32]>,
    exemplar_of: impl Fn(u32) -> usize + Sync,
    tones: &[ExemplarTone],
) -> Vec<ToneMap> {
    let c = channels;
    let n = source.len();
    let sizes_agree = c > 0
        && values.len() == n * c
        && lods.is_none_or(|l| l.len() == n)
        && tones.iter().all(|t| t.channels() == c);
    if mode == Tone::Off || !sizes_agree || tones.is_empty() {
        return Vec::new();
    }
    let contrast = mode == Tone::Match;
    let group = |s: u32| (s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED).then(|| exemplar_of(s));
    let partial: Vec<Vec<Sums>> = source
        .par_chunks(CHUNK)
        .zip(values.par_chunks(CHUNK * c))
        .enumerate()
        .map(|(k, (source, values))| {
            let mut sums = vec![Sums::new(c); tones.len()];
            for (i, (&s, v)) in source.iter().zip(values.chunks_exact(c)).enumerate() {
                let Some(g) = group(s).filter(|&g| g < tones.len()) else {
                    continue;
                };
                let lod = lods.map_or(0.0, |l| l[k * CHUNK + i]);
                let sums = &mut sums[g];
                sums.n += 1;
                for ((sum, sum_sq), &x) in sums.sum.iter_mut().zip(&mut sums.sum_sq).zip(v) {
                    let x = f64::from(x);
                    *sum += x;
                    *sum_sq += x * x;
                }
                if contrast {
                    tones[g].add_variance_at(lod, &mut sums.reference);
                }
            }
            sums
        })
        .collect();
    let mut total = vec![Sums::new(c); tones.len()];
    for sums in &partial {
        for (t, s) in total.iter_mut().zip(sums) {
            t.add(s);
        }
    }
    let maps: Vec<ToneMap> = total
        .iter()
        .zip(tones)
        .map(|(s, t)| s.map(t, contrast))
        .collect();
    // f32 coefficients: v' = a + v·g with a = target − mean·g.
    let coefficients: Vec<Vec<(f32, f32)>> = maps
        .iter()
        .map(|m| {
            (0..c)
                .map(|ch| {
                    let g = m.gain[ch];
                    ((m.target_mean[ch] - m.mean[ch] * g) as f32, g as f32)
                })
                .collect()
        })
        .collect();
    values
        .par_chunks_mut(CHUNK * c)
        .zip(source.par_chunks(CHUNK))
        .for_each(|(values, source)| {
            for (&s, v) in source.iter().zip(values.chunks_exact_mut(c)) {
                let Some(coefficients) = group(s).and_then(|g| coefficients.get(g)) else {
                    continue;
                };
                for (x, &(a, g)) in v.iter_mut().zip(coefficients) {
                    *x = a + *x * g;
                }
            }
        });
    maps
}

#[cfg(test)]
mod tests;
