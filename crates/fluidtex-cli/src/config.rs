//! The `run` configuration: a TOML file mirrored by command-line flags.
//!
//! Precedence: built-in defaults < `--config FILE` < flags. Relative paths
//! in the file are relative to the file's folder, so a config can travel
//! with its shot. Every key is documented in the README; unknown keys are an
//! error (a typo must not silently fall back to a default).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use fluidtex::methods::atlas_check::AtlasCheckParams;
use fluidtex::methods::dual_rest::DualRestParams;
use fluidtex::methods::erosion::{ErosionParams, Falloff, Orientation, Placement, WeightMode};
use fluidtex::methods::lapped_rigid::LappedRigidParams;
use fluidtex::methods::optimization::OptimizationParams;
use fluidtex::methods::registry::{MethodKind, MethodParams};
use fluidtex::named::Named;
use fluidtex::pipeline::OutputOptions;
use serde::{Deserialize, Serialize};

/// Everything a `run` needs, after merging file and flags.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Mesh sequence pattern (`fluid.$F4.ply`, `fluid.####.ply`, `fluid.%04d.ply`).
    pub mesh: Option<String>,
    /// Frame range `A-B` or `A`; all frames found on disk when absent.
    pub frames: Option<String>,
    /// Output folder.
    pub out: Option<PathBuf>,
    /// Method name \[erosion] (see [`MethodKind`]).
    pub method: Option<MethodKind>,
    /// Atlas width and height in texels \[4096].
    pub atlas: Option<u32>,
    /// Gutter between charts in texels \[4].
    pub gutter: Option<u32>,
    /// Frames per second of the simulation \[24].
    pub fps: Option<f32>,
    /// Seed of every random choice \[0].
    pub seed: Option<u64>,
    /// Colour exemplar image; the built-in pebbles when absent.
    pub exemplar: Option<PathBuf>,
    /// Feature map image; derived from the exemplar when absent.
    pub feature: Option<PathBuf>,
    /// How to derive a missing feature map: auto, luminance, distance \[auto].
    pub feature_method: Option<String>,
    /// How minified exemplar texels are read: trilinear, none \[trilinear].
    /// Left out of the file when unset, so fingerprints of older runs hold.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exemplar_filter: Option<String>,
    /// Extra channels: name = image.
    pub channels: BTreeMap<String, PathBuf>,
    /// Names of the three velocity properties in PLY files.
    pub velocity: Option<[String; 3]>,
    /// Erosion method parameters.
    pub erosion: ErosionParams,
    /// atlas-check method parameters.
    pub atlas_check: AtlasCheckParams,
    /// dual-rest baseline parameters.
    pub dual_rest: DualRestParams,
    /// Which files to write.
    pub outputs: OutputOptions,
    /// After the run, encode the previews as `preview.mp4` with ffmpeg
    /// [false]. Not part of the fingerprint: it changes no texture.
    #[serde(skip_serializing)]
    pub preview_video: Option<bool>,
    /// USD input: the Mesh prim to read, when the stage holds several.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prim: Option<String>,
    /// optimization method parameters. Left out of the file when at their
    /// defaults, so fingerprints of older runs hold.
    #[serde(skip_serializing_if = "is_default_optimization")]
    pub optimization: OptimizationParams,
    /// lapped-rigid (2016 method) parameters. Left out of the file when at
    /// their defaults, so fingerprints of older runs hold.
    #[serde(skip_serializing_if = "is_default_rigid")]
    pub lapped_rigid: LappedRigidParams,
    /// Several exemplars per surface, instead of `exemplar` (each with its
    /// weight, and its own feature map and extra channels). Left out of the
    /// file when empty, so fingerprints of older runs hold.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub exemplars: Vec<ExemplarEntry>,
    /// How a new patch picks among several exemplars: probability,
    /// region, histogram \[probability].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exemplar_select: Option<String>,
    /// Region image of `exemplar_select = "region"` (grey level = exemplar
    /// index, projected from above over the first frame's x-z extent).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exemplar_region: Option<PathBuf>,
}

/// One of several exemplars (`exemplars = [{ path = ..., weight = ... }]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExemplarEntry {
    /// Colour image.
    pub path: PathBuf,
    /// Target proportion \[1] (normalised over all exemplars).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub weight: Option<f32>,
    /// Its feature map; derived when absent (all exemplars alike).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feature: Option<PathBuf>,
    /// Its extra channels, name = image (every exemplar the same names).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub channels: BTreeMap<String, PathBuf>,
}

