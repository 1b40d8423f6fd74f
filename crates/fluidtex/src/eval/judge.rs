//! The verdicts that need more than one run: each method's switch share,
//! popping and aligned share judged against the floor method's on the
//! same scene and frames (the evaluation's relative rules), and the notes
//! on a run's worst frames.

use super::MethodRun;
use crate::metrics::{self, Metric, Thresholds};

/// Judges every run's source switch share against the floor method's
/// (`thresholds.source_switch.floor_method`, advect) on the same scene,
/// frame by frame ([`Thresholds::summarize_against_floor`]): call it with
/// all the runs of one scene once they are done. Without a floor run the
/// verdicts stay n/a and each run gets a note saying so.
///
/// A frame is judged on the points both runs cover at both ends (the
/// evaluation's common support, [`FrameRecord::switch_same_points`](super::FrameRecord::switch_same_points)): a
/// method that covers advect's holes with new patches is not charged for
/// the switches advect does not have to make there, and advect is not
/// credited for the points it leaves uncovered. Where the points were not
/// recorded (a run measured on other points), each run's own share stands
/// in. The cell shows the judged shares; each run's own-point share is
/// kept in a note, for information.
pub fn judge_against_floor(runs: &mut [MethodRun], thresholds: &Thresholds) {
    judge_against_floor_on(runs, thresholds, "");
}

/// [`judge_against_floor`] for the runs of scene `scene`. On a scene of
/// `popping.strong_shear_scenes` (ruling 4: the flow shears the surface
/// faster than a patch can live, so the distortion bound forces renewal)
/// every frame is judged against the *renewal floor* too: the share of
/// points whose previous patch, carried by the floor method (advect, which
/// never erodes), is past δ_max at the carried point
/// ([`FrameRecord::switch_causes`](super::FrameRecord::switch_causes)). A run's switch share passes a frame
/// at most `source_switch.max_excess_over_floor` above advect's plus that
/// floor, and its popped share at most the same excess above the floor
/// (instead of the absolute popping rule).
pub fn judge_against_floor_on(runs: &mut [MethodRun], thresholds: &Thresholds, scene: &str) {
    let floor_name = thresholds.source_switch.floor_method.clone();
    compare_on_same_points(runs, &floor_name);
    let strong_shear = thresholds
        .popping
        .strong_shear_scenes
        .iter()
        .any(|s| s == scene);
    // The floor run's renewal floor per frame (0 where it recorded none:
    // the stricter reading).
    let renewal: Vec<(i32, f64)> = runs
        .iter()
        .find(|r| r.method == floor_name && strong_shear)
        .map(|r| {
            (r.frames.iter())
                .map(|f| (f.frame, f.switch_causes[2]))
                .map(|(n, v)| (n, if v.is_finite() { v } else { 0.0 }))
                .collect()
        })
        .unwrap_or_default();
    let renewal_at = |frame: i32| {
        renewal
            .iter()
            .find(|(n, _)| *n == frame)
            .map_or(0.0, |&(_, v)| v)
    };
    let floor: Option<Vec<(i32, f64)>> = runs.iter().find(|r| r.method == floor_name).map(|r| {
        r.frames
            .iter()
            .map(|f| (f.frame, f.value(Metric::SourceSwitch)))
            .collect()
    });
    for run in runs.iter_mut() {
        let Some(floor) = &floor else {
            run.notes.push(format!(
                "source switch share: not judged, it is judged against {floor_name} on the \
                 same frames and {floor_name} was not run"
            ));
            continue;
        };
        let (values, floor_values): (Vec<f64>, Vec<f64>) = run
            .frames
            .iter()
            .map(|f| {
                let (mine, theirs) = match f.switch_same_points {
                    [mine, theirs] if mine.is_finite() && theirs.is_finite() => (mine, theirs),
                    _ => (
                        f.value(Metric::SourceSwitch),
                        floor
                            .iter()
                            .find(|(n, _)| *n == f.frame)
                            .map_or(f64::NAN, |&(_, v)| v),
                    ),
                };
                (mine, theirs + renewal_at(f.frame))
            })
            .unzip();
        let summary = thresholds.summarize_against_floor(&values, &floor_values);
        if let Some(s) = run.summary_mut(Metric::SourceSwitch) {
            *s = summary;
        }
    }
    if !renewal.is_empty() {
        judge_popping_against_renewal(runs, thresholds, &renewal);
    }
    judge_aligned_against_floor(runs, thresholds);
    note_switch_peaks(runs);
}

