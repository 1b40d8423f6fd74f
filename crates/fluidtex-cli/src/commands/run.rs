//! `fluidtex run`: texture a mesh sequence.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Error, Result, anyhow, bail};
use clap::Args;
use fluidtex::atlas::AtlasParams;
use fluidtex::exemplar::bubbles::BUBBLE_FRAMES;
use fluidtex::exemplar::set::{AttributeRange, SelectBy};
use fluidtex::exemplar::{
    Exemplar, ExemplarClock, ExemplarFilter, ExemplarSelect, ExemplarSet, FeatureMethod, LavaState,
    RegionImage, SequenceBudget, SequenceFiles, builtin_bubbles, builtin_lava, builtin_pebbles,
    is_sequence, load_sequence,
};
use fluidtex::io::ReadOptions;
use fluidtex::methods::{Method, Stat, StatsExt};
use fluidtex::named::Named;
use fluidtex::pipeline::{self, Event, FrameSource, Job, Phase, SequenceSource};

use crate::config::{Config, RunFlags};
use crate::progress::Progress;

#[derive(Args, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    pub flags: RunFlags,
    /// TOML config file; flags override its values
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Continue a killed run from the last finished frame in --out
    #[arg(long)]
    pub resume: bool,
    /// Print every resolved parameter (defaults, --preset, --config, flags)
    /// as TOML and exit
    #[arg(long)]
    pub print_config: bool,
    /// No progress bar and no summary
    #[arg(long)]
    pub quiet: bool,
    /// Stop after the frame that leaves the run holding more than SIZE of
    /// memory, or inside a stage that grows past it within a frame (e.g.
    /// 5.5G, 800M; 0: never) [what the machine has available at the start,
    /// less a tenth]
    #[arg(long, value_name = "SIZE")]
    pub max_memory: Option<String>,
    /// Run in two phases, for a render farm: `select` is the sequential
    /// pass (per frame selection.F.bin and state.bin, no channels);
    /// `resample` writes every file of the frames in --frames from their
    /// selections, ranges in any order, in separate processes [one-pass]
    #[arg(long, value_parser = crate::config::named::<Phase>(), default_value = "one-pass")]
    pub phase: Phase,
}

/// Size of the built-in exemplar in texels.
pub const BUILTIN_EXEMPLAR_SIZE: u32 = 512;

pub fn run(a: &RunArgs) -> Result<()> {
    let mut config = Config::load_with_preset(a.config.as_deref(), a.flags.preset.as_deref())?;
    a.flags.apply(&mut config)?;
    if a.print_config {
        print!("{}", config.resolved_toml()?);
        return Ok(());
    }
    let limit = memory_limit(a.max_memory.as_deref())?;
    let pattern = config
        .mesh
        .clone()
        .context("no mesh sequence: give --mesh PATTERN (or `mesh = ...` in the config)")?;
    let out = config
        .out
        .clone()
        .context("no output folder: give --out DIR")?;
    let options = config_read_options(&config)?;
    if crate::usd::is_usd(&pattern) {
        let mut source = crate::usd::UsdSource::open_with(
            &pattern,
            config.prim.as_deref(),
            config.frames.as_deref(),
            options,
        )?;
        return execute(&config, out, &mut source, a.resume, a.quiet, limit, a.phase);
    }
    let mut source = SequenceSource::open(&pattern, config.frames.as_deref(), options)?;
    execute(&config, out, &mut source, a.resume, a.quiet, limit, a.phase)
}

/// The run's memory limit: `--max-memory` (0: none), or by default what
/// the machine has available at the start less a tenth.
pub fn memory_limit(flag: Option<&str>) -> Result<Option<u64>> {
    match flag {
        None => Ok(fluidtex::output::default_memory_limit()),
        Some(text) => {
            let bytes =
                fluidtex::output::parse_size(text).map_err(|e| anyhow!("--max-memory {e}"))?;
            Ok((bytes > 0).then_some(bytes))
        }
    }
}

