//! `fluidtex compare` in-process: a tiny comparison writes the three
//! reports and the pictures with the expected structure; bad input gives
//! one clear line and no output.

#![allow(clippy::unwrap_used)]

use std::path::Path;

fn compare(out: &Path, extra: &[&str]) -> anyhow::Result<()> {
    let defaults = [
        ("--scenes", "rigid-rotation"),
        ("--methods", "atlas-check"),
        ("--frames", "0-2"),
        ("--atlas", "64"),
        ("--resolution", "16"),
        ("--render", "48"),
    ];
    let mut args: Vec<String> = vec!["fluidtex".into(), "compare".into(), "--quiet".into()];
    // A flag given in `extra` replaces its default (clap refuses repeats).
    for (flag, value) in defaults {
        if !extra.contains(&flag) {
            args.push(flag.into());
            args.push(value.into());
        }
    }
    args.push("--out".into());
    args.push(out.display().to_string());
    args.extend(extra.iter().map(|s| s.to_string()));
    fluidtex_cli::run(args)
}

#[test]
fn compare_writes_json_markdown_html_and_pictures() {
    let dir = tempfile::tempdir().unwrap();
    compare(dir.path(), &[]).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("report.json")).unwrap()).unwrap();
    let scene = &json["scenes"][0];
    assert_eq!(scene["name"], "rigid-rotation");
    assert_eq!(scene["frames"], serde_json::json!([0, 1, 2]));
    let method = &scene["methods"][0];
    assert_eq!(method["name"], "atlas-check");
    // Every metric's verdict on this known case: a world-space checker on a
    // rigidly rotating sphere (the eval's known-bad control for flow).
    let expected = [
        // Every chart texel gets a checker colour; no texel has two layers.
        ("coverage", "PASS"),
        ("ghosting", "PASS"),
        // A two-tone checker has far more contrast than the exemplar: more
        // than the 5 % above it that the rule allows (ruling 2).
        ("contrast", "FAIL"),
        // No patch uv to measure and no exemplar to compare with.
        ("distortion", "n/a"),
        ("fidelity", "n/a"),
        // The checker stays put in world space while the surface turns:
        // the texture does not follow the flow, and warping the previous
        // frame along the true motion does not predict the next one.
        ("flow_epe", "FAIL"),
        ("flow_aligned", "FAIL"),
        ("popping", "FAIL"),
        // The checker has no patches: no source to switch; the harness
        // measures the colour follow ratio on methods with provenance only.
        ("source_switch", "n/a"),
        ("colour_follow", "n/a"),
        // The rotation never stops, and the size cost is bench's.
        ("static_stop", "n/a"),
        ("size_cost", "n/a"),
    ];
    let metrics = method["metrics"].as_array().unwrap();
    let got: Vec<(&str, &str)> = metrics
        .iter()
        .map(|m| (m["key"].as_str().unwrap(), m["verdict"].as_str().unwrap()))
        .collect();
    assert_eq!(got, expected);
    assert_eq!(metrics[0]["median"], 0.0, "no uncovered texel");
    assert_eq!(metrics[1]["median"], 0.0, "no ghosting");
    assert_eq!(method["per_frame"].as_array().unwrap().len(), 3);
    assert_eq!(
        method["parameters"]["parameters"]["cells_per_diagonal"],
        24.0
    );
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("| atlas-check | 0 [0, 0] PASS |"), "{md}");
    let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    for file in ["rigid-rotation_sheet.png", "rigid-rotation_frame0000.png"] {
        assert!(html.contains(file), "{file} not linked");
        assert!(dir.path().join(file).is_file(), "{file} not written");
    }
}

