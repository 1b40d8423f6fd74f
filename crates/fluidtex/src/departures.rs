//! The departures ledger: every place where fluidtex does something other
//! than the paper it implements, in one table.
//!
//! Three papers are implemented: Gagnon et al. 2021 (patch erosion, the
//! `erosion` method and the baselines built on its patches), Gagnon,
//! Dagenais, Paquette 2016 (dynamic lapped textures, `lapped-rigid`) and
//! Kwatra et al. 2007 (surface texture optimisation, `optimization`).
//! [`DEPARTURES`] lists each departure with the paper's section, our
//! default, the paper's setting, the key or flag that selects it and what
//! it was measured to change; [`AS_PUBLISHED`] lists every other method
//! parameter, with why its default is what it is (the paper's value, or a
//! choice the paper leaves open).
//!
//! `docs/departures.md` is generated from these tables by [`render`], and
//! the test `crates/fluidtex/tests/departures_ledger.rs` checks that the
//! file is current and that every parameter of
//! [`crate::methods::registry::MethodParams`] has exactly one place here:
//! a new parameter that is not in the ledger fails CI. Regenerate the file
//! with `FLUIDTEX_BLESS=1 cargo test -p fluidtex --test departures_ledger`.
//!
//! Measured numbers come from the README and the code comments, with the
//! command that measures them; "not measured" says that nobody has.

mod erosion_rows;
mod lapped_rows;
mod optimization_rows;
mod published;
#[cfg(test)]
mod switch_tests;

/// One way fluidtex departs from a paper it implements.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Departure {
    /// The methods it applies to (`--method` names).
    pub method: &'static str,
    /// The paper and where in it, e.g. "2021 Sec. 5.2, Eq. 1"; the year
    /// picks the table ([`FAMILIES`]).
    pub paper: &'static str,
    /// What the departure is about.
    pub what: &'static str,
    /// What fluidtex does by default.
    pub ours: &'static str,
    /// What the paper does, and how to get it (or "no paper setting yet").
    pub paper_setting: &'static str,
    /// The method parameter (`section.key`, as in the config file) this
    /// entry is the ledger's place for; `None` where the departure has no
    /// parameter of its own (no switch yet, or one owned by another entry
    /// or a run setting, which `flag` then names).
    pub key: Option<&'static str>,
    /// The command-line setting that restores the paper's behaviour, if any.
    pub flag: Option<&'static str>,
    /// What `--preset paper` sets for this entry: TOML lines with dotted
    /// keys as in the config file (e.g. `erosion.weights = "paper"`);
    /// empty where the paper's behaviour has no setting yet, or another
    /// entry's lines set it.
    pub preset: &'static str,
    /// The measured effect, with numbers where they were measured.
    pub effect: &'static str,
    /// The command that measures it.
    pub measure: &'static str,
    /// The unit test that pins the behaviour, as a module path from the
    /// crate root and the test's name (e.g.
    /// `methods::optimization::behaviour_tests::a_frame_without_motion_skips_synthesis`),
    /// or `tests::FILE::NAME` for an integration test; the row's number or
    /// rule, checked from both sides. Every row without a parameter names
    /// one (`tests/departures_ledger.rs` checks that it exists); a row with
    /// a parameter may leave it empty, since its switch is run both ways by
    /// the ledger's switch test.
    pub pinned_by: &'static str,
}

/// The method families, one table each: (year prefix of
/// [`Departure::paper`], heading).
pub const FAMILIES: &[(&str, &str)] = &[
    (
        "2021",
        "Patch erosion (Gagnon et al. 2021): `erosion`, and `advect`, `blend-deformable`, \
         `dual-rest` built on its patches",
    ),
    (
        "2016",
        "Dynamic lapped textures (Gagnon, Dagenais, Paquette 2016): `lapped-rigid`",
    ),
    (
        "2007",
        "Texturing fluids by surface texture optimisation (Kwatra et al. 2007): `optimization`",
    ),
];

/// Every departure from the papers, grouped by paper (one file each).
pub const DEPARTURES: &[Departure] = &ALL;

/// How many rows the three files hold.
const COUNT: usize =
    erosion_rows::ROWS.len() + lapped_rows::ROWS.len() + optimization_rows::ROWS.len();

/// The three files' rows in one array: the 2021 rows, then 2016, then 2007.
const ALL: [Departure; COUNT] = {
    let parts = [
        erosion_rows::ROWS,
        lapped_rows::ROWS,
        optimization_rows::ROWS,
    ];
    let mut out = [erosion_rows::ROWS[0]; COUNT];
    let (mut p, mut at) = (0, 0);
    while p < parts.len() {
        let mut i = 0;
        while i < parts[p].len() {
            out[at] = parts[p][i];
            at += 1;
            i += 1;
        }
        p += 1;
    }
    out
};