fn is_default_optimization(p: &OptimizationParams) -> bool {
    *p == OptimizationParams::default()
}

fn is_default_rigid(p: &LappedRigidParams) -> bool {
    *p == LappedRigidParams::default()
}

impl Config {
    /// Reads a TOML config; relative paths become relative to its folder.
    pub fn load(path: &Path) -> Result<Config> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the config", path.display()))?;
        Config::parse(&text, path)
    }

    /// Parses a config's text; `path` names it in messages and anchors its
    /// relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Config> {
        let mut config: Config = toml::from_str(text).map_err(|e| {
            let msg = e.message().to_string();
            // Count bytes, not chars: a span need not fall on a char boundary.
            let line = e
                .span()
                .map(|s| {
                    let end = s.start.min(text.len());
                    text.as_bytes()[..end]
                        .iter()
                        .filter(|&&b| b == b'\n')
                        .count()
                        + 1
                })
                .unwrap_or(0);
            anyhow::anyhow!("{}: line {line}: {msg}", path.display())
        })?;
        let base = path.parent().unwrap_or(Path::new(""));
        let rebase = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = base.join(&*p);
            }
        };
        if let Some(m) = &mut config.mesh
            && Path::new(m).is_relative()
        {
            *m = base.join(&*m).to_string_lossy().into_owned();
        }
        for p in [&mut config.out, &mut config.exemplar, &mut config.feature]
            .into_iter()
            .flatten()
        {
            rebase(p);
        }
        for p in config.channels.values_mut() {
            rebase(p);
        }
        if let Some(p) = &mut config.lapped_rigid.mask {
            rebase(p);
        }
        if let Some(p) = &mut config.exemplar_region {
            rebase(p);
        }
        for e in &mut config.exemplars {
            rebase(&mut e.path);
            if let Some(p) = &mut e.feature {
                rebase(p);
            }
            for p in e.channels.values_mut() {
                rebase(p);
            }
        }
        Ok(config)
    }

    /// A stable text that changes whenever a setting that affects the
    /// texture changes (used to refuse resuming a different run). The
    /// output folder and the frame range are left out: resuming with a
    /// later last frame extends a run.
    pub fn fingerprint(&self) -> String {
        let mut c = self.clone();
        c.out = None;
        c.frames = None;
        let json = serde_json::to_string(&c).unwrap_or_default();
        // FNV-1a, 64 bit: stable across platforms and versions, unlike std's hasher.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in json.bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        format!("{:016x}-v{}", h, env!("CARGO_PKG_VERSION"))
    }
}

/// A clap parser for a [`Named`] setting: its names are the possible values
/// (listed by `--help`, checked by clap).
pub fn named<T: Named + Send + Sync + Clone>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(T::ALL.iter().map(|v| v.name()))
        .try_map(|s: String| T::parse_named("value", &s))
}

/// The same check for settings the config keeps as text.
pub fn names<T: Named>() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(T::ALL.iter().map(|v| v.name()))
}

impl Config {
    /// The method the config names (erosion when none).
    pub fn method_kind(&self) -> MethodKind {
        self.method.unwrap_or_default()
    }

    /// Every method's parameter section.
    pub fn method_params(&self) -> MethodParams {
        MethodParams {
            erosion: self.erosion.clone(),
            atlas_check: self.atlas_check.clone(),
            dual_rest: self.dual_rest.clone(),
            optimization: self.optimization.clone(),
            lapped_rigid: self.lapped_rigid.clone(),
        }
    }
}

