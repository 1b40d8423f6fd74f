//! Exemplars chosen by a per-vertex attribute through the binary (issue
//! 40): `--select-by ATTR` with `--exemplar IMG@LO:HI` (and the same in
//! the TOML `[[exemplars]]`), the built-in lava exemplars, the state
//! agreement in each frame's statistics, and the one-line errors.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::*;

/// Frames of the run: 1/rate = 6 frames, and margin for the new patches.
const FRAMES: usize = 16;

fn stats(out: &Path, frame: usize) -> serde_json::Value {
    let bytes = std::fs::read(out.join(format!("stats.{frame:04}.json"))).unwrap();
    serde_json::from_slice(&bytes).unwrap()
}

fn state_agreement(out: &Path, frame: usize) -> f64 {
    stats(out, frame)["state_agreement"]
        .as_f64()
        .unwrap_or_else(|| panic!("frame {frame}: no state_agreement in {}", stats(out, frame)))
}

#[test]
fn the_built_in_lava_exemplars_follow_the_temperature() {
    let dir = tempfile::tempdir().unwrap();
    // Hot on the left half, cold on the right.
    let mesh = cooling_grid(&dir.path().join("in"), FRAMES, |x, _| {
        if x < 0.0 { 1.0 } else { 0.0 }
    });
    let out = dir.path().join("out");
    let m = mesh.to_str().unwrap();
    let o = out.to_str().unwrap();
    ok(&[
        "run",
        "--mesh",
        m,
        "--out",
        o,
        "--atlas",
        "256",
        "--select-by",
        "temperature",
        "--mismatch-rate",
        "4",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    // Patches a third of the surface wide straddle the border at first;
    // their wrong side erodes within 1/rate seconds and new patches of the
    // right exemplar close it.
    let (first, last) = (state_agreement(&out, 0), state_agreement(&out, FRAMES - 1));
    assert!(
        first > 0.8 && last >= 0.95 && last > first,
        "{first} -> {last}"
    );
    let texels = &stats(&out, 0)["exemplar_texels"];
    let (crust, glow) = (texels[0].as_u64().unwrap(), texels[1].as_u64().unwrap());
    assert!(crust > 1000 && glow > 1000, "crust {crust}, glow {glow}");
    // The same selection from the TOML table, with the images swapped.
    let swapped = dir.path().join("swapped");
    let config = dir.path().join("swapped.toml");
    std::fs::write(
        &config,
        "select_by = \"temperature\"\nmismatch_rate = 4.0\n\
         [[exemplars]]\npath = \"builtin:glow\"\nrange = [0.0, 0.5]\n\
         [[exemplars]]\npath = \"builtin:crust\"\nrange = [0.5, 1.0]\n",
    )
    .unwrap();
    ok(&[
        "run",
        "--config",
        config.to_str().unwrap(),
        "--mesh",
        m,
        "--out",
        swapped.to_str().unwrap(),
        "--atlas",
        "256",
    ]);
    // It agrees as well...
    assert!(state_agreement(&swapped, FRAMES - 1) >= 0.95);
    // ...and shows the other image on each half: the glow is now cold.
    let red = |dir: &Path| {
        let t = image(&dir.join("color.0000.png"));
        t.data.iter().step_by(t.channels).sum::<f32>() / (t.width * t.height) as f32
    };
    assert!(
        (red(&out) - red(&swapped)).abs() > 0.01,
        "{} vs {}",
        red(&out),
        red(&swapped)
    );
}

#[test]
fn bad_selections_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = cooling_grid(&dir.path().join("in"), 1, |_, _| 0.5);
    let m = mesh.to_str().unwrap();
    let o = dir.path().join("out");
    let o = o.to_str().unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "--mesh", m, "--out", o, "--atlas", "64"];
        args.extend_from_slice(extra);
        user_error(&args)
    };
    let e = run(&[
        "--select-by",
        "temperature",
        "--exemplar",
        "builtin:glow@0.6:0.2",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(
        e.contains("builtin:glow@0.6:0.2") && e.contains("low end above"),
        "{e}"
    );
    let e = run(&[
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(e.contains("needs --select-by"), "{e}");
    let e = run(&[
        "--select-by",
        "temperature",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust",
    ]);
    assert!(e.contains("builtin:crust has no range"), "{e}");
    let e = run(&["--select-by", "temperature", "--exemplar", "builtin:glow"]);
    assert!(e.contains("several exemplars"), "{e}");
    let e = run(&[
        "--select-by",
        "temperature",
        "--exemplar",
        "builtin:lava@0:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(
        e.contains("builtin:lava") && e.contains("builtin:glow"),
        "{e}"
    );
    let e = run(&[
        "--select-by",
        "temperature",
        "--mismatch-rate",
        "0",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(e.contains("mismatch_rate"), "{e}");
    let e = run(&[
        "--select-by",
        "temperature",
        "--mismatch-gain=-1",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(e.contains("mismatch_gain") && e.contains("from 0"), "{e}");
    let e = run(&[
        "--mismatch-gain",
        "5",
        "--exemplar",
        "builtin:glow",
        "--exemplar",
        "builtin:crust",
    ]);
    assert!(e.contains("mismatch_gain needs --select-by"), "{e}");
    let e = run(&[
        "--select-by",
        "temperature",
        "--exemplar-select",
        "histogram",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(e.contains("--exemplar-select histogram"), "{e}");
    let e = run(&[
        "--exemplar-select",
        "attribute",
        "--exemplar",
        "builtin:glow",
        "--exemplar",
        "builtin:crust",
    ]);
    assert!(e.contains("needs --select-by"), "{e}");
    // An attribute the input does not have: the file and the name.
    let e = run(&[
        "--select-by",
        "age",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
    assert!(e.contains("age") && e.contains("fluid.0000.ply"), "{e}");
    // A control: the same run with the attribute it has works.
    ok(&[
        "run",
        "--mesh",
        m,
        "--out",
        o,
        "--atlas",
        "64",
        "--select-by",
        "temperature",
        "--exemplar",
        "builtin:glow@0.5:1",
        "--exemplar",
        "builtin:crust@0:0.5",
    ]);
}

#[test]
fn compare_reports_the_state_agreement_of_each_method() {
    let dir = tempfile::tempdir().unwrap();
    // Cold everywhere from frame 3 on: the glow of frames 0-2 must go.
    let mesh = cooling_grid(&dir.path().join("in"), FRAMES, |_, f| {
        if f < 3 { 1.0 } else { 0.0 }
    });
    let out = dir.path().join("cmp");
    let config = dir.path().join("rate.toml");
    std::fs::write(&config, "mismatch_rate = 4.0\n").unwrap();
    ok(&[
        "compare",
        "--mesh",
        mesh.to_str().unwrap(),
        "--select-by",
        "temperature",
        "--config",
        config.to_str().unwrap(),
        "--atlas",
        "128",
        "--render",
        "64",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let methods = report["scenes"][0]["methods"].as_array().unwrap();
    let names: Vec<&str> = methods
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    // The default methods with --select-by: those that choose per patch.
    assert_eq!(names, ["erosion", "advect", "lapped-rigid"]);
    let last_of = |m: &serde_json::Value, key: &str| {
        m["per_frame"].as_array().unwrap().last().unwrap()[key]
            .as_f64()
            .unwrap()
    };
    let last = |m: &serde_json::Value| last_of(m, "state_agreement");
    // Erosion renews what cooled; advect never renews, so its glow stays
    // (the known-bad control).
    assert!(last(&methods[0]) >= 0.95, "erosion: {}", last(&methods[0]));
    assert!(last(&methods[1]) < 0.5, "advect: {}", last(&methods[1]));
    // Every point is 0 or 1, half the span from the split: all decisive,
    // and the same verdicts.
    let decisive = |m: &serde_json::Value| last_of(m, "state_agreement_decisive");
    assert!(decisive(&methods[0]) >= 0.95, "{}", decisive(&methods[0]));
    assert!(decisive(&methods[1]) < 0.5, "{}", decisive(&methods[1]));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("state agreement"), "{md}");
    assert!(md.contains("on decisive points"), "{md}");
    // A plain comparison has no such column.
    let plain = dir.path().join("plain");
    ok(&[
        "compare",
        "--mesh",
        mesh.to_str().unwrap(),
        "--methods",
        "erosion",
        "--atlas",
        "128",
        "--render",
        "64",
        "--out",
        plain.to_str().unwrap(),
        "--quiet",
    ]);
    let md = std::fs::read_to_string(plain.join("report.md")).unwrap();
    assert!(!md.contains("state agreement"));
}

#[test]
fn a_killed_run_chosen_by_attribute_resumes_to_the_same_files() {
    // The front crosses the grid while the run is killed after frame 4:
    // the weights the mismatch lowered, the exemplar of every patch and the
    // ranges must all come back from state.bin.
    let dir = tempfile::tempdir().unwrap();
    let mesh = cooling_grid(&dir.path().join("in"), 10, |x, f| {
        if x < -0.5 + f as f32 / 8.0 { 0.0 } else { 1.0 }
    });
    let args = |out: &Path| -> Vec<String> {
        [
            "run",
            "--mesh",
            mesh.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--atlas",
            "128",
            "--select-by",
            "temperature",
            "--mismatch-rate",
            "4",
            "--exemplar",
            "builtin:glow@0.5:1",
            "--exemplar",
            "builtin:crust@0:0.5",
        ]
        .map(String::from)
        .to_vec()
    };
    let reference = dir.path().join("reference");
    ok(&args(&reference));
    let killed = dir.path().join("killed");
    let paused = spawn_paused(&args(&killed), &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "4")]);
    assert_eq!(paused.line, "fluidtex-test: paused after frame 4");
    paused.kill();
    assert!(!killed.join("color.0005.png").exists());
    let mut resume = args(&killed);
    resume.push("--resume".into());
    ok(&resume);
    assert_same_outputs(&reference, &killed);
    // The control: the state agreement changed over the run, so the
    // frames after the kill are not trivially the same.
    assert!(state_agreement(&reference, 5) < state_agreement(&reference, 9));
}
