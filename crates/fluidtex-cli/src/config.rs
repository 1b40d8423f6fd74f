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
    /// Method name [erosion].
    pub method: Option<String>,
    /// Atlas width and height in texels [4096].
    pub atlas: Option<u32>,
    /// Gutter between charts in texels [4].
    pub gutter: Option<u32>,
    /// Frames per second of the simulation [24].
    pub fps: Option<f32>,
    /// Seed of every random choice [0].
    pub seed: Option<u64>,
    /// Colour exemplar image; the built-in pebbles when absent.
    pub exemplar: Option<PathBuf>,
    /// Feature map image; derived from the exemplar when absent.
    pub feature: Option<PathBuf>,
    /// How to derive a missing feature map: auto, luminance, distance [auto].
    pub feature_method: Option<String>,
    /// How minified exemplar texels are read: trilinear, none [trilinear].
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
    /// lapped-rigid (2016 method) parameters. Left out of the file when at
    /// their defaults, so fingerprints of older runs hold.
    #[serde(skip_serializing_if = "is_default_rigid")]
    pub lapped_rigid: LappedRigidParams,
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

/// Flags of `fluidtex run` that mirror the config (flags win).
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
    /// Texturing method: erosion (default), advect, dual-rest, blend-deformable, atlas-check, lapped-rigid
    #[arg(long)]
    pub method: Option<String>,
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
    /// Colour exemplar (PNG, JPEG, EXR); default: built-in pebbles
    #[arg(long)]
    pub exemplar: Option<PathBuf>,
    /// Feature map (grey image, bright = important features, eroded last)
    #[arg(long)]
    pub feature: Option<PathBuf>,
    /// How to derive a missing feature map: auto, luminance, distance
    #[arg(long)]
    pub feature_method: Option<String>,
    /// Exemplar filtering where it is shown minified: trilinear (mip
    /// pyramid at each texel's footprint) or none (bilinear, aliases)
    #[arg(long, value_name = "trilinear|none")]
    pub exemplar_filter: Option<String>,
    /// Extra channel NAME=IMG, written as NAME.F.png|exr (repeatable)
    #[arg(long = "channel", value_name = "NAME=IMG")]
    pub channels: Vec<String>,
    /// PLY velocity property names, e.g. --velocity vel_x,vel_y,vel_z
    #[arg(long, value_delimiter = ',', num_args = 3)]
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
    #[arg(long)]
    pub placement: Option<String>,
    /// Weights over time: progressive (monotone, rate-limited) or paper
    #[arg(long)]
    pub weights: Option<String>,
    /// Progressive weights: largest fall of w per second [2.4]
    #[arg(long)]
    pub erosion_rate: Option<f32>,
    /// Where the erosion falloff D reaches 0: footprint (r/S) or paper (0.5)
    #[arg(long)]
    pub falloff: Option<String>,
    /// Exemplar orientation on new patches: random or aligned (with --up-axis)
    #[arg(long)]
    pub orientation: Option<String>,
    /// World direction the exemplar's up follows with --orientation aligned [0,1,0]
    #[arg(long, value_delimiter = ',', num_args = 3, allow_hyphen_values = true)]
    pub up_axis: Option<Vec<f32>>,
    /// Default r is never below this many median edge lengths [4]
    #[arg(long)]
    pub radius_edges: Option<f32>,
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
    /// Write preview.F.png every N frames (0: never)
    #[arg(long)]
    pub preview_every: Option<u32>,
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
            exemplar,
            feature,
            feature_method,
            exemplar_filter
        );
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
        if let Some(p) = &self.placement {
            e.placement = match p.as_str() {
                "local" => Placement::Local,
                "global" => Placement::Global,
                other => bail!("--placement {other}: expected local or global"),
            };
        }
        if let Some(w) = &self.weights {
            e.weights = match w.as_str() {
                "progressive" => WeightMode::Progressive,
                "paper" => WeightMode::Paper,
                other => bail!("--weights {other}: expected progressive or paper"),
            };
        }
        if let Some(v) = self.erosion_rate {
            e.erosion_rate = v;
        }
        if let Some(f) = &self.falloff {
            e.falloff = match f.as_str() {
                "footprint" => Falloff::Footprint,
                "paper" => Falloff::Paper,
                other => bail!("--falloff {other}: expected footprint or paper"),
            };
        }
        if let Some(o) = &self.orientation {
            e.orientation = match o.as_str() {
                "random" => Orientation::Random,
                "aligned" => Orientation::Aligned,
                other => bail!("--orientation {other}: expected random or aligned"),
            };
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
        if let Some(n) = self.preview_every {
            o.preview_every = n;
        }
        self.rigid.apply(&mut config.lapped_rigid);
        Ok(())
    }
}

/// Flags of the lapped-rigid method (`[lapped_rigid]` keys), one per key.
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
            placement: Some("global".into()),
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
        let bad = RunFlags {
            placement: Some("everywhere".into()),
            ..Default::default()
        };
        assert!(bad.apply(&mut c).is_err());
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