/// Flags of `fluidtex run` that mirror the config (flags win).
// The field docs are the `--help` text, printed verbatim by clap: `[4096]`
// is a default, not an intra-doc link (escaping it would show in the help).
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Args, Clone, Debug, Default)]
pub struct RunFlags {
    /// Mesh sequence: fluid.$F4.ply, fluid.####.ply or fluid.%04d.ply (PLY, OBJ or VTK)
    #[arg(long)]
    pub mesh: Option<String>,
    /// Frame range A-B (or a single frame A); default: every frame found
    #[arg(long)]
    pub frames: Option<String>,
    /// Output folder
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Texturing method [erosion]
    #[arg(long, value_parser = named::<MethodKind>())]
    pub method: Option<MethodKind>,
    /// Atlas size in texels (square) [4096]
    #[arg(long)]
    pub atlas: Option<u32>,
    /// Gutter between atlas charts in texels [4]
    #[arg(long)]
    pub gutter: Option<u32>,
    /// Frames per second of the simulation [24]
    #[arg(long)]
    pub fps: Option<f32>,
    /// Seed for every random choice [0]
    #[arg(long)]
    pub seed: Option<u64>,
    /// Colour exemplar (PNG, JPEG, EXR); default: built-in pebbles. Repeat
    /// for several exemplars per surface, each IMG:WEIGHT (weight 1 when
    /// left out)
    #[arg(long = "exemplar", value_name = "IMG[:WEIGHT]")]
    pub exemplar: Vec<String>,
    /// Several exemplars: how a new patch picks one [probability]
    #[arg(long, value_parser = names::<fluidtex::exemplar::ExemplarSelect>())]
    pub exemplar_select: Option<String>,
    /// Several exemplars, region selection: grey image of exemplar indices
    /// (black 0, white the last), seen from above over the first frame;
    /// default: the mesh's per-vertex exemplar_id
    #[arg(long, value_name = "IMG")]
    pub exemplar_region: Option<PathBuf>,
    /// Feature map (grey image, bright = important features, eroded last)
    #[arg(long)]
    pub feature: Option<PathBuf>,
    /// How to derive a missing feature map [auto]
    #[arg(long, value_parser = names::<fluidtex::exemplar::FeatureMethod>())]
    pub feature_method: Option<String>,
    /// Exemplar filtering where it is shown minified: trilinear (mip
    /// pyramid at each texel's footprint) or none (bilinear, aliases)
    #[arg(long, value_parser = names::<fluidtex::exemplar::ExemplarFilter>())]
    pub exemplar_filter: Option<String>,
    /// Extra channel NAME=IMG, written as NAME.F.png|exr (repeatable)
    #[arg(long = "channel", value_name = "NAME=IMG")]
    pub channels: Vec<String>,
    /// PLY velocity property names, e.g. --velocity vel_x,vel_y,vel_z
    #[arg(long, value_delimiter = ',', num_args = 1)]
    pub velocity: Option<Vec<String>>,
    /// Patch radius r in world units [bbox diagonal / 25]
    #[arg(long)]
    pub radius: Option<f32>,
    /// World size covered by the exemplar [2.6 r]
    #[arg(long)]
    pub exemplar_size: Option<f32>,
    /// Maximal triangle distortion δ_max (Eq. 1) [3]
    #[arg(long)]
    pub delta_max: Option<f32>,
    /// Erosion ε (Sec. 5.2) [0.1]
    #[arg(long)]
    pub epsilon: Option<f32>,
    /// Remove patch vertices farther than this × r from the surface [0.25]
    #[arg(long)]
    pub far_fraction: Option<f32>,
    /// Never erode within this × r of a patch centre (Eq. 2) [0.25]
    #[arg(long)]
    pub centre_fraction: Option<f32>,
    /// RK4 substeps per frame [1]
    #[arg(long)]
    pub substeps: Option<u32>,
    /// Disable the random rotation of new patches
    #[arg(long)]
    pub no_rotation: bool,
    /// New patch placement: local (the paper) or global
    #[arg(long, value_parser = named::<Placement>())]
    pub placement: Option<Placement>,
    /// Weights over time: progressive (monotone, rate-limited) or paper
    #[arg(long, value_parser = named::<WeightMode>())]
    pub weights: Option<WeightMode>,
    /// Progressive weights: largest fall of w per second [2.4]
    #[arg(long)]
    pub erosion_rate: Option<f32>,
    /// Where the erosion falloff D reaches 0: footprint (r/S) or paper (0.5)
    #[arg(long, value_parser = named::<Falloff>())]
    pub falloff: Option<Falloff>,
    /// Exemplar orientation on new patches: random or aligned (with --up-axis)
    #[arg(long, value_parser = named::<Orientation>())]
    pub orientation: Option<Orientation>,
    /// World direction the exemplar's up follows with --orientation aligned [0,1,0]
    #[arg(long, value_delimiter = ',', num_args = 1, allow_hyphen_values = true)]
    pub up_axis: Option<Vec<f32>>,
    /// Default r is never below this many median edge lengths [4]
    #[arg(long)]
    pub radius_edges: Option<f32>,
    /// Split patch edges longer than this many median edge lengths of the frame (0: never, the paper) [2]
    #[arg(long)]
    pub split_edges: Option<f32>,
    /// dual-rest: frames between two resets of a layer [24]
    #[arg(long)]
    pub period: Option<u32>,
    /// Do not write mesh.F.obj / .mtl
    #[arg(long)]
    pub no_obj: bool,
    /// Do not write mesh.F.glb
    #[arg(long)]
    pub no_glb: bool,
    /// Do not write patches.F.png / source.F.exr
    #[arg(long)]
    pub no_debug: bool,
    /// With debug outputs: also write switch.F.png, the per-texel switch map (slow at large atlases)
    #[arg(long)]
    pub switch_map: bool,
    /// Write preview.F.png every N frames (0: never)
    #[arg(long)]
    pub preview_every: Option<u32>,
    /// After the run, encode the previews as preview.mp4 with ffmpeg (previews every frame unless --preview-every says otherwise)
    #[arg(long)]
    pub preview_video: bool,
    /// USD input (--mesh shot.usd|usda|usdc): the Mesh prim to read, e.g. /liquid/surface
    #[arg(long)]
    pub prim: Option<String>,
    /// optimization: target points at the finest level on the first frame [200000]
    #[arg(long)]
    pub points: Option<u32>,
    /// optimization: exemplar width in synthesis texels (point spacings) [128]
    #[arg(long)]
    pub exemplar_texels: Option<u32>,
    /// optimization: hierarchy levels on the first frame [3]
    #[arg(long)]
    pub levels: Option<u32>,
    /// optimization: hierarchy levels on later frames [1]
    #[arg(long)]
    pub levels_after_first: Option<u32>,
    /// optimization: neighbourhood widths of the passes, odd [33,17,9]
    #[arg(long, value_delimiter = ',')]
    pub sizes: Option<Vec<u32>>,
    /// optimization: the search compares a G x G subsample of each neighbourhood [9]
    #[arg(long)]
    pub search_grid: Option<u32>,
    /// optimization: k-d tree candidates re-ranked by full distance [16]
    #[arg(long)]
    pub rerank: Option<u32>,
    /// optimization: most search + averaging iterations per pass [3]
    #[arg(long)]
    pub iterations: Option<u32>,
    /// optimization: spacing of neighbourhood centres, fraction of the width [0.25]
    #[arg(long)]
    pub centre_spacing: Option<f32>,
    /// optimization: weight of the transported texture (lambda, Eq. 2) [1]
    #[arg(long)]
    pub coherence: Option<f32>,
    /// optimization: orientation smoothing iterations per level [10]
    #[arg(long)]
    pub orientation_iterations: Option<u32>,
    /// optimization: robust exponent of the texture energy (2: least squares) [0.8]
    #[arg(long)]
    pub robust: Option<f32>,
    #[command(flatten)]
    pub rigid: RigidFlags,
}

