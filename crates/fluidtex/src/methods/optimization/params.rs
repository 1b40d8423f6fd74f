//! The parameters of `--method optimization` (config section
//! `[optimization]`): their declaration with defaults and docs, their
//! checks, and the choices they name (search, histogram).

use serde::{Deserialize, Serialize};

use super::orientation;
use crate::methods::{MethodError, check_range};

crate::methods::params::params! {
    /// Parameters of the optimisation method. Every field is a config key
    /// (`\[optimization]`) and a CLI flag.
    pub struct OptimizationParams {
        /// Target number of points at the finest level on the first frame
        /// \[200000]; the spacing it gives is then kept, so the count follows the
        /// area (Sec. IV-A). Never denser than the atlas texels (the atlas could
        /// not show more). The paper used 100k–500k.
        pub points: u32 = 200_000
            => "points" : "optimization: target points at the finest level on the first frame [200000]",
        /// Width of the exemplar in synthesis texels = points \[128]: one point
        /// per exemplar texel at the finest level (Sec. IV-A: the points are the
        /// texture's resolution), so the exemplar spans 128 point spacings on
        /// the surface. Ignored when `exemplar_size` is given.
        pub exemplar_texels: u32 = 128
            => "exemplar-texels" : "optimization: exemplar width in synthesis texels (point spacings) [128]",
        /// World size S covered by the exemplar's width; overrides
        /// `exemplar_texels` (then exemplar_texels = S / spacing).
        pub exemplar_size: Option<f32> = None
            => "exemplar-size" : "optimization: world size covered by the exemplar's width [exemplar_texels point spacings]",
        /// Levels of the hierarchy on the first frame \[3] (Sec. V-B).
        pub levels: u32 = 3
            => "levels" : "optimization: hierarchy levels on the first frame [3]",
        /// Levels synthesised on later frames \[1] (the paper's footnote 5, for
        /// the synthesis only: every frame still builds all `levels`, over
        /// which the orientation is transported and smoothed).
        pub levels_after_first: u32 = 1
            => "levels-after-first" : "optimization: hierarchy levels synthesised on later frames; all --levels are still built [1]",
        /// Neighbourhood widths of the passes at each level, in order
        /// \[33, 17, 9] (Sec. V-B). Odd, ≥ 3.
        pub sizes: Vec<u32> = vec![33, 17, 9]
            => "sizes" : "optimization: neighbourhood widths of the passes, odd [33,17,9]",
        /// Passes on frames that start from the transported texture: the last
        /// this many of `sizes` \[2], so 17² and 9² (every size when there are
        /// fewer). A departure from the paper, which runs every size: the
        /// transported texture already holds the large structure the widest
        /// pass would re-synthesise, and that pass costs as much as each of the
        /// others (dropping it takes a carried `dam-break` frame from 11 s to
        /// 7–8 s; the `vortex` report cells stay as they were). `sizes.len()`
        /// restores the paper's.
        pub passes_after_first: u32 = 2
            => "passes-after-first" : "optimization: passes on carried frames, the last N of --sizes [2]",
        /// How the exemplar is searched \[pca]: `pca` compares a g × g
        /// subsample (`search_grid`) reduced by PCA in a k-d tree;
        /// `clustered` the whole w × w neighbourhood in a hierarchical
        /// clustering of the exemplar's neighbourhoods (Sec. VII, the
        /// paper's; [`cluster`](super::cluster)); `exact` the whole
        /// neighbourhood against every candidate (what the clustering
        /// approximates; slow). See [`search`](super::search). Left out of
        /// the settings at `pca`.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub search: Search = Search::Pca
            => "search" : "optimization: exemplar search, a PCA k-d tree over a subsample (pca), a hierarchical clustering of whole neighbourhoods (clustered, the paper's) or every candidate over the whole window (exact; slow) [pca]",
        /// Candidates a `clustered` search compares by full SSD per query in
        /// the widest pass \[64], nearest branches of the clustering first;
        /// a pass of width w compares (widest / w)² times as many, so every
        /// pass compares about as many numbers per query (33², 17², 9²: 64,
        /// 241, 860). The candidate count makes it exact. No paper
        /// counterpart: the paper names the clustering, not how deep a
        /// query looks.
        #[serde(skip_serializing_if = "is_default_checks")]
        pub checks: u32 = 64
            => "checks" : "optimization: candidates a clustered search compares per query in the widest pass, (widest / w)^2 times as many in a pass of width w [64]",
        /// Search grid g: the pixel neighbourhood compared is a g × g
        /// subsample of the w × w one \[9] (odd, 3..=15). Unused by
        /// `search = "exact"`.
        pub search_grid: u32 = 9
            => "search-grid" : "optimization: the search compares a G x G subsample of each neighbourhood [9]",
        /// Candidates taken from the PCA k-d tree and re-ranked by full SSD \[8]
        /// (16 costs twice the k-d tree time for the same report cells on the
        /// `vortex` scene).
        pub rerank: u32 = 8
            => "rerank" : "optimization: k-d tree candidates re-ranked by full distance [8]",
        /// Most search + averaging iterations per pass \[3]; a pass also stops
        /// when no match changes. With the matched histogram 3 keep every
        /// report cell of 5 on the `vortex` scene (contrast 1.01, SWD ratio
        /// 1.50 against 1.52); the paper's plain average needs more (on a flat
        /// square with 3 levels, 3 iterations keep 0.70 of the exemplar's
        /// contrast, 5 keep 0.93).
        pub iterations: u32 = 3
            => "iterations" : "optimization: most search + averaging iterations per pass [3]",
        /// A pass has converged, and stops, when an iteration lowered the
        /// energy E (Eq. 1–2) by less than this share of it \[0: only when no
        /// match changed]. The paper iterates until convergence; an
        /// approximate search (`clustered`, `pca`) keeps a handful of
        /// near-tied matches trading places for ever, so the energy, not
        /// the matches, says when it has converged. Left out of the
        /// settings at 0.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub convergence: f32 = 0.0
            => "convergence" : "optimization: a pass also stops when an iteration lowers the energy by less than this share of it (0: only when no match changes) [0]",
        /// Spacing of the centres S† as a fraction of the window width \[0.25]
        /// (Kwatra et al. 2005's quarter-width overlap).
        pub centre_spacing: f32 = 0.25
            => "centre-spacing" : "optimization: spacing of neighbourhood centres, fraction of the width [0.25]",
        /// Weight of the transported texture, λ of Eq. 2 relative to the
        /// neighbourhoods covering a point, scaled by its gradient \[1].
        pub coherence: f32 = 1.0
            => "coherence" : "optimization: weight of the transported texture (lambda, Eq. 2) [1]",
        /// Robust exponent r of the texture energy \[0.8]: each neighbourhood's
        /// term of Eq. 1 is weighted by its current mean squared error to the
        /// power (r − 2)/2, as in the texture optimisation the paper builds on
        /// (Kwatra et al. 2005, Sec. 3, r = 0.8). 2 gives Eq. 1 unweighted,
        /// which averages mismatched neighbourhoods into blur.
        pub robust: f32 = 0.8
            => "robust" : "optimization: robust exponent of the texture energy (2: least squares) [0.8]",
        /// After every averaging step, remap the point values onto the working
        /// exemplar's histogram \[matched]; `paper` leaves them as averaged
        /// (Eq. 1–2 alone). A departure from the paper: see [`histogram`](super::histogram).
        pub histogram: Histogram = Histogram::Matched
            => "histogram" : "optimization: after each average, values take the exemplar's histogram (matched) or stay as averaged (paper) [matched]",
        /// Orientation smoothing iterations per level \[10] (Sec. IV-B).
        pub orientation_iterations: u32 = 10
            => "orientation-iterations" : "optimization: orientation smoothing iterations per level [10]",
        /// How the orientation field is smoothed \[projected]: neighbours'
        /// vectors projected and averaged; `polar` diffuses polar angles
        /// through each vertex's polar map from polar angle 0, as the paper
        /// does (Sec. IV-B). See [`orientation`]. Left out of the settings at
        /// `projected`.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub orientation_smoothing: orientation::Smoothing = orientation::Smoothing::Projected
            => "orientation-smoothing" : "optimization: orientation smoothing by projected vectors (projected) or by polar angles through each vertex's polar map (polar, the paper's) [projected]",
        /// How the points are placed \[lattice]: a subdivision lattice of the
        /// fluid triangles, nested across levels
        /// ([`lattice`](super::lattice)); `repulsion` draws random points and
        /// spreads them by repulsion, then re-tiles the surface with them, as
        /// the paper does (Sec. IV-A; [`scatter`](super::scatter); slower).
        /// Left out of the settings at `lattice`.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub placement: Placement = Placement::Lattice
            => "point-placement" : "optimization: points on a subdivision lattice of the fluid triangles (lattice) or random points spread by repulsion and re-tiled (repulsion, the paper's) [lattice]",
        /// How the texture is carried to the next frame \[trace]: `trace`
        /// back-tracks each point by RK4 through the mesh velocities and
        /// carries the orientation as a short vector; `grid` is the paper's
        /// (Sec. VI, Eqs. 3 and 4): the coordinate field and the extended
        /// orientation advected by first-order upwind steps on a narrow
        /// band of grid nodes at the point spacing
        /// ([`grid`](super::grid)). Left out of the settings at `trace`.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub transport: Transport = Transport::Trace
            => "transport" : "optimization: texture transport by back-tracking through the mesh velocities (trace) or the paper's upwind advection on a narrow-band grid (grid) [trace]",
        /// RK4 steps per frame for transport \[1].
        pub substeps: u32 = 1
            => "substeps" : "optimization: RK4 substeps per frame of transport [1]",
        /// Relaxation sweeps after a vertex neighbourhood is laid out ring by
        /// ring \[0: none] (Sec. V-A.2; the paper names no count, its preset
        /// uses 4). See [`neighbourhood`](super::neighbourhood). Left out of the settings at 0.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub relaxation: u32 = 0
            => "relaxation" : "optimization: relaxation sweeps of each vertex neighbourhood's layout (the paper relaxes) [0]",
        /// Diffusion sweeps (1-ring averages) of the values carried up to a
        /// finer level \[0: none] (Sec. V-B: the paper copies, then diffuses,
        /// with no count; its preset uses 2). Left out of the settings at 0.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub upsample_diffusion: u32 = 0
            => "upsample-diffusion" : "optimization: diffusion sweeps of the values carried up to a finer level (the paper diffuses) [0]",
    }
}

