//! The verdicts that need more than one run: each method's switch share,
//! popping, colour follow and flow fidelity judged against the floor
//! method's on the same scene and frames (the evaluation's relative rules
//! and rulings, [`judge_against_floor_on`]), and the notes on a run's
//! causes of switches and worst frames.

use super::MethodRun;
use crate::metrics::{self, Metric, Thresholds, Verdict};

/// Judges every run against the floor method's run on the same scene and
/// frames (`thresholds.source_switch.floor_method`, advect): call it with
/// all the runs of one scene once they are done. Without a floor run the
/// switch verdicts stay n/a and each run gets a note saying so.
///
/// A frame is judged on the points both runs cover at both ends (the
/// evaluation's common support, [`FrameRecord::switch_same_points`](super::FrameRecord::switch_same_points)): a
/// method that covers advect's holes with new patches is not charged for
/// the switches advect does not have to make there, and advect is not
/// credited for the points it leaves uncovered. Where the points were not
/// recorded (a run measured on other points), each run's own share stands
/// in. The cell shows the judged shares; each run's own-point share is
/// kept in a note, for information. [`judge_against_floor_on`] gives the
/// rules.
pub fn judge_against_floor(runs: &mut [MethodRun], thresholds: &Thresholds) {
    judge_against_floor_on(runs, thresholds, "");
}

/// What the floor run (advect) says of one frame, for the other runs'
/// verdicts.
#[derive(Clone, Copy, Debug)]
struct FloorFrame {
    frame: i32,
    /// Its switch share on its own points.
    switch: f64,
    /// Its holder-past-δ_max share: the cumulative renewal floor.
    renewal: f64,
    /// The growth of that share on this frame: the per-frame renewal floor.
    renewal_new: f64,
    /// Its popped share.
    popping: f64,
}

/// The floor run's frames, in order.
struct Floor {
    name: String,
    frames: Vec<FloorFrame>,
    /// Above this per-frame renewal floor a frame is violent.
    violent_above: f64,
}

impl Floor {
    fn of(run: &MethodRun, thresholds: &Thresholds) -> Floor {
        Floor {
            name: run.method.clone(),
            frames: (run.frames.iter())
                .map(|f| FloorFrame {
                    frame: f.frame,
                    switch: f.value(Metric::SourceSwitch),
                    renewal: f.switch_causes.holder_distorted,
                    renewal_new: f.switch_causes.holder_distorted_new,
                    popping: f.value(Metric::Popping),
                })
                .collect(),
            violent_above: thresholds.popping.violent_min_new_floor,
        }
    }

    fn at(&self, frame: i32) -> Option<&FloorFrame> {
        self.frames.iter().find(|f| f.frame == frame)
    }

    /// Ruling 2: the flow itself pushes more than `violent_min_new_floor`
    /// of the never-renewed surface past δ_max on this frame.
    fn violent(&self, frame: i32) -> bool {
        self.at(frame)
            .is_some_and(|f| f.renewal_new > self.violent_above)
    }

    /// The violent frames, in order.
    fn violent_frames(&self) -> Vec<i32> {
        (self.frames.iter())
            .map(|f| f.frame)
            .filter(|&n| self.violent(n))
            .collect()
    }
}

