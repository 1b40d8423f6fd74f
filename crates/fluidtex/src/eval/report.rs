//! The comparison report: a serialisable model (`report.json`) and its
//! Markdown and self-contained HTML renderings (tables of
//! "median [min, max] PASS" cells, per-metric plots over time as inline
//! SVG, links to the pictures). Pure functions returning text; the caller
//! writes the files.

use std::fmt::Write;

use serde::Serialize;

use super::{MethodRun, PER_FRAME, PreparedScene, metric_key, patch_counts, seconds_per_frame};
use crate::metrics::{Metric, Thresholds, Verdict};
use crate::texture::Texture;

/// A report cell: one metric over one sequence.
#[derive(Clone, Debug, Serialize)]
pub struct MetricCell {
    pub key: &'static str,
    pub name: &'static str,
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    /// Frames with a value, and frames without one.
    pub frames: usize,
    pub skipped: usize,
    /// "PASS", "FAIL" or "n/a".
    pub verdict: String,
    pub pass: bool,
}

/// Median, min and max.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Spread {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

fn is_nan(x: &f64) -> bool {
    x.is_nan()
}

/// One frame in the JSON (NaN is written as null).
#[derive(Clone, Debug, Serialize)]
pub struct FrameJson {
    pub frame: i32,
    pub seconds: f64,
    pub patches: Option<f64>,
    pub still: bool,
    pub values: Vec<(&'static str, f64)>,
    /// Area-weighted p95 of σ₁/σ₂, for information beside distortion.
    pub anisotropy: f64,
    /// This method's and the floor method's source switch share on the
    /// points both cover at both ends (information beside the switch share).
    pub switch_same_points: [f64; 2],
    /// The switches by cause and the shares of points whose previous patch
    /// is past δ_max, in all and newly on this frame (information beside
    /// the switch share).
    pub switch_causes: super::CauseShares,
    /// Exemplars chosen by an attribute: the share of covered texels whose
    /// exemplar matches it (absent otherwise).
    #[serde(skip_serializing_if = "is_nan")]
    pub state_agreement: f64,
    /// The same over the decisive points (at least 0.2 of the ranges'
    /// span from every split; absent otherwise).
    #[serde(skip_serializing_if = "is_nan")]
    pub state_agreement_decisive: f64,
}

/// One method on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct MethodReport {
    pub name: String,
    /// The method's parameters as configured.
    pub parameters: serde_json::Value,
    pub seconds_per_frame: Spread,
    pub patches: Option<Spread>,
    /// Per-frame p95 anisotropy σ₁/σ₂ over frames (information only: the
    /// distortion verdict is on δ).
    pub anisotropy: Option<Spread>,
    /// Per-frame forced switch share over frames (information only).
    pub switch_forced: Option<Spread>,
    /// Per-frame unforced switch share over frames (information only).
    pub switch_unforced: Option<Spread>,
    /// Per-frame share of points whose previous patch is past δ_max; on
    /// advect, the renewal floor (information only).
    pub holder_distorted: Option<Spread>,
    /// Per-frame growth of that share; on advect, the per-frame renewal
    /// floor that marks a violent frame (information only).
    pub holder_distorted_new: Option<Spread>,
    /// Per-frame state agreement over frames, where the exemplars are
    /// chosen by an attribute (information only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state_agreement: Option<Spread>,
    /// The same over the decisive points, whose attribute lies at least
    /// 0.2 of the ranges' span from every split (information only; the
    /// evaluation asks ≥ 0.9 on every frame of a cooling blob).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state_agreement_decisive: Option<Spread>,
    /// Exemplar texels per atlas texel the fidelity reference used.
    pub fidelity_scale: f64,
    pub metrics: Vec<MetricCell>,
    pub notes: Vec<String>,
    pub per_frame: Vec<FrameJson>,
}

