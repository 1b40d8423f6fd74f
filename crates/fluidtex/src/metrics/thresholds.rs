//! The committed pass thresholds, per-frame verdicts and summaries over
//! frames.
//!
//! `thresholds.toml` (beside this file) is compiled in, so a binary always
//! judges by the thresholds of its own commit. Each section holds one
//! metric's pass threshold(s) and the settings it is measured with: both
//! are part of what "pass" means and both are fixed before methods run.

use std::fmt;

use serde::Deserialize;

use super::MetricsError;

const FILE: &str = "metrics/thresholds.toml";
const COMMITTED: &str = include_str!("thresholds.toml");

/// The committed `thresholds.toml` as text: what a report that records
/// how it was judged (`fluidtex reproduce`'s fingerprint) hashes.
pub fn committed_text() -> &'static str {
    COMMITTED
}

/// One range check: (key, value, whether it is allowed, the allowed range).
type Check = (&'static str, f64, bool, &'static str);

/// The first failing check, in order, as an error naming its key.
fn check_all(checks: &[Check]) -> Result<(), MetricsError> {
    for &(name, value, ok, allowed) in checks {
        if !(ok && value.is_finite()) {
            return Err(MetricsError::Invalid {
                name,
                value,
                allowed,
            });
        }
    }
    Ok(())
}

/// A share: in [0, 1].
fn share(v: f64) -> bool {
    (0.0..=1.0).contains(&v)
}

/// Coverage (share of chart texels with no source).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CoverageThresholds {
    /// Largest passing share, in [0, 1]. docs/evaluation.md: 0.
    pub max_uncovered_share: f64,
}

/// Ghost fraction (share of chart texels with ≥ 2 significant layers).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GhostingThresholds {
    /// Weight from which a layer counts, in (0, 1]. docs/evaluation.md: 0.05.
    pub min_layer_weight: f32,
    /// Largest passing share, in [0, 1]. docs/evaluation.md: 0.
    pub max_share: f64,
}

/// Contrast ratio ρ = σ(output)/σ_ex.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ContrastThresholds {
    /// Smallest passing ρ (the minimum over frames must reach it). 0.95:
    /// within 5 % of the exemplar (ruling 2).
    pub min_ratio: f64,
    /// Largest passing ρ (the maximum over frames must stay below it).
    /// 1.05: a stretched texture shows more contrast than the exemplar at
    /// its level, and is no better for it.
    pub max_ratio: f64,
}

/// Distortion: area-weighted quantile of Sorkine's δ = max(σ₁/s₀, s₀/σ₂).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DistortionThresholds {
    /// The quantile, in (0, 1]. docs/evaluation.md: 0.95.
    pub quantile: f32,
    /// δ_max, the largest passing δ (inclusive), ≥ 1. 3.
    pub max_delta: f64,
}

/// Exemplar fidelity: relative sliced Wasserstein distance.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FidelityThresholds {
    /// Largest passing SWD(output, exemplar)/SWD(half, half). 2.5.
    pub max_ratio: f64,
    /// Laplacian pyramid levels, 1–8. 4.
    pub levels: u32,
    /// Side of the square patch descriptor (odd, 3–15). 7.
    pub patch_size: u32,
    /// Random projection directions, 1–4096. 128.
    pub projections: u32,
    /// Patches drawn per image and level, 16–1 048 576. 4096.
    pub patches_per_level: u32,
    /// Seed of patch positions and projections.
    pub seed: u64,
}