/// The rules a scene's runs are judged by against the floor run, beyond
/// each metric's absolute rule (docs/evaluation.md, "Rulings"):
/// - **Switch share, forced and unforced** (ruling 1 of the violent-liquid
///   rulings): a run that records why its points switched (erosion,
///   advect) passes when its *unforced* share is at most
///   `source_switch.max_excess_over_floor` above advect's switch share on
///   every frame from the first lifetime on ([`FIRST_LIFETIME_FRAMES`]);
///   renewal of a holder past δ_max or being eroded there (its weight
///   below one) is forced and not charged. A run that records no causes is judged
///   on its whole share against advect's, plus, on a scene of
///   `popping.strong_shear_scenes`, the cumulative renewal floor.
/// - **Methods that blend layers** (`lapped-rigid`, `blend-deformable`,
///   `dual-rest`, [`MethodRun::blends`](super::MethodRun::blends)): the
///   switch share of their heaviest layer is information; popping and
///   ghosting judge them.
/// - **Violent frames** (ruling 2): where advect's per-frame renewal floor
///   is above `popping.violent_min_new_floor`, a run's popped share may be
///   at most `popping.violent_max_excess_over_floor` above advect's on that
///   frame, its switch share there is information, and its colour follow
///   ratio is judged from the first lifetime on. Calm frames keep every
///   absolute rule.
/// - **Strong shear** (ruling 4 of the fast-flow rulings, the vortex at
///   T = 8 s): on its calm frames, popping at most `max_excess_over_floor`
///   above the cumulative renewal floor.
/// - **Flow fidelity where advect itself fails**: the aligned share at
///   most `flow.max_aligned_shortfall_under_floor` below advect's, the
///   median end-point error at most `flow.max_epe_excess_over_floor_px`
///   above advect's (ruling 5).
pub fn judge_against_floor_on(runs: &mut [MethodRun], thresholds: &Thresholds, scene: &str) {
    let floor_name = thresholds.source_switch.floor_method.clone();
    compare_on_same_points(runs, &floor_name);
    let strong_shear = thresholds
        .popping
        .strong_shear_scenes
        .iter()
        .any(|s| s == scene);
    let Some(floor) = runs
        .iter()
        .find(|r| r.method == floor_name)
        .map(|r| Floor::of(r, thresholds))
    else {
        for run in runs.iter_mut() {
            run.notes.push(format!(
                "source switch share: not judged, it is judged against {floor_name} on the \
                 same frames and {floor_name} was not run"
            ));
        }
        note_switch_peaks(runs);
        return;
    };
    for run in runs.iter_mut() {
        judge_switch(run, &floor, thresholds, strong_shear);
        note_unforced_causes(run);
    }
    judge_popping(runs, &floor, thresholds, strong_shear);
    judge_follow_on_violent_frames(runs, &floor, thresholds);
    judge_aligned_against_floor(runs, thresholds);
    judge_epe_against_floor(runs, thresholds);
    note_switch_peaks(runs);
}

/// The first frame of `run` that the rules after the first lifetime judge:
/// [`FIRST_LIFETIME_FRAMES`] after its first, or its first when the run is
/// shorter than two lifetimes.
fn after_first_lifetime(run: &MethodRun) -> i32 {
    let first = run.frames.iter().map(|f| f.frame).min().unwrap_or(0);
    let last = run.frames.iter().map(|f| f.frame).max().unwrap_or(0);
    if last - first + 1 >= 2 * FIRST_LIFETIME_FRAMES {
        first + FIRST_LIFETIME_FRAMES
    } else {
        first
    }
}

/// Whether `run` recorded why its points switched (forced or unforced).
fn records_causes(run: &MethodRun) -> bool {
    run.frames
        .iter()
        .any(|f| f.switch_causes.unforced.is_finite())
}

/// The lead of the notes [`judge_switch`] writes.
const SWITCH_RULE: &str = "source switch share: judged";