impl MethodReport {
    pub fn new(run: &MethodRun, parameters: serde_json::Value) -> MethodReport {
        let (median, min, max) = seconds_per_frame(run);
        MethodReport {
            name: run.method.clone(),
            parameters,
            seconds_per_frame: Spread { median, min, max },
            patches: patch_counts(run).map(|(median, min, max)| Spread { median, min, max }),
            anisotropy: spread(run.frames.iter().map(|r| r.anisotropy)),
            switch_forced: spread(run.frames.iter().map(|r| r.switch_causes.forced)),
            switch_unforced: spread(run.frames.iter().map(|r| r.switch_causes.unforced)),
            holder_distorted: spread(run.frames.iter().map(|r| r.switch_causes.holder_distorted)),
            holder_distorted_new: spread(
                (run.frames.iter()).map(|r| r.switch_causes.holder_distorted_new),
            ),
            state_agreement: spread(run.frames.iter().map(|r| r.state_agreement)),
            state_agreement_decisive: spread(
                (run.frames.iter()).map(|r| r.state_agreement_decisive),
            ),
            fidelity_scale: run.fidelity_scale,
            metrics: run
                .summaries
                .iter()
                .map(|s| MetricCell {
                    key: metric_key(s.metric),
                    name: s.metric.name(),
                    median: s.median,
                    min: s.min,
                    max: s.max,
                    mean: s.mean,
                    frames: s.frames,
                    skipped: s.skipped,
                    verdict: s.verdict.to_string(),
                    pass: s.verdict == Verdict::Pass,
                })
                .collect(),
            notes: run.notes.clone(),
            per_frame: run
                .frames
                .iter()
                .map(|r| FrameJson {
                    frame: r.frame,
                    seconds: r.seconds,
                    patches: r.patches,
                    still: r.still,
                    anisotropy: r.anisotropy,
                    switch_same_points: r.switch_same_points,
                    switch_causes: r.switch_causes,
                    state_agreement: r.state_agreement,
                    state_agreement_decisive: r.state_agreement_decisive,
                    values: PER_FRAME
                        .iter()
                        .zip(r.values)
                        .map(|(&m, v)| (metric_key(m), v))
                        .collect(),
                })
                .collect(),
        }
    }

    fn cell(&self, key: &str) -> Option<&MetricCell> {
        self.metrics.iter().find(|c| c.key == key)
    }
}

/// One scene: its setup, every method, the pictures.
#[derive(Clone, Debug, Serialize)]
pub struct SceneReport {
    pub name: String,
    pub description: String,
    pub frames: Vec<i32>,
    pub fps: f64,
    pub scene_parameters: serde_json::Value,
    pub render_size: u32,
    pub camera_eye: [f32; 3],
    pub camera_target: [f32; 3],
    pub truth_motion: String,
    pub methods: Vec<MethodReport>,
    /// Pictures, relative to the report: (caption, file).
    pub images: Vec<(String, String)>,
}

impl SceneReport {
    pub fn new(
        scene: &PreparedScene,
        methods: Vec<MethodReport>,
        images: Vec<(String, String)>,
    ) -> SceneReport {
        SceneReport {
            name: scene.info.name.clone(),
            description: scene.info.description.clone(),
            frames: scene.frames.iter().map(|f| f.number).collect(),
            fps: scene.info.fps,
            scene_parameters: scene.info.parameters.clone(),
            render_size: scene.camera.width,
            camera_eye: scene.camera.eye.to_array(),
            camera_target: scene.camera.target.to_array(),
            truth_motion: scene.truth.describe(),
            methods,
            images,
        }
    }
}

/// The whole comparison.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The command line or other description of how it was made.
    pub command: String,
    pub atlas_size: u32,
    pub seed: u64,
    pub exemplar: String,
    /// Wall time of the whole comparison (s).
    pub seconds: f64,
    pub scenes: Vec<SceneReport>,
    /// Metrics left out of every scene, and why.
    pub not_measured: Vec<String>,
}