pub use self::published::AS_PUBLISHED;

/// A table cell: `|` escaped, no line breaks.
fn cell(text: &str) -> String {
    text.replace('|', "\\|").replace('\n', " ")
}

/// A key or flag as code, or a dash.
fn code_or_dash(text: Option<&str>) -> String {
    match text {
        Some(t) => format!("`{}`", cell(t)),
        None => "—".to_string(),
    }
}

/// The markdown of `docs/departures.md`.
pub fn render() -> String {
    let mut out = String::new();
    out.push_str(
        "# Where fluidtex departs from the papers\n\
         \n\
         <!-- Generated from crates/fluidtex/src/departures.rs and departures/ by \
         fluidtex::departures::render(); do not edit by hand. Regenerate with \
         FLUIDTEX_BLESS=1 cargo test -p fluidtex --test departures_ledger -->\n\
         \n\
         fluidtex implements three papers: Gagnon et al. 2021 (patch erosion), Gagnon, \
         Dagenais, Paquette 2016 (dynamic lapped textures) and Kwatra et al. 2007 (surface \
         texture optimisation). This ledger lists every place where it does something else, \
         one row each: the paper's section, what fluidtex does by default, what the paper \
         does, the method parameter (config key, `section.key`) the row is the place for and \
         the flag that restores the paper, and what the departure was measured to change, with \
         the command that measures it (\"not measured\" where nobody has). A command run \
         \"without and with `--config P`\" is run twice, the second time with P, a TOML file \
         holding the lines given. Every method parameter appears exactly once in this ledger, \
         as a departure or in the last table (the paper's value, or a choice the paper leaves \
         open); a test holds the ledger against the parameters, so a new parameter must be \
         entered here. Rows without a key are behaviours with no parameter of their own: \
         each says why it has no switch (or which setting is its switch) and names, under \
         \"pinned by\", the unit test that checks its rule or number from both sides, so a \
         change of behaviour fails that test until the row is revisited; a test checks that \
         the named test exists. Every row whose paper setting has preset lines is run both \
         ways on a tiny scene by `departures::switch_tests`, which fails when the two runs \
         are the same. The README explains the larger departures at length.\n",
    );
    for (year, heading) in FAMILIES {
        out.push_str(&format!("\n## {heading}\n\n"));
        out.push_str(
            "| method | paper | what | ours (default) | the paper's | key | flag | measured \
             effect | measured by | pinned by |\n",
        );
        out.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
        for d in DEPARTURES.iter().filter(|d| d.paper.starts_with(year)) {
            out.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                cell(d.method),
                cell(d.paper),
                cell(d.what),
                cell(d.ours),
                cell(d.paper_setting),
                code_or_dash(d.key),
                code_or_dash(d.flag),
                cell(d.effect),
                cell(d.measure),
                code_or_dash((!d.pinned_by.is_empty()).then_some(d.pinned_by)),
            ));
        }
    }
    out.push_str(
        "\n## Parameters as published, or left open by the paper\n\n\
         Every other method parameter: the paper's value, a choice the paper leaves open, or a \
         setting of a departure above or of a method that is not from a paper.\n\n\
         | key | why |\n|---|---|\n",
    );
    for (key, why) in AS_PUBLISHED {
        out.push_str(&format!("| `{}` | {} |\n", cell(key), cell(why)));
    }
    out.push_str(
        "\n## `--preset paper`\n\n\
         `fluidtex run --preset paper` (or `preset = \"paper\"` in the config) sets every \
         departure above that has a paper setting to it, for every method; the keys the \
         config file or a flag sets still win. Rows that say \"no paper setting yet\" keep \
         fluidtex's behaviour under the preset. `lapped-rigid` gets the plain radial mask \
         (`lapped_rigid.mask_feature_weight = 0`), the closer stand-in for the paper's \
         hand-painted masks: give one with `--mask`. `--print-config` prints every resolved \
         parameter. The preset is:\n\n\
         ```toml\n",
    );
    out.push_str(&paper_preset());
    out.push_str("```\n");
    out
}

/// The TOML lines `--preset paper` sets ([`Departure::preset`] of every
/// entry, each line once, in ledger order).
pub fn paper_preset() -> String {
    let mut lines: Vec<&str> = Vec::new();
    for d in DEPARTURES {
        for line in d.preset.lines() {
            if !lines.contains(&line) {
                lines.push(line);
            }
        }
    }
    lines.iter().map(|l| format!("{l}\n")).collect()
}
