//! `fluidtex farm`: a shot as jobs of an existing scheduler, in the two
//! phases of `fluidtex run --phase` (see the library's `pipeline::phases`).
//! Every job runs `fluidtex run` with the shot's own arguments (given after
//! `--`, exactly as to `fluidtex run`) plus `--phase`, `--frames` for its
//! chunk and `--resume`, so a killed or requeued job goes on from its last
//! finished frame.
//!
//! - `farm slurm`: phase 1 runs as a chain of array tasks, one per chunk of
//!   frames, one at a time; phase-2 task k depends on phase-1 task k only
//!   (`aftercorr`), so a chunk is resampled while phase 1 goes on with the
//!   next ones. The scripts are written to `OUT/farm/`, with logs in
//!   `OUT/farm/logs/`; `--submit` hands them to `sbatch`.
//! - `farm openjd`: an Open Job Description job template (`openjd.rs`), the
//!   format of AWS Deadline Cloud and of the `openjd` command line.
//!
//! No scheduler of our own: the cluster's, through its command line.

mod openjd;

use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};

use crate::config::Config;

#[derive(Args, Debug)]
pub struct FarmArgs {
    #[command(subcommand)]
    pub scheduler: Scheduler,
}

#[derive(Subcommand, Debug)]
pub enum Scheduler {
    /// Write (and with --submit, submit) a shot's Slurm jobs: fluidtex farm
    /// slurm [OPTIONS] -- RUN ARGUMENTS (as for `fluidtex run`), or
    /// --shots FILE for several
    Slurm(SlurmArgs),
    /// Write a shot's Open Job Description job template (a Deadline Cloud
    /// job bundle; `openjd run` runs it on this machine): fluidtex farm
    /// openjd [OPTIONS] -- RUN ARGUMENTS, or --shots FILE for several
    Openjd(openjd::OpenjdArgs),
}

/// What every scheduler's command takes: the shot (or shots) and how its
/// frames are split.
#[derive(Args, Debug)]
pub struct ShotArgs {
    /// Frames per phase-2 task [10]
    #[arg(long, default_value_t = 10)]
    pub chunk: u32,
    /// CPUs per job, and fluidtex's threads in it (Slurm: --cpus-per-task;
    /// Open Job Description: the worker's vCPUs, at least) [2]
    #[arg(long, default_value_t = 2)]
    pub cpus: u32,
    /// Several shots: a TOML file of `[[shot]]` tables, each with `args`
    /// (its `fluidtex run` arguments) and an optional `name`
    #[arg(long, value_name = "FILE", conflicts_with = "run")]
    pub shots: Option<PathBuf>,
    /// The shot: `fluidtex run` arguments (--mesh, --out, settings), after `--`
    #[arg(
        last = true,
        required_unless_present = "shots",
        value_name = "RUN ARGUMENTS"
    )]
    pub run: Vec<OsString>,
}

#[derive(Args, Debug)]
pub struct SlurmArgs {
    #[command(flatten)]
    pub shot: ShotArgs,
    /// Slurm partition of every job (sbatch --partition) [the cluster's default]
    #[arg(long)]
    pub partition: Option<String>,
    /// Time limit per job (sbatch --time, e.g. 2:00:00) [the partition's]
    #[arg(long)]
    pub time: Option<String>,
    /// Submit the jobs through sbatch (otherwise only write the scripts)
    #[arg(long)]
    pub submit: bool,
}

/// `--shots FILE`: one table per shot.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ShotsFile {
    shot: Vec<ShotEntry>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ShotEntry {
    /// For messages [shot N].
    name: Option<String>,
    /// The shot's `fluidtex run` arguments, as after `--`.
    args: Vec<String>,
}