/// The pass threshold of a per-frame metric, for plots. The source switch
/// share has none of its own (it is judged against the floor method).
pub fn threshold_of(t: &Thresholds, m: Metric) -> Option<f64> {
    Some(match m {
        Metric::SourceSwitch => return None,
        Metric::ColourFollow => t.colour_follow.max_ratio,
        Metric::Coverage => t.coverage.max_uncovered_share,
        Metric::Ghosting => t.ghosting.max_share,
        Metric::Contrast => t.contrast.min_ratio,
        Metric::Distortion => t.distortion.max_delta,
        Metric::Fidelity => t.fidelity.max_ratio,
        Metric::FlowEpe => t.flow.max_median_epe_px,
        Metric::FlowAligned => t.flow.min_aligned_share,
        Metric::Popping => t.popping.max_worst_share,
        Metric::StaticStop => t.static_stop.max_changed_frames as f64,
        Metric::SizeCost => t.size_cost.max_ratio,
    })
}

fn num(v: f64) -> String {
    if v.is_nan() {
        "—".into()
    } else if v.is_infinite() {
        if v > 0.0 {
            "∞".into()
        } else {
            "−∞".into()
        }
    } else if v == 0.0 {
        "0".into()
    } else if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 0.01 {
        format!("{v:.3}")
    } else {
        format!("{v:.2e}")
    }
}

/// "median [min, max] PASS", or "n/a".
pub fn cell_text(c: &MetricCell) -> String {
    if c.frames == 0 {
        return "n/a".into();
    }
    if c.frames == 1 {
        return format!("{} {}", num(c.median), c.verdict);
    }
    format!(
        "{} [{}, {}] {}",
        num(c.median),
        num(c.min),
        num(c.max),
        c.verdict
    )
}

/// Median, min and max of the non-NaN values, if any.
fn spread(values: impl Iterator<Item = f64>) -> Option<Spread> {
    let mut v: Vec<f64> = values.filter(|x| !x.is_nan()).collect();
    v.sort_unstable_by(f64::total_cmp);
    match (v.first(), v.last()) {
        (Some(&min), Some(&max)) => Some(Spread {
            median: v[(v.len() - 1) / 2],
            min,
            max,
        }),
        _ => None,
    }
}

/// Title of the information column shown after distortion.
const ANISOTROPY: &str = "anisotropy p95 (info)";
/// Titles of the information columns shown after the source switch share.
const SWITCH_SPLIT: [&str; 4] = [
    "switches forced (info)",
    "switches unforced (info)",
    "holder past δ_max (info; advect: renewal floor)",
    "newly past δ_max (info; advect: per-frame renewal floor)",
];

impl MethodReport {
    /// The texts of the [`SWITCH_SPLIT`] columns.
    fn switch_split_texts(&self) -> [String; 4] {
        [
            &self.switch_forced,
            &self.switch_unforced,
            &self.holder_distorted,
            &self.holder_distorted_new,
        ]
        .map(|s| s.as_ref().map_or("—".into(), spread_text))
    }
}

fn spread_text(s: &Spread) -> String {
    format!("{} [{}, {}]", num(s.median), num(s.min), num(s.max))
}

/// Titles of the information columns of a run whose exemplars follow an
/// attribute (shown only then).
const STATE: [&str; 2] = [
    "state agreement (info; ≥ 0.95 once settled)",
    "on decisive points (info; ≥ 0.9 every frame)",
];

impl MethodReport {
    /// The texts of the [`STATE`] columns.
    fn state_texts(&self) -> [String; 2] {
        [&self.state_agreement, &self.state_agreement_decisive]
            .map(|s| s.as_ref().map_or("—".into(), spread_text))
    }
}

impl SceneReport {
    /// The Markdown table's header and rule lines for this scene.
    fn markdown_head(&self) -> String {
        let mut head = String::from("| method |");
        let mut rule = String::from("| --- |");
        for &m in COLUMNS {
            let _ = write!(head, " {} |", m.name());
            rule.push_str(" --- |");
            if m == Metric::Distortion {
                let _ = write!(head, " {ANISOTROPY} |");
                rule.push_str(" --- |");
            }
            if m == Metric::SourceSwitch {
                for title in SWITCH_SPLIT {
                    let _ = write!(head, " {title} |");
                    rule.push_str(" --- |");
                }
            }
        }
        if self.has_state() {
            for title in STATE {
                let _ = write!(head, " {title} |");
                rule.push_str(" --- |");
            }
        }
        head.push_str(" s/frame | patches |");
        rule.push_str(" --- | --- |");
        format!("{head}\n{rule}")
    }

