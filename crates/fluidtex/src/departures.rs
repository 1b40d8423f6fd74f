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

mod published;

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

/// Every departure from the papers, grouped by paper.
pub const DEPARTURES: &[Departure] = &[
    // ---- 2021: patch erosion ----------------------------------------
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.2, Eq. 3",
        what: "How the vertex weights w_V evolve from frame to frame.",
        ours: "`weights = progressive`: w_V never rises and falls by at most `erosion_rate` per \
               second towards Q_V·B_V; a patch that did not move keeps its weights.",
        paper_setting: "w_V = Q_V·B_V recomputed from scratch every frame (`weights = paper`).",
        key: Some("erosion.weights"),
        flag: Some("--weights paper"),
        preset: "erosion.weights = \"paper\"",
        effect: "Not measured. With the paper's weights re-meshing jitter and new boundary \
                 vertices make texels erode, come back and erode again (the texture boils).",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-47 --methods erosion \
                  --out cmp`, without and with `--config P`, P: `erosion.weights = \"paper\"`",
    },
    Departure {
        method: "erosion, blend-deformable",
        paper: "2021 Sec. 5.2, Eq. 1",
        what: "Where the triangle quality Q_T starts to fall.",
        ours: "`delta_onset = 1.5` with `erosion_rate = 4.8`: Q_T stays 1 up to δ = 1.5, then \
               falls linearly to 0 at δ_max; the faster rate still removes a patch before δ_max.",
        paper_setting: "Q_T falls from δ = 1 on (`delta_onset = 1`, with the rate it came with, \
                        `erosion_rate = 2.4`).",
        key: Some("erosion.delta_onset"),
        flag: Some("--delta-onset 1 --erosion-rate 2.4"),
        preset: "erosion.delta_onset = 1.0\nerosion.erosion_rate = 2.4",
        effect: "Paper → ours: switch share median (worst) on `vortex` 17.2 % (20.1) → 14.5 % \
                 (17.7), on `dam-break` 27.7 % (40.5) → 25.3 % (39.1); colour follow ratio \
                 0.223 → 0.206 (dam-break); distortion p95 3.47 → 2.71 (enright).",
        measure: "`fluidtex compare --scenes vortex --frames 0-47 --atlas 512 --methods erosion \
                  --out cmp` (and `--scenes dam-break --frames 0-30 --atlas 1024`, \
                  `--scenes enright`), without and with `--config P`, P: \
                  `erosion.delta_onset = 1.0` and `erosion.erosion_rate = 2.4`",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.2, Eqs. 1 and 3",
        what: "Texels of a patch triangle stretched past δ_max.",
        ours: "`bound = hard`: never shown. The erosion test treats the triangle as eroded \
               whole, so the distortion bound holds on every texel, however fast the flow.",
        paper_setting: "Shown where the vertex weights keep them (`bound = paper`): Q_T = 0 \
                        past δ_max, but Q_V averages Q_T over a vertex's triangles, and \
                        progressive weights fall at a bounded rate.",
        key: Some("erosion.bound"),
        flag: Some("--bound paper"),
        preset: "erosion.bound = \"paper\"",
        effect: "Weights → hard, default erosion: distortion p95 median (worst) on `dam-break` \
                 frames 6–17, atlas 512, 2.95 (3.56) → 2.54 (2.64), popping 0.120 → 0.122, \
                 switch share 0.197 → 0.199. A unit test on `vortex` counts texels shown by a \
                 holder past δ_max: some under the weights, none under the hard bound.",
        measure: "`fluidtex compare --scenes dam-break --frames 6-17 --methods erosion,advect \
                  --out cmp`, without and with `--config P`, P: `erosion.bound = \"paper\"`; \
                  `cargo test -p fluidtex --lib \
                  under_the_hard_bound_no_texel_shows_a_triangle_past_delta_max`",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.2, Eqs. 2–3",
        what: "The first weights of a new patch.",
        ours: "With progressive weights a new patch starts at w = 1 on its pinned vertices \
               (within r/4 of p, and the corners of p's triangle), whatever Q_V; they then fall \
               towards Q_V·B_V at the erosion rate.",
        paper_setting: "w_V = Q_V·B_V from the first frame (`weights = paper`, owned by the \
                        progressive-weights entry).",
        key: None,
        flag: Some("--weights paper"),
        preset: "",
        effect: "Not measured on a scene. A unit test builds a curved creation site (δ_max = \
                 1.2) where the pinned vertices' paper weights fall below 0.5: such a patch \
                 erodes its own seed texel and is deleted and recreated every frame, even at \
                 rest.",
        measure: "`cargo test -p fluidtex --lib \
                  a_new_patch_keeps_its_centre_whole_however_curved_the_surface`",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.2 (D(u, v))",
        what: "Where the centre falloff D of the erosion test reaches 0.",
        ours: "`falloff = footprint`: at the patch's own footprint, uv distance r/S (≈ 0.385 \
               with S = 2.6 r).",
        paper_setting: "At uv distance 0.5, the edge of the exemplar square (`falloff = paper`).",
        key: Some("erosion.falloff"),
        flag: Some("--falloff paper"),
        preset: "erosion.falloff = \"paper\"",
        effect: "Not measured. With the paper's reach D stays ≥ 0.23 on a patch, so an \
                 undistorted patch keeps its polygonal border instead of one along the features.",
        measure: "`fluidtex compare --scenes vortex,dam-break --methods erosion --out cmp`, \
                  without and with `--config P`, P: `erosion.falloff = \"paper\"`",
    },
    Departure {
        method: "erosion, advect, blend-deformable, dual-rest",
        paper: "2021 Sec. 4",
        what: "Refining patch triangles stretched by the flow.",
        ours: "`split_edges = 2`: after advection, patch edges longer than 2 median edge lengths \
               of the frame are split at their midpoint, projected onto the surface; erosion \
               leaves edges stretched past δ_max whole, and where every triangle is kept (the \
               baselines, `eroded_triangles = \"kept\"`) a triangle distorted past 4·δ_max is \
               split no more, so a patch's triangles follow the surface it covers, not the \
               run's history.",
        paper_setting: "A patch keeps the triangles it was made with (`split_edges = 0`).",
        key: Some("erosion.split_edges"),
        flag: Some("--split-edges 0"),
        preset: "erosion.split_edges = 0.0",
        effect: "On the dam break with erosion off, the per-frame source switches fell from \
                 about 10 % to 7 %.",
        measure: "`fluidtex compare --scenes dam-break --methods erosion --out cmp --config P` \
                  with P: `erosion.delta_max = 1000`, then with `erosion.split_edges = 0` added",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.1",
        what: "The tone of the composite.",
        ours: "`tone = mean`: each frame every channel is shifted so that its mean over the \
               covered texels is the exemplar's.",
        paper_setting: "The composite as the fill makes it (`tone = off`).",
        key: Some("erosion.tone"),
        flag: Some("--tone off"),
        preset: "erosion.tone = \"off\"",
        effect: "Dam break, frames 0–30, atlas 1024, luminance against advect: up to 15.8 % \
                 brighter with the paper's composite, at most 2.9 % with `mean`; popping median \
                 0.113 against 0.114 without it.",
        measure: "`fluidtex compare --scenes dam-break --frames 0-30 --atlas 1024 --methods \
                  erosion,advect --out cmp`, without and with `--config P`, P: \
                  `erosion.tone = \"off\"`",
    },
    Departure {
        method: "erosion, advect, dual-rest",
        paper: "2021 Sec. 5.1",
        what: "How a minified exemplar is read.",
        ours: "Every channel is read from the exemplar's mip pyramid at the atlas texel's \
               footprint (run setting `exemplar_filter = trilinear`).",
        paper_setting: "The patch texel's colour at full resolution (`exemplar_filter = none`).",
        key: None,
        flag: Some("--exemplar-filter none"),
        preset: "exemplar_filter = \"none\"",
        effect: "Not measured. Point samples of a minified exemplar alias and flicker from frame \
                 to frame.",
        measure: "`fluidtex compare --scenes vortex,dam-break --methods erosion --out cmp`, \
                  without and with `--config P`, P: `exemplar_filter = \"none\"`",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.2 (F_m)",
        what: "How the erosion test reads the feature map.",
        ours: "Always at the mip level matching one atlas texel on the patch triangle, also with \
               `--exemplar-filter none`.",
        paper_setting: "F_m at the texel's uv, bilinear at full resolution \
                        (`feature_filter = full`).",
        key: Some("erosion.feature_filter"),
        flag: Some("--feature-filter full"),
        preset: "erosion.feature_filter = \"full\"",
        effect: "Dam break, frames 0–23, atlas 512: unforced switches 19.1 % → 22.8 % per frame \
                 (median), flow-aligned share 0.674 → 0.612, popping 0.113 → 0.106; vortex: \
                 popping 0.117 → 0.109, aligned 0.797 → 0.783. The filtered border is a smooth \
                 curve that moves with the patch instead of texel-sized speckle.",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-23 --methods erosion --out cmp`, \
                  without and with `--config P`, P: `erosion.feature_filter = \"full\"`",
    },
    Departure {
        method: "erosion, advect, blend-deformable, dual-rest",
        paper: "2021 Sec. 4",
        what: "Which fluid triangles a new patch copies.",
        ours: "The triangles within r of p that face the side of p's normal and are \
               edge-connected, through such triangles, to p's triangle.",
        paper_setting: "Every triangle within r of p that does not face away from the normal at \
                        p, connected or not (`patch_region = paper`; the pieces LSCM cannot \
                        reach continue the flattening of p's piece by a least-squares affine \
                        map of their tangent-plane projection).",
        key: Some("erosion.patch_region"),
        flag: Some("--patch-region paper"),
        preset: "erosion.patch_region = \"paper\"",
        effect: "Vortex and dam break, frames 0–23, atlas 512: no report cell moved by more \
                 than 0.015 (vortex worst popping 0.144 → 0.159). A nearby but separate sheet or \
                 droplet is not copied into the patch.",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-23 --methods erosion --out cmp`, \
                  without and with `--config P`, P: `erosion.patch_region = \"paper\"`",
    },
    Departure {
        method: "erosion, blend-deformable",
        paper: "2021 Sec. 5.2, Eq. 2",
        what: "Which vertices hold B_V = 1.",
        ours: "Interior vertices, those within r/4 of p and also the three corners of p's \
               triangle, in every weights mode (`--weights paper` included).",
        paper_setting: "Interior vertices and those within r/4 of p only \
                        (`seed_corners = paper`).",
        key: Some("erosion.seed_corners"),
        flag: Some("--seed-corners paper"),
        preset: "erosion.seed_corners = \"paper\"",
        effect: "Vortex and dam break, frames 0–23, atlas 512: every cell within 0.002 (dam \
                 break: 881 patches alive against 867). B_V can no longer erode the texel that \
                 created the patch, the case the paper's r/4 rule is there to prevent.",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-23 --methods erosion --out cmp`, \
                  without and with `--config P`, P: `erosion.seed_corners = \"paper\"`",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.1",
        what: "A new patch that erodes the texel it was created for.",
        ours: "The texel is assigned to that patch anyway (uv 0.5, 0.5) and counted as forced.",
        paper_setting: "The texel stays uncovered and asks for another patch (Eq. 2 is meant to \
                        prevent the case): `seed_texel = paper`. Our patches are made \
                        deterministically from the point, so another patch there would be the \
                        same one; the texel stays uncovered until the next frame.",
        key: Some("erosion.seed_texel"),
        flag: Some("--seed-texel paper"),
        preset: "erosion.seed_texel = \"paper\"",
        effect: "With the default weights no patch erodes its seed texel on our scenes, so \
                 `seed_texel = paper` changes nothing there; under the paper's weights, \
                 pinned-corner rule and a small δ_max it does (the unit test \
                 `the_papers_seed_texel_stays_uncovered_where_ours_is_forced`). Every new \
                 patch covers at least one texel, so the update loop ends.",
        measure: "`forced_texels` in each frame's `stats.F.json` of `fluidtex run` counts the \
                  texels concerned.",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 4",
        what: "Dropping patch triangles that can never show again.",
        ours: "Each frame, triangles the erosion test erodes whole for good are removed (with \
               `--weights paper` only once also past δ_max); a vertex left on the new rim keeps \
               B_V = 1.",
        paper_setting: "A patch keeps every triangle but those of vertices far from the surface \
                        (`eroded_triangles = \"kept\"`: edges past δ_max are split again, and \
                        hidden parts kept too).",
        key: Some("erosion.eroded_triangles"),
        flag: Some("--eroded-triangles kept"),
        preset: "erosion.eroded_triangles = \"kept\"",
        effect: "Mantaflow splash at `--radius 0.4`, frames 1–16, atlas 1024 (with edges past \
                 δ_max no longer split): 560 s and 22.9 GB kept, 13.5 s and 194 MB dropped. On \
                 `differential-rotation` (radius 0.6, 96 frames) the patch triangles level off \
                 by frame 48 when dropped and keep growing when kept. Not only a cost: on \
                 `vortex` (10 frames, atlas 96, hidden parts kept in both) the pictures are \
                 the same until frame 8, where an edge past δ_max is split in one run and not \
                 in the other and 38 % of the colour values differ.",
        measure: "`fluidtex run --mesh 'splash/mesh/fluid.####.ply' --frames 1-16 --radius 0.4 \
                  --atlas 1024 --out o` on `tools/mantaflow_splash.py`'s bake, without and with \
                  `--eroded-triangles kept`; `patch_triangles` and `triangles_pruned` in \
                  `stats.F.json`; `cargo test -p fluidtex --lib \
                  patch_cost_follows_the_surface_not_the_history` and \
                  `kept_eroded_triangles_are_the_papers_bookkeeping`",
    },
    Departure {
        method: "erosion",
        paper: "2021 Sec. 5.1",
        what: "Dropping the parts of a patch hidden under older patches.",
        ours: "`hidden_reach = 0.1`: after each frame's fill and update, a patch keeps only the \
               triangles within about 0.1 r (in its rest space) of a texel it showed; the rest \
               lie under older patches and go, with their vertices on the new rim keeping \
               B_V = 1. Where an older patch erodes there later, the update makes a fresh patch \
               instead of showing one that was stretched all the while.",
        paper_setting: "A patch keeps every triangle until it shows nothing \
                        (`hidden_reach = 0`).",
        key: Some("erosion.hidden_reach"),
        flag: Some("--hidden-reach 0"),
        preset: "erosion.hidden_reach = 0.0",
        effect: "Mantaflow splash, frames 2–48, atlas 1024, default radius: patch triangles per \
                 surface triangle 6.7 → 3.3, candidate pairs per fluid triangle 43 → 23, fill \
                 0.54 → 0.33 s per frame, switch share 46.5 % → 44.4 %, unforced 19.8 % → \
                 18.6 %, colour follow ratio 0.435 → 0.418 (means), patches made per frame \
                 434 → 589.",
        measure: "`fluidtex run --mesh 'splash/mesh/fluid.####.ply' --atlas 1024 --out o`, with \
                  and without `--hidden-reach 0`, on `tools/mantaflow_splash.py`'s bake; \
                  `patch_triangles`, `candidate_pairs`, `source_switch_share` in \
                  `stats.F.json`",
    },
    // ---- 2016: dynamic lapped textures --------------------------------
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.3",
        what: "Where new trackers go.",
        ours: "One at a time, at the first uncovered texel in texel order (the 2021 rule); its \
               patch is composited before the next seed is picked.",
        paper_setting: "A random distribution of trackers over the uncovered areas \
                        (`placement = random`: each next seed a uniformly random uncovered \
                        texel, from a generator seeded per frame).",
        key: Some("lapped_rigid.placement"),
        flag: Some("--rigid-placement random"),
        preset: "lapped_rigid.placement = \"random\"",
        effect: "Vortex and dam break, frames 0–23, atlas 512: slightly fewer patches (dam break \
                 1436 against 1535 alive), ghost fraction 0.407 → 0.394 and vortex switch share \
                 0.131 → 0.123 (medians); every other cell within 0.004. Random seeds are drawn \
                 per frame, so a fluid at rest still gives identical frames.",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-23 --methods \
                  lapped-rigid --out cmp`, without and with `--config P`, P: \
                  `lapped_rigid.placement = \"random\"`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.1–3.1.3",
        what: "Deleting a tracker that left the surface.",
        ours: "`far_fraction = 0.25`: a tracker farther than r/4 from the next surface after \
               advection is deleted (the 2021 rule for patch vertices).",
        paper_setting: "No rule for it: the tracker is projected onto the closest surface \
                        point, and a patch goes only once unused (`far_fraction = 0`).",
        key: Some("lapped_rigid.far_fraction"),
        flag: Some("--rigid-far-fraction 0"),
        preset: "lapped_rigid.far_fraction = 0.0",
        effect: "Vortex: no cell changed; dam break, frames 0–23, atlas 512: 1601 patches alive \
                 against 1535, switch share 0.215 → 0.219 (medians), every other cell within \
                 0.003. Trackers over droplets that leave the surface are carried to whatever \
                 surface is closest.",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-23 --methods \
                  lapped-rigid --out cmp`, without and with `--config P`, P: \
                  `lapped_rigid.far_fraction = 0.0`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.3",
        what: "When a texel counts as uncovered.",
        ours: "`coverage = 0.99`: composite α below 0.99 seeds a new tracker.",
        paper_setting: "A texel that no opaque patch covers (`coverage = 1`).",
        key: Some("lapped_rigid.coverage"),
        flag: Some("--rigid-coverage 1"),
        preset: "lapped_rigid.coverage = 1.0",
        effect: "Not measured. At 1 soft masks would have to reach exact opacity.",
        measure: "`fluidtex compare --scenes vortex --methods lapped-rigid --out cmp`, without \
                  and with `--config P`, P: `lapped_rigid.coverage = 1.0`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.3, Alg. 1",
        what: "Faint contributions and unused patches.",
        ours: "`keep_weight = 0.003921569` (1/255): smaller contributions are dropped, and a \
               patch left with none is deleted as unused.",
        paper_setting: "Every contribution counts; a patch is deleted when it is not used at all \
                        (`keep_weight = 0`).",
        key: Some("lapped_rigid.keep_weight"),
        flag: Some("--rigid-keep-weight 0"),
        preset: "lapped_rigid.keep_weight = 0.0",
        effect: "Not measured. Invisible in 8 bits, and deleting an unused patch then changes \
                 no texel.",
        measure: "`fluidtex compare --scenes vortex --methods lapped-rigid --out cmp`, without \
                  and with `--config P`, P: `lapped_rigid.keep_weight = 0.0`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3, Alg. 1",
        what: "The patch mask.",
        ours: "Without a `mask` image, one derived from the feature map: a radial profile moved \
               by the features (`mask_feature_weight` 0.05), with a soft border, so borders \
               follow the exemplar's features.",
        paper_setting: "A mask the user supplies (`mask = IMG`). Without one, `--preset paper` \
                        takes the plain radial mask (`mask_feature_weight = 0`): the paper's \
                        masks are images, painted by hand, not moved by a feature map, so a \
                        radial profile is the closer stand-in.",
        key: Some("lapped_rigid.mask"),
        flag: Some("--mask IMG"),
        preset: "lapped_rigid.mask_feature_weight = 0.0",
        effect: "Against a user's mask: not measured. How far the features move the derived \
                 border (`mask_feature_weight` 0.2, 0.1, 0.05, 0; medians at atlas 512): the \
                 share of points whose top patch changes per frame, frames 20-31, is 7.1, 5.1, \
                 4.3, 4.2 % on `viscous-drop` (advect 3.1 %) and 5.7, 3.7, 3.1, 2.9 % on \
                 `rigid-rotation` (advect 2.7 %); popping, frames 0-23, is 0.243, 0.261, 0.270, \
                 0.284 on `vortex` and 0.059, 0.068, 0.069, 0.074 on `dam-break`. The default \
                 0.05 is the largest of these within advect + 2 points on every slow frame.",
        measure: "`fluidtex compare --scenes vortex --methods lapped-rigid --out cmp`, without \
                  and with `--config P`, P: `lapped_rigid.mask = \"IMG\"`; the weight by \
                  `fluidtex compare --scenes viscous-drop,rigid-rotation --methods \
                  lapped-rigid,advect --frames 20-31 --out cmp` with P: \
                  `lapped_rigid.mask_feature_weight = W`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.3",
        what: "When a patch is a sink.",
        ours: "`sink_speed = 0.25`: all four frame corners move towards the centre faster than \
               r/4 per second.",
        paper_setting: "All four corner velocities point towards the centre \
                        (`sink_speed = 0`).",
        key: Some("lapped_rigid.sink_speed"),
        flag: Some("--rigid-sink-speed 0"),
        preset: "lapped_rigid.sink_speed = 0.0",
        effect: "Not measured.",
        measure: "`fluidtex compare --scenes vortex --methods lapped-rigid --out cmp`, without \
                  and with `--config P`, P: `lapped_rigid.sink_speed = 0.0`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.2.1",
        what: "Where the alpha falloff is evaluated.",
        ours: "Per texel, from the angle of the interpolated vertex normal, so a patch is opaque \
               at its own tracker.",
        paper_setting: "Per receiver vertex, the alphas interpolated linearly (`falloff_at = \
                        vertex`).",
        key: Some("lapped_rigid.falloff_at"),
        flag: Some("--rigid-falloff-at vertex"),
        preset: "lapped_rigid.falloff_at = \"vertex\"",
        effect: "More blending: frames 0–23 at atlas 512 (medians), ghost fraction 0.407 → \
                 0.461 on `dam-break` and 0.481 → 0.602 on `vortex`, contrast 0.885 → 0.867 \
                 and 0.875 → 0.842, distortion p95 1.359 → 1.434 and 1.448 → 1.491; popping \
                 0.059 → 0.062 and 0.243 → 0.233. Per-vertex alphas fall off across a whole \
                 triangle wherever one corner turns past ψ, so more texels are partly \
                 transparent. (Before the seed texel was forced, such patches also missed \
                 their seed texel on meshes coarse for ψ and came back every frame.)",
        measure: "`fluidtex compare --scenes vortex --methods lapped-rigid --out cmp`, without \
                  and with `--config P`, P: `lapped_rigid.falloff_at = \"vertex\"`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.3, Alg. 1",
        what: "The compositing formula.",
        ours: "The over operator, oldest patch on top, with α = falloff × mask × fade both for \
               the patch's colour and for what it hides.",
        paper_setting: "Algorithm 1 as printed scales what lies beneath by 1 − falloff only \
                        and adds falloff × mask × colour (`composite = paper`). `--preset \
                        paper` keeps ours: as printed, the clear part of a patch's mask inside \
                        its receivers shows black, which none of the paper's figures do, so we \
                        read the line as alpha blending with α = falloff × mask.",
        key: Some("lapped_rigid.composite"),
        flag: Some("--rigid-composite paper"),
        preset: "",
        effect: "Frames 0–23 at atlas 512 (medians, ours → as printed): every patch gets a black \
                 rim where its mask fades out; uncovered share 0 → 0.135 on `vortex` and 0 → \
                 0.232 on `dam-break` (black texels no patch shows), contrast 0.875 → 1.230 and \
                 0.885 → 1.384, popping 0.243 → 0.321 and 0.059 → 0.233, ghost fraction 0.481 \
                 → 0.210 and 0.407 → 0.125 (the rims hide what lies beneath).",
        measure: "`fluidtex compare --scenes vortex,dam-break --frames 0-23 --atlas 512 --methods \
                  lapped-rigid --out cmp`, without and with `--config P`, P: \
                  `lapped_rigid.composite = \"paper\"`; the formula by `cargo test -p fluidtex \
                  --lib as_printed_a_clear_mask_hides_what_lies_beneath`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.3",
        what: "A new patch that leaves its own seed texel short.",
        ours: "The texel is closed with what it has (the patch centre, opaque, if nothing showed) \
               and counted as forced.",
        paper_setting: "The insertion repeats until every texel is covered \
                        (`seed_texel = paper`: the texel is left to the trackers still to come; \
                        another tracker at the same point would be the same one, so it seeds \
                        none, and what stays short keeps what it has).",
        key: Some("lapped_rigid.seed_texel"),
        flag: Some("--rigid-seed-texel paper"),
        preset: "lapped_rigid.seed_texel = \"paper\"",
        effect: "At the default `coverage = 0.99` no seed is left short on vortex or dam break \
                 (identical reports). At `coverage = 1` rounding leaves seeds a hair short; both \
                 rules then give the same frames where every short texel has some α (the unit \
                 test `the_papers_seed_texel_is_left_to_later_trackers`).",
        measure: "`forced_texels` and `uncovered_texels` in each frame's `stats.F.json` of \
                  `fluidtex run --method lapped-rigid`",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.3, Alg. 1",
        what: "How a minified exemplar is read.",
        ours: "Every channel from the exemplar's mip pyramid at the texel's footprint (run \
               setting `exemplar_filter = trilinear`).",
        paper_setting: "The exemplar at full resolution (`exemplar_filter = none`).",
        key: None,
        flag: Some("--exemplar-filter none"),
        preset: "exemplar_filter = \"none\"",
        effect: "Not measured.",
        measure: "`fluidtex compare --scenes vortex --methods lapped-rigid --out cmp`, without \
                  and with `--config P`, P: `exemplar_filter = \"none\"`",
    },
    // ---- 2007: surface texture optimisation ---------------------------
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B, Eqs. 1–2",
        what: "What the point values become after each averaging step.",
        ours: "`histogram = matched`: each channel is remapped rank by rank onto the exemplar's \
               values.",
        paper_setting: "The weighted average as it is (`histogram = paper`).",
        key: Some("optimization.histogram"),
        flag: Some("--histogram paper"),
        preset: "optimization.histogram = \"paper\"",
        effect: "`vortex`: contrast kept 0.64 → 1.01 of the exemplar's, SWD fidelity ratio \
                 3.8 → 1.5 (paper → ours), same flow and popping cells.",
        measure: "`fluidtex compare --scenes vortex --atlas 512 --methods optimization --out \
                  cmp`, without and with `--config P`, P: \
                  `optimization.histogram = \"paper\"`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B",
        what: "Passes on frames that start from the transported texture.",
        ours: "`passes_after_first = 2`: the 17² and 9² passes only.",
        paper_setting: "Every pass, 33², 17², 9² (`passes_after_first = 3`).",
        key: Some("optimization.passes_after_first"),
        flag: Some("--passes-after-first 3"),
        preset: "optimization.passes_after_first = 3",
        effect: "A carried `dam-break` frame takes 7–8 s instead of 11 s; the `vortex` report \
                 cells stay as they were.",
        measure: "`fluidtex scene dam-break --out dam`, then `fluidtex run --mesh \
                  'dam/fluid.####.ply' --method optimization --out o`, without and with \
                  `--passes-after-first 3` (seconds in `stats.F.json`)",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B",
        what: "When a pass stops.",
        ours: "`iterations = 3`: at most 3 search + average rounds, fewer when no match changes.",
        paper_setting: "Until convergence (`iterations = 100`; a pass stops when at most one \
                        centre in a thousand changed match, `convergence = 0.001`: the \
                        approximate search keeps a few near-tied matches trading places, \
                        which left 1–4 of 7 744 centres changing after 100 iterations on a \
                        `dam-break` frame).",
        key: Some("optimization.iterations"),
        flag: Some("--iterations 100 --convergence 0.001"),
        preset: "optimization.iterations = 100\noptimization.convergence = 0.001",
        effect: "With the matched histogram 3 keep every `vortex` report cell of 5 (contrast \
                 1.01, SWD ratio 1.50 against 1.52).",
        measure: "`fluidtex compare --scenes vortex --atlas 512 --methods optimization --out \
                  cmp`, without and with `--config P`, P: `optimization.iterations = 5`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B, Eq. 1",
        what: "The norm of the texture energy.",
        ours: "`robust = 0.8`: each neighbourhood's term is weighted by its error to the power \
               (0.8 − 2)/2, the robust optimisation of Kwatra et al. 2005.",
        paper_setting: "Sum of squared differences (`robust = 2`).",
        key: Some("optimization.robust"),
        flag: Some("--robust 2"),
        preset: "optimization.robust = 2.0",
        effect: "Not measured. Least squares averages mismatched neighbourhoods into blur.",
        measure: "`fluidtex compare --scenes vortex --atlas 512 --methods optimization --out \
                  cmp`, without and with `--config P`, P: `optimization.robust = 2.0`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B, Sec. VII",
        what: "The nearest-neighbour search in the exemplar.",
        ours: "`search_grid = 9`: PCA to 8 dimensions and a k-d tree over a 9 × 9 subsample of \
               each w × w neighbourhood, colour channels only, `rerank` candidates re-ranked by \
               full distance.",
        paper_setting: "The full w × w neighbourhood, accelerated by a hierarchical clustering \
                        of the exemplar's neighbourhoods (`search = \"clustered\"`: a k-means \
                        tree, 8 children a node, at most 16 candidates a leaf, a query \
                        comparing `checks` candidates nearest branch first). `search = \
                        \"exact\"` compares the full neighbourhood with every candidate, the \
                        optimum the clustering approximates.",
        key: Some("optimization.search"),
        flag: Some("--search clustered"),
        preset: "optimization.search = \"clustered\"",
        effect: "`fluidtex bench --exemplar-search` (pebbles, RGB, 128² working exemplar, 400 \
                 synthesis-like queries a window, 2 cores): the clustered search finds the exact \
                 optimum for 0.97 / 0.92 / 0.98 of the queries at 33² / 17² / 9² (mean SSD \
                 1.04 / 1.04 / 1.01 × the optimum's) in 0.12 / 0.07 / 0.05 ms a query, against \
                 23 / 5.8 / 1.6 ms for the exact scan; ours (PCA) 0.71 / 0.71 / 0.86 in 0.01–0.02 \
                 ms. The trees take 2.6 + 1.0 + 0.4 s to build at the finest level, once a run, \
                 the same for a 256² and a 2048² exemplar. With the preset on `dam-break` at \
                 100k points (frames 20–23, 256² gravel, atlas 512): the first, three-level \
                 frame 33 s, carried frames 13–14 s; the exact scan's first frame had not \
                 finished in 14 minutes.",
        measure: "`fluidtex bench --exemplar-search`; `cargo test -p fluidtex --lib cluster` \
                  and `exact_search_finds_the_full_window_optimum`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-A.2",
        what: "Laying out a vertex neighbourhood.",
        ours: "Ring by ring, each vertex at the average of the positions its placed neighbours \
               predict; no relaxation afterwards.",
        paper_setting: "The same average followed by a relaxation step (`relaxation = 4`: \
                        Gauss–Seidel sweeps, each point to the mean of what all its placed \
                        neighbours predict; the paper gives no count).",
        key: Some("optimization.relaxation"),
        flag: Some("--relaxation 4"),
        preset: "optimization.relaxation = 4",
        effect: "Vortex, frames 0–5, atlas 512 (medians): SWD ratio 1.353 → 1.395, contrast 1.009 → \
                 1.011, flow EPE 0.152 → 0.142 px, popping and colour follow unchanged; the run \
                 took 67 s instead of 48 s. On a sphere the layout misfit falls with every \
                 sweep; on a plane the first layout is already exact.",
        measure: "`fluidtex compare --scenes vortex --methods optimization --out cmp`, without \
                  and with `--config P`, P: `optimization.relaxation = 4`; the layout misfit \
                  by `cargo test -p fluidtex --lib relaxation_lowers_the_layout_misfit`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B",
        what: "Up-sampling from a coarser level.",
        ours: "Shared points keep their values, new points take the linear interpolation of the \
               coarser cell; no diffusion.",
        paper_setting: "Copy from the coarser level, then diffusion at the finer level \
                        (`upsample_diffusion = 2`: 1-ring averaging sweeps after the copy; the \
                        paper gives no count; the copy stays our interpolation).",
        key: Some("optimization.upsample_diffusion"),
        flag: Some("--upsample-diffusion 2"),
        preset: "optimization.upsample_diffusion = 2",
        effect: "Vortex, frames 0–5, atlas 512 (medians): SWD ratio 1.353 → 1.347, contrast 1.009 → \
                 1.008, every other cell unchanged: the finer level's passes undo what the \
                 diffusion smooths.",
        measure: "`fluidtex compare --scenes vortex --frames 0-5 --methods optimization --out \
                  cmp`, without and with `--config P`, P: `optimization.upsample_diffusion = 2`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. IV-A",
        what: "Placing the points and their hierarchy.",
        ours: "A regular barycentric lattice subdividing every fluid triangle, nested across \
               levels; its steps are chosen per frame to keep the first frame's spacing.",
        paper_setting: "Random points drawn by area and spread by surface-restricted repulsion \
                        (Turk 1991), level by level from the coarsest, each finer level keeping \
                        the coarser points and adding its own (Turk 2001), then connected into a \
                        mesh (`placement = \"repulsion\"`; 20 repulsion rounds, radius 1.86 \
                        spacings: the paper gives neither).",
        key: Some("optimization.placement"),
        flag: Some("--point-placement repulsion"),
        preset: "optimization.placement = \"repulsion\"",
        effect: "Vortex, frames 0–5, atlas 512 (medians, ours → paper): SWD ratio 1.421 → 1.413, \
                 flow EPE 0.153 → 0.155 px, popping 1.69e-3 → 8.3e-4, colour follow 0.044 → \
                 0.045, contrast 1.007 → 1.006; 7.2 → 21.5 s per frame (placing and re-tiling \
                 200k points on three levels takes about 7 s). Another draw of the points moved \
                 the SWD ratio by 0.04, so only the popping changes beyond the draw. On a plane, repulsion takes the spread \
                 of nearest-neighbour distances from 0.51 (random points) to 0.06 of their mean; \
                 the lattice's spacing follows the fluid triangles' shapes, within about a \
                 factor of two of the target.",
        measure: "`fluidtex compare --scenes vortex --frames 0-5 --methods optimization --out \
                  cmp`, without and with `--config P`, P: `optimization.placement = \
                  \"repulsion\"`; the spacing by `cargo test -p fluidtex --lib \
                  repulsion_evens_the_spacing`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. IV-A",
        what: "Connecting scattered points into a mesh (`placement = \"repulsion\"` only).",
        ours: "The dual of the points' Voronoi partition restricted to the surface, read off \
               samples at about a third of the spacing (the same steps on every fluid edge): a \
               sample triangle whose corners are nearest to three different points (facing the \
               same way) gives the mesh a triangle in the fluid's orientation.",
        paper_setting: "Turk 1992's re-tiling (mutual tessellation, then the old vertices \
                        removed), triangulated with the Triangle library. No paper setting.",
        key: None,
        flag: None,
        preset: "",
        effect: "Both connect points that are neighbours along the surface. On a sphere (2,265 \
                 points, three seeds, and its coarser level) the mesh is closed and oriented, \
                 every edge between two triangles (χ = 2); the two sides of a sheet thinner \
                 than the spacing stay apart.",
        measure: "`cargo test -p fluidtex --lib retiling_a_sphere_gives_a_closed_oriented_mesh` \
                  and `the_two_sides_of_a_thin_sheet_stay_apart`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. IV-B",
        what: "Smoothing the orientation field.",
        ours: "Each neighbour's vector projected into the point's tangent plane and averaged; \
               on a fresh surface the field starts from world X projected on the tangent plane.",
        paper_setting: "Diffusion of polar-map angles (Zhang et al.): around each vertex the \
                        corner angles are rescaled by 2π/Θ, Θ the vertex's total corner angle, \
                        and a neighbour's angle is carried along the common edge; from polar \
                        angle 0 everywhere, measured from a reference vector the paper leaves \
                        open (ours: world X projected, the default's start) \
                        (`orientation_smoothing = polar`).",
        key: Some("optimization.orientation_smoothing"),
        flag: Some("--orientation-smoothing polar"),
        preset: "optimization.orientation_smoothing = \"polar\"",
        effect: "Vortex, frames 0–5, atlas 512 (medians, ours → paper): SWD ratio 1.421 → 1.484, \
                 flow EPE 0.153 → 0.147 px, popping 1.69e-3 → 1.14e-3, colour follow 0.044 → \
                 0.046, contrast 1.007 both. On a sphere the rescaled angle defects add up to \
                 4π and the field smooths as with projection; on a plane both give the same \
                 field. With polar angle 0 at each vertex's first fan edge (unrelated from one \
                 vertex to the next) instead of a shared reference, the field stayed rough after 10 \
                 iterations and the SWD ratio rose to 2.04.",
        measure: "`fluidtex compare --scenes vortex --frames 0-5 --methods optimization --out \
                  cmp`, without and with `--config P`, P: `optimization.orientation_smoothing = \
                  \"polar\"`; the polar maps by `cargo test -p fluidtex --lib polar`",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. VI-A, Eq. 3",
        what: "Transporting the colour.",
        ours: "Each new point back-tracked by RK4 through the mesh's vertex velocities, then the \
               previous values read at the closest point of the previous surface.",
        paper_setting: "The coordinate field advected on the simulation grid by a first-order \
                        upwind scheme. No paper setting yet.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "None yet: needs a switch.",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. VI-B, Eq. 4",
        what: "Transporting the orientation.",
        ours: "The head and tail of a short vector (a quarter of the point spacing) advected \
               through the flow, then normalised and projected on the new tangent plane.",
        paper_setting: "Eq. 4 solved by upwind differencing on the grid, after extending the \
                        field off the surface. No paper setting yet.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "None yet: needs a switch.",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. III, Sec. VI-A",
        what: "The velocity the transport reads.",
        ours: "Per-vertex mesh velocities of the two frames, blended linearly in time; \
               fluidtex reads no simulation grid.",
        paper_setting: "The simulation's grid velocities at every intermediate time step. No \
                        paper setting yet.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "None yet: needs grid input.",
    },
];

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
         <!-- Generated from crates/fluidtex/src/departures.rs by \
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
         entered here. The README explains the larger departures at length.\n",
    );
    for (year, heading) in FAMILIES {
        out.push_str(&format!("\n## {heading}\n\n"));
        out.push_str(
            "| method | paper | what | ours (default) | the paper's | key | flag | measured \
             effect | measured by |\n",
        );
        out.push_str("|---|---|---|---|---|---|---|---|---|\n");
        for d in DEPARTURES.iter().filter(|d| d.paper.starts_with(year)) {
            out.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                cell(d.method),
                cell(d.paper),
                cell(d.what),
                cell(d.ours),
                cell(d.paper_setting),
                code_or_dash(d.key),
                code_or_dash(d.flag),
                cell(d.effect),
                cell(d.measure),
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