/// The shots of `--shots FILE`, each with the name messages give it, or
/// the one after `--` (no name).
fn listed_shots(a: &ShotArgs) -> Result<Vec<(Option<String>, Vec<OsString>)>> {
    let Some(path) = &a.shots else {
        return Ok(vec![(None, a.run.clone())]);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read it", path.display()))?;
    let file: ShotsFile = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message().replace('\n', " ")))?;
    if file.shot.is_empty() {
        bail!("{}: no [[shot]] table", path.display());
    }
    Ok(file
        .shot
        .into_iter()
        .enumerate()
        .map(|(k, s)| {
            let name = s.name.unwrap_or_else(|| format!("shot {}", k + 1));
            let label = format!("{}: {name}", path.display());
            (
                Some(label),
                s.args.into_iter().map(OsString::from).collect(),
            )
        })
        .collect())
}

pub fn farm(a: &FarmArgs) -> Result<()> {
    match &a.scheduler {
        Scheduler::Slurm(s) => {
            for (_, shot) in checked_shots(&s.shot)? {
                write_shot(s, &shot)?;
            }
            Ok(())
        }
        Scheduler::Openjd(o) => {
            for (_, shot) in checked_shots(&o.shot)? {
                openjd::write_template(&o.shot, &shot)?;
            }
            Ok(())
        }
    }
}

/// A shot, as its jobs see it.
struct Shot {
    /// The run arguments without `--frames` (each job gives its own).
    args: Vec<OsString>,
    out: PathBuf,
    first: i32,
    last: i32,
    /// Where relative paths in the arguments are relative to.
    workdir: PathBuf,
    binary: PathBuf,
}

/// Every shot of `a`, checked before anything is written or submitted,
/// each with the label its messages carry ("" for the one after `--`).
fn checked_shots(a: &ShotArgs) -> Result<Vec<(String, Shot)>> {
    if a.chunk == 0 {
        bail!("--chunk 0: give at least one frame per task");
    }
    if !(1..=4096).contains(&a.cpus) {
        bail!("--cpus {}: allowed 1 to 4096", a.cpus);
    }
    let mut shots = Vec::new();
    for (label, run) in listed_shots(a)? {
        let s = match &label {
            Some(label) => shot(&run).with_context(|| label.clone())?,
            None => shot(&run)?,
        };
        let label = label.unwrap_or_default();
        if let Some((other, _)) = shots.iter().find(|(_, o): &&(String, Shot)| o.out == s.out) {
            bail!("{label}: writes into {} as {other} does", s.out.display());
        }
        shots.push((label, s));
    }
    Ok(shots)
}

impl Shot {
    /// Phase-2 tasks of `chunk` frames each (the last may hold fewer).
    fn tasks(&self, chunk: u32) -> u32 {
        ((i64::from(self.last) - i64::from(self.first)) / i64::from(chunk) + 1) as u32
    }
}

/// Writes one shot's scripts (and submits them, with `--submit`).
fn write_shot(a: &SlurmArgs, shot: &Shot) -> Result<()> {
    let farm = shot.out.join("farm");
    std::fs::create_dir_all(farm.join("logs"))
        .with_context(|| format!("{}: cannot create the folder", farm.display()))?;
    let tasks = shot.tasks(a.shot.chunk);
    let select = farm.join("select.sbatch");
    let resample = farm.join("resample.sbatch");
    write_script(&select, &select_script(a, shot, tasks))?;
    write_script(&resample, &resample_script(a, shot, tasks))?;
    write_script(&farm.join("submit.sh"), &submit_script(&select, &resample))?;
    println!(
        "{}: {tasks} chunks of {} frames, phase 1 in {}, phase 2 in {}",
        shot.out.display(),
        a.shot.chunk,
        select.display(),
        resample.display()
    );
    if a.submit {
        let first = sbatch(&[select.as_os_str()])?;
        let dependency = OsString::from(format!("--dependency=aftercorr:{first}"));
        let second = sbatch(&[dependency.as_os_str(), resample.as_os_str()])?;
        println!("submitted: phase 1 array job {first}, phase 2 array job {second}");
    }
    Ok(())
}