/// Runs the configured method over `source` into `out` with a progress
/// bar, stopping after the frame that passes `max_memory` bytes.
pub fn execute(
    config: &Config,
    out: PathBuf,
    source: &mut dyn FrameSource,
    resume: bool,
    quiet: bool,
    max_memory: Option<u64>,
    phase: Phase,
) -> Result<()> {
    let mut notes = Vec::new();
    let mut method = build_method_noting(config, &mut notes)?;
    let mut job = build_job(config, out.clone(), resume)?;
    job.max_memory = max_memory;
    job.phase = phase;
    let total = source.frames().len() as u64;
    let progress = Progress::new(total, method.name(), quiet);
    // Stated before the first frame: what animated exemplars take.
    for note in &notes {
        progress.info(note);
    }
    let mut estimated = None;
    let mut observer = |e: Event<'_>| match e {
        Event::Start { number, .. } => progress.set_message(format!("frame {number}")),
        Event::Done { stats } => {
            // Say once which patch radius the method chose, and why.
            if let Some(rule) = stats.method_stats.text(Stat::RadiusRule) {
                progress.info(&format!("patch radius: {rule}"));
            }
            let patches = stats
                .method_stats
                .value(Stat::PatchesAlive)
                .map(|p| format!(", {p} patches"))
                .unwrap_or_default();
            let secs: f64 = stats.seconds.values().sum();
            progress.set_message(format!("frame {} done in {secs:.2}s{patches}", stats.frame));
            progress.inc();
        }
        Event::Warning(w) => progress.warn(&w),
        Event::Memory(m) => {
            progress.info(&format!("memory: {}", m.describe()));
            estimated = Some(m.bytes);
        }
    };
    let summary = pipeline::run(&job, source, method.as_mut(), &mut observer)?;
    progress.finish();
    if !quiet {
        if let Some(f) = summary.resumed_after {
            eprintln!("resumed after frame {f}");
        }
        let per = if summary.frames_done > 0 {
            summary.seconds / summary.frames_done as f64
        } else {
            0.0
        };
        eprintln!(
            "{}: {} frames in {:.1} s ({per:.2} s/frame) -> {}",
            method.name(),
            summary.frames_done,
            summary.seconds,
            out.display()
        );
        // How close the up-front estimate came: a user sizing farm nodes
        // reads the real peak here.
        if let (Some(peak), Some(estimate)) = (fluidtex::output::peak_memory(), estimated) {
            eprintln!(
                "peak memory {} (estimated {})",
                fluidtex::output::gib(peak),
                fluidtex::output::gib(estimate)
            );
        }
    }
    // --preview-video: a post-step; a missing ffmpeg is said, not an error.
    if config.preview_video == Some(true) && phase != Phase::Select {
        let every = config.outputs.preview_every;
        let outcome = super::preview_video::write(&out, job.fps, every)?;
        eprintln!("{}", outcome.describe());
    }
    Ok(())
}

/// The frames `fluidtex run` would process for `config`'s sequence at
/// `pattern` (a file sequence or a USD stage).
pub fn frames_of(config: &Config, pattern: &str) -> Result<Vec<i32>> {
    if crate::usd::is_usd(pattern) {
        let source =
            crate::usd::UsdSource::open(pattern, config.prim.as_deref(), config.frames.as_deref())?;
        return Ok(source.frames());
    }
    let options = config_read_options(config)?;
    Ok(SequenceSource::open(pattern, config.frames.as_deref(), options)?.frames())
}

/// The reader options of `config`: its velocity properties, and the
/// attribute that selects the exemplars, which every frame must carry.
fn config_read_options(config: &Config) -> Result<ReadOptions> {
    let mut options = read_options(config.velocity.as_ref().map(|v| v.as_slice()))?;
    options
        .scalar_attributes
        .extend(config.select_by.iter().cloned());
    Ok(options)
}

/// The reader options for `--velocity a,b,c`.
pub fn read_options(velocity: Option<&[String]>) -> Result<ReadOptions> {
    let mut o = ReadOptions::default();
    match velocity {
        None => {}
        Some([a, b, c]) => o.velocity_properties = Some([a.clone(), b.clone(), c.clone()]),
        Some(other) => bail!("--velocity needs three property names, got {}", other.len()),
    }
    Ok(o)
}

/// The config's feature-map method and exemplar filter, each its default
/// where the config names none.
fn feature_settings(config: &Config) -> Result<(FeatureMethod, ExemplarFilter)> {
    let method = match config.feature_method.as_deref() {
        None => FeatureMethod::default(),
        Some(name) => FeatureMethod::parse_named("feature method", name).map_err(Error::msg)?,
    };
    let filter = match config.exemplar_filter.as_deref() {
        None => ExemplarFilter::default(),
        Some(name) => ExemplarFilter::parse_named("exemplar filter", name).map_err(Error::msg)?,
    };
    Ok((method, filter))
}

