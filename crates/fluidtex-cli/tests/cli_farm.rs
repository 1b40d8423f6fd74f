//! `fluidtex farm slurm`: the scripts it writes (phase 1 as a chain of
//! chunks, phase-2 chunk k after phase-1 chunk k), what it refuses, and a
//! shot submitted to a real single-node Slurm cluster
//! (`tools/slurm_cluster.sh`) whose files are byte for byte those of a
//! one-pass run. `fluidtex farm openjd`: the job template, checked and run
//! by the Open Job Description command line (`openjd`), to the same bytes.
//! Without Slurm or `openjd` here those tests say so and are skipped,
//! except with FLUIDTEX_REQUIRE_TOOLS=1 (CI), where they must run.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::*;

/// The shot's `fluidtex run` arguments.
fn shot(pattern: &Path, out: &Path) -> Vec<std::ffi::OsString> {
    [
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--atlas".as_ref(),
        "96".as_ref(),
        "--preview-every".as_ref(),
        "2".as_ref(),
    ]
    .map(std::ffi::OsString::from)
    .to_vec()
}

fn farm(options: &[&str], run: &[std::ffi::OsString]) -> Vec<std::ffi::OsString> {
    farm_on("slurm", options, run)
}

fn farm_on(
    scheduler: &str,
    options: &[&str],
    run: &[std::ffi::OsString],
) -> Vec<std::ffi::OsString> {
    let mut a: Vec<std::ffi::OsString> = vec!["farm".into(), scheduler.into()];
    a.extend(options.iter().map(std::ffi::OsString::from));
    a.push("--".into());
    a.extend(run.iter().cloned());
    a
}

/// Frames 1-5 of the small vortex into `dir/shot`: the shot's folder and
/// run arguments.
fn frames_1_to_5(dir: &Path) -> (PathBuf, Vec<std::ffi::OsString>) {
    let pattern = small_vortex(dir);
    let out = dir.join("shot");
    let mut run = shot(&pattern, &out);
    run.extend(["--frames".into(), "1-5".into()]);
    (out, run)
}

/// A one-pass run of the shot into `dir/one-pass`: the files the farm's
/// jobs must write.
fn one_pass(dir: &Path, pattern: &Path) -> PathBuf {
    let reference = dir.join("one-pass");
    let mut one = vec!["run".into()];
    one.extend(shot(pattern, &reference));
    one.push("--quiet".into());
    ok(&one);
    reference
}

#[test]
fn the_scripts_chain_phase_1_by_chunks_and_resample_each_chunk_after_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = frames_1_to_5(dir.path());
    ok(&farm(
        &["--chunk", "2", "--cpus", "3", "--partition", "gpu"],
        &run,
    ));
    let read = |name: &str| std::fs::read_to_string(out.join("farm").join(name)).unwrap();
    let select = read("select.sbatch");
    let resample = read("resample.sbatch");
    assert!(
        select.contains("--frames \"$first-$b\" --phase select --resume"),
        "{select}"
    );
    // One phase-1 task per chunk, one at a time.
    assert!(select.contains("#SBATCH --array=0-2%1\n"), "{select}");
    assert!(select.contains("#SBATCH --cpus-per-task=3\n"), "{select}");
    assert!(select.contains("#SBATCH --partition=gpu\n"), "{select}");
    // 5 frames in chunks of 2: three tasks, the last of one frame.
    assert!(resample.contains("#SBATCH --array=0-2\n"), "{resample}");
    assert!(
        resample.contains("first=1; last=5; chunk=2\n"),
        "{resample}"
    );
    assert!(resample.contains("--phase resample --resume"), "{resample}");
    // The shot's own --frames is not repeated (each job gives its own).
    assert!(!resample.contains("'--frames'"), "{resample}");
    assert!(read("submit.sh").contains("--dependency=aftercorr:"));
    for script in ["select.sbatch", "resample.sbatch", "submit.sh"] {
        let check = Command::new("bash")
            .arg("-n")
            .arg(out.join("farm").join(script))
            .output()
            .unwrap();
        assert!(check.status.success(), "{script}: {check:?}");
    }
    // Task k's frames, as the scripts compute them: phase 1 selects up to
    // the end of chunk k, phase 2 resamples chunk k.
    let ranges = |script: &str, echo: &str| -> Vec<String> {
        (0..3)
            .map(|k| {
                let body: String = script
                    .lines()
                    .filter(|l| ["first=", "a=", "b="].iter().any(|p| l.starts_with(p)))
                    .collect::<Vec<_>>()
                    .join("\n");
                let out = Command::new("bash")
                    .arg("-c")
                    .arg(format!("{body}\necho {echo}"))
                    .env("SLURM_ARRAY_TASK_ID", k.to_string())
                    .output()
                    .unwrap();
                String::from_utf8_lossy(&out.stdout).trim().to_string()
            })
            .collect()
    };
    assert_eq!(ranges(&resample, "\"$a-$b\""), ["1-2", "3-4", "5-5"]);
    assert_eq!(ranges(&select, "\"$first-$b\""), ["1-2", "1-4", "1-5"]);
}