    /// Method `m`'s row of the Markdown table.
    fn markdown_row(&self, m: &MethodReport) -> String {
        let mut row = format!("| {} |", m.name);
        for &c in COLUMNS {
            let text = m.cell(metric_key(c)).map_or("n/a".into(), cell_text);
            let _ = write!(row, " {text} |");
            if c == Metric::Distortion {
                let text = m.anisotropy.as_ref().map_or("—".into(), spread_text);
                let _ = write!(row, " {text} |");
            }
            if c == Metric::SourceSwitch {
                for text in m.switch_split_texts() {
                    let _ = write!(row, " {text} |");
                }
            }
        }
        if self.has_state() {
            for text in m.state_texts() {
                let _ = write!(row, " {text} |");
            }
        }
        let _ = write!(
            row,
            " {} | {} |",
            spread_text(&m.seconds_per_frame),
            m.patches.as_ref().map_or("—".into(), spread_text)
        );
        row
    }

    /// Whether a method of the scene reports a state agreement.
    fn has_state(&self) -> bool {
        self.methods.iter().any(|m| m.state_agreement.is_some())
    }
}

/// Columns of the tables: every metric but exemplar-size cost.
const COLUMNS: &[Metric] = Metric::ALL.split_at(11).0;

impl Report {
    /// The Markdown report.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# fluidtex compare\n");
        let _ = writeln!(
            s,
            "`{}`  \natlas {}², seed {}, exemplar {}, {:.0} s in all. Thresholds: \
             `metrics/thresholds.toml` (committed). Cells: median [min, max] over frames, \
             PASS/FAIL of the committed rule and the rulings of docs/evaluation.md (source switch \
             share: the whole share on the points both cover, judged by its unforced part where \
             the method records causes, at most 0.02 above advect's; information on violent frames \
             and for methods that blend; n/a without an advect run). Each run's notes say which \
             rule judged a cell.\n",
            self.command, self.atlas_size, self.seed, self.exemplar, self.seconds
        );
        for n in &self.not_measured {
            let _ = writeln!(s, "- not measured: {n}");
        }
        for scene in &self.scenes {
            let _ = writeln!(s, "\n## {}\n", scene.name);
            let _ = writeln!(
                s,
                "{}. Frames {}–{} ({} frames, {} fps); render {}² px; true motion: {}.\n",
                scene.description,
                scene.frames.first().copied().unwrap_or(0),
                scene.frames.last().copied().unwrap_or(0),
                scene.frames.len(),
                scene.fps,
                scene.render_size,
                scene.truth_motion
            );
            let _ = writeln!(s, "{}", scene.markdown_head());
            for m in &scene.methods {
                let _ = writeln!(s, "{}", scene.markdown_row(m));
            }
            for m in &scene.methods {
                for n in &m.notes {
                    let _ = writeln!(s, "\n- {}: {n}", m.name);
                }
            }
            let _ = writeln!(s);
            for (caption, file) in &scene.images {
                let _ = writeln!(s, "![{caption}]({file})  ");
            }
        }
        let _ = writeln!(s, "\n## Method parameters\n");
        let mut seen = Vec::new();
        for m in self.scenes.iter().flat_map(|s| &s.methods) {
            if seen.contains(&m.name) {
                continue;
            }
            seen.push(m.name.clone());
            let _ = writeln!(
                s,
                "- **{}**: `{}`",
                m.name,
                serde_json::to_string(&m.parameters).unwrap_or_default()
            );
        }
        s
    }

    /// The HTML report: one self-contained page (inline CSS and SVG),
    /// pictures linked by relative path.
    pub fn to_html(&self, thresholds: &Thresholds) -> String {
        let mut s = String::new();
        s.push_str(
            "<!doctype html><html><head><meta charset=\"utf-8\"><title>fluidtex compare</title>\
             <style>body{font-family:sans-serif;margin:20px;color:#222}\
             table{border-collapse:collapse;font-size:12px;margin:8px 0}\
             td,th{border:1px solid #bbb;padding:3px 6px;text-align:left;vertical-align:top}\
             th{background:#eee}td.pass{background:#d8f0d8}td.fail{background:#f6d0d0}\
             td.na{color:#888}.plots{display:flex;flex-wrap:wrap;gap:8px}\
             .plots figure{margin:0}figcaption{font-size:12px}\
             img{max-width:100%;border:1px solid #ccc}code{font-size:11px}\
             .note{font-size:12px;color:#444}</style></head><body>\n",
        );
        let _ = writeln!(
            s,
            "<h1>fluidtex compare</h1><p><code>{}</code><br>atlas {}², seed {}, exemplar {}, \
             {:.0} s in all. Thresholds: <code>metrics/thresholds.toml</code> (committed). \
             Cells: median [min, max] over frames, PASS/FAIL of the committed rule \
             and the rulings of docs/evaluation.md (contrast: min; flow: median; popping: mean \
             and worst, or per frame against advect on violent frames; source switch share: the \
             unforced part, or the whole share where a method records no causes, at most 0.02 \
             above advect's on the points both cover; others: worst). Each run's notes say \
             which rule judged a cell.</p>",
            esc(&self.command),
            self.atlas_size,
            self.seed,
            esc(&self.exemplar),
            self.seconds
        );
        for n in &self.not_measured {
            let _ = writeln!(s, "<p class=\"note\">Not measured: {}</p>", esc(n));
        }
        for scene in &self.scenes {
            scene_html(&mut s, scene, thresholds);
        }
        s.push_str("<h2>Method parameters</h2><table><tr><th>method</th><th>parameters</th></tr>");
        let mut seen = Vec::new();
        for m in self.scenes.iter().flat_map(|s| &s.methods) {
            if seen.contains(&m.name) {
                continue;
            }
            seen.push(m.name.clone());
            let _ = write!(
                s,
                "<tr><th>{}</th><td><code>{}</code></td></tr>",
                esc(&m.name),
                esc(&serde_json::to_string_pretty(&m.parameters).unwrap_or_default())
                    .replace('\n', "<br>")
            );
        }
        s.push_str("</table></body></html>\n");
        s
    }
}