/// The exemplar the config names, or the built-in pebbles: its frames
/// (one for a still image).
fn build_exemplar_frames(config: &Config, budget: &mut Budget) -> Result<Vec<Exemplar>> {
    let (method, filter) = feature_settings(config)?;
    let channels: Vec<(String, PathBuf)> = config
        .channels
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let seed = config.seed.unwrap_or(0);
    let frames = match &config.exemplar {
        Some(path) => {
            let files = SequenceFiles {
                colour: path,
                channels: &channels,
                feature: config.feature.as_deref(),
            };
            load_frames(&files, method, seed, budget)?
        }
        None => {
            if !channels.is_empty() || config.feature.is_some() {
                bail!(
                    "--channel and --feature need --exemplar (the built-in pebbles carry their own)"
                );
            }
            vec![builtin_pebbles(BUILTIN_EXEMPLAR_SIZE, seed)]
        }
    };
    Ok(frames.into_iter().map(|e| e.with_filter(filter)).collect())
}

/// Prefix of the built-in exemplars' names (`builtin:glow`).
pub const BUILTIN_PREFIX: &str = "builtin:";

/// The built-in exemplars by name: the pebbles of the demo, the two lava
/// states of selection by temperature and the animated bubbles.
pub const BUILTIN_EXEMPLARS: &[&str] = &["pebbles", "glow", "crust", "bubbles"];

/// Texels per side of the built-in bubbles' frames: 16 frames at 512²
/// would hold 130 MiB for a demo.
const BUBBLES_SIZE: u32 = 256;

/// What the animated exemplars may still take ([`SequenceBudget`]), as the
/// entries are loaded one after another.
struct Budget {
    limit: SequenceBudget,
    used: u64,
}

impl Budget {
    fn of(config: &Config) -> Budget {
        Budget {
            limit: config
                .exemplar_memory
                .map_or_else(SequenceBudget::default, |mib| SequenceBudget {
                    bytes: mib.saturating_mul(1 << 20),
                }),
            used: 0,
        }
    }
}