#[test]
fn what_the_farm_gives_each_job_is_refused_in_the_run_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    let out = dir.path().join("shot");
    let mut run = shot(&pattern, &out);
    run.extend(["--phase".into(), "select".into()]);
    let err = user_error(&farm(&[], &run));
    assert!(
        err.contains("--phase: the farm gives each job its own"),
        "{err}"
    );
    let err = user_error(&farm(&["--chunk", "0"], &shot(&pattern, &out)));
    assert!(err.contains("--chunk 0"), "{err}");
    let missing = dir.path().join("nothing.####.ply");
    let err = user_error(&farm(&[], &shot(&missing, &out)));
    assert!(err.contains("nothing"), "{err}");
}

/// A single-node cluster for the test's life (stopped on drop).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Result<Cluster, String> {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/slurm_cluster.sh");
        let out = Command::new("bash")
            .arg(&script)
            .arg("start")
            .arg(dir)
            .output()
            .map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
        }
        Ok(Cluster {
            dir: dir.to_path_buf(),
            conf: PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()),
        })
    }

    /// Jobs still queued or running.
    fn queued(&self) -> usize {
        let out = Command::new("squeue")
            .args(["-h", "-o", "%i"])
            .env("SLURM_CONF", &self.conf)
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).lines().count()
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/slurm_cluster.sh");
        let _ = Command::new("bash")
            .arg(script)
            .arg("stop")
            .arg(&self.dir)
            .output();
    }
}

#[test]
fn a_shot_on_a_real_slurm_cluster_writes_the_one_pass_files() {
    let dir = tempfile::tempdir().unwrap();
    let cluster = match Cluster::start(&dir.path().join("cluster")) {
        Ok(c) => c,
        Err(why) => {
            missing_tool("the Slurm farm test", &format!("no Slurm cluster: {why}"));
            return;
        }
    };
    let pattern = small_vortex(dir.path());
    let reference = one_pass(dir.path(), &pattern);
    let out = dir.path().join("shot");
    let submitted = fluidtex()
        .args(farm(
            &["--chunk", "2", "--cpus", "1", "--submit"],
            &shot(&pattern, &out),
        ))
        .env("SLURM_CONF", &cluster.conf)
        .output()
        .unwrap();
    check_ok(&submitted, &["farm slurm --submit"]);
    let said = String::from_utf8_lossy(&submitted.stdout);
    assert!(said.contains("submitted: phase 1 array job "), "{said}");
    let start = Instant::now();
    while cluster.queued() > 0 {
        assert!(
            start.elapsed() < Duration::from_secs(240),
            "the jobs did not finish in 240 s; logs in {}",
            out.join("farm/logs").display()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    let logs: Vec<String> = std::fs::read_dir(out.join("farm/logs"))
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            format!("{}: {}", p.display(), std::fs::read_to_string(&p).unwrap())
        })
        .collect();
    // Three phase-1 and three phase-2 task logs.
    assert_eq!(logs.len(), 6, "{logs:#?}");
    // The farm's scripts and logs are in a folder of their own.
    let farm_folder = out.join("farm");
    let moved = dir.path().join("farm-scripts");
    std::fs::rename(&farm_folder, &moved).unwrap();
    let names: Vec<String> = files(&out).into_keys().collect();
    assert!(
        names.iter().any(|n| n == "stats.0005.json"),
        "{names:?}; logs: {logs:#?}"
    );
    assert_two_phase_matches(&reference, &out);
}