/// The shot the run arguments describe: checked as `fluidtex run` checks
/// them, its frames found on disk (or in the stage).
fn shot(run: &[OsString]) -> Result<Shot> {
    for arg in run {
        let text = arg.to_string_lossy();
        for own in ["--phase", "--resume"] {
            if text == own || text.starts_with(&format!("{own}=")) {
                bail!("{own}: the farm gives each job its own; leave it out of the run arguments");
            }
        }
    }
    let mut argv: Vec<OsString> = vec!["fluidtex".into(), "run".into()];
    argv.extend(run.iter().cloned());
    let crate::Cli {
        command: crate::Command::Run(r),
    } = crate::Cli::try_parse_from(&argv)?
    else {
        bail!("the run arguments do not parse as `fluidtex run`");
    };
    let mut config = match &r.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    r.flags.apply(&mut config)?;
    let pattern = config
        .mesh
        .clone()
        .context("no mesh sequence: give --mesh PATTERN after --")?;
    let out = config
        .out
        .clone()
        .context("no output folder: give --out DIR after --")?;
    let frames = super::run::frames_of(&config, &pattern)?;
    let (Some(&first), Some(&last)) = (frames.first(), frames.last()) else {
        bail!("{pattern}: no frames");
    };
    Ok(Shot {
        args: without_frames(run),
        out: std::path::absolute(&out)
            .with_context(|| format!("{}: no absolute path", out.display()))?,
        first,
        last,
        workdir: std::env::current_dir()?,
        binary: std::env::current_exe().context("cannot find the fluidtex binary")?,
    })
}

/// `args` without `--frames X` / `--frames=X`.
fn without_frames(args: &[OsString]) -> Vec<OsString> {
    let mut kept = Vec::new();
    let mut skip = false;
    for a in args {
        if std::mem::take(&mut skip) {
            continue;
        }
        let text = a.to_string_lossy();
        if text == "--frames" {
            skip = true;
        } else if !text.starts_with("--frames=") {
            kept.push(a.clone());
        }
    }
    kept
}

/// `s` as one word of a POSIX shell.
fn quote(s: &OsStr) -> String {
    format!("'{}'", s.to_string_lossy().replace('\'', r"'\''"))
}

/// The `#SBATCH` lines of a job (`extra`: its own, each ending in a
/// newline); sbatch reads them only above the first command.
fn header(a: &SlurmArgs, shot: &Shot, name: &str, log: &str, extra: &str) -> String {
    let mut h = format!(
        "#!/bin/bash\n\
         #SBATCH --job-name={name}\n\
         #SBATCH --output={}\n\
         #SBATCH --chdir={}\n\
         #SBATCH --cpus-per-task={}\n\
         #SBATCH --requeue\n",
        shot.out.join("farm/logs").join(log).display(),
        shot.workdir.display(),
        a.shot.cpus
    );
    if let Some(p) = &a.partition {
        h.push_str(&format!("#SBATCH --partition={p}\n"));
    }
    if let Some(t) = &a.time {
        h.push_str(&format!("#SBATCH --time={t}\n"));
    }
    h.push_str(extra);
    h.push_str(&format!(
        "set -euo pipefail\n\
         export RAYON_NUM_THREADS=\"${{SLURM_CPUS_PER_TASK:-{}}}\"\n",
        a.shot.cpus
    ));
    h
}

/// `fluidtex run` with the shot's arguments, as a shell command.
fn run_command(shot: &Shot) -> String {
    format!("{} run{}", quote(shot.binary.as_os_str()), shot_words(shot))
}

/// The shot's run arguments as shell words, each after a space.
fn shot_words(shot: &Shot) -> String {
    shot.args.iter().map(|a| format!(" {}", quote(a))).collect()
}

/// The shell lines that set `a` and `b`, the frames of the task whose
/// chunk number is in shell variable `task` (chunk k: FIRST + k · CHUNK
/// onwards, `chunk` frames or up to the shot's last).
fn chunk_lines(chunk: u32, shot: &Shot, task: &str) -> String {
    format!(
        "first={}; last={}; chunk={}\n\
         a=$((first + {task} * chunk))\n\
         b=$((a + chunk - 1)); if [ \"$b\" -gt \"$last\" ]; then b=$last; fi\n",
        shot.first, shot.last, chunk
    )
}

