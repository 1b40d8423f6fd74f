//! The second table of the ledger ([`super`]): every method parameter that
//! is not a departure, with why its default is what it is. Kept apart from
//! [`super::DEPARTURES`] so each file stays readable.

/// Every method parameter that is not a departure: (config key, why its
/// default is what it is).
pub const AS_PUBLISHED: &[(&str, &str)] = &[
    // erosion (2021)
    (
        "erosion.radius",
        "The paper leaves r to the user; unset, r comes from `radius_fraction` and \
         `radius_edges`.",
    ),
    (
        "erosion.radius_fraction",
        "The paper leaves r to the user: 1/25 of the first frame's bounding-box diagonal, a \
         default that follows the scene's size.",
    ),
    (
        "erosion.radius_edges",
        "Not in the paper: r is at least 4 median edge lengths of the first frame, so a patch \
         spans enough triangles that re-meshing noise does not set its shape.",
    ),
    (
        "erosion.exemplar_size",
        "The paper leaves the exemplar's world size open; unset, `exemplar_scale` × r.",
    ),
    (
        "erosion.exemplar_scale",
        "The paper gives no value; 2.6 r is our choice: a patch is a disc 2 r across, which \
         any S above 2 r holds at any rotation, and 2.6 r leaves 0.3 r on each side (the \
         footprint reaches uv radius r/S ≈ 0.385 of the square's 0.5), so the patch's rim \
         never reads the exemplar across its edge.",
    ),
    (
        "erosion.delta_max",
        "The paper's value, δ_max = 3 (Sec. 5.2).",
    ),
    ("erosion.epsilon", "The paper's value, ε = 0.1 (Sec. 5.2)."),
    (
        "erosion.far_fraction",
        "The paper's value: vertices farther than r/4 from the surface are removed (Sec. 4).",
    ),
    (
        "erosion.centre_fraction",
        "The paper's value: B_V = 1 within r/4 of p (Eq. 2).",
    ),
    (
        "erosion.normal_dot",
        "Left open (the paper uses the Poisson distribution of Gagnon et al. 2019): disks whose \
         normals' dot product is below 0.9 do not block each other, so both faces of a thin \
         sheet get patches.",
    ),
    (
        "erosion.substeps",
        "The paper names no integrator: one RK4 step per frame, as the 2016 paper advects its \
         trackers.",
    ),
    (
        "erosion.random_rotation",
        "Left open: a seeded random angle per patch, which hides repetition in stochastic \
         exemplars.",
    ),
    (
        "erosion.placement",
        "The paper's rule, `local` (Sec. 5.1); `global` is the strategy its Sec. 7 leaves to \
         future work.",
    ),
    (
        "erosion.erosion_rate",
        "Not in the paper: the rate of the progressive weights (see `erosion.weights`), 4.8 per \
         second (0.2 per frame at 24 fps), set with `delta_onset` so a patch is gone by δ_max.",
    ),
    (
        "erosion.orientation",
        "Left open: `random`; `aligned` turns the exemplar's up towards `up_axis` for oriented \
         exemplars.",
    ),
    (
        "erosion.up_axis",
        "Only with `orientation = aligned`: world +Y.",
    ),
    (
        "erosion.transition",
        "The paper's at its default 0 (one source per texel); N > 0 is an opt-in cross-fade, \
         measured in the README (*Choosing a transition*).",
    ),
    // dual-rest and atlas-check: no paper
    (
        "dual_rest.period",
        "Not from a paper: the production baseline's reset period, 24 frames.",
    ),
    (
        "atlas_check.cell",
        "Not from a paper: the diagnostic checker's cell size; unset, from \
         `cells_per_diagonal`.",
    ),
    (
        "atlas_check.cells_per_diagonal",
        "Not from a paper: 24 checker cells along the first frame's bounding-box diagonal.",
    ),
    // optimization (2007)
    (
        "optimization.points",
        "Within the paper's 100k–500k (Sec. VII): 200000 asked for on the first frame, then the \
         spacing is kept so the count follows the area (Sec. IV-A). Never more than about one \
         point per atlas texel (see the behaviour row *Points per atlas texel*), so a small \
         atlas gets fewer: under 65,536 at `--atlas 256`.",
    ),
    (
        "optimization.exemplar_texels",
        "Left open: one point per exemplar texel (the points are the texture's resolution, \
         Sec. IV-A), so the exemplar spans 128 point spacings.",
    ),
    (
        "optimization.exemplar_size",
        "Left open: a world size for the exemplar instead of `exemplar_texels`.",
    ),
    (
        "optimization.levels",
        "The paper's: three levels on the first frame (Sec. VII, footnote 5).",
    ),
    (
        "optimization.levels_after_first",
        "The paper's for synthesis: one level synthesised on later frames (Sec. VII, footnote \
         5). Not for the points: every frame still builds all `levels` levels (see the \
         behaviour row *The hierarchy on frames after the first*).",
    ),
    (
        "optimization.sizes",
        "The paper's passes, 33², 17², 9² (Sec. V-B).",
    ),
    (
        "optimization.search_grid",
        "No paper counterpart: the subsample the PCA search compares (see \
         `optimization.search`); unused by the whole-window searches (`clustered`, `exact`).",
    ),
    (
        "optimization.rerank",
        "No paper counterpart: candidates of the search that stands in for the paper's (see \
         `optimization.search`); 16 costs twice the k-d tree time for the same `vortex` \
         report cells; unused by the whole-window searches.",
    ),
    (
        "optimization.checks",
        "No paper counterpart: how many candidates a query of the paper's clustered search \
         compares (the paper names the clustering, not its depth); 64 finds the exact optimum \
         for 0.97 of 33² queries (see `optimization.search`); unused by the other searches.",
    ),
    (
        "optimization.convergence",
        "Left open (the paper iterates until convergence): 0, a pass stops when no match \
         changed; the preset's 0.001 is set by the `optimization.iterations` entry.",
    ),
    (
        "optimization.centre_spacing",
        "Left open (the paper asks for significant overlap, Sec. V-B): centres every quarter \
         width, the overlap of Kwatra et al. 2005.",
    ),
    (
        "optimization.coherence",
        "Left open: λ_k of Eq. 2 is gradient-weighted as the paper suggests, coherence × \
         (neighbourhoods covering k) × min(g_k/ḡ, 3), with coherence = 1.",
    ),
    (
        "optimization.orientation_iterations",
        "Left open (several smoothing iterations, Sec. IV-B): 10 per level.",
    ),
    (
        "optimization.substeps",
        "No paper counterpart: RK4 steps per frame of the back-tracking that replaces the \
         paper's grid advection (see the colour-transport departure).",
    ),
    // lapped-rigid (2016)
    (
        "lapped_rigid.radius",
        "The paper leaves the patch size to the user; unset, as erosion's rule.",
    ),
    (
        "lapped_rigid.radius_fraction",
        "Left open: erosion's 1/25 of the diagonal, so both methods compare at one patch size.",
    ),
    (
        "lapped_rigid.radius_edges",
        "Not in the paper: erosion's rule, at least 4 median edge lengths.",
    ),
    (
        "lapped_rigid.exemplar_size",
        "Left open; unset, `exemplar_scale` × r.",
    ),
    (
        "lapped_rigid.exemplar_scale",
        "The paper sizes the exemplar from the patch size without a value: erosion's 2.6 r, so \
         both methods show the exemplar at one scale.",
    ),
    (
        "lapped_rigid.phi_max",
        "The paper's value, φ_max = 130° (Sec. 3.2.1).",
    ),
    (
        "lapped_rigid.alpha_opaque",
        "The paper gives no value: 30°, where the orthographic stretch 1/cos θ is at most 1.15.",
    ),
    (
        "lapped_rigid.alpha_transparent",
        "The paper gives no value: 60° (stretch 2), keeping ψ_{α=1} < ψ_{α=0} < φ_max.",
    ),
    (
        "lapped_rigid.substeps",
        "The paper's RK4 (Sec. 3.1.1), one step per frame (the paper gives no count).",
    ),
    (
        "lapped_rigid.normal_dot",
        "Left open (first-frame Poisson disks, Sec. 3.1.3): erosion's 0.9, so both faces of a \
         thin sheet get trackers.",
    ),
    (
        "lapped_rigid.random_rotation",
        "Left open: a seeded random tangent direction per new tracker.",
    ),
    (
        "lapped_rigid.mask_feature_weight",
        "No paper counterpart: how far the features move the derived mask's border (see \
         `lapped_rigid.mask`), 0.05; `--preset paper` sets 0, a plain radial mask.",
    ),
    (
        "lapped_rigid.mask_softness",
        "No paper counterpart: width of the derived mask's soft border (see \
         `lapped_rigid.mask`), 0.2.",
    ),
    (
        "lapped_rigid.sink_fade_rate",
        "Left open (a fade rate proportional to the inward speed, Sec. 3.1.3): 1 fades a sink \
         out in the time the flow takes to carry its corners to its centre.",
    ),
];