/// Flow fidelity.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FlowThresholds {
    /// Pixels with a slower true motion are not measured (px/frame). 0.3.
    pub min_speed_px: f32,
    /// Half-size of the search window around the predicted position (px), 1–32. 3.
    pub search_radius_px: u32,
    /// Half-size of the block matched by [`super::image_motion`] (px), 1–16. 3.
    pub block_half_px: u32,
    /// cos(angle) above which a pixel counts as aligned, in [-1, 1]. 0.9.
    pub min_cos: f32,
    /// Largest passing median end-point error (px). 0.25.
    pub max_median_epe_px: f64,
    /// Smallest passing share of aligned pixels, in [0, 1]. 0.90.
    pub min_aligned_share: f64,
    /// On a scene where the floor method (advect) itself stays below
    /// `min_aligned_share`, a method passes when its aligned share is at
    /// most this much below the floor's instead, in [0, 1]. 0.03.
    pub max_aligned_shortfall_under_floor: f64,
    /// On a scene where the floor method itself misses
    /// `max_median_epe_px`, a method passes when its median end-point
    /// error is at most this much above the floor's instead (px). 0.1.
    pub max_epe_excess_over_floor_px: f64,
}

/// Silhouette margin used by flow and popping in renders.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SilhouetteSettings {
    /// Margin from background, border and depth edges (px), 0–32. 2.
    pub radius_px: u32,
    /// Relative depth jump that makes an edge, > 0. 0.02.
    pub relative_depth_jump: f32,
}

/// Popping (warping error with the true motion).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PoppingThresholds {
    /// A pixel pops where |I₁ − warp(I₀)| > `sigma_factor` σ_ex. 0.5.
    pub sigma_factor: f32,
    /// Largest passing mean popped share over frames, in [0, 1]. 0.02.
    pub max_mean_share: f64,
    /// Largest passing popped share of any frame, in [0, 1]. 0.05.
    pub max_worst_share: f64,
    /// Scenes judged against the renewal floor instead (the vortex at
    /// T = 8 s): see [`crate::eval::judge_against_floor_on`].
    pub strong_shear_scenes: Vec<String>,
    /// A frame is *violent* where the floor method's per-frame renewal
    /// floor (the share of points its never-renewed patches pushed past
    /// δ_max on that frame alone) is above this, in [0, 1]. 0.05.
    pub violent_min_new_floor: f64,
    /// On a violent frame a method's popped share may be at most this much
    /// above the floor method's on the same frame (instead of the absolute
    /// rule), in [0, 1]. 0.02.
    pub violent_max_excess_over_floor: f64,
}

/// Source switch share (points carried by the flow whose patch changes).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SourceSwitchThresholds {
    /// Points sampled per frame pair, 100–10 000 000. 20 000.
    pub samples: u32,
    /// Seed of the sample positions.
    pub seed: u64,
    /// Largest passing excess over the floor method's share on the same
    /// frame (absolute share, 0.02 = 2 points), in [0, 1].
    pub max_excess_over_floor: f64,
    /// The method whose share is the floor ("advect").
    pub floor_method: String,
}

/// Colour follow ratio.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ColourFollowThresholds {
    /// Points moving fewer atlas texels are not compared, ≥ 0. 3.
    pub min_move_texels: f32,
    /// Frames with fewer moving points have no value, ≥ 1. 200.
    pub min_moving_samples: u32,
    /// Largest passing ratio (the worst frame must pass), > 0. 0.5.
    pub max_ratio: f64,
}

/// Static stop.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StaticStopThresholds {
    /// Frames after the stop allowed to differ from the first still one. 0.
    pub max_changed_frames: u32,
}

/// Exemplar-size cost.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SizeCostThresholds {
    /// Largest passing time(2048²)/time(256²), > 0. 1.15.
    pub max_ratio: f64,
}

/// All thresholds and measurement settings, one section per metric.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Thresholds {
    pub coverage: CoverageThresholds,
    pub ghosting: GhostingThresholds,
    pub contrast: ContrastThresholds,
    pub distortion: DistortionThresholds,
    pub fidelity: FidelityThresholds,
    pub flow: FlowThresholds,
    pub silhouette: SilhouetteSettings,
    pub popping: PoppingThresholds,
    pub source_switch: SourceSwitchThresholds,
    pub colour_follow: ColourFollowThresholds,
    pub static_stop: StaticStopThresholds,
    pub size_cost: SizeCostThresholds,
}