#[test]
fn a_shots_file_writes_each_shot_and_names_the_shot_it_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    let shots = dir.path().join("shots.toml");
    let arg_list = |out: &str, frames: &str| {
        format!(
            "[\"--mesh\", \"{}\", \"--out\", \"{}\", \"--frames\", \"{frames}\"]",
            pattern.display(),
            dir.path().join(out).display()
        )
    };
    std::fs::write(
        &shots,
        format!(
            "[[shot]]\nname = \"sh010\"\nargs = {}\n\n[[shot]]\nargs = {}\n",
            arg_list("sh010", "0-5"),
            arg_list("sh020", "2-3")
        ),
    )
    .unwrap();
    ok(&[
        "farm".as_ref(),
        "slurm".as_ref(),
        "--chunk".as_ref(),
        "3".as_ref(),
        "--shots".as_ref(),
        shots.as_os_str(),
    ]);
    let array = |out: &str| {
        let text =
            std::fs::read_to_string(dir.path().join(out).join("farm/resample.sbatch")).unwrap();
        text.lines()
            .find(|l| l.starts_with("#SBATCH --array="))
            .unwrap()
            .to_string()
    };
    assert_eq!(array("sh010"), "#SBATCH --array=0-1");
    assert_eq!(array("sh020"), "#SBATCH --array=0-0");
    // A shot that cannot run is named, and nothing of any shot is written.
    let bad = dir.path().join("bad.toml");
    let missing = dir.path().join("nothing.####.ply");
    std::fs::write(
        &bad,
        format!(
            "[[shot]]\nargs = {}\n\n[[shot]]\nname = \"sh040\"\nargs = [\"--mesh\", \"{}\", \"--out\", \"{}\"]\n",
            arg_list("sh030", "0-5"),
            missing.display(),
            dir.path().join("sh040").display()
        ),
    )
    .unwrap();
    let run = |file: &Path| -> Vec<std::ffi::OsString> {
        vec!["farm".into(), "slurm".into(), "--shots".into(), file.into()]
    };
    let err = user_error(&run(&bad));
    assert!(err.contains("bad.toml: sh040: "), "{err}");
    assert!(!dir.path().join("sh030").exists());
    // Two shots into one folder, and an unknown key.
    std::fs::write(
        &bad,
        format!(
            "[[shot]]\nargs = {}\n[[shot]]\nargs = {}\n",
            arg_list("a", "0-1"),
            arg_list("a", "2-3")
        ),
    )
    .unwrap();
    let err = user_error(&run(&bad));
    assert!(err.contains("bad.toml: shot 2: writes into "), "{err}");
    std::fs::write(&bad, "[[shot]]\nargz = []\n").unwrap();
    let err = user_error(&run(&bad));
    assert!(err.contains("bad.toml: unknown field `argz`"), "{err}");
}