/// Ruling 4's popping rule on a strongly sheared scene: every frame's
/// popped share at most `source_switch.max_excess_over_floor` above that
/// frame's renewal floor (`renewal`, per frame number), with a note giving
/// the floor.
fn judge_popping_against_renewal(
    runs: &mut [MethodRun],
    thresholds: &Thresholds,
    renewal: &[(i32, f64)],
) {
    let excess = thresholds.source_switch.max_excess_over_floor;
    let lead = "popping: judged against the renewal floor";
    let Some((median, (_, worst))) = median_and_worst(renewal) else {
        return;
    };
    for run in runs.iter_mut() {
        run.notes.retain(|n| !n.starts_with(lead));
        let verdicts: Vec<bool> = run
            .frames
            .iter()
            .filter_map(|f| {
                let p = f.value(Metric::Popping);
                let floor = renewal.iter().find(|(n, _)| *n == f.frame)?.1;
                p.is_finite().then_some(p <= floor + excess + 1e-12)
            })
            .collect();
        let Some(s) = run.summary_mut(Metric::Popping) else {
            continue;
        };
        if verdicts.is_empty() {
            continue;
        }
        s.verdict = metrics::Verdict::of(verdicts.iter().all(|&v| v));
        run.notes.push(format!(
            "{lead} (strong shear): every frame at most {excess} above the share of points whose \
             never-eroded patch is past δ_max there (median {:.3}, worst {:.3} over {} frames)",
            median,
            worst,
            renewal.len()
        ));
    }
}

/// The flow-aligned share where the floor method itself stays below the
/// absolute rule on the scene: every run then passes when its median share
/// is at most `flow.max_aligned_shortfall_under_floor` below the floor's
/// (a flow the image measurement cannot follow well there fails every
/// method alike, and the rule keeps what can still be told apart: whether
/// a method follows it worse than a texture that rides it by
/// construction). Elsewhere the absolute rule stands.
fn judge_aligned_against_floor(runs: &mut [MethodRun], thresholds: &Thresholds) {
    let floor_name = &thresholds.source_switch.floor_method;
    let Some(floor) = runs
        .iter()
        .find(|r| &r.method == floor_name)
        .and_then(|r| r.summary(Metric::FlowAligned))
        .map(|s| s.median)
        .filter(|m| m.is_finite() && *m < thresholds.flow.min_aligned_share)
    else {
        return;
    };
    let allowed = floor - thresholds.flow.max_aligned_shortfall_under_floor;
    let lead = "flow aligned share: judged against";
    for run in runs.iter_mut() {
        run.notes.retain(|n| !n.starts_with(lead));
        let Some(s) = run.summary_mut(Metric::FlowAligned) else {
            continue;
        };
        if !s.median.is_finite() {
            continue;
        }
        s.verdict = metrics::Verdict::of(s.median >= allowed);
        run.notes.push(format!(
            "{lead} {floor_name}'s {:.3} less {} ({floor_name} is below the absolute {:.2} here)",
            floor,
            thresholds.flow.max_aligned_shortfall_under_floor,
            thresholds.flow.min_aligned_share
        ));
    }
}

/// The lower median of per-frame values (as every cell of the report gives
/// it) and the worst frame, the first of equal ones; `None` without values.
fn median_and_worst(values: &[(i32, f64)]) -> Option<(f64, (i32, f64))> {
    let mut sorted: Vec<f64> = values.iter().map(|v| v.1).collect();
    sorted.sort_by(f64::total_cmp);
    let median = *sorted.get(sorted.len().checked_sub(1)? / 2)?;
    let worst = values
        .iter()
        .copied()
        .reduce(|best, v| if v.1 > best.1 { v } else { best })?;
    Some((median, worst))
}