/// One run's switch verdict against the floor (see
/// [`judge_against_floor_on`] for the rules).
fn judge_switch(run: &mut MethodRun, floor: &Floor, thresholds: &Thresholds, strong_shear: bool) {
    run.notes.retain(|n| !n.starts_with(SWITCH_RULE));
    let excess = thresholds.source_switch.max_excess_over_floor;
    let by_cause = records_causes(run);
    let from = after_first_lifetime(run);
    // (shown share, floor share) per frame, and the judged frames' verdicts.
    let mut shown = Vec::new();
    let mut floor_shown = Vec::new();
    let mut verdicts = Vec::new();
    let mut worst: Option<(i32, f64, f64)> = None;
    for f in &run.frames {
        let (mine, theirs) = match f.switch_same_points {
            [mine, theirs] if mine.is_finite() && theirs.is_finite() => (mine, theirs),
            _ => (
                f.value(Metric::SourceSwitch),
                floor.at(f.frame).map_or(f64::NAN, |x| x.switch),
            ),
        };
        shown.push(mine);
        floor_shown.push(theirs);
        if run.blends || floor.violent(f.frame) {
            continue;
        }
        let (value, bar) = if by_cause {
            if f.frame < from {
                continue;
            }
            (f.switch_causes.unforced, theirs)
        } else {
            let renewal = match floor.at(f.frame) {
                Some(x) if strong_shear && x.renewal.is_finite() => x.renewal,
                _ => 0.0,
            };
            (mine, theirs + renewal)
        };
        let v = thresholds.switch_verdict(value, bar);
        if v == Verdict::NoData {
            continue;
        }
        if worst.is_none_or(|w| value - bar > w.1 - w.2) {
            worst = Some((f.frame, value, bar));
        }
        verdicts.push(v);
    }
    let mut summary = thresholds.summarize_against_floor(&shown, &floor_shown);
    summary.verdict = if verdicts.is_empty() {
        Verdict::NoData
    } else {
        Verdict::of(verdicts.iter().all(|v| v.is_pass()))
    };
    if let Some(s) = run.summary_mut(Metric::SourceSwitch) {
        *s = summary;
    }
    let violent = floor.violent_frames();
    let leave_out = if violent.is_empty() {
        String::new()
    } else {
        format!(
            "; {} violent frame(s) ({}) are information",
            violent.len(),
            frame_list(&violent)
        )
    };
    let note = if run.blends {
        format!(
            "{SWITCH_RULE} as information: the method blends layers, so a flip of its heaviest \
             layer need not change a texel; popping and ghosting judge it"
        )
    } else if by_cause {
        format!(
            "{SWITCH_RULE} on unforced switches (ruling 1): at most {excess} above {}'s share on \
             every frame from {from} on{leave_out}{}",
            floor.name,
            worst.map_or(String::new(), |(n, v, b)| format!(
                "; closest frame {n}: unforced {v:.3} against {b:.3}"
            ))
        )
    } else {
        format!(
            "{SWITCH_RULE} on the whole share (the method records no causes): at most {excess} \
             above {}'s{}{leave_out}",
            floor.name,
            if strong_shear {
                " plus the renewal floor"
            } else {
                ""
            }
        )
    };
    run.notes.push(note);
}

/// Frame numbers as ranges: "3–5, 9".
fn frame_list(frames: &[i32]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            frames[i].to_string()
        } else {
            format!("{}–{}", frames[i], frames[j])
        });
        i = j + 1;
    }
    parts.join(", ")
}

/// The lead of the note [`note_unforced_causes`] writes.
const CAUSES_NOTE: &str = "unforced switches by cause";

/// A note with the median share of each cause of the unforced switches
/// (border crossings, patches drawn on top, the rest), where the run
/// records them.
fn note_unforced_causes(run: &mut MethodRun) {
    run.notes.retain(|n| !n.starts_with(CAUSES_NOTE));
    if !records_causes(run) {
        return;
    }
    let median = |pick: fn(&super::CauseShares) -> f64| {
        let values: Vec<(i32, f64)> = (run.frames.iter())
            .map(|f| (f.frame, pick(&f.switch_causes)))
            .filter(|(_, v)| v.is_finite())
            .collect();
        median_and_worst(&values).map_or(f64::NAN, |(m, _)| m)
    };
    let [border, on_top, other, eroding] = [
        median(|c| c.unforced_border),
        median(|c| c.unforced_on_top),
        median(|c| c.unforced_other),
        median(|c| c.forced_eroding),
    ];
    run.notes.push(format!(
        "{CAUSES_NOTE} (median frame, information): border crossings {:.1} %, new patches drawn \
         on top {:.1} %, other {:.1} %; forced by the erosion of a distorted holder {:.1} %",
        100.0 * border,
        100.0 * on_top,
        100.0 * other,
        100.0 * eroding
    ));
}

/// The lead of the notes [`judge_popping`] writes.
const POPPING_RULE: &str = "popping: judged";

