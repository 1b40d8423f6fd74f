//! `fluidtex farm openjd`: a shot as an Open Job Description job template
//! (specification 2023-09), written to `OUT/farm/openjd/template.json`.
//! That folder is a job bundle as AWS Deadline Cloud submits it
//! (`deadline bundle submit OUT/farm/openjd`), and the `openjd` command line
//! runs the same template on one machine
//! (`openjd run --step Resample --run-dependencies …/template.json`).
//!
//! Two steps: `Select`, one task that runs phase 1 over every frame, and
//! `Resample`, one task per chunk of frames (task parameter `Chunk`), which
//! depends on `Select`. The 2023-09 specification has dependencies between
//! steps only, not between one step's tasks, so phase 2 starts once phase 1
//! has selected the whole shot; Slurm's chain (`farm slurm`) resamples chunk
//! k while phase 1 selects the next ones. Every task adds `--resume`, so a
//! task the scheduler retries goes on from its last finished frame.
//!
//! The template is built as JSON with `serde_json` rather than from a text
//! template: the shot's arguments reach the tasks' shell scripts quoted once
//! ([`super::quote`]), and the binary and the thread count are job
//! parameters, passed to the scripts as arguments (never substituted into
//! their text), so a farm can point `Fluidtex` at its own install.

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use serde_json::{Value, json};

use super::{Shot, ShotArgs, chunk_lines, quote, shot_words};

#[derive(Args, Debug)]
pub struct OpenjdArgs {
    #[command(flatten)]
    pub shot: ShotArgs,
}

