//! The `run` configuration: a TOML file mirrored by command-line flags.
//!
//! Precedence: built-in defaults < `--config FILE` < flags. Relative paths
//! in the file are relative to the file's folder, so a config can travel
//! with its shot. Every key is documented in the README; unknown keys are an
//! error (a typo must not silently fall back to a default).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use fluidtex::methods::registry::{MethodKind, MethodParams};
use fluidtex::named::Named;
use fluidtex::pipeline::OutputOptions;

use fluidtex::methods::flags::MethodFlags;
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
    /// Every method's parameter section (`[erosion]`, `[lapped_rigid]`,
    /// ...), as the methods' registry declares them: a new method's
    /// section is a table of this file without a line here. The sections
    /// added after runs were fingerprinted are left out while at their
    /// defaults, so older runs resume.
    #[serde(flatten, serialize_with = "MethodParams::serialize_as_config")]
    pub params: MethodParams,
    /// Which files to write.
    pub outputs: OutputOptions,
    /// After the run, encode the previews as `preview.mp4` with ffmpeg
    /// [false]. Not part of the fingerprint: it changes no texture.
    #[serde(skip_serializing)]
    pub preview_video: Option<bool>,
    /// USD input: the Mesh prim to read, when the stage holds several.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prim: Option<String>,
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
    /// Several exemplars chosen by a per-vertex scalar of the input
    /// (`temperature`, `age`, ...): each exemplar entry gives its `range`,
    /// new patches take the exemplar whose range holds the value at their
    /// centre, and what no longer matches goes at `mismatch_rate`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub select_by: Option<String>,
    /// With `select_by`: how fast a patch part whose exemplar no longer
    /// matches goes, per second, where the state has just left its range
    /// \[1] (erosion: the most a vertex weight falls; lapped-rigid: the
    /// fade a patch loses).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mismatch_rate: Option<f32>,
    /// With `select_by`: how much faster it goes the farther the state is
    /// past the range: the rate is `mismatch_rate` · (1 + gain · d), d the
    /// distance past it as a share of the ranges' span \[20] (0: constant).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mismatch_gain: Option<f32>,
    /// Animated exemplars (an image sequence such as `bubbles.####.png`):
    /// exemplar frames shown per fluid frame \[1]; each patch starts at
    /// its own seeded phase.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exemplar_rate: Option<f32>,
    /// Animated exemplars: the memory, in MiB, their frames may take
    /// together, mip pyramids included \[2048]; a sequence over it is
    /// refused before the run. Not part of the fingerprint: it changes no
    /// texture ([`Config::fingerprint`] leaves it out).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exemplar_memory: Option<u64>,
    /// `paper`: every departure from the papers that has a paper setting
    /// set to it (`docs/departures.md`); the file's keys and the flags win.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
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
    /// With `select_by`: the closed range `[lo, hi]` of the attribute this
    /// exemplar shows (overlapping ranges share their overlap).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<[f32; 2]>,
}

/// Inserts every key of `from` that `into` does not have, table by table.
fn fill_missing(into: &mut toml::Table, from: toml::Table) {
    for (key, value) in from {
        match (into.get_mut(&key), value) {
            (Some(toml::Value::Table(mine)), toml::Value::Table(theirs)) => {
                fill_missing(mine, theirs)
            }
            (Some(_), _) => {}
            (None, value) => {
                into.insert(key, value);
            }
        }
    }
}