/// The Open Job Description command line: `FLUIDTEX_OPENJD`, the one
/// `.ci/run` installs (`.tools/openjd/bin/openjd`), or `openjd` on the
/// path. `None` (the test skipped) when there is none, unless
/// FLUIDTEX_REQUIRE_TOOLS=1.
fn openjd() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let candidates = [
        std::env::var_os("FLUIDTEX_OPENJD").map(PathBuf::from),
        Some(root.join(".tools/openjd/bin/openjd")),
        Some(PathBuf::from("openjd")),
    ];
    for c in candidates.into_iter().flatten() {
        let works = Command::new(&c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success());
        if works {
            return Some(c);
        }
    }
    missing_tool(
        "the Open Job Description test",
        "no `openjd`: run `python3 -m venv .tools/openjd && .tools/openjd/bin/pip install \
         openjd-cli==0.8.0` at the workspace root, or set FLUIDTEX_OPENJD",
    );
    None
}

/// The Open Job Description command line accepts the template at `path`
/// (`openjd check`), where there is one (see [`openjd`]).
fn assert_openjd_accepts(path: &Path) {
    if let Some(openjd) = openjd() {
        let check = Command::new(&openjd)
            .arg("check")
            .arg(path)
            .output()
            .unwrap();
        assert!(check.status.success(), "openjd check: {check:?}");
    }
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn the_job_template_selects_the_shot_once_then_resamples_each_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = frames_1_to_5(dir.path());
    let said = ok(&farm_on("openjd", &["--chunk", "2", "--cpus", "3"], &run));
    assert!(said.contains("3 chunks of 2 frames"), "{said}");
    let path = out.join("farm/openjd/template.json");
    let t = read_json(&path);
    assert_eq!(t["specificationVersion"], "jobtemplate-2023-09");
    assert_eq!(t["parameterDefinitions"][1]["name"], "Threads");
    assert_eq!(t["parameterDefinitions"][1]["default"], 3);
    let steps = t["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 2);
    assert_eq!(steps[0]["name"], "Select");
    assert!(steps[0].get("parameterSpace").is_none(), "one phase-1 task");
    assert_eq!(steps[1]["name"], "Resample");
    assert_eq!(steps[1]["dependencies"][0]["dependsOn"], "Select");
    // 5 frames in chunks of 2: three tasks, the last of one frame.
    let space = &steps[1]["parameterSpace"]["taskParameterDefinitions"][0];
    assert_eq!(space["name"], "Chunk");
    assert_eq!(space["range"], "0-2");
    for s in steps {
        assert_eq!(
            s["hostRequirements"]["amounts"][0]["name"],
            "amount.worker.vcpu"
        );
        assert_eq!(s["hostRequirements"]["amounts"][0]["min"], 3);
    }
    // Each step's script, run by bash as the template's action runs it,
    // with a stand-in for fluidtex that records its threads and arguments.
    let fake = dir.path().join("fake-fluidtex");
    let record = dir.path().join("record");
    std::fs::write(
        &fake,
        format!(
            "#!/bin/bash\nprintf '%s\\n' \"$RAYON_NUM_THREADS\" \"$@\" > '{}'\n",
            record.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let script = |step: usize| -> String {
        let action = &steps[step]["script"]["actions"]["onRun"];
        assert_eq!(action["command"], "bash");
        let args: Vec<&str> = (action["args"].as_array().unwrap().iter())
            .map(|a| a.as_str().unwrap())
            .collect();
        let expected: &[&str] = if step == 0 {
            &[
                "{{Task.File.Run}}",
                "{{Param.Fluidtex}}",
                "{{Param.Threads}}",
            ]
        } else {
            &[
                "{{Task.File.Run}}",
                "{{Param.Fluidtex}}",
                "{{Param.Threads}}",
                "{{Task.Param.Chunk}}",
            ]
        };
        assert_eq!(args, expected);
        let file = &steps[step]["script"]["embeddedFiles"][0];
        assert_eq!(file["name"], "Run");
        file["data"].as_str().unwrap().to_string()
    };
    let run_script = |text: &str, args: &[&str]| -> Vec<String> {
        let file = dir.path().join("task.sh");
        std::fs::write(&file, text).unwrap();
        let status = Command::new("bash")
            .arg(&file)
            .arg(&fake)
            .args(args)
            .status()
            .unwrap();
        assert!(status.success());
        let recorded = std::fs::read_to_string(&record).unwrap();
        recorded.lines().map(str::to_string).collect()
    };
    let tail = |words: &[String], n: usize| words[words.len() - n..].join(" ");
    let select = run_script(&script(0), &["3"]);
    assert_eq!(select[0], "3", "RAYON_NUM_THREADS");
    assert_eq!(select[1], "run");
    assert_eq!(
        tail(&select, 6),
        "--frames 1-5 --phase select --resume --quiet"
    );
    // The shot's own --frames is not repeated (each task gives its own).
    assert_eq!(select.iter().filter(|w| *w == "--frames").count(), 1);
    assert!(
        select.contains(&"--preview-every".to_string()),
        "{select:?}"
    );
    let chunks: Vec<String> = (0..3)
        .map(|k| tail(&run_script(&script(1), &["2", &k.to_string()]), 6))
        .collect();
    assert_eq!(
        chunks,
        [
            "--frames 1-2 --phase resample --resume --quiet",
            "--frames 3-4 --phase resample --resume --quiet",
            "--frames 5-5 --phase resample --resume --quiet"
        ]
    );
    assert_openjd_accepts(&path);
}

#[test]
fn a_long_folder_name_and_a_single_chunk_still_make_a_valid_template() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    // The specification caps a job's name at 128 characters.
    let out = dir.path().join("x".repeat(200));
    ok(&farm_on(
        "openjd",
        &["--chunk", "10"],
        &shot(&pattern, &out),
    ));
    let path = out.join("farm/openjd/template.json");
    let t = read_json(&path);
    let name = t["name"].as_str().unwrap();
    assert_eq!(name.chars().count(), 128, "{name}");
    assert!(name.starts_with("fluidtex xxx"), "{name}");
    // Six frames in chunks of 10: one phase-2 task.
    let range = &t["steps"][1]["parameterSpace"]["taskParameterDefinitions"][0]["range"];
    assert_eq!(range, "0-0");
    assert_openjd_accepts(&path);
}

#[test]
fn a_shot_run_by_the_open_job_description_command_line_writes_the_one_pass_files() {
    let Some(openjd) = openjd() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    let reference = one_pass(dir.path(), &pattern);
    let out = dir.path().join("shot");
    ok(&farm_on(
        "openjd",
        &["--chunk", "4", "--cpus", "1"],
        &shot(&pattern, &out),
    ));
    let template = out.join("farm/openjd/template.json");
    // Phase 1's one task, then phase 2's two chunks (frames 0-3 and 4-5).
    let ran = Command::new(&openjd)
        .args(["run", "--step", "Resample", "--run-dependencies"])
        .arg(&template)
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&ran.stdout);
    assert!(ran.status.success(), "openjd run: {ran:?}");
    assert!(log.contains("Session ended successfully"), "{log}");
    let moved = dir.path().join("farm-files");
    std::fs::rename(out.join("farm"), &moved).unwrap();
    assert_two_phase_matches(&reference, &out);
    // A task that fails fails the job: here the binary is not fluidtex.
    let failed = Command::new(&openjd)
        .args(["run", "--step", "Select", "-p", "Fluidtex=/bin/false"])
        .arg(moved.join("openjd/template.json"))
        .output()
        .unwrap();
    assert!(!failed.status.success(), "{failed:?}");
}

#[test]
fn a_shot_whose_arguments_hold_a_template_expression_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    let out = dir.path().join("sh{{Param.X}}");
    let err = user_error(&farm_on("openjd", &[], &shot(&pattern, &out)));
    assert!(err.contains("sh{{Param.X}}: holds `{{`"), "{err}");
    assert!(!out.exists());
}