impl RunFlags {
    /// Applies the flags that are set on top of `config`.
    pub fn apply(&self, config: &mut Config) -> Result<()> {
        macro_rules! set {
            ($($field:ident),*) => { $( if let Some(v) = &self.$field { config.$field = Some(v.clone()); } )* };
        }
        set!(
            mesh,
            frames,
            out,
            method,
            atlas,
            gutter,
            fps,
            seed,
            feature,
            feature_method,
            exemplar_filter,
            exemplar_select,
            exemplar_region
        );
        match self.exemplar.as_slice() {
            [] => {}
            [one] => {
                let (path, _) = exemplar_spec(one)?;
                config.exemplar = Some(path);
                config.exemplars.clear();
            }
            several => {
                config.exemplar = None;
                config.exemplars = several
                    .iter()
                    .map(|spec| {
                        let (path, weight) = exemplar_spec(spec)?;
                        Ok(ExemplarEntry {
                            path,
                            weight,
                            ..Default::default()
                        })
                    })
                    .collect::<Result<_>>()?;
            }
        }
        for spec in &self.channels {
            let Some((name, path)) = spec.split_once('=') else {
                bail!("--channel {spec}: expected NAME=IMAGE, e.g. displacement=disp.exr");
            };
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                bail!("--channel {spec}: the name must be letters, digits, '_' or '-'");
            }
            config
                .channels
                .insert(name.to_string(), PathBuf::from(path));
        }
        if let Some(v) = &self.velocity {
            let [a, b, c] = v.as_slice() else {
                bail!("--velocity needs three property names, e.g. vx,vy,vz");
            };
            config.velocity = Some([a.clone(), b.clone(), c.clone()]);
        }
        let e = &mut config.erosion;
        if let Some(v) = self.radius {
            e.radius = Some(v);
        }
        if let Some(v) = self.exemplar_size {
            e.exemplar_size = Some(v);
        }
        if let Some(v) = self.delta_max {
            e.delta_max = v;
        }
        if let Some(v) = self.epsilon {
            e.epsilon = v;
        }
        if let Some(v) = self.far_fraction {
            e.far_fraction = v;
        }
        if let Some(v) = self.centre_fraction {
            e.centre_fraction = v;
        }
        if let Some(v) = self.substeps {
            e.substeps = v;
        }
        if self.no_rotation {
            e.random_rotation = false;
        }
        if let Some(v) = self.placement {
            e.placement = v;
        }
        if let Some(v) = self.weights {
            e.weights = v;
        }
        if let Some(v) = self.erosion_rate {
            e.erosion_rate = v;
        }
        if let Some(v) = self.falloff {
            e.falloff = v;
        }
        if let Some(v) = self.orientation {
            e.orientation = v;
        }
        if let Some(a) = &self.up_axis {
            let [x, y, z] = a.as_slice() else {
                bail!("--up-axis needs three numbers, e.g. 0,1,0");
            };
            e.up_axis = [*x, *y, *z];
        }
        if let Some(v) = self.radius_edges {
            e.radius_edges = v;
        }
        if let Some(v) = self.split_edges {
            e.split_edges = v;
        }
        if let Some(p) = self.period {
            config.dual_rest.period = p;
        }
        let o = &mut config.outputs;
        if self.no_obj {
            o.obj = false;
        }
        if self.no_glb {
            o.glb = false;
        }
        if self.no_debug {
            o.debug = false;
        }
        if self.switch_map {
            o.switch_map = true;
        }
        if let Some(n) = self.preview_every {
            o.preview_every = n;
        }
        if self.preview_video {
            config.preview_video = Some(true);
        }
        if let Some(p) = &self.prim {
            config.prim = Some(p.clone());
        }
        // A video needs previews: every frame unless the user chose.
        if config.preview_video == Some(true) && config.outputs.preview_every == 0 {
            config.outputs.preview_every = 1;
        }
        let p = &mut config.optimization;
        if let Some(v) = self.exemplar_size {
            p.exemplar_size = Some(v);
        }
        if let Some(v) = self.substeps {
            p.substeps = v;
        }
        if let Some(v) = self.points {
            p.points = v;
        }
        if let Some(v) = self.exemplar_texels {
            p.exemplar_texels = v;
        }
        if let Some(v) = self.levels {
            p.levels = v;
        }
        if let Some(v) = self.levels_after_first {
            p.levels_after_first = v;
        }
        if let Some(v) = &self.sizes {
            p.sizes = v.clone();
        }
        if let Some(v) = self.search_grid {
            p.search_grid = v;
        }
        if let Some(v) = self.rerank {
            p.rerank = v;
        }
        if let Some(v) = self.iterations {
            p.iterations = v;
        }
        if let Some(v) = self.centre_spacing {
            p.centre_spacing = v;
        }
        if let Some(v) = self.coherence {
            p.coherence = v;
        }
        if let Some(v) = self.orientation_iterations {
            p.orientation_iterations = v;
        }
        if let Some(v) = self.robust {
            p.robust = v;
        }
        self.rigid.apply(&mut config.lapped_rigid);
        Ok(())
    }
}

