//! The markdown of `docs/reproduction.md`: the papers' published figures
//! (typed in from the papers, with their table or figure) beside ours.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::Value;

use super::{Input, Plan, TimingResult};

/// One input's comparison: the input, its files with their SHA-256, the
/// `compare` report, the folder it was written to.
pub type Compared = (Input, Vec<(String, String)>, Value, PathBuf);

/// A metric of `method` in `report`: (median, worst frame). The worst is
/// the lowest for shares where higher is better, the highest otherwise.
fn metric(report: &Value, method: &str, key: &str) -> Option<(f64, f64)> {
    let m = report["scenes"][0]["methods"]
        .as_array()?
        .iter()
        .find(|m| m["name"] == method)?;
    let row = m["metrics"].as_array()?.iter().find(|r| r["key"] == key)?;
    let worst = if matches!(key, "contrast" | "flow_aligned") {
        "min"
    } else {
        "max"
    };
    // A worst frame with no finite value (every texel of it renewed, an
    // end-point error without end) is written as NaN and shown as "—".
    Some((
        row["median"].as_f64()?,
        row[worst].as_f64().unwrap_or(f64::NAN),
    ))
}

/// "median (worst)" with `digits` decimals, or "n/a".
fn cell(v: Option<(f64, f64)>, digits: usize) -> String {
    match v {
        Some((m, w)) if w.is_nan() => format!("{m:.digits$} (—)"),
        Some((m, w)) => format!("{m:.digits$} ({w:.digits$})"),
        None => "n/a".into(),
    }
}

/// The seconds per frame of `method` in `report`: (median, worst).
fn seconds(report: &Value, method: &str) -> Option<(f64, f64)> {
    let m = report["scenes"][0]["methods"]
        .as_array()?
        .iter()
        .find(|m| m["name"] == method)?;
    Some((
        m["seconds_per_frame"]["median"].as_f64()?,
        m["seconds_per_frame"]["max"].as_f64()?,
    ))
}

/// The two runs of every method in a comparison: its defaults, and
/// `--preset paper` (reported as `METHOD (paper)`).
const VARIANTS: [(&str, &str); 2] = [("defaults", ""), ("`--preset paper`", " (paper)")];

/// One row per input and variant: the row's label, then `cells` of the
/// comparison `r` with the variant's suffix for the method names.
fn variant_rows(
    compared: &[Compared],
    cells: impl Fn(&Value, &dyn Fn(&str) -> String) -> Vec<String>,
) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for (input, _, r, _) in compared {
        for (label, suffix) in VARIANTS {
            let name = |m: &str| format!("{m}{suffix}");
            let mut row = vec![format!("{}, {label}", input.key)];
            row.extend(cells(r, &name));
            rows.push(row);
        }
    }
    rows
}

/// A table with one row per input and variant and, for each column of
/// `spec` (method, metric key, decimals, header), that metric's "median
/// (worst)" cell.
fn comparison_table(s: &mut String, compared: &[Compared], spec: &[(&str, &str, usize, &str)]) {
    let rows = variant_rows(compared, |r, name| {
        spec.iter()
            .map(|&(m, key, digits, _)| cell(metric(r, &name(m), key), digits))
            .collect()
    });
    let header: Vec<&str> = std::iter::once("input")
        .chain(spec.iter().map(|c| c.3))
        .collect();
    table(s, &header, &rows);
}

/// The medians of `key` for `a` and `b` on every input and variant, as
/// (input and variant, a's, b's), where both were measured.
fn pairs(compared: &[Compared], a: &str, b: &str, key: &str) -> Vec<(String, f64, f64)> {
    let mut out = Vec::new();
    for (input, _, r, _) in compared {
        for (label, suffix) in VARIANTS {
            let x = metric(r, &format!("{a}{suffix}"), key);
            let y = metric(r, &format!("{b}{suffix}"), key);
            if let (Some((x, _)), Some((y, _))) = (x, y) {
                out.push((format!("{}, {label}", input.key), x, y));
            }
        }
    }
    out
}