/// The frames of one exemplar: a sequence (`bubbles.####.png`, within the
/// budget), a built-in (`builtin:NAME`, which carries its own feature map
/// and has no extra channels) or one image.
fn load_frames(
    files: &SequenceFiles<'_>,
    method: FeatureMethod,
    seed: u64,
    budget: &mut Budget,
) -> Result<Vec<Exemplar>> {
    let path = files.colour;
    if is_sequence(path) {
        let (frames, bytes) = load_sequence(files, method, budget.limit, budget.used)?;
        budget.used += bytes;
        return Ok(frames);
    }
    let Some(name) = path.to_str().and_then(|p| p.strip_prefix(BUILTIN_PREFIX)) else {
        return Ok(vec![Exemplar::load(
            path,
            files.channels,
            files.feature,
            method,
        )?]);
    };
    if !files.channels.is_empty() || files.feature.is_some() {
        bail!(
            "{}: a built-in exemplar carries its own feature map and no extra channels",
            path.display()
        );
    }
    let size = BUILTIN_EXEMPLAR_SIZE;
    Ok(match name {
        "pebbles" => vec![builtin_pebbles(size, seed)],
        "glow" => vec![builtin_lava(LavaState::Glow, size, seed)],
        "crust" => vec![builtin_lava(LavaState::Crust, size, seed)],
        "bubbles" => {
            let frames = builtin_bubbles(BUBBLES_SIZE, BUBBLE_FRAMES, seed);
            budget.used += frames.iter().map(Exemplar::memory_bytes).sum::<u64>();
            frames
        }
        _ => bail!(
            "{}: no such built-in exemplar; available: {}",
            path.display(),
            BUILTIN_EXEMPLARS
                .iter()
                .map(|n| format!("{BUILTIN_PREFIX}{n}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    })
}

/// The exemplars the config names: `exemplars` (several per surface) or
/// the one exemplar of [`build_exemplar_frames`]; animated ones advance at the
/// config's `exemplar_rate`.
pub fn build_exemplar_set(config: &Config) -> Result<ExemplarSet> {
    let set = build_exemplar_entries(config)?;
    let set = match config.exemplar_rate {
        Some(_) if !set.is_animated() => bail!(
            "--exemplar-rate needs an animated exemplar (an image sequence such as \
             bubbles.####.png, or builtin:bubbles)"
        ),
        Some(rate) => set.with_clock(ExemplarClock::new(rate)?),
        None => set,
    };
    Ok(set)
}

/// What a run says of its animated exemplars before the first frame:
/// their frames, rate and memory against the budget.
fn animation_notes(set: &ExemplarSet, config: &Config) -> Vec<String> {
    set.animation_summary(Budget::of(config).limit.bytes)
}

fn build_exemplar_entries(config: &Config) -> Result<ExemplarSet> {
    let select = match config.exemplar_select.as_deref() {
        None => ExemplarSelect::default(),
        Some(name) => {
            ExemplarSelect::parse_named("exemplar selection", name).map_err(Error::msg)?
        }
    };
    let mut budget = Budget::of(config);
    if config.exemplars.is_empty() {
        if config.select_by.is_some() {
            bail!(
                "--select-by needs several exemplars, each with its range \
                 (--exemplar IMG@LO:HI, repeated)"
            );
        }
        if config.exemplar_region.is_some() {
            bail!("--exemplar-region needs several exemplars (--exemplar IMG:WEIGHT, repeated)");
        }
        let mut frames = build_exemplar_frames(config, &mut budget)?;
        if frames.len() == 1 {
            return Ok(ExemplarSet::single(Arc::new(frames.remove(0))));
        }
        let name = config
            .exemplar
            .as_ref()
            .map_or_else(|| "exemplar".into(), |p| p.display().to_string());
        let frames = frames.into_iter().map(Arc::new).collect();
        return Ok(ExemplarSet::animated(
            vec![(name, frames, 1.0)],
            ExemplarSelect::default(),
            None,
        )?);
    }
    if config.exemplar.is_some() || !config.channels.is_empty() || config.feature.is_some() {
        bail!(
            "several exemplars: give each its feature map and channels in the config's \
             `exemplars` entries, not with exemplar, --feature or --channel"
        );
    }
    let (method, filter) = feature_settings(config)?;
    let seed = config.seed.unwrap_or(0);
    let mut entries = Vec::with_capacity(config.exemplars.len());
    for e in &config.exemplars {
        let channels: Vec<(String, PathBuf)> = e
            .channels
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        let files = SequenceFiles {
            colour: &e.path,
            channels: &channels,
            feature: e.feature.as_deref(),
        };
        let frames = load_frames(&files, method, seed, &mut budget)?;
        entries.push((
            e.path.display().to_string(),
            frames
                .into_iter()
                .map(|x| Arc::new(x.with_filter(filter)))
                .collect(),
            e.weight.unwrap_or(1.0),
        ));
    }
    let region = match &config.exemplar_region {
        Some(path) => Some(RegionImage::load(path)?),
        None => None,
    };
    let set = ExemplarSet::animated(entries, select, region)?;
    match select_by(config)? {
        Some(by) => Ok(set.with_select_by(by)?),
        None => Ok(set),
    }
}

/// The config's selection by attribute: `select_by` with every exemplar's
/// `range` (and `mismatch_rate`, `mismatch_gain`); ranges, a rate or a
/// gain without `select_by`, or an exemplar without its range, are
/// refused with the entry named.
fn select_by(config: &Config) -> Result<Option<SelectBy>> {
    let Some(attribute) = &config.select_by else {
        if let Some(e) = config.exemplars.iter().find(|e| e.range.is_some()) {
            bail!(
                "exemplar {}: a range needs --select-by ATTR (the attribute it ranges over)",
                e.path.display()
            );
        }
        if config.mismatch_rate.is_some() {
            bail!("mismatch_rate needs --select-by ATTR");
        }
        if config.mismatch_gain.is_some() {
            bail!("mismatch_gain needs --select-by ATTR");
        }
        if config.exemplar_select.as_deref() == Some("attribute") {
            bail!(
                "--exemplar-select attribute needs --select-by ATTR (the attribute to choose by)"
            );
        }
        return Ok(None);
    };
    if attribute.is_empty() {
        bail!("--select-by needs an attribute name");
    }
    if config
        .exemplar_select
        .as_deref()
        .is_some_and(|s| s != "attribute")
    {
        bail!(
            "--select-by {attribute} chooses by the attribute: it cannot be combined with \
             --exemplar-select {}",
            config.exemplar_select.as_deref().unwrap_or_default()
        );
    }
    let mut ranges = Vec::with_capacity(config.exemplars.len());
    for e in &config.exemplars {
        let Some([lo, hi]) = e.range else {
            bail!(
                "--select-by {attribute}: exemplar {} has no range (give IMG@LO:HI, or \
                 `range = [lo, hi]` in its [[exemplars]] entry)",
                e.path.display()
            );
        };
        ranges.push(
            AttributeRange::new(lo, hi)
                .map_err(|m| anyhow!("exemplar {}: {m}", e.path.display()))?,
        );
    }
    let mut by = SelectBy::new(attribute.clone(), ranges);
    if let Some(rate) = config.mismatch_rate {
        by = by.with_mismatch_rate(rate).map_err(Error::msg)?;
    }
    if let Some(gain) = config.mismatch_gain {
        by = by.with_mismatch_gain(gain).map_err(Error::msg)?;
    }
    Ok(Some(by))
}

/// The method the config names, its parameters checked before the
/// exemplar is read.
pub fn build_method(config: &Config) -> Result<Box<dyn Method>> {
    build_method_noting(config, &mut Vec::new())
}

/// [`build_method`] over exemplars already built: `compare` builds them
/// once (decoding an image, generating a built-in, reading a sequence) for
/// every scene and method it runs.
pub fn build_method_over(config: &Config, set: &ExemplarSet) -> Result<Box<dyn Method>> {
    config
        .params
        .build_set(config.method_kind(), config.seed.unwrap_or(0), || {
            Ok::<_, Error>(set.clone())
        })
}

/// [`build_method`], adding to `notes` what the run should say of its
/// exemplars before the first frame.
fn build_method_noting(config: &Config, notes: &mut Vec<String>) -> Result<Box<dyn Method>> {
    config
        .params
        .build_set(config.method_kind(), config.seed.unwrap_or(0), || {
            let set = build_exemplar_set(config)?;
            notes.extend(animation_notes(&set, config));
            Ok(set)
        })
}

/// The frame job the config describes.
pub fn build_job(config: &Config, out: PathBuf, resume: bool) -> Result<Job> {
    let size = config.atlas.unwrap_or(4096);
    // The library's own limit, so a size it would refuse is refused here,
    // before any frame is read.
    let max = fluidtex::atlas::MAX_SIDE;
    if !(16..=max).contains(&size) {
        bail!("--atlas {size}: allowed 16 to {max} texels");
    }
    let fps = config.fps.unwrap_or(24.0);
    if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
        bail!("--fps {fps}: must be a number in (0, 10000]");
    }
    let mut atlas = AtlasParams {
        width: size,
        height: size,
        ..Default::default()
    };
    if let Some(g) = config.gutter {
        if g > 64 {
            bail!("--gutter {g}: allowed 0 to 64 texels");
        }
        atlas.gutter = g;
    }
    Ok(Job {
        out_dir: out,
        atlas,
        fps,
        outputs: config.outputs.clone(),
        resume,
        fingerprint: config.fingerprint(),
        max_memory: None,
        phase: Default::default(),
        hooks: crate::test_hooks::from_env()?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exemplar_filter_is_trilinear_unless_asked_otherwise() {
        let with = |value: Option<&str>| {
            build_exemplar_set(&Config {
                exemplar_filter: value.map(str::to_string),
                ..Default::default()
            })
        };
        let filter = |set: ExemplarSet| set.primary().filter;
        assert_eq!(
            filter(with(None).expect("valid")),
            ExemplarFilter::Trilinear
        );
        assert_eq!(
            filter(with(Some("trilinear")).expect("valid")),
            ExemplarFilter::Trilinear
        );
        assert_eq!(
            filter(with(Some("none")).expect("valid")),
            ExemplarFilter::Unfiltered
        );
        let err = with(Some("bicubic")).expect_err("unknown filter");
        assert!(err.to_string().contains("trilinear, none"), "{err}");
    }
}
