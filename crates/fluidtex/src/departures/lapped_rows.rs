//! The ledger's rows for Gagnon, Dagenais, Paquette 2016 (dynamic lapped
//! textures, `lapped-rigid`), part of [`super::DEPARTURES`].

use super::Departure;

/// The rows of this paper, in ledger order.
pub(super) const ROWS: &[Departure] = &[
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "departures::switch_tests::every_switch_changes_its_tiny_scene",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.3",
        what: "Adding new trackers: one at a time or as a batch.",
        ours: "One at a time under either placement: each new tracker's patch is composited \
               under the uncovered texels before the next seed is drawn, so no seed falls \
               where an earlier new patch of the frame is already opaque (with a hard mask \
               the new trackers of a frame lie at least r/2 apart).",
        paper_setting: "A random distribution of new trackers over the uncovered areas, then \
                        the atlas filled again. No switch: a batch needs a rule for how many \
                        trackers and how far apart, which the paper does not give; \
                        `placement = random` draws each seed at random, one at a time.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured. One at a time creates no tracker that a sibling of the same \
                 frame hides at once.",
        measure: "`patches_created` in each frame's `stats.F.json`; `cargo test -p fluidtex \
                  --lib new_trackers_are_placed_and_composited_one_at_a_time`",
        pinned_by: "methods::lapped_rigid::behaviour_tests::new_trackers_are_placed_and_composited_one_at_a_time",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.2–3.1.3",
        what: "Where the tangent tracker and the sink test's corners sit.",
        ours: "The tangent tracker T at r/2 from P along the tangent, re-placed there every \
               frame; the sink test samples the flow at the frame's corners P + (r/2)(±t ± b), \
               r/√2 from P.",
        paper_setting: "The paper gives neither distance: T anywhere along the tangent, the \
                        velocities at the patch's four corners, wherever they are. No switch: \
                        constants of the method.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "`cargo test -p fluidtex --lib \
                  the_tangent_tracker_is_at_half_r_and_the_sink_corners_at_r_over_sqrt2`",
        pinned_by: "methods::lapped_rigid::behaviour_tests::the_tangent_tracker_is_at_half_r_and_the_sink_corners_at_r_over_sqrt2",
    },
    Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.1.3",
        what: "A tracker once found to be a sink.",
        ours: "Stays marked for the rest of its life: it fades while the flow converges on it, \
               and its fade holds (never rises) when the flow diverges or stops.",
        paper_setting: "The paper says sinks are deleted by blending their masks, not whether a \
                        patch whose flow stops converging recovers. No switch: recovering \
                        would make a patch fade in and out on a flow that hesitates.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "`cargo test -p fluidtex --lib \
                  a_sink_stays_marked_when_the_flow_stops_converging`",
        pinned_by: "methods::lapped_rigid::behaviour_tests::a_sink_stays_marked_when_the_flow_stops_converging",
    },
];