/// `IMG` or `IMG:WEIGHT` of `--exemplar`: the weight is what follows the
/// last `:` when it reads as a number (so `C:\\tex\\a.png` stays a path).
fn exemplar_spec(spec: &str) -> Result<(PathBuf, Option<f32>)> {
    if let Some((path, w)) = spec.rsplit_once(':')
        && !path.is_empty()
        && let Ok(weight) = w.parse::<f32>()
    {
        if !(weight.is_finite() && weight > 0.0) {
            bail!("--exemplar {spec}: the weight must be a positive number");
        }
        return Ok((PathBuf::from(path), Some(weight)));
    }
    Ok((PathBuf::from(spec), None))
}

/// Flags of the lapped-rigid method (`[lapped_rigid]` keys), one per key.
// Field docs are `--help` text: `[4]` is a default, not a link.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Args, Clone, Debug, Default)]
pub struct RigidFlags {
    /// lapped-rigid: patch size r in world units [bbox diagonal / 25]
    #[arg(long)]
    pub rigid_radius: Option<f32>,
    /// lapped-rigid: default r as a fraction of the bbox diagonal [0.04]
    #[arg(long)]
    pub rigid_radius_fraction: Option<f32>,
    /// lapped-rigid: default r is never below this many median edge lengths [4]
    #[arg(long)]
    pub rigid_radius_edges: Option<f32>,
    /// lapped-rigid: world size covered by the exemplar [exemplar_scale × r]
    #[arg(long)]
    pub rigid_exemplar_size: Option<f32>,
    /// lapped-rigid: default exemplar size as a multiple of r [2.6]
    #[arg(long)]
    pub rigid_exemplar_scale: Option<f32>,
    /// lapped-rigid: φ_max, receivers turning farther from the frame normal are rejected, degrees [130]
    #[arg(long)]
    pub rigid_phi_max: Option<f32>,
    /// lapped-rigid: ψ_{α=1}, receiver vertices within this angle are opaque, degrees [30]
    #[arg(long)]
    pub rigid_alpha_opaque: Option<f32>,
    /// lapped-rigid: ψ_{α=0}, receiver vertices beyond this angle are transparent, degrees [60]
    #[arg(long)]
    pub rigid_alpha_transparent: Option<f32>,
    /// lapped-rigid: trackers farther than this × r from the next surface are deleted [0.25]
    #[arg(long)]
    pub rigid_far_fraction: Option<f32>,
    /// lapped-rigid: RK4 substeps per frame [1]
    #[arg(long)]
    pub rigid_substeps: Option<u32>,
    /// lapped-rigid: first-frame Poisson disks with normals less aligned do not block [0.9]
    #[arg(long)]
    pub rigid_normal_dot: Option<f32>,
    /// lapped-rigid: no random tangent direction for new trackers
    #[arg(long)]
    pub rigid_no_rotation: bool,
    /// lapped-rigid: composite alpha below which a texel seeds a tracker [0.99]
    #[arg(long)]
    pub rigid_coverage: Option<f32>,
    /// lapped-rigid: contributions below this are dropped, a patch with none is deleted [1/255]
    #[arg(long)]
    pub rigid_keep_weight: Option<f32>,
    /// lapped-rigid: patch mask image (grey, covers the exemplar square); default: from the feature map
    #[arg(long, value_name = "IMG")]
    pub mask: Option<PathBuf>,
    /// lapped-rigid: derived mask, how far features move the patch border [0.2]
    #[arg(long)]
    pub rigid_mask_feature_weight: Option<f32>,
    /// lapped-rigid: derived mask, width of the soft border [0.2]
    #[arg(long)]
    pub rigid_mask_softness: Option<f32>,
    /// lapped-rigid: sink test, corners must move inward faster than this × r per second [0.25]
    #[arg(long)]
    pub rigid_sink_speed: Option<f32>,
    /// lapped-rigid: sink fade speed (1: gone when the corners would reach the centre) [1]
    #[arg(long)]
    pub rigid_sink_fade_rate: Option<f32>,
}