impl Config {
    /// Reads a TOML config; relative paths become relative to its folder.
    pub fn load(path: &Path) -> Result<Config> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the config", path.display()))?;
        Config::parse(&text, path)
    }

    /// Reads the config at `path` (none: the defaults) under `preset` (a
    /// `--preset` flag, which wins over the file's `preset` key).
    pub fn load_with_preset(path: Option<&Path>, preset: Option<&str>) -> Result<Config> {
        match path {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .with_context(|| format!("{}: cannot read the config", path.display()))?;
                Config::parse_with_preset(&text, path, preset)
            }
            None => Config::parse_with_preset("", Path::new(""), preset),
        }
    }

    /// Parses a config's text; `path` names it in messages and anchors its
    /// relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Config> {
        Config::parse_with_preset(text, path, None)
    }

    /// [`Config::parse`] under `preset` (or the text's own `preset` key):
    /// the preset's keys fill in what the text does not set.
    pub fn parse_with_preset(text: &str, path: &Path, preset: Option<&str>) -> Result<Config> {
        let config = Config::parse_text(text, path)?;
        let Some(preset) = preset.map(str::to_owned).or(config.preset.clone()) else {
            return Ok(config);
        };
        if preset != "paper" {
            bail!(
                "{}: preset = {preset:?}: the one preset is \"paper\"",
                path.display()
            );
        }
        let mut table: toml::Table = toml::from_str(text)
            .with_context(|| format!("{}: not a TOML table", path.display()))?;
        let paper: toml::Table = toml::from_str(&fluidtex::departures::paper_preset())
            .context("the paper preset of the departures ledger is not valid TOML")?;
        fill_missing(&mut table, paper);
        table.insert("preset".into(), toml::Value::String(preset));
        let text = toml::to_string(&table).context("cannot write the preset's config")?;
        Config::parse_text(&text, path)
    }

    /// Every resolved parameter as TOML (`--print-config`): the sections
    /// left out of the fingerprint when at their defaults are written too.
    pub fn resolved_toml(&self) -> Result<String> {
        let mut table = toml::Table::try_from(self).context("cannot write the config")?;
        // Every key of every section, including those left out of the
        // fingerprint at their defaults.
        for (name, every) in self.params.every_key() {
            let toml::Value::Table(every) = every else {
                continue;
            };
            let section = table
                .entry(name)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(section) = section {
                fill_missing(section, every);
            }
        }
        Ok(toml::to_string(&table)?)
    }

    /// Parses a config's text and makes its paths relative to `path`'s
    /// folder.
    fn parse_text(text: &str, path: &Path) -> Result<Config> {
        let mut config: Config = toml::from_str(text).map_err(|e| read_error(text, path, e))?;
        let base = path.parent().unwrap_or(Path::new(""));
        let rebase = |p: &mut PathBuf| {
            // `builtin:NAME` names an exemplar, not a file.
            let builtin = p.to_str().is_some_and(|s| s.starts_with("builtin:"));
            if p.is_relative() && !builtin {
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
        if let Some(p) = &mut config.params.lapped_rigid.mask {
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
        // A budget changes no texture: a resume may raise it.
        c.exemplar_memory = None;
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

/// The one line of a config that does not read: `FILE: line N: what`.
///
/// The method sections are flattened into [`Config`], and serde reads a
/// flattened part from a buffer that has lost toml's positions; so an
/// error without a position is looked for again: in the sections read on
/// their own (a key of `[erosion]`), then among the top-level keys (a key
/// no section and no setting has).
fn read_error(text: &str, path: &Path, e: toml::de::Error) -> anyhow::Error {
    let placed = |e: &toml::de::Error| e.span().is_some_and(|s| !s.is_empty());
    let e = if placed(&e) {
        e
    } else {
        match MethodParams::check_sections(text) {
            Err(section) if placed(&section) => section,
            _ => e,
        }
    };
    let start = match e.span() {
        Some(s) if !s.is_empty() => Some(s.start),
        span => top_level_key(text, e.message()).or(span.map(|s| s.start)),
    };
    // Count bytes, not chars: a span need not fall on a char boundary.
    let line = start.map_or(0, |start| {
        let end = start.min(text.len());
        text.as_bytes()[..end]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1
    });
    anyhow!("{}: line {line}: {}", path.display(), e.message())
}

/// Where the top-level key that `message` ("unknown field `KEY`, ...")
/// names starts in `text`.
fn top_level_key(text: &str, message: &str) -> Option<usize> {
    let key = message.strip_prefix("unknown field `")?.split('`').next()?;
    let keys: BTreeMap<toml::Spanned<String>, serde::de::IgnoredAny> = toml::from_str(text).ok()?;
    keys.keys()
        .find(|k| k.get_ref() == key)
        .map(|k| k.span().start)
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
    /// left out), or IMG@LO:HI with --select-by (the attribute range it shows)
    #[arg(long = "exemplar", value_name = "IMG[:WEIGHT][@LO:HI]")]
    pub exemplar: Vec<String>,
    /// Several exemplars: choose by this per-vertex scalar of the input
    /// (temperature, age, ...), each exemplar showing its IMG@LO:HI range
    #[arg(long, value_name = "ATTR")]
    pub select_by: Option<String>,
    /// With --select-by: how fast what no longer matches goes, per second,
    /// just past its range [1]
    #[arg(long)]
    pub mismatch_rate: Option<f32>,
    /// With --select-by: how much faster far past the range: rate × (1 +
    /// gain × distance past it / the ranges' span) [20] (0: constant)
    #[arg(long)]
    pub mismatch_gain: Option<f32>,
    /// Animated exemplar (IMG a sequence such as bubbles.####.png, or
    /// builtin:bubbles): exemplar frames per fluid frame [1]
    #[arg(long)]
    pub exemplar_rate: Option<f32>,
    /// Animated exemplars: MiB their frames may take, pyramids included [2048]
    #[arg(long, value_name = "MIB")]
    pub exemplar_memory: Option<u64>,
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
    /// Every departure from the papers that has a paper setting set to it
    /// (docs/departures.md); the config file's keys and other flags win
    #[arg(long, value_parser = ["paper"])]
    pub preset: Option<String>,
    /// The methods' parameter flags, from their declarations.
    #[command(flatten)]
    pub params: MethodFlags,
}

/// The flags that copy their value to one config key, one row each:
/// `flag field => config key: how`, where how is `some` (the key is an
/// option), `value` (the key takes the value), `off` (a `--no-...` switch
/// clears the key), `on` (a switch sets an optional key) or `set` (a
/// switch sets a plain one). The same table gives
/// [`FLAG_KEYS`], which the tests hold against clap's flags and serde's
/// keys, so a flag or key added to one side only fails a test. Flags whose
/// value is parsed first (several exemplars, channels, three-part values)
/// are applied by hand: [`HAND_FLAGS`].
macro_rules! flag_keys {
    ($($($flag:ident).+ => $($key:ident).+ : $how:ident),* $(,)?) => {
        impl RunFlags {
            /// Copies every set flag of the table to its key.
            fn apply_table(&self, config: &mut Config) {
                $( flag_keys!(@$how self.$($flag).+, config.$($key).+); )*
            }
        }

        /// (flag field, config key) of every row of the table; a flag field
        /// of a flattened group is written `group.field`.
        pub const FLAG_KEYS: &[(&str, &str)] = &[
            $((flag_keys!(@path $($flag).+), flag_keys!(@path $($key).+))),*
        ];
    };
    (@some $src:expr, $dst:expr) => { if let Some(v) = &$src { $dst = Some(v.to_owned()); } };
    (@value $src:expr, $dst:expr) => { if let Some(v) = &$src { $dst = v.to_owned(); } };
    (@off $src:expr, $dst:expr) => { if $src { $dst = false; } };
    (@on $src:expr, $dst:expr) => { if $src { $dst = Some(true); } };
    (@set $src:expr, $dst:expr) => { if $src { $dst = true; } };
    (@path $first:ident $(. $rest:ident)*) => {
        concat!(stringify!($first) $(, ".", stringify!($rest))*)
    };
}

flag_keys! {
    mesh => mesh: some,
    frames => frames: some,
    out => out: some,
    method => method: some,
    atlas => atlas: some,
    gutter => gutter: some,
    fps => fps: some,
    seed => seed: some,
    feature => feature: some,
    feature_method => feature_method: some,
    exemplar_filter => exemplar_filter: some,
    exemplar_select => exemplar_select: some,
    exemplar_region => exemplar_region: some,
    select_by => select_by: some,
    mismatch_rate => mismatch_rate: some,
    mismatch_gain => mismatch_gain: some,
    exemplar_rate => exemplar_rate: some,
    exemplar_memory => exemplar_memory: some,
    preview_video => preview_video: on,
    prim => prim: some,
    preset => preset: some,
    no_obj => outputs.obj: off,
    no_glb => outputs.glb: off,
    no_debug => outputs.debug: off,
    switch_map => outputs.switch_map: set,
    preview_every => outputs.preview_every: value,
}

/// Flags applied by hand in [`RunFlags::apply`] (their value is parsed
/// first), with the keys each sets.
pub const HAND_FLAGS: &[(&str, &[&str])] = &[
    ("exemplar", &["exemplar", "exemplars"]),
    ("channels", &["channels"]),
    ("velocity", &["velocity"]),
];

/// Config keys without a flag: rarely changed, set them in the file (the
/// README's run section lists them too).
pub const KEYS_WITHOUT_FLAG: &[&str] = &[
    "erosion.radius_fraction",
    "erosion.exemplar_scale",
    "erosion.normal_dot",
    "atlas_check.cells_per_diagonal",
    "atlas_check.cell",
    "outputs.preview_size",
];

impl RunFlags {
    /// Applies the flags that are set on top of `config`.
    pub fn apply(&self, config: &mut Config) -> Result<()> {
        self.apply_table(config);
        self.apply_exemplars(config)?;
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
        self.params
            .apply(&mut config.params)
            .map_err(|e| anyhow!(e))?;
        // A video needs previews: every frame unless the user chose.
        if config.preview_video == Some(true) && config.outputs.preview_every == 0 {
            config.outputs.preview_every = 1;
        }
        Ok(())
    }

    /// `--exemplar`: one replaces the config's exemplar(s); several become
    /// weighted `exemplars`.
    fn apply_exemplars(&self, config: &mut Config) -> Result<()> {
        match self.exemplar.as_slice() {
            [] => {}
            [one] => {
                let (path, _, range) = exemplar_spec(one)?;
                if range.is_some() {
                    bail!("--exemplar {one}: a range needs several exemplars to choose among");
                }
                config.exemplar = Some(path);
                config.exemplars.clear();
            }
            several => {
                config.exemplar = None;
                config.exemplars = several
                    .iter()
                    .map(|spec| {
                        let (path, weight, range) = exemplar_spec(spec)?;
                        Ok(ExemplarEntry {
                            path,
                            weight,
                            range,
                            ..Default::default()
                        })
                    })
                    .collect::<Result<_>>()?;
            }
        }
        Ok(())
    }
}

/// `IMG`, `IMG:WEIGHT`, `IMG@LO:HI` or `IMG:WEIGHT@LO:HI` of
/// `--exemplar`: the range is what follows the last `@` when it reads as
/// two numbers, the weight what follows the last `:` before it when it
/// reads as a number (so `C:\\tex\\a.png` stays a path).
fn exemplar_spec(spec: &str) -> Result<(PathBuf, Option<f32>, Option<[f32; 2]>)> {
    let mut rest = spec;
    let mut range = None;
    if let Some((head, tail)) = spec.rsplit_once('@')
        && !head.is_empty()
        && let Some((lo, hi)) = tail.split_once(':')
        && let (Ok(lo), Ok(hi)) = (lo.parse::<f32>(), hi.parse::<f32>())
    {
        fluidtex::exemplar::set::AttributeRange::new(lo, hi)
            .map_err(|e| anyhow!("--exemplar {spec}: {e}"))?;
        range = Some([lo, hi]);
        rest = head;
    }
    if let Some((path, w)) = rest.rsplit_once(':')
        && !path.is_empty()
        && let Ok(weight) = w.parse::<f32>()
    {
        if !(weight.is_finite() && weight > 0.0) {
            bail!("--exemplar {spec}: the weight must be a positive number");
        }
        return Ok((PathBuf::from(path), Some(weight), range));
    }
    Ok((PathBuf::from(rest), None, range))
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

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
        let flags = parse_flags(&[
            "--atlas",
            "512",
            "--epsilon",
            "0.05",
            "--placement",
            "global",
        ])
        .expect("valid flags");
        flags.apply(&mut c).expect("valid flags");
        assert_eq!(c.atlas, Some(512));
        assert_eq!(c.params.erosion.epsilon, 0.05);
        assert_eq!(c.params.erosion.radius, Some(0.5));
        assert_eq!(
            c.params.erosion.placement,
            fluidtex::methods::erosion::Placement::Global
        );
        // A flag two sections declare sets both; a bad value is refused
        // when the flags are read.
        let flags = parse_flags(&["--substeps", "3", "--up-axis", "-1,0,0"]).expect("valid");
        let mut c = Config::default();
        flags.apply(&mut c).expect("valid flags");
        assert_eq!(
            (c.params.erosion.substeps, c.params.optimization.substeps),
            (3, 3)
        );
        assert_eq!(c.params.erosion.up_axis, [-1.0, 0.0, 0.0]);
        for bad in [
            &["--epsilon", "small"][..],
            &["--up-axis", "1,0"],
            &["--placement", "nowhere"],
            &["--sizes", "33,x"],
        ] {
            assert!(parse_flags(bad).is_err(), "{bad:?} was accepted");
        }
    }

    /// `run`'s flags as clap reads them from `args`.
    fn parse_flags(args: &[&str]) -> Result<RunFlags, clap::Error> {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            flags: RunFlags,
        }
        Cli::try_parse_from(std::iter::once("run").chain(args.iter().copied())).map(|c| c.flags)
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
        // The method sections are read flattened, which loses toml's
        // positions: every kind of error still names its line.
        for (text, line, what) in [
            (
                "atlas = 1\nfoo = 2\n[erosion]\nradius = 0.5\n",
                2,
                "unknown field `foo`",
            ),
            (
                "\n[lapped_rigid]\nmask_softness = \"x\"\n",
                3,
                "expected f32",
            ),
            (
                "[erosion]\n[optimization]\nlevels = -1\n",
                3,
                "expected u32",
            ),
            ("[outputs]\nobj = 3\n", 2, "expected a boolean"),
            ("atlas = \"big\"\n", 1, "expected u32"),
        ] {
            let err = Config::parse(text, &path).expect_err(text).to_string();
            assert!(
                err.contains(&format!("bad.toml: line {line}: ")) && err.contains(what),
                "{text:?}: {err}"
            );
        }
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
        // The animated exemplars' budget changes no texture either.
        b.exemplar_memory = Some(64);
        assert_eq!(a.fingerprint(), b.fingerprint());
        b.exemplar_rate = Some(0.5);
        assert_ne!(a.fingerprint(), b.fingerprint());
        b.exemplar_rate = None;
        b.params.erosion.epsilon = 0.2;
        assert_ne!(a.fingerprint(), b.fingerprint());
    }

    use fluidtex::methods::atlas_check::AtlasCheckParams;
    use fluidtex::methods::dual_rest::DualRestParams;
    use fluidtex::methods::erosion::ErosionParams;
    use fluidtex::methods::lapped_rigid::LappedRigidParams;
    use fluidtex::methods::optimization::OptimizationParams;
    use fluidtex::methods::registry::field_names as fields_of;

    /// `--print-config` prints every method parameter, those left out of
    /// the fingerprint at their defaults included; only an unset option
    /// (TOML has no null) is absent.
    #[test]
    fn the_resolved_config_names_every_method_parameter() {
        fn missing<T: serde::Serialize + Default + for<'de> Deserialize<'de>>(
            table: &toml::Table,
            section: &str,
        ) -> Vec<String> {
            let defaults = serde_json::to_value(T::default()).expect("json");
            let printed = table.get(section).and_then(|v| v.as_table());
            fields_of::<T>()
                .iter()
                .filter(|f| defaults.get(**f).is_none_or(|v| !v.is_null()))
                .filter(|f| printed.is_none_or(|t| !t.contains_key(**f)))
                .map(|f| format!("{section}.{f}"))
                .collect()
        }
        let text = Config::default().resolved_toml().expect("toml");
        let table: toml::Table = toml::from_str(&text).expect("parse");
        let mut absent = missing::<ErosionParams>(&table, "erosion");
        absent.extend(missing::<LappedRigidParams>(&table, "lapped_rigid"));
        absent.extend(missing::<OptimizationParams>(&table, "optimization"));
        absent.extend(missing::<AtlasCheckParams>(&table, "atlas_check"));
        absent.extend(missing::<DualRestParams>(&table, "dual_rest"));
        assert!(absent.is_empty(), "not printed: {absent:?}\n{text}");
        // Known-bad control: a table without the later keys is caught.
        let mut cut = table.clone();
        if let Some(toml::Value::Table(o)) = cut.get_mut("optimization") {
            o.remove("relaxation");
        }
        assert_eq!(
            missing::<OptimizationParams>(&cut, "optimization"),
            ["optimization.relaxation"]
        );
    }

    /// A config with every field set, each named (no `..`): a field added
    /// to [`Config`] does not compile here until it is named, and then
    /// serialises, so [`config_keys`] sees it (serde cannot list the
    /// fields of a struct that flattens another).
    fn every_field_set() -> Config {
        let text = || Some(String::new());
        let file = || Some(PathBuf::new());
        Config {
            mesh: text(),
            frames: text(),
            out: file(),
            method: Some(MethodKind::default()),
            atlas: Some(0),
            gutter: Some(0),
            fps: Some(0.0),
            seed: Some(0),
            exemplar: file(),
            feature: file(),
            feature_method: text(),
            exemplar_filter: text(),
            channels: BTreeMap::new(),
            velocity: Some(Default::default()),
            params: MethodParams::default(),
            outputs: OutputOptions::default(),
            // Never serialised (it changes no texture): named in
            // `config_keys` by hand.
            preview_video: Some(true),
            prim: text(),
            exemplars: vec![ExemplarEntry::default()],
            exemplar_select: text(),
            exemplar_region: file(),
            select_by: text(),
            mismatch_rate: Some(0.0),
            mismatch_gain: Some(0.0),
            exemplar_rate: Some(0.0),
            exemplar_memory: Some(0),
            preset: text(),
        }
    }

    /// Every config key, `section.key` inside the method and output
    /// sections (tables of user names, `channels` and `exemplars`, are keys).
    fn config_keys() -> BTreeSet<String> {
        let mut sections = MethodParams::section_keys();
        sections.push(("outputs", fields_of::<OutputOptions>()));
        let json = serde_json::to_value(every_field_set()).expect("json");
        let own = json
            .as_object()
            .expect("an object")
            .keys()
            .map(String::as_str);
        let mut keys = BTreeSet::from(["channels".to_string(), "preview_video".to_string()]);
        keys.extend(own.map(str::to_string));
        for (s, fields) in sections {
            keys.remove(s);
            keys.extend(fields.iter().map(|f| format!("{s}.{f}")));
        }
        keys
    }

    /// The fields of `run`'s flags (clap ids: the field names).
    fn flag_fields() -> BTreeSet<String> {
        RunFlags::augment_args(clap::Command::new("run"))
            .get_arguments()
            .map(|a| a.get_id().to_string())
            .collect()
    }

    /// (flag id, config key) of the `flag_keys!` table and of every
    /// method's declared flags (a flag two sections declare is two rows).
    fn flag_rows() -> Vec<(String, String)> {
        FLAG_KEYS
            .iter()
            .map(|(f, k)| (f.to_string(), k.to_string()))
            .chain(
                MethodParams::flags()
                    .map(|(section, f)| (f.flag.to_string(), format!("{section}.{}", f.field))),
            )
            .collect()
    }

    /// Where the flag table, the hand-applied flags and the keys without a
    /// flag disagree with clap's flags and serde's keys, one line each.
    fn disagreements(
        flags: &BTreeSet<String>,
        keys: &BTreeSet<String>,
        without: &[&str],
    ) -> Vec<String> {
        let mut rows = flag_rows();
        for (flag, ks) in HAND_FLAGS {
            rows.extend(ks.iter().map(|k| (flag.to_string(), k.to_string())));
        }
        let leaf = |f: &str| f.rsplit('.').next().unwrap_or(f).to_string();
        let mut problems = Vec::new();
        for (flag, key) in &rows {
            if !flags.contains(&leaf(flag)) {
                problems.push(format!("the table names flag {flag}, which RunFlags lacks"));
            }
            if !keys.contains(key) {
                problems.push(format!("the table names key {key}, which Config lacks"));
            }
        }
        for key in without {
            if !keys.contains(*key) {
                problems.push(format!("KEYS_WITHOUT_FLAG names {key}, which Config lacks"));
            }
            if rows.iter().any(|r| r.1 == *key) {
                problems.push(format!("KEYS_WITHOUT_FLAG names {key}, which a flag sets"));
            }
        }
        for f in flags
            .iter()
            .filter(|f| !rows.iter().any(|r| leaf(&r.0) == **f))
        {
            problems.push(format!("flag {f} sets no key: add a row to flag_keys!"));
        }
        for k in keys
            .iter()
            .filter(|k| !rows.iter().any(|r| r.1 == **k) && !without.contains(&k.as_str()))
        {
            problems.push(format!(
                "config key {k} has no flag: add one to RunFlags and flag_keys!, or list it in \
                 KEYS_WITHOUT_FLAG"
            ));
        }
        problems
    }

    #[test]
    fn every_flag_sets_a_key_and_every_key_has_a_flag_or_is_listed() {
        let problems = disagreements(&flag_fields(), &config_keys(), KEYS_WITHOUT_FLAG);
        assert!(problems.is_empty(), "{problems:#?}");
        // Both sides were really read (the introspection found the keys).
        assert!(config_keys().contains("lapped_rigid.sink_fade_rate"));
        assert!(
            config_keys().contains("exemplar_region"),
            "skipped when unset"
        );
        assert!(
            flag_fields().contains("rigid-radius"),
            "a method's declared flag"
        );
    }

    /// Known-bad controls: a key without a flag, a flag without a key and
    /// a stale exception are each reported.
    #[test]
    fn a_key_or_flag_on_one_side_only_is_caught() {
        let (flags, keys) = (flag_fields(), config_keys());
        let mut more_keys = keys.clone();
        more_keys.insert("erosion.invented".into());
        let p = disagreements(&flags, &more_keys, KEYS_WITHOUT_FLAG);
        assert!(
            p.iter()
                .any(|l| l.contains("config key erosion.invented has no flag")),
            "{p:#?}"
        );
        let mut more_flags = flags.clone();
        more_flags.insert("invented".into());
        let p = disagreements(&more_flags, &keys, KEYS_WITHOUT_FLAG);
        assert!(
            p.iter().any(|l| l.contains("flag invented sets no key")),
            "{p:#?}"
        );
        let p = disagreements(&flags, &keys, &["outputs.preview_size", "erosion.radius"]);
        assert!(
            p.iter()
                .any(|l| l.contains("erosion.radius, which a flag sets")),
            "{p:#?}"
        );
        assert!(
            p.iter()
                .any(|l| l.contains("erosion.normal_dot has no flag")),
            "{p:#?}"
        );
    }

    /// Each row's flag, applied alone, changes its key.
    #[test]
    fn each_table_row_sets_its_key() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            flags: RunFlags,
        }
        let cmd = <Cli as clap::CommandFactory>::command();
        // `preview_video` is never serialised (it is not part of the
        // fingerprint), so it is put back to be compared like the others.
        let json = |c: &Config| {
            let mut v = serde_json::to_value(c).expect("json");
            v["preview_video"] = serde_json::json!(c.preview_video);
            v
        };
        let default = json(&Config::default());
        for (flag, key) in flag_rows() {
            let leaf = flag.rsplit('.').next().unwrap_or(&flag);
            let arg = cmd
                .get_arguments()
                .find(|a| a.get_id() == leaf)
                .unwrap_or_else(|| panic!("{flag}: no such flag"));
            let long = format!("--{}", arg.get_long().unwrap_or(leaf));
            let changed = [
                "7",
                "0.5",
                "a",
                "global",
                "paper",
                "full",
                "random",
                "aligned",
                "advect",
                "none",
                "distance",
                "histogram",
                "off",
                "exact",
                "vertex",
                "polar",
                "kept",
                "repulsion",
                "grid",
                "3,3,3",
            ]
            .iter()
            .map(|v| vec!["run", long.as_str(), v])
            .chain([vec!["run", long.as_str()]])
            .filter_map(|args| Cli::try_parse_from(args).ok())
            .any(|cli| {
                let mut c = Config::default();
                cli.flags.apply(&mut c).expect("apply");
                let now = json(&c);
                let at = |v: &serde_json::Value| {
                    key.split('.').try_fold(v.clone(), |v, k| v.get(k).cloned())
                };
                at(&now) != at(&default)
            });
            assert!(changed, "{long} does not change {key}");
        }
    }

    /// The value at dotted `key` of a resolved config's TOML (`None`: the
    /// key is unset, e.g. an optional setting left to its default).
    fn at<'a>(table: &'a toml::Table, key: &str) -> Option<&'a toml::Value> {
        let mut parts = key.split('.');
        let mut value = table.get(parts.next().unwrap_or_default());
        for part in parts {
            value = value.and_then(|v| v.get(part));
        }
        value
    }

    /// `--preset paper` resolves every key the ledger's paper column names
    /// to that value, and each of them differs from the default (it is a
    /// departure); a key the file sets wins over the preset, a `--preset`
    /// flag works without a file, and an unknown preset is refused.
    #[test]
    fn the_paper_preset_resolves_to_the_ledgers_paper_column() {
        let preset: toml::Table =
            toml::from_str(&fluidtex::departures::paper_preset()).expect("ledger TOML");
        let mut keys = Vec::new();
        for (section, value) in &preset {
            match value {
                toml::Value::Table(t) => keys.extend(t.keys().map(|k| format!("{section}.{k}"))),
                _ => keys.push(section.clone()),
            }
        }
        assert!(keys.len() >= 12, "{keys:?}");
        let resolve = |config: &Config| -> toml::Table {
            toml::from_str(&config.resolved_toml().expect("toml")).expect("parse")
        };
        let paper = resolve(&Config::parse("preset = \"paper\"", Path::new("c.toml")).unwrap());
        let flag = resolve(&Config::load_with_preset(None, Some("paper")).unwrap());
        let default = resolve(&Config::default());
        assert_eq!(paper, flag);
        // Parameters are f32: the ledger's 2.4 reads back as 2.4000000953674316.
        let same = |a: Option<&toml::Value>, b: Option<&toml::Value>| match (
            a.and_then(|v| v.as_float()),
            b.and_then(|v| v.as_float()),
        ) {
            (Some(x), Some(y)) => x as f32 == y as f32,
            _ => a == b,
        };
        for key in &keys {
            assert!(same(at(&paper, key), at(&preset, key)), "{key}");
            assert!(
                !same(at(&default, key), at(&preset, key)),
                "{key} is no departure"
            );
        }
        let own = "preset = \"paper\"\n[erosion]\ntone = \"mean\"\n";
        let own = resolve(&Config::parse(own, Path::new("c.toml")).unwrap());
        assert_eq!(
            at(&own, "erosion.tone").and_then(|v| v.as_str()),
            Some("mean")
        );
        assert_eq!(
            at(&own, "erosion.weights").and_then(|v| v.as_str()),
            Some("paper")
        );
        let err = Config::parse("preset = \"papr\"", Path::new("c.toml")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "c.toml: preset = \"papr\": the one preset is \"paper\""
        );
    }
}