/// Writes `OUT/farm/openjd/template.json` for `shot`.
pub(super) fn write_template(a: &ShotArgs, shot: &Shot) -> Result<()> {
    let template = template(a, shot)?;
    let bundle = shot.out.join("farm").join("openjd");
    std::fs::create_dir_all(&bundle)
        .with_context(|| format!("{}: cannot create the folder", bundle.display()))?;
    let path = bundle.join("template.json");
    let text = serde_json::to_string_pretty(&template).context("the job template")? + "\n";
    let mut staging = fluidtex::io::Staging::new(None, None);
    staging.write(&path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    staging.commit()?;
    println!(
        "{}: {} chunks of {} frames, job template {} \
         (run here: openjd run --step Resample --run-dependencies {}; \
         Deadline Cloud: deadline bundle submit {})",
        shot.out.display(),
        shot.tasks(a.chunk),
        a.chunk,
        path.display(),
        path.display(),
        bundle.display()
    );
    Ok(())
}

/// The job template of `shot`, split as `a` says.
fn template(a: &ShotArgs, shot: &Shot) -> Result<Template> {
    refuse_format_strings(shot)?;
    // The specification caps a job's name at 128 characters.
    let folder = (shot.out.file_name()).map_or_else(|| "shot".into(), |n| n.to_string_lossy());
    let name: String = format!("fluidtex {folder}").chars().take(128).collect();
    let cd = format!("cd {}\n", quote(shot.workdir.as_os_str()));
    let run = format!("exec \"$fluidtex\" run{}", shot_words(shot));
    let select = format!(
        "set -euo pipefail\n\
         fluidtex=\"$1\"; export RAYON_NUM_THREADS=\"$2\"\n\
         {cd}\
         # Phase 1, the sequential pass over the whole shot, going on from the\n\
         # last selected frame should the task be retried (--resume).\n\
         {run} --frames '{}-{}' --phase select --resume --quiet\n",
        shot.first, shot.last
    );
    let resample = format!(
        "set -euo pipefail\n\
         fluidtex=\"$1\"; export RAYON_NUM_THREADS=\"$2\"; k=\"$3\"\n\
         {cd}\
         # Phase 2: chunk k of the shot's frames.\n\
         {}\
         {run} --frames \"$a-$b\" --phase resample --resume --quiet\n",
        chunk_lines(a.chunk, shot, "k")
    );
    let tasks = shot.tasks(a.chunk);
    let select = step(
        "Select",
        "Phase 1: the sequential pass, writing each frame's selection",
        a.cpus,
        select,
        false,
    );
    let resample = Step {
        dependencies: Some(json!([{ "dependsOn": "Select" }])),
        parameter_space: Some(json!({
            "taskParameterDefinitions": [
                { "name": "Chunk", "type": "INT", "range": format!("0-{}", tasks - 1) }
            ]
        })),
        ..step(
            "Resample",
            "Phase 2: every file of the chunk's frames, from their selections",
            a.cpus,
            resample,
            true,
        )
    };
    Ok(Template {
        specification_version: "jobtemplate-2023-09",
        name,
        // Without the output folder, which can be longer than a
        // description may be (2,048 characters); the scripts hold it.
        description: format!(
            "fluidtex in two phases: frames {}-{}, phase 2 in {tasks} chunks of {} frames",
            shot.first, shot.last, a.chunk
        ),
        parameter_definitions: vec![
            Parameter {
                name: "Fluidtex",
                kind: "STRING",
                description: "The fluidtex binary, as the workers see it",
                default: json!(shot.binary.to_string_lossy()),
                min_length: Some(1),
                min_value: None,
                max_value: None,
            },
            Parameter {
                name: "Threads",
                kind: "INT",
                description: "fluidtex's threads per task (RAYON_NUM_THREADS)",
                default: json!(a.cpus),
                min_length: None,
                min_value: Some(1),
                max_value: Some(4096),
            },
        ],
        steps: vec![select, resample],
    })
}

/// The template's fields in the order the specification lists them (a
/// `serde_json::Value` would sort them by name), for whoever reads or
/// edits the file.
#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Template {
    specification_version: &'static str,
    name: String,
    description: String,
    parameter_definitions: Vec<Parameter>,
    steps: Vec<Step>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Parameter {
    name: &'static str,
    #[serde(rename = "type")]
    kind: &'static str,
    description: &'static str,
    default: Value,
    #[serde(skip_serializing_if = "Option::is_none")]
    min_length: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    min_value: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    max_value: Option<u32>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Step {
    name: &'static str,
    description: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    dependencies: Option<Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    parameter_space: Option<Value>,
    host_requirements: Value,
    script: Value,
}

/// A step: its name, description, vCPUs and script, with neither
/// dependencies nor task parameters. `chunked`: the script also takes the
/// task's `Chunk`.
fn step(
    name: &'static str,
    description: &'static str,
    cpus: u32,
    script: String,
    chunked: bool,
) -> Step {
    let mut args = vec![
        "{{Task.File.Run}}",
        "{{Param.Fluidtex}}",
        "{{Param.Threads}}",
    ];
    if chunked {
        args.push("{{Task.Param.Chunk}}");
    }
    Step {
        name,
        description,
        dependencies: None,
        parameter_space: None,
        host_requirements: json!({ "amounts": [{ "name": "amount.worker.vcpu", "min": cpus }] }),
        script: json!({
            "actions": { "onRun": { "command": "bash", "args": args } },
            "embeddedFiles": [{ "name": "Run", "type": "TEXT", "data": script }]
        }),
    }
}

/// Open Job Description reads `{{` in names, descriptions and scripts as
/// the start of an expression, and has no escape for it: a shot whose
/// arguments or folders hold one is refused.
fn refuse_format_strings(shot: &Shot) -> Result<()> {
    let paths = [&shot.out, &shot.workdir];
    let texts = (shot.args.iter().map(|a| a.to_string_lossy().into_owned()))
        .chain(paths.iter().map(|p| p.to_string_lossy().into_owned()));
    for text in texts {
        if text.contains("{{") {
            bail!("{text}: holds `{{{{`, which a job template reads as an expression");
        }
    }
    Ok(())
}