impl OptimizationParams {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), MethodError> {
        check_range("points", self.points as f32, 100.0, 5e7, "100..=50000000")?;
        check_range(
            "exemplar_texels",
            self.exemplar_texels as f32,
            8.0,
            4096.0,
            "8..=4096",
        )?;
        if let Some(s) = self.exemplar_size {
            check_range("exemplar_size", s, f32::MIN_POSITIVE, f32::MAX, "> 0")?;
        }
        check_range("levels", self.levels as f32, 1.0, 6.0, "1..=6")?;
        check_range(
            "levels_after_first",
            self.levels_after_first as f32,
            1.0,
            6.0,
            "1..=6",
        )?;
        if self.sizes.is_empty()
            || self
                .sizes
                .iter()
                .any(|&w| !(3..=129).contains(&w) || w.is_multiple_of(2))
        {
            return Err(MethodError::InvalidParameter {
                name: "sizes",
                value: format!("{:?}", self.sizes),
                allowed: "one or more odd widths in 3..=129",
            });
        }
        check_range(
            "passes_after_first",
            self.passes_after_first as f32,
            1.0,
            64.0,
            "1..=64",
        )?;
        if self.search_grid.is_multiple_of(2) {
            return Err(MethodError::InvalidParameter {
                name: "search_grid",
                value: self.search_grid.to_string(),
                allowed: "odd, 3..=15",
            });
        }
        check_range(
            "search_grid",
            self.search_grid as f32,
            3.0,
            15.0,
            "odd, 3..=15",
        )?;
        check_range("rerank", self.rerank as f32, 1.0, 1024.0, "1..=1024")?;
        check_range("checks", self.checks as f32, 1.0, 1e7, "1..=10000000")?;
        check_range("iterations", self.iterations as f32, 1.0, 100.0, "1..=100")?;
        check_range("convergence", self.convergence, 0.0, 1.0, "0..=1")?;
        check_range(
            "centre_spacing",
            self.centre_spacing,
            0.05,
            1.0,
            "[0.05, 1]",
        )?;
        check_range("coherence", self.coherence, 0.0, 1e6, "[0, 1e6]")?;
        check_range("robust", self.robust, 0.1, 2.0, "[0.1, 2]")?;
        check_range(
            "orientation_iterations",
            self.orientation_iterations as f32,
            0.0,
            1000.0,
            "0..=1000",
        )?;
        check_range("substeps", self.substeps as f32, 1.0, 64.0, "1..=64")?;
        check_range("relaxation", self.relaxation as f32, 0.0, 64.0, "0..=64")?;
        check_range(
            "upsample_diffusion",
            self.upsample_diffusion as f32,
            0.0,
            64.0,
            "0..=64",
        )?;
        Ok(())
    }
}