/// "Ours: ..." — where `a`'s median is below `b`'s on every input and
/// variant, and where not.
fn lower_everywhere(out: &mut String, what: &str, a: &str, b: &str, pairs: &[(String, f64, f64)]) {
    let (held, not): (Vec<_>, Vec<_>) = pairs.iter().partition(|(_, x, y)| x < y);
    let list = |v: &[&(String, f64, f64)]| {
        v.iter()
            .map(|(l, x, y)| format!("{l}: {x:.3} against {y:.3}"))
            .collect::<Vec<_>>()
            .join("; ")
    };
    if not.is_empty() {
        let _ = writeln!(
            out,
            "Ours: {a}'s {what} is below {b}'s on every run ({}).\n",
            list(&held)
        );
    } else if held.is_empty() {
        let _ = writeln!(
            out,
            "Ours: {a}'s {what} is below {b}'s on no run ({}).\n",
            list(&not)
        );
    } else {
        let _ = writeln!(
            out,
            "Ours: {a}'s {what} is below {b}'s on {} of {} runs ({}); not on the others ({}).\n",
            held.len(),
            pairs.len(),
            list(&held),
            list(&not)
        );
    }
}

/// A markdown table: a header and rows of cells.
fn table(out: &mut String, header: &[&str], rows: &[Vec<String>]) {
    let _ = writeln!(out, "| {} |", header.join(" | "));
    let _ = writeln!(out, "|{}", " --- |".repeat(header.len()));
    for r in rows {
        let _ = writeln!(out, "| {} |", r.join(" | "));
    }
    out.push('\n');
}

/// The whole report.
pub fn render(
    plan: &Plan,
    fingerprint: &str,
    compared: &[Compared],
    timings: &BTreeMap<String, TimingResult>,
    out_path: &Path,
) -> Result<String> {
    let mut s = String::new();
    let threads = timings.values().map(|t| t.threads).max().unwrap_or(0);
    let _ = writeln!(
        s,
        "# Reproduction: each paper's headline comparison beside ours\n\n\
         Generated by `fluidtex reproduce --splash SPLASH --viscous VISCOUS --work WORK` \
         (SPLASH and VISCOUS baked as the inputs table says); do not edit by hand.\n\n\
         fingerprint: `{fingerprint}`\n\n\
         The fingerprint is a SHA-256 of the version ({}), the commands below, every method's \
         default parameters, the paper preset and the committed thresholds. \
         `cargo test -p fluidtex-cli --test reproduction_report` fails when it no longer matches \
         what the command would use: then regenerate this file.\n\n\
         Ours ran on {threads} threads. The papers' times are from 12-core machines (2016: \
         Intel i7-3960X; 2021: Xeon Silver 4214, 12 cores for patch and atlas creation) and \
         from 2007 hardware (2007). Every \"median (worst)\" is over the compared frames; the \
         worst is the highest, or the lowest for contrast and the aligned share. The metrics \
         are those of `docs/evaluation.md`.\n",
        env!("CARGO_PKG_VERSION")
    );
    inputs_section(&mut s, plan, compared);
    pictures(&mut s, compared, out_path)?;
    section_2021(&mut s, compared, timings);
    section_2016(&mut s, compared, timings);
    section_2007(&mut s, compared, timings);
    Ok(s)
}

fn inputs_section(s: &mut String, plan: &Plan, compared: &[Compared]) {
    s.push_str("## Inputs and commands\n\n");
    let rows: Vec<Vec<String>> = compared
        .iter()
        .map(|(input, files, _, _)| {
            let first = files.first().map(|(n, h)| format!("{n} `{}`", &h[..12]));
            let last = files.last().map(|(n, h)| format!("{n} `{}`", &h[..12]));
            vec![
                input.key.to_string(),
                input.what.to_string(),
                format!("`{} {}`", super::BAKE, input.bake),
                format!(
                    "{} ({} files; first {}, last {})",
                    input.frames,
                    files.len(),
                    first.unwrap_or_default(),
                    last.unwrap_or_default()
                ),
                format!(
                    "`{}`",
                    super::compare_command_line(
                        &plan.compare_args(input, &input.key.to_uppercase(), PathBuf::new()),
                        &super::all_methods()
                    )
                ),
            ]
        })
        .collect();
    table(
        s,
        &[
            "input",
            "what",
            "bake (OUT: a folder)",
            "frames (SHA-256)",
            "compare",
        ],
        &rows,
    );
    s.push_str("Timing runs, on the generated scenes at the papers' sizes:\n\n");
    for t in &plan.timings {
        let _ = writeln!(s, "- `{}` ({})", t.command(), t.id);
    }
    s.push('\n');
}