/// The metrics a report has a cell for. Flow fidelity has two.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Metric {
    Coverage,
    Ghosting,
    Contrast,
    Distortion,
    Fidelity,
    FlowEpe,
    FlowAligned,
    Popping,
    SourceSwitch,
    ColourFollow,
    StaticStop,
    SizeCost,
}

impl Metric {
    /// Every metric, in report order.
    pub const ALL: [Metric; 12] = [
        Metric::Coverage,
        Metric::Ghosting,
        Metric::Contrast,
        Metric::Distortion,
        Metric::Fidelity,
        Metric::FlowEpe,
        Metric::FlowAligned,
        Metric::Popping,
        Metric::SourceSwitch,
        Metric::ColourFollow,
        Metric::StaticStop,
        Metric::SizeCost,
    ];

    /// Column title of the report.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Coverage => "uncovered share",
            Metric::Ghosting => "ghost fraction",
            Metric::Contrast => "contrast ratio",
            Metric::Distortion => "distortion p95 (δ)",
            Metric::Fidelity => "SWD ratio",
            Metric::FlowEpe => "flow median EPE (px)",
            Metric::FlowAligned => "flow aligned share",
            Metric::Popping => "popping share",
            Metric::SourceSwitch => "source switch share",
            Metric::ColourFollow => "colour follow ratio",
            Metric::StaticStop => "frames changed after stop",
            Metric::SizeCost => "exemplar-size cost",
        }
    }
}

impl fmt::Display for Metric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The outcome of a threshold test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    Pass,
    Fail,
    /// Nothing was measured (no frame had samples): never a pass.
    NoData,
}

impl Verdict {
    pub(crate) fn of(pass: bool) -> Verdict {
        if pass { Verdict::Pass } else { Verdict::Fail }
    }

    pub fn is_pass(self) -> bool {
        self == Verdict::Pass
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::NoData => "n/a",
        })
    }
}

/// One metric over a sequence: a report cell, "median [min, max] PASS".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub metric: Metric,
    /// Frames with a value.
    pub frames: usize,
    /// Frames without one (NaN: nothing to measure), left out of the rest.
    pub skipped: usize,
    /// Lower median (the ⌈n/2⌉-th smallest value).
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    pub verdict: Verdict,
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:.4} [{:.4}, {:.4}] {}",
            self.median, self.min, self.max, self.verdict
        )
    }
}

impl Thresholds {
    /// The thresholds committed with this build.
    pub fn committed() -> Result<Thresholds, MetricsError> {
        Thresholds::from_toml(COMMITTED)
    }

    /// Parses and validates a thresholds file (for tests of the parser; the
    /// evaluation uses [`Thresholds::committed`]).
    pub fn from_toml(text: &str) -> Result<Thresholds, MetricsError> {
        let t: Thresholds = toml::from_str(text).map_err(|e| MetricsError::Thresholds {
            file: FILE,
            message: e.message().to_string(),
        })?;
        t.validate()?;
        Ok(t)
    }

    fn validate(&self) -> Result<(), MetricsError> {
        check_all(&self.image_checks())?;
        check_all(&self.motion_checks())?;
        check_all(&self.popping_checks())?;
        if self.source_switch.floor_method.trim().is_empty() {
            return Err(MetricsError::Thresholds {
                file: FILE,
                message: "source_switch.floor_method is empty".into(),
            });
        }
        check_all(&self.follow_checks())
    }