/// Popping frame by frame where a ruling replaces the absolute rule on
/// some frames: violent frames against advect's popping on the same frame
/// (ruling 2), the calm frames of a strongly sheared scene against the
/// cumulative renewal floor (ruling 4), the other frames by the absolute
/// rule (mean and worst over those frames).
fn judge_popping(
    runs: &mut [MethodRun],
    floor: &Floor,
    thresholds: &Thresholds,
    strong_shear: bool,
) {
    let violent = floor.violent_frames();
    if violent.is_empty() && !strong_shear {
        return;
    }
    let p = &thresholds.popping;
    let excess = thresholds.source_switch.max_excess_over_floor;
    for run in runs.iter_mut() {
        run.notes.retain(|n| !n.starts_with(POPPING_RULE));
        let mut verdicts = Vec::new();
        let mut calm = Vec::new();
        for f in &run.frames {
            let popped = f.value(Metric::Popping);
            let Some(x) = floor.at(f.frame).filter(|_| popped.is_finite()) else {
                continue;
            };
            if floor.violent(f.frame) {
                if x.popping.is_finite() {
                    verdicts.push(popped <= x.popping + p.violent_max_excess_over_floor + 1e-12);
                }
            } else if strong_shear {
                let renewal = if x.renewal.is_finite() {
                    x.renewal
                } else {
                    0.0
                };
                verdicts.push(popped <= renewal + excess + 1e-12);
            } else {
                calm.push(popped);
            }
        }
        if !calm.is_empty() {
            let mean = calm.iter().sum::<f64>() / calm.len() as f64;
            let worst = calm.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            verdicts.push(mean <= p.max_mean_share && worst <= p.max_worst_share);
        }
        let Some(s) = run.summary_mut(Metric::Popping) else {
            continue;
        };
        if verdicts.is_empty() {
            continue;
        }
        s.verdict = Verdict::of(verdicts.iter().all(|&v| v));
        run.notes
            .push(popping_note(floor, &violent, thresholds, strong_shear));
    }
}

/// The note that says how [`judge_popping`] judged a run.
fn popping_note(floor: &Floor, violent: &[i32], t: &Thresholds, strong_shear: bool) -> String {
    let p = &t.popping;
    let mut parts = Vec::new();
    if !violent.is_empty() {
        let floors: Vec<(i32, f64)> = (floor.frames.iter())
            .filter(|f| violent.contains(&f.frame))
            .map(|f| (f.frame, f.renewal_new))
            .collect();
        let (median, (n, worst)) = median_and_worst(&floors).unwrap_or((f64::NAN, (0, f64::NAN)));
        parts.push(format!(
            "on {} violent frame(s) ({}; per-frame renewal floor above {}: median {:.3}, worst \
             {:.3} at frame {n}) at most {} above advect's popping on the same frame",
            violent.len(),
            frame_list(violent),
            p.violent_min_new_floor,
            median,
            worst,
            p.violent_max_excess_over_floor
        ));
    }
    if strong_shear {
        let renewal: Vec<(i32, f64)> = (floor.frames.iter())
            .filter(|f| f.renewal.is_finite() && !violent.contains(&f.frame))
            .map(|f| (f.frame, f.renewal))
            .collect();
        if let Some((median, (_, worst))) = median_and_worst(&renewal) {
            parts.push(format!(
                "against the renewal floor (strong shear) on the other frames: every frame at \
                 most {} above the share of points whose never-eroded patch is past δ_max there \
                 (median {median:.3}, worst {worst:.3} over {} frames)",
                t.source_switch.max_excess_over_floor,
                renewal.len()
            ));
        }
    } else {
        parts.push("by the absolute rule on the other frames".into());
    }
    format!("{POPPING_RULE} {}", parts.join("; "))
}

/// The lead of the note [`judge_follow_on_violent_frames`] writes.
const FOLLOW_RULE: &str = "colour follow ratio: judged";

