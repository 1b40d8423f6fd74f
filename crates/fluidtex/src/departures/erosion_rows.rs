//! The ledger's rows for Gagnon et al. 2021 (patch erosion: `erosion` and
//! the baselines built on its patches), part of [`super::DEPARTURES`].

use super::Departure;

/// The rows of this paper, in ledger order.
pub(super) const ROWS: &[Departure] = &[
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
        pinned_by: "",
    },
    Departure {
        method: "erosion, blend-deformable",
        paper: "2021 Sec. 5.2, Eq. 1",
        what: "Where the triangle quality Q_T starts to fall.",
        ours: "`delta_onset = 1.5` with `erosion_rate = 4.8`: Q_T stays 1 up to δ = 1.5, then \
               falls linearly to 0 at δ_max; the faster rate still removes a patch before δ_max.",
        paper_setting: "Q_T falls from δ = 1 on (`delta_onset = 1`). The rate is no part of it: \
                        `erosion_rate` sets how fast progressive weights fall and does nothing \
                        under the paper's weights (`weights = paper`, which `--preset paper` \
                        also sets), so the preset leaves it; with progressive weights, 2.4 is \
                        the rate that gets a patch gone by δ_max from an onset of 1 (the flag).",
        key: Some("erosion.delta_onset"),
        flag: Some("--delta-onset 1 --erosion-rate 2.4"),
        preset: "erosion.delta_onset = 1.0",
        effect: "Paper → ours: switch share median (worst) on `vortex` 17.2 % (20.1) → 14.5 % \
                 (17.7), on `dam-break` 27.7 % (40.5) → 25.3 % (39.1); colour follow ratio \
                 0.223 → 0.206 (dam-break); distortion p95 3.47 → 2.71 (enright).",
        measure: "`fluidtex compare --scenes vortex --frames 0-47 --atlas 512 --methods erosion \
                  --out cmp` (and `--scenes dam-break --frames 0-30 --atlas 1024`, \
                  `--scenes enright`), without and with `--config P`, P: \
                  `erosion.delta_onset = 1.0` and `erosion.erosion_rate = 2.4`",
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "methods::erosion::tests::a_new_patch_keeps_its_centre_whole_however_curved_the_surface",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "methods::footprint::tests::unfiltered_exemplars_are_left_as_the_fill_wrote_them",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
    },
    Departure {
        method: "erosion, advect, blend-deformable, dual-rest",
        paper: "2021 Sec. 5.1",
        what: "How far a patch triangle reaches when the fill locates a texel in it.",
        ours: "A texel's surface point is located in a patch triangle down to barycentric −0.05 \
               and up to r/8 off the triangle's plane, so a triangle also covers a thin band \
               past its edges (closing the slivers between neighbouring chords of a curved \
               surface); of several, the one with the largest smallest barycentric holds it.",
        paper_setting: "The texel's point inside the patch triangle (the paper gives no \
                        tolerance). No switch: without a band the chords of a curved patch \
                        leave uncovered slivers between them, which new patches would fill.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "`cargo test -p fluidtex --lib \
                  a_patch_triangle_covers_to_barycentric_minus_0_05_and_r_over_8_off_its_plane`",
        pinned_by: "methods::erosion::behaviour_tests::a_patch_triangle_covers_to_barycentric_minus_0_05_and_r_over_8_off_its_plane",
    },
    Departure {
        method: "erosion, advect, blend-deformable, dual-rest, lapped-rigid",
        paper: "2021 Sec. 5.2, Sec. 7",
        what: "An exemplar given without a feature map.",
        ours: "A feature map is derived from the colour (run setting `feature_method`, \
               `auto` by default: a feature distance or the luminance, whichever separates \
               the exemplar better) and the run goes on.",
        paper_setting: "The feature map is an input the user provides with the exemplar; the \
                        paper names drawing or computing one as the user's task (Sec. 7). No \
                        switch: the paper has no behaviour without one; give it with \
                        `--feature IMG` to follow the paper.",
        key: None,
        flag: Some("--feature IMG"),
        preset: "",
        effect: "Not measured against hand-made maps; the derived maps are checked to be valid \
                 and to tile (`cargo test -p fluidtex --lib derived_maps_are_valid_and_tile`).",
        measure: "`cargo test -p fluidtex --lib \
                  without_a_feature_map_one_is_derived_and_a_given_one_is_used_as_given`",
        pinned_by: "exemplar::tests::without_a_feature_map_one_is_derived_and_a_given_one_is_used_as_given",
    },
];