/// Copies each input's contact sheet beside the report and links it.
fn pictures(s: &mut String, compared: &[Compared], out_path: &Path) -> Result<()> {
    let dir = out_path
        .parent()
        .unwrap_or(Path::new("."))
        .join("reproduction");
    s.push_str(
        "## Pictures\n\nThe papers' comparisons are pictures and videos (2021 Figs. 13, 14 and \
         16; 2016 Figs. 4–9); they are not reproduced here. Ours, every method side by side \
         (rows: methods, default then `(paper)`; columns: frames):\n\n",
    );
    for (input, _, report, folder) in compared {
        let Some(images) = report["scenes"][0]["images"].as_array() else {
            continue;
        };
        let Some(sheet) = images.iter().find_map(|i| {
            let name = i.get(1)?.as_str()?;
            name.ends_with("_sheet.png")
                .then(|| (i.get(0).and_then(Value::as_str).unwrap_or(""), name))
        }) else {
            continue;
        };
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let name = format!("{}_sheet.png", input.key);
        let bytes = std::fs::read(folder.join(sheet.1))
            .with_context(|| format!("cannot read {}", folder.join(sheet.1).display()))?;
        super::write(&dir.join(&name), &bytes)?;
        let _ = writeln!(
            s,
            "- {}: {}\n\n  ![{}](reproduction/{name})\n",
            input.key, sheet.0, input.key
        );
    }
    Ok(())
}

fn section_2021(s: &mut String, compared: &[Compared], timings: &BTreeMap<String, TimingResult>) {
    s.push_str("## 2021: patch erosion (Gagnon et al.)\n\n");
    s.push_str(
        "### Against the 2019 blend (`blend-deformable`): ghosting and contrast\n\nPaper (Fig. \
         14, a picture): erosion shows one patch per texel, so no ghosting; the 2019 blend \
         ghosts and washes the exemplar out.\n\n",
    );
    comparison_table(
        s,
        compared,
        &[
            ("erosion", "ghosting", 3, "erosion ghost fraction"),
            ("blend-deformable", "ghosting", 3, "blend ghost fraction"),
            ("erosion", "contrast", 3, "erosion contrast"),
            ("blend-deformable", "contrast", 3, "blend contrast"),
        ],
    );
    lower_everywhere(
        s,
        "ghost fraction",
        "erosion",
        "blend-deformable",
        &pairs(compared, "erosion", "blend-deformable", "ghosting"),
    );
    lower_everywhere(
        s,
        "contrast loss (1 − contrast ratio)",
        "erosion",
        "blend-deformable",
        &pairs(compared, "erosion", "blend-deformable", "contrast")
            .into_iter()
            .map(|(l, x, y)| (l, 1.0 - x, 1.0 - y))
            .collect::<Vec<_>>(),
    );
    against_2016(s, compared);
    figure_16(s, compared);
    table_1_2021(s, timings);
}

fn against_2016(s: &mut String, compared: &[Compared]) {
    s.push_str(
        "### Against 2016 (`lapped-rigid`): rigidity and popping\n\nPaper (Fig. 13, a \
         picture): rigid 2016 patches do not follow the flow; erosion's deform with it, \
         stretched at most to δ_max = 3.\n\n",
    );
    comparison_table(
        s,
        compared,
        &[
            ("erosion", "distortion", 2, "erosion distortion p95"),
            ("erosion", "flow_epe", 2, "erosion flow EPE (px)"),
            ("erosion", "popping", 3, "erosion popping"),
            ("lapped-rigid", "distortion", 2, "2016 distortion p95"),
            ("lapped-rigid", "flow_epe", 2, "2016 flow EPE (px)"),
            ("lapped-rigid", "popping", 3, "2016 popping"),
        ],
    );
    lower_everywhere(
        s,
        "flow EPE",
        "erosion",
        "lapped-rigid",
        &pairs(compared, "erosion", "lapped-rigid", "flow_epe"),
    );
    lower_everywhere(
        s,
        "popping share",
        "erosion",
        "lapped-rigid",
        &pairs(compared, "erosion", "lapped-rigid", "popping"),
    );
}