    /// Range checks of the single-image metrics.
    fn image_checks(&self) -> Vec<Check> {
        let (c, g, d, f) = (
            &self.coverage,
            &self.ghosting,
            &self.distortion,
            &self.fidelity,
        );
        let w = g.min_layer_weight as f64;
        let q = d.quantile as f64;
        let r = self.contrast.min_ratio;
        vec![
            (
                "coverage.max_uncovered_share",
                c.max_uncovered_share,
                share(c.max_uncovered_share),
                "[0, 1]",
            ),
            (
                "ghosting.min_layer_weight",
                w,
                w > 0.0 && w <= 1.0,
                "(0, 1]",
            ),
            (
                "ghosting.max_share",
                g.max_share,
                share(g.max_share),
                "[0, 1]",
            ),
            ("contrast.min_ratio", r, r > 0.0, "(0, inf)"),
            (
                "contrast.max_ratio",
                self.contrast.max_ratio,
                self.contrast.max_ratio >= r,
                "[contrast.min_ratio, inf)",
            ),
            ("distortion.quantile", q, q > 0.0 && q <= 1.0, "(0, 1]"),
            (
                "distortion.max_delta",
                d.max_delta,
                d.max_delta >= 1.0,
                "[1, inf)",
            ),
            (
                "fidelity.max_ratio",
                f.max_ratio,
                f.max_ratio > 0.0,
                "(0, inf)",
            ),
            (
                "fidelity.levels",
                f.levels as f64,
                (1..=8).contains(&f.levels),
                "1..=8",
            ),
            (
                "fidelity.patch_size",
                f.patch_size as f64,
                (3..=15).contains(&f.patch_size) && f.patch_size % 2 == 1,
                "odd, 3..=15",
            ),
            (
                "fidelity.projections",
                f.projections as f64,
                (1..=4096).contains(&f.projections),
                "1..=4096",
            ),
            (
                "fidelity.patches_per_level",
                f.patches_per_level as f64,
                (16..=1 << 20).contains(&f.patches_per_level),
                "16..=1048576",
            ),
        ]
    }

    /// Range checks of the metrics over frame pairs and renders.
    fn motion_checks(&self) -> Vec<Check> {
        let (fl, s) = (&self.flow, &self.silhouette);
        vec![
            (
                "flow.min_speed_px",
                fl.min_speed_px as f64,
                fl.min_speed_px >= 0.0,
                "[0, inf)",
            ),
            (
                "flow.search_radius_px",
                fl.search_radius_px as f64,
                (1..=32).contains(&fl.search_radius_px),
                "1..=32",
            ),
            (
                "flow.block_half_px",
                fl.block_half_px as f64,
                (1..=16).contains(&fl.block_half_px),
                "1..=16",
            ),
            (
                "flow.min_cos",
                fl.min_cos as f64,
                (-1.0..=1.0).contains(&fl.min_cos),
                "[-1, 1]",
            ),
            (
                "flow.max_median_epe_px",
                fl.max_median_epe_px,
                fl.max_median_epe_px >= 0.0,
                "[0, inf)",
            ),
            (
                "flow.min_aligned_share",
                fl.min_aligned_share,
                share(fl.min_aligned_share),
                "[0, 1]",
            ),
            (
                "flow.max_aligned_shortfall_under_floor",
                fl.max_aligned_shortfall_under_floor,
                share(fl.max_aligned_shortfall_under_floor),
                "[0, 1]",
            ),
            (
                "flow.max_epe_excess_over_floor_px",
                fl.max_epe_excess_over_floor_px,
                fl.max_epe_excess_over_floor_px >= 0.0,
                "[0, inf)",
            ),
            (
                "silhouette.radius_px",
                s.radius_px as f64,
                s.radius_px <= 32,
                "0..=32",
            ),
            (
                "silhouette.relative_depth_jump",
                s.relative_depth_jump as f64,
                s.relative_depth_jump > 0.0,
                "(0, inf)",
            ),
        ]
    }

    /// Range checks of popping and the source switch share.
    fn popping_checks(&self) -> Vec<Check> {
        let (p, sw) = (&self.popping, &self.source_switch);
        vec![
            (
                "popping.sigma_factor",
                p.sigma_factor as f64,
                p.sigma_factor > 0.0,
                "(0, inf)",
            ),
            (
                "popping.max_mean_share",
                p.max_mean_share,
                share(p.max_mean_share),
                "[0, 1]",
            ),
            (
                "popping.max_worst_share",
                p.max_worst_share,
                share(p.max_worst_share),
                "[0, 1]",
            ),
            (
                "popping.violent_min_new_floor",
                p.violent_min_new_floor,
                share(p.violent_min_new_floor),
                "[0, 1]",
            ),
            (
                "popping.violent_max_excess_over_floor",
                p.violent_max_excess_over_floor,
                share(p.violent_max_excess_over_floor),
                "[0, 1]",
            ),
            (
                "source_switch.samples",
                sw.samples as f64,
                (100..=10_000_000).contains(&sw.samples),
                "100..=10000000",
            ),
            (
                "source_switch.max_excess_over_floor",
                sw.max_excess_over_floor,
                share(sw.max_excess_over_floor),
                "[0, 1]",
            ),
        ]
    }