#[test]
fn bad_compare_input_is_one_line_and_writes_nothing() {
    let cases: [(&[&str], &str); 5] = [
        (&["--scenes", "vortx"], "unknown scene 'vortx'"),
        (
            &["--methods", "erosion,magic"],
            "unknown method magic; available: ",
        ),
        (&["--frames", "5-2"], "5-2"),
        (
            &["--frames", "0-500"],
            "--frames 0-500: scene rigid-rotation has frames 0-96",
        ),
        (&["--atlas", "8"], "--atlas 8"),
    ];
    for (extra, expected) in cases {
        let dir = tempfile::tempdir().unwrap();
        let e = compare(dir.path(), extra).err().unwrap();
        let line = fluidtex_cli::one_line(&e);
        assert!(line.contains(expected), "{extra:?}: {line}");
        assert!(!line.contains('\n'));
        assert!(!dir.path().join("report.json").exists());
    }
}

#[test]
fn compare_takes_method_parameters_from_a_config_file() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("params.toml");
    // The file's atlas and mesh must not win over compare's own choices.
    std::fs::write(
        &config,
        "mesh = \"nowhere.####.ply\"\natlas = 4096\n[erosion]\ndelta_max = 2.0\ndelta_onset = 1.25\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    compare(
        &out,
        &["--methods", "erosion", "--config", config.to_str().unwrap()],
    )
    .unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["atlas_size"], 64);
    let params = &json["scenes"][0]["methods"][0]["parameters"];
    assert_eq!(params["atlas"], 64);
    assert_eq!(params["parameters"]["delta_max"], 2.0);
    assert_eq!(params["parameters"]["delta_onset"], 1.25);
    // Without the file: the defaults.
    let plain = dir.path().join("plain");
    compare(&plain, &["--methods", "erosion"]).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(plain.join("report.json")).unwrap()).unwrap();
    let params = &json["scenes"][0]["methods"][0]["parameters"];
    assert_eq!(params["parameters"]["delta_max"], 3.0);
    // A bad value in the file is refused before any scene is generated.
    std::fs::write(&config, "[erosion]\ndelta_onset = 9.0\n").unwrap();
    let bad = dir.path().join("bad");
    let e = compare(
        &bad,
        &["--methods", "erosion", "--config", config.to_str().unwrap()],
    )
    .err()
    .unwrap();
    let line = fluidtex_cli::one_line(&e);
    assert!(line.contains("delta_onset = 9"), "{line}");
    assert!(!bad.join("report.json").exists());
}

/// `--paper` runs each method twice, its default and `--preset paper`,
/// side by side: the second row carries the preset's parameters (with the
/// config file's own keys still winning) and measures a different texture.
#[test]
fn compare_paper_reports_each_method_beside_its_preset_run() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("params.toml");
    std::fs::write(&config, "[erosion]\ntone = \"match\"\n").unwrap();
    let out = dir.path().join("out");
    compare(
        &out,
        &[
            "--methods",
            "erosion,lapped-rigid",
            "--paper",
            "--config",
            config.to_str().unwrap(),
        ],
    )
    .unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert!(json["command"].as_str().unwrap().ends_with(" --paper"));
    let methods = json["scenes"][0]["methods"].as_array().unwrap();
    let names: Vec<&str> = methods
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "erosion",
            "erosion (paper)",
            "lapped-rigid",
            "lapped-rigid (paper)"
        ]
    );
    let params = |k: usize| &methods[k]["parameters"]["parameters"];
    assert_eq!(params(0)["weights"], "progressive");
    assert_eq!(params(1)["weights"], "paper");
    assert_eq!(params(1)["seed_corners"], "paper");
    // The file's key wins over the preset's `tone = "off"`.
    assert_eq!(params(0)["tone"], "match");
    assert_eq!(params(1)["tone"], "match");
    assert_eq!(params(3)["placement"], "random");
    assert_eq!(methods[3]["parameters"]["preset"], "paper");
    // The preset changes what is measured.
    let popping = |k: usize| {
        methods[k]["metrics"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["key"] == "popping")
            .unwrap()["mean"]
            .clone()
    };
    assert_ne!(popping(0), popping(1));
    assert_ne!(popping(2), popping(3));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("| erosion (paper) |"), "{md}");
}