fn figure_16(s: &mut String, compared: &[Compared]) {
    s.push_str(
        "### Fig. 16: the render's optical flow against the velocity field\n\nPaper (a \
         picture): the two fields agree closely. Ours: the median end-point error between \
         the texture's image motion and the true motion, and the share of pixels within the \
         aligned tolerance; `advect`, which carries every texel exactly, is the reference.\n\n",
    );
    comparison_table(
        s,
        compared,
        &[
            ("erosion", "flow_epe", 2, "erosion EPE (px)"),
            ("erosion", "flow_aligned", 3, "erosion aligned share"),
            ("advect", "flow_epe", 2, "advect EPE (px)"),
            ("advect", "flow_aligned", 3, "advect aligned share"),
        ],
    );
    let gaps: Vec<String> = pairs(compared, "erosion", "advect", "flow_epe")
        .iter()
        .map(|(l, x, y)| format!("{l}: {:+.2} px", x - y))
        .collect();
    let _ = writeln!(
        s,
        "Ours: erosion's median end-point error minus advect's (the exact carry): {}. Renewed \
         texels have no motion to follow, so they count as misses; the paper gives the \
         agreement as a picture, without a number.\n",
        gaps.join("; ")
    );
}

/// The paper's Table 1 rows: (timing id, scene, polys, patches, advection,
/// creation, update, total).
type Table1Row = (
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    f64,
    f64,
    f64,
    f64,
);

const TABLE_1_2021: &[Table1Row] = &[
    (
        "2021-dam-break",
        "Dam break",
        "85k",
        "4881",
        0.74,
        34.89,
        74.23,
        110.95,
    ),
    (
        "2021-lava",
        "Lava",
        "271k",
        "4664",
        2.07,
        96.69,
        197.39,
        296.15,
    ),
    (
        "2021-viscous-drop",
        "Viscous drop",
        "61k",
        "617",
        0.67,
        11.96,
        33.20,
        45.83,
    ),
];

fn stage(t: &TimingResult, names: &[&str]) -> f64 {
    names.iter().filter_map(|n| t.stages.get(*n)).sum()
}