    /// Range checks of colour following and the size cost.
    fn follow_checks(&self) -> Vec<Check> {
        let cf = &self.colour_follow;
        let size = self.size_cost.max_ratio;
        vec![
            (
                "colour_follow.min_move_texels",
                cf.min_move_texels as f64,
                cf.min_move_texels >= 0.0,
                "[0, inf)",
            ),
            (
                "colour_follow.min_moving_samples",
                cf.min_moving_samples as f64,
                cf.min_moving_samples >= 1,
                "1 or more",
            ),
            (
                "colour_follow.max_ratio",
                cf.max_ratio,
                cf.max_ratio > 0.0,
                "(0, inf)",
            ),
            ("size_cost.max_ratio", size, size > 0.0, "(0, inf)"),
        ]
    }

    /// The verdict on one frame's value (one sequence's value for
    /// [`Metric::StaticStop`] and [`Metric::SizeCost`]). NaN is
    /// [`Verdict::NoData`]. A single frame of popping is judged against the
    /// worst-frame threshold. The source switch share has no absolute
    /// threshold: it is judged against the floor method's share on the same
    /// frame ([`Thresholds::switch_verdict`]), so here it is always
    /// [`Verdict::NoData`].
    pub fn verdict(&self, metric: Metric, value: f64) -> Verdict {
        if value.is_nan() {
            return Verdict::NoData;
        }
        Verdict::of(match metric {
            Metric::Coverage => value <= self.coverage.max_uncovered_share,
            Metric::Ghosting => value <= self.ghosting.max_share,
            Metric::Contrast => {
                value >= self.contrast.min_ratio && value <= self.contrast.max_ratio
            }
            Metric::Distortion => value <= self.distortion.max_delta,
            Metric::Fidelity => value <= self.fidelity.max_ratio,
            Metric::FlowEpe => value <= self.flow.max_median_epe_px,
            Metric::FlowAligned => value >= self.flow.min_aligned_share,
            Metric::Popping => value <= self.popping.max_worst_share,
            Metric::SourceSwitch => return Verdict::NoData,
            Metric::ColourFollow => value <= self.colour_follow.max_ratio,
            Metric::StaticStop => value <= self.static_stop.max_changed_frames as f64,
            Metric::SizeCost => value <= self.size_cost.max_ratio,
        })
    }