/// How the nearest exemplar neighbourhood is found ([`search`](super::search)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Search {
    /// A g × g subsample of the window, reduced to 8 dimensions by PCA, in
    /// a k-d tree; `rerank` candidates re-ranked by full SSD.
    #[default]
    Pca,
    /// The whole w × w window against every candidate by SSD: the search
    /// the paper's hierarchical clustering approximates.
    Exact,
    /// The whole w × w window in a k-means tree of the exemplar's
    /// neighbourhoods (the paper's, Sec. VII).
    Clustered,
}

crate::named!(Search {
    Pca => "pca",
    Exact => "exact",
    Clustered => "clustered",
});

/// `checks` is written to the settings only where it was changed (it does
/// nothing unless `search = "clustered"`, so default runs keep their
/// settings and fingerprints).
fn is_default_checks(v: &u32) -> bool {
    *v == 64
}

/// How the texture is carried between frames
/// ([`OptimizationParams::transport`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Transport {
    /// Each point back-tracked by RK4 through the mesh velocities
    /// ([`transport`](super::transport)).
    #[default]
    Trace,
    /// Upwind advection of the coordinates and the orientation on a
    /// narrow-band grid (the paper's, [`grid`](super::grid)).
    Grid,
}

crate::named!(Transport {
    Trace => "trace",
    Grid => "grid",
});

/// Where the points go ([`OptimizationParams::placement`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Placement {
    /// A barycentric lattice subdividing every fluid triangle.
    #[default]
    Lattice,
    /// Random points spread by repulsion and re-tiled (the paper's).
    Repulsion,
}

crate::named!(Placement {
    Lattice => "lattice",
    Repulsion => "repulsion",
});

/// What the averaging step's result becomes before the next search.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Histogram {
    /// Each channel remapped rank by rank onto the working exemplar's
    /// values ([`histogram`](super::histogram)): the texture keeps the exemplar's contrast,
    /// and the search keeps matching textured neighbourhoods.
    #[default]
    Matched,
    /// The paper's: the weighted average as it is. Overlapping predictions
    /// that disagree by a fraction of a texel soften it, the search then
    /// prefers the exemplar's smooth regions, and transport softens it a
    /// little more every frame.
    Paper,
}

crate::named!(Histogram {
    Matched => "matched",
    Paper => "paper",
});