/// One scene's section of the HTML report: heading, table of cells,
/// notes, per-frame plots and pictures.
fn scene_html(s: &mut String, scene: &SceneReport, thresholds: &Thresholds) {
    let _ = writeln!(
        s,
        "<h2>{}</h2><p class=\"note\">{}. Frames {}–{} ({} frames, {} fps); render {}² px; \
             true motion: {}.</p>",
        esc(&scene.name),
        esc(&scene.description),
        scene.frames.first().copied().unwrap_or(0),
        scene.frames.last().copied().unwrap_or(0),
        scene.frames.len(),
        scene.fps,
        scene.render_size,
        esc(&scene.truth_motion)
    );
    scene_table(s, scene);
    for m in &scene.methods {
        for n in &m.notes {
            let _ = writeln!(s, "<p class=\"note\">{}: {}</p>", esc(&m.name), esc(n));
        }
    }
    s.push_str("<div class=\"plots\">");
    for &m in PER_FRAME {
        s.push_str(&plot(scene, m, threshold_of(thresholds, m)));
    }
    s.push_str("</div>\n");
    for (caption, file) in &scene.images {
        let _ = writeln!(
            s,
            "<figure><figcaption>{}</figcaption><a href=\"{f}\"><img src=\"{f}\"></a></figure>",
            esc(caption),
            f = esc(file)
        );
    }
}