/// Ruling 2's colour follow rule on a scene with violent frames: the worst
/// of the calm frames and of the violent frames from the first lifetime on
/// ([`FIRST_LIFETIME_FRAMES`]) must pass; violent frames inside the first
/// lifetime are information.
fn judge_follow_on_violent_frames(runs: &mut [MethodRun], floor: &Floor, thresholds: &Thresholds) {
    let violent = floor.violent_frames();
    if violent.is_empty() {
        return;
    }
    let max = thresholds.colour_follow.max_ratio;
    for run in runs.iter_mut() {
        run.notes.retain(|n| !n.starts_with(FOLLOW_RULE));
        let from = after_first_lifetime(run);
        let judged: Vec<f64> = (run.frames.iter())
            .filter(|f| f.frame >= from || !violent.contains(&f.frame))
            .map(|f| f.value(Metric::ColourFollow))
            .filter(|v| v.is_finite())
            .collect();
        let Some(s) = run.summary_mut(Metric::ColourFollow) else {
            continue;
        };
        if !s.median.is_finite() {
            continue;
        }
        s.verdict = if judged.is_empty() {
            Verdict::NoData
        } else {
            Verdict::of(judged.iter().all(|&v| v <= max))
        };
        run.notes.push(format!(
            "{FOLLOW_RULE} on {} of {} frames: the violent ones from frame {from} on and every \
             calm one (ruling 2)",
            judged.len(),
            run.frames.len()
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
    let fl = &thresholds.flow;
    let floor_name = &thresholds.source_switch.floor_method;
    judge_median_against_floor(
        runs,
        thresholds,
        Metric::FlowAligned,
        |floor| floor < fl.min_aligned_share,
        |median, floor| median >= floor - fl.max_aligned_shortfall_under_floor,
        |floor| {
            format!(
                "flow aligned share: judged against {floor_name}'s {floor:.3} less {} \
                 ({floor_name} is below the absolute {:.2} here)",
                fl.max_aligned_shortfall_under_floor, fl.min_aligned_share
            )
        },
    );
}

/// Ruling 5: the median end-point error where the floor method itself
/// misses the absolute rule on the scene: every run then passes when its
/// median is at most `flow.max_epe_excess_over_floor_px` above the
/// floor's (a violent flow that the texture of a method riding it by
/// construction cannot follow within a quarter pixel either). Elsewhere
/// the absolute rule stands.
fn judge_epe_against_floor(runs: &mut [MethodRun], thresholds: &Thresholds) {
    let fl = &thresholds.flow;
    let floor_name = &thresholds.source_switch.floor_method;
    judge_median_against_floor(
        runs,
        thresholds,
        Metric::FlowEpe,
        |floor| floor > fl.max_median_epe_px,
        |median, floor| median <= floor + fl.max_epe_excess_over_floor_px + 1e-12,
        |floor| {
            format!(
                "flow median EPE: judged against {floor_name}'s {floor:.3} px plus {} px \
                 ({floor_name} misses the absolute {} px here)",
                fl.max_epe_excess_over_floor_px, fl.max_median_epe_px
            )
        },
    );
}

/// Where the floor run's median of `metric` fails the absolute rule
/// (`floor_fails`), every run's median is judged against it instead
/// (`passes(median, floor)`), with the note `note(floor)`; the notes of an
/// earlier call are replaced.
fn judge_median_against_floor(
    runs: &mut [MethodRun],
    thresholds: &Thresholds,
    metric: Metric,
    floor_fails: impl Fn(f64) -> bool,
    passes: impl Fn(f64, f64) -> bool,
    note: impl Fn(f64) -> String,
) {
    let floor_name = &thresholds.source_switch.floor_method;
    let Some(floor) = runs
        .iter()
        .find(|r| &r.method == floor_name)
        .and_then(|r| r.summary(metric))
        .map(|s| s.median)
        .filter(|m| m.is_finite() && floor_fails(*m))
    else {
        return;
    };
    let text = note(floor);
    let lead = text.split(':').next().unwrap_or_default().to_string();
    for run in runs.iter_mut() {
        run.notes.retain(|n| !n.starts_with(&lead));
        let Some(s) = run.summary_mut(metric) else {
            continue;
        };
        if !s.median.is_finite() {
            continue;
        }
        s.verdict = Verdict::of(passes(s.median, floor));
        run.notes.push(text.clone());
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
        let from = after_first_lifetime(run);
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