    /// Summarises per-frame values and judges the sequence:
    /// - coverage, ghosting, distortion, fidelity, static stop, size cost:
    ///   the worst (largest) value must pass;
    /// - contrast: the smallest and the largest ρ must pass (every frame
    ///   within 5 % of the exemplar);
    /// - flow EPE and aligned share: the median over frames must pass. The
    ///   median, because a frame's flow is measured on the pixels that move
    ///   faster than `flow.min_speed_px`, and near a stop or a reversal of
    ///   the flow those are few and at the edge of the measurable;
    /// - popping: the mean must pass `max_mean_share` and the worst frame
    ///   `max_worst_share`;
    /// - colour follow ratio: the worst (largest) frame must pass;
    /// - source switch share: [`Verdict::NoData`] here; the report judges it
    ///   against the floor method with [`Thresholds::summarize_against_floor`].
    ///
    /// NaN values (frames with nothing to measure) are skipped; no values
    /// at all give [`Verdict::NoData`].
    pub fn summarize(&self, metric: Metric, values: &[f64]) -> Summary {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
        v.sort_unstable_by(f64::total_cmp);
        let skipped = values.len() - v.len();
        let (Some(&min), Some(&max)) = (v.first(), v.last()) else {
            return Summary {
                metric,
                frames: 0,
                skipped,
                median: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
                mean: f64::NAN,
                verdict: Verdict::NoData,
            };
        };
        let median = v[(v.len() - 1) / 2];
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let verdict = match metric {
            Metric::Contrast => Verdict::of(
                self.verdict(metric, min).is_pass() && self.verdict(metric, max).is_pass(),
            ),
            Metric::FlowEpe | Metric::FlowAligned => self.verdict(metric, median),
            Metric::Popping => Verdict::of(
                mean <= self.popping.max_mean_share && max <= self.popping.max_worst_share,
            ),
            Metric::SourceSwitch => Verdict::NoData,
            Metric::Coverage
            | Metric::Ghosting
            | Metric::ColourFollow
            | Metric::Distortion
            | Metric::Fidelity
            | Metric::StaticStop
            | Metric::SizeCost => self.verdict(metric, max),
        };
        Summary {
            metric,
            frames: v.len(),
            skipped,
            median,
            min,
            max,
            mean,
            verdict,
        }
    }
}

impl Thresholds {
    /// The source switch verdict of one frame: `share` may exceed the floor
    /// method's `floor` share on the same frame by at most
    /// `source_switch.max_excess_over_floor` (inclusive). NaN on either side
    /// is [`Verdict::NoData`].
    pub fn switch_verdict(&self, share: f64, floor: f64) -> Verdict {
        if share.is_nan() || floor.is_nan() {
            return Verdict::NoData;
        }
        // A hair of tolerance so that "exactly 2 points more" passes although
        // shares are ratios of counts (0.05 - 0.03 is not 0.02 in binary).
        Verdict::of(share - floor <= self.source_switch.max_excess_over_floor + 1e-12)
    }

