//! The ledger's rows for Kwatra et al. 2007 (surface texture optimisation,
//! `optimization`), part of [`super::DEPARTURES`].

use super::Departure;

/// The rows of this paper, in ledger order.
pub(super) const ROWS: &[Departure] = &[
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "",
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
        pinned_by: "methods::optimization::scatter::tests::retiling_a_sphere_gives_a_closed_oriented_mesh",
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
        pinned_by: "",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. VI-A, Eq. 3",
        what: "Transporting the colour.",
        ours: "`transport = trace`: each new point back-tracked by RK4 through the mesh's vertex \
               velocities, then the previous values read at the closest point of the previous \
               surface.",
        paper_setting: "The coordinate field advected by a first-order upwind scheme on a grid, \
                        then the previous values read at the closest point to the advected \
                        coordinates (`transport = grid`): fluidtex builds the grid itself, a \
                        narrow band at the finest point spacing around the new surface, up to \
                        12 cells each side, with the velocity of each frame's closest surface \
                        point blended in time (the paper used its simulation's grid, see the \
                        velocity row). Not in `--preset paper` yet: its cost at the papers' \
                        point counts is not measured, and the preset keeps the back-tracking \
                        until it is.",
        key: Some("optimization.transport"),
        flag: Some("--transport grid"),
        preset: "",
        effect: "Not measured on the scenes yet. Exact on a translation (a unit test); a \
                 characteristic longer than the band (12 point spacings a frame) keeps the band \
                 edge's coordinates, which the synthesis then pastes over.",
        measure: "`fluidtex compare --scenes vortex --frames 0-11 --methods optimization --out \
                  cmp`, without and with `--config P`, P: `optimization.transport = \"grid\"`; \
                  `cargo test -p fluidtex --lib grid_colour_transport`",
        pinned_by: "",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. VI-B, Eq. 4",
        what: "Transporting the orientation.",
        ours: "Only at the points of the coarsest of the `levels` levels (three by default, \
               4 h apart): the head and tail of a short vector, a quarter of that level's \
               spacing (h, the finest spacing, at three levels), advected through the flow, \
               then normalised and projected on the new tangent plane. The finer levels get \
               the carried field interpolated up and re-smoothed \
               (`orientation_iterations` steps a level), as on a first frame.",
        paper_setting: "Eq. 4 (vector advection) solved by upwind differencing on the grid, \
                        after extending the field off the surface, at every point. \
                        `transport = grid` (the colour row's switch) solves it on the narrow \
                        band at the finest point spacing, the field extended as the closest \
                        previous surface point's, the advection and stretching terms \
                        alternated each step; the result is then read at the coarsest level's \
                        points and re-smoothed up the hierarchy, as with ours.",
        key: None,
        flag: Some("--transport grid"),
        preset: "",
        effect: "Not measured on the scenes yet. Orientation detail finer than 4 h is not \
                 carried from frame to frame by ours; the grid carries it at h but the \
                 pipeline then reads it at the coarsest level.",
        measure: "The level and the vector by `cargo test -p fluidtex --lib \
                  the_orientation_is_carried_on_the_coarsest_level_only`, the rotation by \
                  `orientation_transport_rotates_with_a_rigid_rotation` and \
                  `grid_orientation_turns_with_a_rigid_rotation`",
        pinned_by: "methods::optimization::behaviour_tests::the_orientation_is_carried_on_the_coarsest_level_only",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. III, Sec. VI-A",
        what: "The velocity the transport reads.",
        ours: "Per-vertex mesh velocities of the two frames, blended linearly in time; \
               fluidtex reads no simulation grid.",
        paper_setting: "The simulation's grid velocities at every intermediate time step. No \
                        switch yet: fluidtex reads no velocity grid (the reader is planned).",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "None yet: needs grid input. The blend by `cargo test -p fluidtex --lib \
                  blends_towards_the_next_frame`",
        pinned_by: "surface::velocity::tests::blends_towards_the_next_frame",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. VII, footnote 5",
        what: "The hierarchy on frames after the first.",
        ours: "Every frame builds all `levels` levels of points (three by default; with \
               `placement = \"repulsion\"` each is scattered, spread and re-tiled), since the \
               orientation field is carried and smoothed over the whole hierarchy; only the \
               synthesis keeps to `levels_after_first` (one) on carried frames.",
        paper_setting: "One level constructed on every frame after the first. No switch: the \
                        orientation transport would then run on the finest points, which is \
                        the grid transport's job (no switch yet either).",
        key: None,
        flag: None,
        preset: "",
        effect: "Costs the coarser levels' construction every frame; with repulsion placement \
                 most of the 7 s that placing and re-tiling 200k points takes.",
        measure: "`cargo test -p fluidtex --lib the_whole_hierarchy_is_built_on_every_frame`",
        pinned_by: "methods::optimization::behaviour_tests::the_whole_hierarchy_is_built_on_every_frame",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-A",
        what: "Reading a pixel neighbourhood.",
        ours: "The vertex neighbourhood's flattened triangles are rasterised: each integer \
               offset of the centre's frame reads the barycentric interpolation of the \
               flattened triangle that holds it.",
        paper_setting: "Each offset found by marching along the surface from the centre. No \
                        switch: on a plane both give the same triangle; on a curved surface \
                        the flattening's error is what `relaxation` lowers.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "`cargo test -p fluidtex --lib \
                  pixel_cells_are_read_from_the_flattened_triangles`",
        pinned_by: "methods::optimization::behaviour_tests::pixel_cells_are_read_from_the_flattened_triangles",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-A",
        what: "Neighbourhood offsets no triangle covers (past the surface's edge or a hole).",
        ours: "They take the mean of the covered offsets (of the members' values where none \
               is covered), so they pull the search towards no particular exemplar texel.",
        paper_setting: "The paper does not say. No switch.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured.",
        measure: "`cargo test -p fluidtex --lib \
                  uncovered_offsets_take_the_mean_of_the_covered_ones`",
        pinned_by: "methods::optimization::behaviour_tests::uncovered_offsets_take_the_mean_of_the_covered_ones",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-A",
        what: "Points facing away from a neighbourhood's centre.",
        ours: "A point whose normal has a dot product below 0.2 with the centre's is left out \
               of the vertex neighbourhood (taken for the other side of a thin sheet).",
        paper_setting: "The paper does not say. No switch: a constant of the method \
                        (`neighbourhood::FACING_DOT`).",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured. Without it the two sides of a sheet thinner than a window mix \
                 in one neighbourhood.",
        measure: "`cargo test -p fluidtex --lib points_facing_away_below_dot_0_2_are_dropped`",
        pinned_by: "methods::optimization::behaviour_tests::points_facing_away_below_dot_0_2_are_dropped",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. V-B",
        what: "Exemplar windows at the edges and on small levels.",
        ours: "Every texel of the working exemplar is a candidate centre and windows wrap \
               across its edges (the exemplar repeats); a window wider than the working \
               exemplar shrinks to its width, odd: the 33² pass is 31² on the 32-texel \
               coarsest level of the default hierarchy.",
        paper_setting: "The paper does not say how windows meet the exemplar's edges or a \
                        coarse level smaller than the window. No switch.",
        key: None,
        flag: None,
        preset: "",
        effect: "Not measured. Wrapping suits tileable exemplars; a non-tileable one offers \
                 seams as candidates.",
        measure: "`cargo test -p fluidtex --lib \
                  windows_shrink_to_fit_and_candidates_wrap_at_the_edges`",
        pinned_by: "methods::optimization::behaviour_tests::windows_shrink_to_fit_and_candidates_wrap_at_the_edges",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. IV-A, Sec. VII",
        what: "Points per atlas texel.",
        ours: "The point spacing is never below one atlas texel: where `points` asks for more \
               points than the atlas has texels on the surface, the atlas sets the spacing \
               (`spacing_rule` in `stats.F.json` says which did). A 256² atlas holds 65,536 \
               texels, of which the charts cover a part, so `--atlas 256` gets well under the \
               default 200,000.",
        paper_setting: "The point count alone sets the resolution (100k–500k points); the \
                        paper renders the points, not an atlas. No switch: the atlas could not \
                        show the extra points.",
        key: None,
        flag: None,
        preset: "",
        effect: "Fewer points, and faster frames, at small atlases; no change at the default \
                 atlas on the built-in scenes where `spacing_rule` is `points`.",
        measure: "`spacing_rule` and `points` in `stats.F.json`; `cargo test -p fluidtex --lib \
                  the_spacing_is_never_below_one_atlas_texel`",
        pinned_by: "methods::optimization::behaviour_tests::the_spacing_is_never_below_one_atlas_texel",
    },
    Departure {
        method: "optimization",
        paper: "2007 Sec. VI",
        what: "A frame without motion.",
        ours: "Where the mesh is the previous frame's and every velocity of both frames is \
               exactly zero, the frame is not synthesised: the previous point values are \
               shown as they are (`still` in `stats.F.json`), bit for bit.",
        paper_setting: "Every frame transported and re-synthesised. No switch: the averaging \
                        and histogram steps are not idempotent, so a fluid at rest would \
                        shimmer.",
        key: None,
        flag: None,
        preset: "",
        effect: "A liquid at rest keeps a still texture.",
        measure: "`cargo test -p fluidtex --lib a_frame_without_motion_skips_synthesis`",
        pinned_by: "methods::optimization::behaviour_tests::a_frame_without_motion_skips_synthesis",
    },
];