/// The scene's table: a row per method, a cell per metric.
fn scene_table(s: &mut String, scene: &SceneReport) {
    s.push_str("<table><tr><th>method</th>");
    for &m in COLUMNS {
        let _ = write!(s, "<th>{}</th>", esc(m.name()));
        if m == Metric::Distortion {
            let _ = write!(s, "<th>{ANISOTROPY}</th>");
        }
        if m == Metric::SourceSwitch {
            for title in SWITCH_SPLIT {
                let _ = write!(s, "<th>{}</th>", esc(title));
            }
        }
    }
    if scene.has_state() {
        for title in STATE {
            let _ = write!(s, "<th>{}</th>", esc(title));
        }
    }
    s.push_str("<th>s/frame</th><th>patches</th></tr>\n");
    for m in &scene.methods {
        let _ = write!(s, "<tr><th>{}</th>", esc(&m.name));
        for &c in COLUMNS {
            match m.cell(metric_key(c)) {
                Some(cell) if cell.frames > 0 => {
                    let class = if cell.pass { "pass" } else { "fail" };
                    let _ = write!(s, "<td class=\"{class}\">{}</td>", esc(&cell_text(cell)));
                }
                _ => s.push_str("<td class=\"na\">n/a</td>"),
            }
            if c == Metric::Distortion {
                let text = m.anisotropy.as_ref().map_or("—".into(), spread_text);
                let _ = write!(s, "<td>{}</td>", esc(&text));
            }
            if c == Metric::SourceSwitch {
                for text in m.switch_split_texts() {
                    let _ = write!(s, "<td>{}</td>", esc(&text));
                }
            }
        }
        if scene.has_state() {
            for text in m.state_texts() {
                let _ = write!(s, "<td>{}</td>", esc(&text));
            }
        }
        let _ = writeln!(
            s,
            "<td>{}</td><td>{}</td></tr>",
            spread_text(&m.seconds_per_frame),
            m.patches.as_ref().map_or("—".into(), spread_text)
        );
    }
    s.push_str("</table>\n");
}

fn esc(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Line colours of the methods in plots.
const PALETTE: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
];

/// An inline SVG plot of metric `m` over frames, one line per method, the
/// threshold dashed. Infinite values are drawn at the top edge.
fn plot(scene: &SceneReport, m: Metric, threshold: Option<f64>) -> String {
    let series = series_of(scene, metric_key(m));
    let area = PlotArea::fit(scene, &series, threshold);
    let mut s = area.axes();
    if let Some(t) = threshold.filter(|t| t.is_finite()) {
        let _ = write!(
            s,
            "<line x1=\"{}\" x2=\"{}\" y1=\"{y}\" y2=\"{y}\" stroke=\"#444\" \
             stroke-dasharray=\"4 3\"/>",
            area.left,
            area.w - area.right,
            y = area.y(t)
        );
    }
    area.lines(&mut s, &series);
    area.legend(&mut s, scene);
    let _ = write!(
        s,
        "</svg><figcaption>{}{}</figcaption></figure>",
        esc(m.name()),
        if threshold.is_some() {
            " (dashed: threshold)"
        } else {
            ""
        }
    );
    s
}

/// Per method, the (frame, value) points of metric `key` (NaN left out).
fn series_of(scene: &SceneReport, key: &str) -> Vec<Vec<(i32, f64)>> {
    scene
        .methods
        .iter()
        .map(|mr| {
            mr.per_frame
                .iter()
                .filter_map(|f| {
                    f.values
                        .iter()
                        .find(|(k, _)| *k == key)
                        .map(|&(_, v)| (f.frame, v))
                })
                .filter(|(_, v)| !v.is_nan())
                .collect()
        })
        .collect()
}

/// A plot's size, margins and ranges (frames on x, values on y).
struct PlotArea {
    w: f64,
    h: f64,
    left: f64,
    right: f64,
    top: f64,
    bottom: f64,
    lo: f64,
    hi: f64,
    f0: f64,
    f1: f64,
}

impl PlotArea {
    /// The area whose value range holds 0, every finite point and the
    /// threshold, with 5 % headroom.
    fn fit(scene: &SceneReport, series: &[Vec<(i32, f64)>], threshold: Option<f64>) -> PlotArea {
        let finite = series
            .iter()
            .flatten()
            .map(|&(_, v)| v)
            .chain(threshold)
            .filter(|v| v.is_finite());
        let (mut lo, mut hi) = finite.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        if lo > hi {
            (lo, hi) = (0.0, 1.0);
        }
        lo = lo.min(0.0);
        if hi - lo < 1e-9 {
            hi = lo + 1.0;
        }
        hi += 0.05 * (hi - lo);
        let f0 = scene.frames.first().copied().unwrap_or(0) as f64;
        let f1 = (scene.frames.last().copied().unwrap_or(1) as f64).max(f0 + 1.0);
        PlotArea {
            w: 300.0,
            h: 170.0,
            left: 46.0,
            right: 8.0,
            top: 8.0,
            bottom: 34.0,
            lo,
            hi,
            f0,
            f1,
        }
    }