    /// Summarises a method's per-frame source switch shares and judges them
    /// against the floor method's shares on the same frames (`floor[i]` is
    /// frame i's, as `values[i]`): every frame measured by both must pass
    /// [`Thresholds::switch_verdict`]. No frame measured by both is
    /// [`Verdict::NoData`]. The spread (median, min, max) is the method's
    /// own.
    pub fn summarize_against_floor(&self, values: &[f64], floor: &[f64]) -> Summary {
        let mut s = self.summarize(Metric::SourceSwitch, values);
        let verdicts: Vec<Verdict> = values
            .iter()
            .zip(floor)
            .map(|(&v, &f)| self.switch_verdict(v, f))
            .filter(|v| *v != Verdict::NoData)
            .collect();
        s.verdict = if verdicts.is_empty() {
            Verdict::NoData
        } else {
            Verdict::of(verdicts.iter().all(|v| v.is_pass()))
        };
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn committed() -> Thresholds {
        Thresholds::committed().expect("the committed thresholds parse")
    }

    #[test]
    fn committed_file_holds_the_evaluation_values() {
        let t = committed();
        assert_eq!(t.coverage.max_uncovered_share, 0.0);
        assert_eq!(t.ghosting.min_layer_weight, 0.05);
        assert_eq!(t.ghosting.max_share, 0.0);
        assert_eq!(t.contrast.min_ratio, 0.95);
        assert_eq!(t.contrast.max_ratio, 1.05);
        assert_eq!(t.distortion.quantile, 0.95);
        assert_eq!(t.distortion.max_delta, 3.0);
        assert_eq!(t.fidelity.max_ratio, 2.5);
        assert_eq!(t.fidelity.levels, 4);
        assert_eq!(t.fidelity.patch_size, 7);
        assert_eq!(t.fidelity.projections, 128);
        assert_eq!(t.flow.min_speed_px, 0.3);
        assert_eq!(t.flow.min_cos, 0.9);
        assert_eq!(t.flow.max_median_epe_px, 0.25);
        assert_eq!(t.flow.min_aligned_share, 0.90);
        assert_eq!(t.flow.max_aligned_shortfall_under_floor, 0.03);
        assert_eq!(t.flow.max_epe_excess_over_floor_px, 0.1);
        assert_eq!(t.popping.violent_min_new_floor, 0.05);
        assert_eq!(t.popping.violent_max_excess_over_floor, 0.02);
        assert_eq!(t.popping.sigma_factor, 0.5);
        assert_eq!(t.popping.max_mean_share, 0.02);
        assert_eq!(t.popping.max_worst_share, 0.05);
        assert_eq!(t.popping.strong_shear_scenes, ["vortex"]);
        assert_eq!(t.static_stop.max_changed_frames, 0);
        assert_eq!(t.size_cost.max_ratio, 1.15);
        assert_eq!(t.source_switch.samples, 20_000);
        assert_eq!(t.source_switch.max_excess_over_floor, 0.02);
        assert_eq!(t.source_switch.floor_method, "advect");
        assert_eq!(t.colour_follow.min_move_texels, 3.0);
        assert_eq!(t.colour_follow.max_ratio, 0.5);
    }

    #[test]
    fn out_of_range_and_unknown_keys_are_named() {
        let bad = COMMITTED.replace("quantile = 0.95", "quantile = 1.5");
        assert_eq!(
            Thresholds::from_toml(&bad),
            Err(MetricsError::Invalid {
                name: "distortion.quantile",
                value: 1.5,
                allowed: "(0, 1]"
            })
        );
        let bad = COMMITTED.replace("patch_size = 7", "patch_size = 8");
        assert!(matches!(
            Thresholds::from_toml(&bad),
            Err(MetricsError::Invalid {
                name: "fidelity.patch_size",
                ..
            })
        ));
        let unknown = COMMITTED.replace("max_ratio = 1.15", "max_ratio = 1.15\nmax_ratoi = 2");
        let err = Thresholds::from_toml(&unknown).expect_err("unknown key");
        assert!(err.to_string().contains("max_ratoi"), "{err}");
        let missing = COMMITTED.replace("min_cos = 0.9", "");
        let err = Thresholds::from_toml(&missing).expect_err("missing key");
        assert!(err.to_string().contains("min_cos"), "{err}");
    }

    #[test]
    fn verdicts_at_and_beyond_each_threshold() {
        let t = committed();
        use Verdict::{Fail, NoData, Pass};
        let cases = [
            (Metric::Coverage, 0.0, Pass),
            (Metric::Coverage, 1e-9, Fail),
            (Metric::Ghosting, 0.0, Pass),
            (Metric::Ghosting, 1e-9, Fail),
            (Metric::Contrast, 0.95, Pass),
            (Metric::Contrast, 0.949, Fail),
            (Metric::Contrast, 1.05, Pass),
            (Metric::Contrast, 1.051, Fail),
            (Metric::Distortion, 3.0, Pass),
            (Metric::Distortion, 3.001, Fail),
            (Metric::Distortion, f64::INFINITY, Fail),
            (Metric::Fidelity, 2.5, Pass),
            (Metric::Fidelity, 2.51, Fail),
            (Metric::FlowEpe, 0.25, Pass),
            (Metric::FlowEpe, 0.26, Fail),
            (Metric::FlowAligned, 0.90, Pass),
            (Metric::FlowAligned, 0.89, Fail),
            (Metric::Popping, 0.05, Pass),
            (Metric::Popping, 0.051, Fail),
            (Metric::StaticStop, 0.0, Pass),
            (Metric::StaticStop, 1.0, Fail),
            (Metric::SizeCost, 1.15, Pass),
            (Metric::SizeCost, 1.16, Fail),
            (Metric::ColourFollow, 0.5, Pass),
            (Metric::ColourFollow, 0.501, Fail),
            (Metric::SourceSwitch, 0.01, NoData),
            (Metric::Contrast, f64::NAN, NoData),
        ];
        for (metric, value, expected) in cases {
            assert_eq!(t.verdict(metric, value), expected, "{metric} = {value}");
        }
    }

    #[test]
    fn summaries_aggregate_as_documented() {
        let t = committed();
        // Contrast: every frame within 5 % of the exemplar.
        let s = t.summarize(Metric::Contrast, &[1.0, 0.95, 0.89, f64::NAN]);
        assert_eq!((s.frames, s.skipped), (3, 1));
        assert_eq!((s.median, s.min, s.max), (0.95, 0.89, 1.0));
        assert_eq!(s.verdict, Verdict::Fail);
        let s = t.summarize(Metric::Contrast, &[1.0, 0.96, 1.04]);
        assert_eq!(s.verdict, Verdict::Pass);
        let s = t.summarize(Metric::Contrast, &[1.0, 0.96, 1.06]);
        assert_eq!(
            s.verdict,
            Verdict::Fail,
            "a stretched frame is too contrasted"
        );
        // Flow EPE: judged by the median, one bad frame of three passes.
        let s = t.summarize(Metric::FlowEpe, &[0.1, 3.0, 0.2]);
        assert_eq!((s.median, s.verdict), (0.2, Verdict::Pass));
        // Popping: mean 0.0225 > 0.02 fails though no frame exceeds 5%.
        let s = t.summarize(Metric::Popping, &[0.01, 0.035]);
        assert!((s.mean - 0.0225).abs() < 1e-12);
        assert_eq!(s.verdict, Verdict::Fail);
        // Popping: mean 0.0175 passes, worst 0.03 passes.
        let s = t.summarize(Metric::Popping, &[0.005, 0.03]);
        assert_eq!(s.verdict, Verdict::Pass);
        // Popping: a single frame above 5% fails whatever the mean.
        let mut calm = vec![0.0; 9];
        calm.push(0.06);
        let s = t.summarize(Metric::Popping, &calm);
        assert_eq!(s.verdict, Verdict::Fail);
        // Coverage: judged by the worst frame.
        let s = t.summarize(Metric::Coverage, &[0.0, 0.0, 0.001]);
        assert_eq!(s.verdict, Verdict::Fail);
        // No frame measured is no pass.
        let s = t.summarize(Metric::FlowAligned, &[f64::NAN]);
        assert_eq!((s.frames, s.verdict), (0, Verdict::NoData));
        assert_eq!(s.verdict.to_string(), "n/a");
        // Colour follow: judged by the worst frame.
        let s = t.summarize(Metric::ColourFollow, &[0.2, 0.3, 0.51]);
        assert_eq!(s.verdict, Verdict::Fail);
    }

    #[test]
    fn source_switch_is_judged_frame_by_frame_against_the_floor() {
        let t = committed();
        use Verdict::{Fail, NoData, Pass};
        // Exactly 2 points above the floor passes, a little more fails.
        assert_eq!(t.switch_verdict(0.05, 0.03), Pass);
        assert_eq!(t.switch_verdict(0.0501, 0.03), Fail);
        assert_eq!(t.switch_verdict(0.01, 0.03), Pass);
        assert_eq!(t.switch_verdict(f64::NAN, 0.03), NoData);
        // One frame 3 points above its floor fails the sequence, although
        // the medians are within 2 points of each other.
        let floor = [0.03, 0.03, 0.02, f64::NAN];
        let s = t.summarize_against_floor(&[0.04, 0.05, 0.05, 0.30], &floor);
        assert_eq!(s.verdict, Fail);
        assert_eq!((s.frames, s.median), (4, 0.05));
        let s = t.summarize_against_floor(&[0.04, 0.05, 0.04, 0.30], &floor);
        assert_eq!(s.verdict, Pass);
        // The floor method against itself passes; nothing shared: n/a.
        let s = t.summarize_against_floor(&floor, &floor);
        assert_eq!(s.verdict, Pass);
        let s = t.summarize_against_floor(&[0.1], &[f64::NAN]);
        assert_eq!(s.verdict, NoData);
    }
}