fn stat_mean(t: &TimingResult, key: &str) -> Option<f64> {
    let v: Vec<f64> = t
        .stats
        .iter()
        .filter_map(|m| m.get(key)?.as_f64())
        .collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn table_1_2021(s: &mut String, timings: &BTreeMap<String, TimingResult>) {
    s.push_str(
        "### Table 1: seconds per frame, by stage\n\nPaper: 12 cores, atlases of about 6k². \
         Ours: the generated scene of the same kind at the paper's triangle count, atlas 2048, \
         the mean of the frames after the first (which places the first patches). Our \
         patch creation is `creation` (the first frame's patches) + `update` (the new patches \
         placed under the uncovered texels of later frames); our patch update is the erosion, \
         `weights` + `delete`; the atlas is `fill`; the total is every stage, writing \
         included.\n\n",
    );
    let mut rows = Vec::new();
    for &(id, scene, polys, patches, adv, cre, upd, tot) in TABLE_1_2021 {
        rows.push(vec![
            format!("{scene} (paper)"),
            polys.into(),
            patches.into(),
            format!("{adv:.2}"),
            format!("{cre:.2}"),
            format!("{upd:.2}"),
            format!("{tot:.2}"),
        ]);
        if let Some(t) = timings.get(id) {
            rows.push(vec![
                format!(
                    "{scene} (ours, `{}`)",
                    t.command.replace("fluidtex bench ", "")
                ),
                format!("{}k", t.triangles / 1000),
                stat_mean(t, "patches_alive").map_or("-".into(), |p| format!("{p:.0}")),
                format!("{:.2}", stage(t, &["advection"])),
                format!("{:.2}", stage(t, &["creation", "update"])),
                format!("{:.2}", stage(t, &["weights", "delete"])),
                format!("{:.2}", t.stages.values().sum::<f64>()),
            ]);
        }
    }
    table(
        s,
        &[
            "scene",
            "polys",
            "patches",
            "advection",
            "patch creation",
            "patch update",
            "total",
        ],
        &rows,
    );
}

fn section_2016(s: &mut String, compared: &[Compared], timings: &BTreeMap<String, TimingResult>) {
    s.push_str(
        "## 2016: dynamic lapped textures (Gagnon, Dagenais, Paquette), `lapped-rigid`\n\n\
         ### Table 1: seconds per frame\n\nPaper: 12 cores (atlas creation in parallel, \
         advection and receivers on one core), atlases 3.5k²–8k². Ours: atlas 2048, the \
         frames after the first; receivers are our `receivers` stage, the atlas our `fill`.\n\n",
    );
    let paper: &[(&str, &str, &str, f64, f64, f64, f64)] = &[
        (
            "2016-dam-break",
            "Dam break",
            "65k",
            0.55,
            30.0,
            45.0,
            75.55,
        ),
        ("2016-lava", "Lava", "260k", 1.25, 175.0, 180.0, 356.25),
    ];
    let mut rows = Vec::new();
    for &(id, scene, polys, adv, rec, atlas, tot) in paper {
        rows.push(vec![
            format!("{scene} (paper)"),
            polys.into(),
            format!("{adv:.2}"),
            format!("{rec:.1}"),
            format!("{atlas:.1}"),
            format!("{tot:.2}"),
        ]);
        if let Some(t) = timings.get(id) {
            rows.push(vec![
                format!(
                    "{scene} (ours, `{}`)",
                    t.command.replace("fluidtex bench ", "")
                ),
                format!("{}k", t.triangles / 1000),
                format!("{:.2}", stage(t, &["advection"])),
                format!("{:.2}", stage(t, &["receivers"])),
                format!("{:.2}", stage(t, &["fill"])),
                format!("{:.2}", t.stages.values().sum::<f64>()),
            ]);
        }
    }
    table(
        s,
        &["scene", "polys", "advection", "receivers", "atlas", "total"],
        &rows,
    );
    s.push_str(
        "### Blur and popping\n\nPaper: blending by the normals blurs about 2 % of the atlas \
         texels on average; the layering leaves the animations free of popping (a claim shown \
         in the video). Ours: the share of chart texels where layers blend \
         (`blended_texels / texels_in_charts`, frames after the first of the timing runs), and \
         the popping share of the comparisons, with erosion beside it. Our count is wider \
         than the paper's: it takes every texel where two layers or more contribute, the soft \
         border of each patch's mask included, where the paper counts the blending by the \
         normals only.\n\n",
    );
    let mut rows = Vec::new();
    for &(id, scene, ..) in paper {
        if let Some(t) = timings.get(id) {
            let blended = stat_mean(t, "blended_texels").zip(stat_mean(t, "texels_in_charts"));
            rows.push(vec![
                format!("{scene} (timing run)"),
                "about 0.02".into(),
                blended.map_or("n/a".into(), |(b, c)| format!("{:.3}", b / c.max(1.0))),
                "—".into(),
                "—".into(),
            ]);
        }
    }
    rows.extend(variant_rows(compared, |r, name| {
        vec![
            "—".into(),
            "—".into(),
            cell(metric(r, &name("lapped-rigid"), "popping"), 3),
            cell(metric(r, &name("erosion"), "popping"), 3),
        ]
    }));
    table(
        s,
        &[
            "input",
            "paper blur share",
            "our blur share",
            "2016 popping",
            "erosion popping",
        ],
        &rows,
    );
}

fn section_2007(s: &mut String, compared: &[Compared], timings: &BTreeMap<String, TimingResult>) {
    s.push_str(
        "## 2007: surface texture optimisation (Kwatra et al.), `optimization --preset paper`\n\n\
         Paper (Sec. VII): synthesis about 60 s per frame for the broken dam, 90 s for the \
         river, 200 s for the lava, with 100k–500k points; the mesh hierarchy (3–15 minutes a \
         frame) was built offline and is not in those times. Ours builds the hierarchy every \
         frame, inside the time below.\n\n",
    );
    let mut rows = Vec::new();
    if let Some(t) = timings.get("2007-dam-break") {
        rows.push(vec![
            format!("dam-break (`{}`)", t.command.replace("fluidtex bench ", "")),
            stat_mean(t, "points").map_or("n/a".into(), |p| format!("{:.0}k", p / 1000.0)),
            "about 60 (broken dam)".into(),
            format!("{:.1}", t.wall_per_frame),
        ]);
    }
    rows.extend(variant_rows(compared, |r, name| {
        vec![
            "up to 1 per atlas texel".into(),
            "—".into(),
            cell(seconds(r, &name("optimization")), 1),
        ]
    }));
    table(
        s,
        &[
            "input (compare: atlas 512)",
            "points",
            "paper s/frame",
            "ours s/frame",
        ],
        &rows,
    );
}