impl RigidFlags {
    /// Applies the flags that are set on top of `p`.
    pub fn apply(&self, p: &mut LappedRigidParams) {
        if let Some(v) = self.rigid_radius {
            p.radius = Some(v);
        }
        if let Some(v) = self.rigid_exemplar_size {
            p.exemplar_size = Some(v);
        }
        if let Some(v) = &self.mask {
            p.mask = Some(v.clone());
        }
        if self.rigid_no_rotation {
            p.random_rotation = false;
        }
        macro_rules! set {
            ($($flag:ident => $field:ident),*) => { $( if let Some(v) = self.$flag { p.$field = v; } )* };
        }
        set!(
            rigid_radius_fraction => radius_fraction,
            rigid_radius_edges => radius_edges,
            rigid_exemplar_scale => exemplar_scale,
            rigid_phi_max => phi_max,
            rigid_alpha_opaque => alpha_opaque,
            rigid_alpha_transparent => alpha_transparent,
            rigid_far_fraction => far_fraction,
            rigid_substeps => substeps,
            rigid_normal_dot => normal_dot,
            rigid_coverage => coverage,
            rigid_keep_weight => keep_weight,
            rigid_mask_feature_weight => mask_feature_weight,
            rigid_mask_softness => mask_softness,
            rigid_sink_speed => sink_speed,
            rigid_sink_fade_rate => sink_fade_rate
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_win_over_the_file_and_paths_follow_the_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("shot.toml");
        std::fs::write(
            &path,
            "mesh = \"sim/fluid.$F4.ply\"\natlas = 2048\nexemplar = \"tex/lava.png\"\n[erosion]\nradius = 0.5\nepsilon = 0.2\n[channels]\ndisplacement = \"tex/disp.exr\"\n",
        )
        .expect("write");
        let mut c = Config::load(&path).expect("valid config");
        assert_eq!(c.atlas, Some(2048));
        assert_eq!(c.exemplar, Some(dir.path().join("tex/lava.png")));
        assert_eq!(
            c.mesh.as_deref(),
            Some(dir.path().join("sim/fluid.$F4.ply").to_str().expect("utf8"))
        );
        assert_eq!(c.channels["displacement"], dir.path().join("tex/disp.exr"));
        let flags = RunFlags {
            atlas: Some(512),
            epsilon: Some(0.05),
            placement: Some(Placement::Global),
            ..Default::default()
        };
        flags.apply(&mut c).expect("valid flags");
        assert_eq!(c.atlas, Some(512));
        assert_eq!(c.erosion.epsilon, 0.05);
        assert_eq!(c.erosion.radius, Some(0.5));
        assert_eq!(c.erosion.placement, Placement::Global);
    }

    #[test]
    fn unknown_keys_and_bad_flags_are_errors() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, "atlas = 1024\n[erosion]\nradus = 0.5\n").expect("write");
        let err = Config::load(&path).expect_err("typo must fail").to_string();
        assert!(
            err.contains("bad.toml: line 3") && err.contains("radus"),
            "{err}"
        );
        let mut c = Config::default();
        let bad = RunFlags {
            channels: vec!["nodelimiter".into()],
            ..Default::default()
        };
        assert!(bad.apply(&mut c).is_err());
    }

    #[test]
    fn repeated_exemplar_flags_give_weighted_exemplars() {
        let flags = |specs: &[&str]| RunFlags {
            exemplar: specs.iter().map(|s| s.to_string()).collect(),
            ..Default::default()
        };
        // One exemplar is today's key, whatever its weight.
        let mut c = Config::default();
        flags(&["lava.png"]).apply(&mut c).expect("valid");
        assert_eq!(c.exemplar, Some(PathBuf::from("lava.png")));
        assert!(c.exemplars.is_empty());
        let mut c = Config::default();
        flags(&["a.png:0.3", "dir:x/b.png", "c.png:2"])
            .apply(&mut c)
            .expect("valid");
        assert_eq!(c.exemplar, None);
        let got: Vec<(PathBuf, Option<f32>)> = c
            .exemplars
            .iter()
            .map(|e| (e.path.clone(), e.weight))
            .collect();
        assert_eq!(
            got,
            vec![
                ("a.png".into(), Some(0.3)),
                ("dir:x/b.png".into(), None),
                ("c.png".into(), Some(2.0)),
            ]
        );
        let err = flags(&["a.png:-1", "b.png"])
            .apply(&mut Config::default())
            .expect_err("negative weight");
        assert!(err.to_string().contains("a.png:-1"), "{err}");
        // The file's entries, relative to the file.
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("shot.toml");
        std::fs::write(
            &path,
            "exemplar_select = \"histogram\"\nexemplars = [{ path = \"a.png\", weight = 0.3, \
             channels = { displacement = \"a_d.exr\" } }, { path = \"b.png\" }]\n",
        )
        .expect("write");
        let c = Config::load(&path).expect("valid");
        assert_eq!(c.exemplars[0].path, dir.path().join("a.png"));
        assert_eq!(
            c.exemplars[0].channels["displacement"],
            dir.path().join("a_d.exr")
        );
        assert_eq!(c.exemplar_select.as_deref(), Some("histogram"));
    }

    #[test]
    fn fingerprint_tracks_settings_but_not_the_output_folder() {
        let a = Config {
            atlas: Some(1024),
            ..Default::default()
        };
        let mut b = a.clone();
        b.out = Some("elsewhere".into());
        b.frames = Some("0-100".into());
        assert_eq!(a.fingerprint(), b.fingerprint());
        b.erosion.epsilon = 0.2;
        assert_ne!(a.fingerprint(), b.fingerprint());
    }
}