/// The lead of the note [`note_switch_peaks`] writes.
const PEAK_NOTE: &str = "source switch share: the worst frame is";

/// Frames of a run, counted from its first, that the wave rule leaves
/// out: the patches born together on the first frame wear out together
/// about one lifetime later (half a second at 24 fps), a start-up wave the
/// README describes; the rule judges the frames after it (12–47 of a
/// 48-frame run).
pub const FIRST_LIFETIME_FRAMES: i32 = 12;

/// A note per run with its worst frame's switch share as a multiple of the
/// run's median frame, over the frames after the first lifetime
/// ([`FIRST_LIFETIME_FRAMES`]; all frames of a run shorter than twice
/// that): the fast-flow rule of the evaluation (no frame above twice the
/// median, no synchronised erosion waves), given as information.
fn note_switch_peaks(runs: &mut [MethodRun]) {
    for run in runs.iter_mut() {
        run.notes.retain(|n| !n.starts_with(PEAK_NOTE));
        let first = run.frames.iter().map(|f| f.frame).min().unwrap_or(0);
        let last = run.frames.iter().map(|f| f.frame).max().unwrap_or(0);
        let from = if last - first + 1 >= 2 * FIRST_LIFETIME_FRAMES {
            first + FIRST_LIFETIME_FRAMES
        } else {
            first
        };
        let shares: Vec<(i32, f64)> = run
            .frames
            .iter()
            .filter(|f| f.frame >= from)
            .map(|f| (f.frame, f.value(Metric::SourceSwitch)))
            .filter(|(_, v)| v.is_finite())
            .collect();
        if let Some((median, (frame, peak))) = median_and_worst(&shares)
            && median > 0.0
        {
            run.notes.push(format!(
                "{PEAK_NOTE} {:.1}x the median frame ({:.1} % at frame {frame}, median {:.1} %)",
                peak / median,
                100.0 * peak,
                100.0 * median
            ));
        }
    }
}

/// Each run's switch share beside the floor run's on the points both cover
/// at both ends, frame by frame ([`FrameRecord::switch_same_points`](super::FrameRecord::switch_same_points), what
/// [`judge_against_floor`] judges), and a note with each run's share on its
/// own points against the floor's, for information.
fn compare_on_same_points(runs: &mut [MethodRun], floor_name: &str) {
    let Some(floor) = runs.iter().find(|r| r.method == floor_name) else {
        return;
    };
    let floor_points: Vec<(i32, Vec<[u32; 2]>)> = floor
        .frames
        .iter()
        .map(|f| (f.frame, f.point_sources.clone()))
        .collect();
    let floor_own: Vec<(i32, f64)> = floor
        .frames
        .iter()
        .map(|f| (f.frame, f.value(Metric::SourceSwitch)))
        .collect();
    let lead = "source switch share on each run's own points";
    for run in runs.iter_mut() {
        // Judging again replaces what an earlier call found.
        run.notes.retain(|n| !n.starts_with(lead));
        let mut excess = Vec::new();
        for f in &mut run.frames {
            f.switch_same_points = [f64::NAN; 2];
            let Some((_, fp)) = floor_points.iter().find(|(n, _)| *n == f.frame) else {
                continue;
            };
            if f.point_sources.is_empty() || fp.is_empty() {
                continue;
            }
            if let Ok((mine, theirs)) = metrics::source_switch_same_points(&f.point_sources, fp) {
                f.switch_same_points = [mine.share(), theirs.share()];
            }
        }
        for f in &run.frames {
            let own = floor_own.iter().find(|(n, _)| *n == f.frame);
            let d = f.value(Metric::SourceSwitch) - own.map_or(f64::NAN, |o| o.1);
            if d.is_finite() {
                excess.push((f.frame, d));
            }
        }
        if run.method == floor_name {
            continue;
        }
        let Some((median, worst)) = median_and_worst(&excess) else {
            continue;
        };
        run.notes.push(format!(
            "{lead} (information; the verdict is on the points both cover): {:+.1} points \
             against {floor_name}'s in the median frame, {:+.1} at worst (frame {})",
            100.0 * median,
            100.0 * worst.1,
            worst.0
        ));
    }
}