    fn x(&self, f: f64) -> f64 {
        self.left + (f - self.f0) / (self.f1 - self.f0) * (self.w - self.left - self.right)
    }

    fn y(&self, v: f64) -> f64 {
        let (lo, hi) = (self.lo, self.hi);
        let v = if v.is_infinite() { hi } else { v.clamp(lo, hi) };
        self.top + (hi - v) / (hi - lo) * (self.h - self.top - self.bottom)
    }

    /// The SVG's opening, frame and axis labels.
    fn axes(&self) -> String {
        let (w, h, left, right, top, bottom) =
            (self.w, self.h, self.left, self.right, self.top, self.bottom);
        let mut s = format!(
            "<figure><svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" \
             font-size=\"10\"><rect x=\"{left}\" y=\"{top}\" width=\"{}\" height=\"{}\" \
             fill=\"#fafafa\" stroke=\"#999\"/>",
            w - left - right,
            h - top - bottom
        );
        for v in [self.lo, 0.5 * (self.lo + self.hi), self.hi] {
            let _ = write!(
                s,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}</text>",
                left - 3.0,
                self.y(v) + 3.0,
                num(v)
            );
        }
        for f in [self.f0, self.f1] {
            let _ = write!(
                s,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
                self.x(f),
                h - bottom + 12.0,
                f as i64
            );
        }
        let _ = write!(
            s,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">frame</text>",
            0.5 * (left + w - right),
            h - bottom + 12.0
        );
        s
    }

    /// A polyline and dots per method.
    fn lines(&self, s: &mut String, series: &[Vec<(i32, f64)>]) {
        for (k, pts) in series.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            let path: Vec<String> = pts
                .iter()
                .map(|&(f, v)| format!("{:.1},{:.1}", self.x(f as f64), self.y(v)))
                .collect();
            if path.len() > 1 {
                let _ = write!(
                    s,
                    "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\" points=\"{}\"/>",
                    path.join(" ")
                );
            }
            for &(f, v) in pts {
                let _ = write!(
                    s,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2\" fill=\"{colour}\"/>",
                    self.x(f as f64),
                    self.y(v)
                );
            }
        }
    }

    /// The method names with their colours, along the bottom.
    fn legend(&self, s: &mut String, scene: &SceneReport) {
        let mut lx = self.left;
        for (k, mr) in scene.methods.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            let _ = write!(
                s,
                "<rect x=\"{lx}\" y=\"{}\" width=\"8\" height=\"8\" fill=\"{colour}\"/>\
                 <text x=\"{}\" y=\"{}\">{}</text>",
                self.h - 12.0,
                lx + 10.0,
                self.h - 4.0,
                esc(&mr.name)
            );
            lx += 16.0 + 6.0 * mr.name.len() as f64;
        }
    }
}

/// Rows of images stacked top to bottom, each row left to right, `gap`
/// pixels apart, on `background` (a contact sheet).
pub fn contact_sheet(rows: &[Vec<&Texture>], gap: u32, background: [f32; 3]) -> Texture {
    let lines: Vec<Texture> = rows
        .iter()
        .map(|r| crate::render::side_by_side(r, gap, background))
        .collect();
    let width = lines.iter().map(|t| t.width).max().unwrap_or(0);
    let height =
        lines.iter().map(|t| t.height).sum::<u32>() + gap * lines.len().saturating_sub(1) as u32;
    let mut out = Texture::filled(width, height, 3, 0.0);
    for px in out.data.chunks_exact_mut(3) {
        px.copy_from_slice(&background);
    }
    let mut top = 0;
    for line in &lines {
        for y in 0..line.height {
            for x in 0..line.width {
                let t = line.texel(x, y);
                out.texel_mut(x, top + y).copy_from_slice(&t[..3]);
            }
        }
        top += line.height + gap;
    }
    out
}