/// Phase 1 as a chain: task k selects every frame up to the end of chunk
/// k, going on from `state.bin` (`--resume`), one task at a time (`%1`).
/// Phase-2 task k waits for phase-1 task k alone (`aftercorr`), so a chunk
/// is resampled as soon as its frames are selected; should the tasks run
/// out of order, a later one has selected the earlier chunks' frames too.
fn select_script(a: &SlurmArgs, shot: &Shot, tasks: u32) -> String {
    format!(
        "{}\
         # Phase 1, the sequential pass: task k selects the frames up to the\n\
         # end of chunk k, going on from the last selected (--resume).\n\
         {}\
         exec {} --frames \"$first-$b\" --phase select --resume --quiet\n",
        header(
            a,
            shot,
            "fluidtex-select",
            "select-%A_%a.log",
            &format!("#SBATCH --array=0-{}%1\n", tasks - 1)
        ),
        chunk_lines(a.shot.chunk, shot, "SLURM_ARRAY_TASK_ID"),
        run_command(shot),
    )
}

fn resample_script(a: &SlurmArgs, shot: &Shot, tasks: u32) -> String {
    format!(
        "{}\
         # Phase 2: task k resamples chunk k once phase-1 task k is done.\n\
         {}\
         exec {} --frames \"$a-$b\" --phase resample --resume --quiet\n",
        header(
            a,
            shot,
            "fluidtex-resample",
            "resample-%A_%a.log",
            &format!("#SBATCH --array=0-{}\n", tasks - 1)
        ),
        chunk_lines(a.shot.chunk, shot, "SLURM_ARRAY_TASK_ID"),
        run_command(shot)
    )
}

fn submit_script(select: &Path, resample: &Path) -> String {
    format!(
        "#!/bin/bash\n\
         # Submits phase 1, then phase 2: chunk k once phase 1 has chunk k.\n\
         set -euo pipefail\n\
         select=$(sbatch --parsable {})\n\
         resample=$(sbatch --parsable --dependency=aftercorr:\"${{select%%;*}}\" {})\n\
         echo \"phase 1 job $select, phase 2 array job $resample\"\n",
        quote(select.as_os_str()),
        quote(resample.as_os_str())
    )
}

fn write_script(path: &Path, text: &str) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    let mut staging = fluidtex::io::Staging::new(None, None);
    staging.write(path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    staging.commit()?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755))
        .with_context(|| format!("{}: cannot make it executable", path.display()))
}

/// Submits with `sbatch --parsable ARGS`; returns the job id.
fn sbatch(args: &[&OsStr]) -> Result<String> {
    let out = std::process::Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .output()
        .context("sbatch: cannot run it (is Slurm installed here?)")?;
    if !out.status.success() {
        bail!(
            "sbatch {}: {}",
            args.iter()
                .map(|a| a.to_string_lossy())
                .collect::<Vec<_>>()
                .join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    // `--parsable` prints "id" or "id;cluster".
    let id = text
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        bail!("sbatch printed no job id: {}", text.trim());
    }
    Ok(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_left_out_in_both_spellings() {
        let args: Vec<OsString> = ["--mesh", "a.ply", "--frames", "1-9", "--frames=2-3", "--x"]
            .map(OsString::from)
            .to_vec();
        let kept: Vec<String> = without_frames(&args)
            .iter()
            .map(|a| a.to_string_lossy().into_owned())
            .collect();
        assert_eq!(kept, ["--mesh", "a.ply", "--x"]);
    }

    #[test]
    fn quoting_survives_the_shell() {
        for s in ["plain", "with space", "it's", "$HOME `x` \"q\"", ""] {
            let out = std::process::Command::new("sh")
                .arg("-c")
                .arg(format!("printf %s {}", quote(OsStr::new(s))))
                .output()
                .expect("sh runs");
            assert_eq!(String::from_utf8_lossy(&out.stdout), s);
        }
    }
}
