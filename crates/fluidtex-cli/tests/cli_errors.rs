//! Bad input through the real binary: each case must exit non-zero without
//! a panic (not 101) and print exactly one stderr line starting with
//! `error: ` that names the file and, where it applies, the frame and the
//! element. Each case also has a known-good twin (the same command on good
//! input succeeds), so a test cannot pass because everything fails.

#![allow(clippy::unwrap_used)]

mod common;

use std::ffi::OsString;
use std::path::Path;

use common::*;

/// `run` arguments: the pattern, the output folder, then `extra`.
fn run_args(pattern: &Path, out: &Path, extra: &[&str]) -> Vec<OsString> {
    let mut a: Vec<OsString> = vec![
        "run".into(),
        "--mesh".into(),
        pattern.into(),
        "--out".into(),
        out.into(),
        "--quiet".into(),
    ];
    a.extend(extra.iter().map(OsString::from));
    a
}

const CHECK_64: &[&str] = &["--method", "atlas-check", "--atlas", "64"];

/// The interop ASCII sequence copied into `dir` as `in.0001.ply`...
fn ascii_frames(dir: &Path, frames: &[i32]) -> std::path::PathBuf {
    let files: Vec<(String, String)> = frames
        .iter()
        .map(|f| (format!("meshio_ascii.{f:04}.ply"), format!("in.{f:04}.ply")))
        .collect();
    let pairs: Vec<(&str, &str)> = files
        .iter()
        .map(|(a, b)| (a.as_str(), b.as_str()))
        .collect();
    copy_interop(dir, &pairs);
    dir.join("in.####.ply")
}

fn assert_contains(line: &str, parts: &[&str]) {
    for p in parts {
        assert!(line.contains(p), "{line:?} does not contain {p:?}");
    }
}

#[test]
fn missing_frame_in_a_range_names_the_frame_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = ascii_frames(&dir.path().join("in"), &[1, 3]);
    let out = dir.path().join("out");
    let missing = dir.path().join("in/in.0002.ply");
    for extra in [&["--frames", "1-3"][..], &[]] {
        let args = run_args(&pattern, &out, &[CHECK_64, extra].concat());
        let line = user_error(&args);
        assert_eq!(
            line,
            format!(
                "error: missing frame 2: {} does not exist",
                missing.display()
            )
        );
        assert!(!out.exists(), "a missing frame is found before any work");
    }
    let line = user_error(&[Path::new("info"), &pattern]);
    assert_contains(&line, &["missing frame 2", &missing.display().to_string()]);
    // Known good: the frames that exist.
    ok(&run_args(
        &pattern,
        &out,
        &[CHECK_64, &["--frames", "3"]].concat(),
    ));
}

#[test]
fn truncated_ply_names_the_file_and_the_last_element() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (source, vertex_bytes) in [
        ("trimesh_binary.0001.ply", Some(24)),
        ("meshio_ascii.0001.ply", None),
    ] {
        let bytes = std::fs::read(interop(source)).unwrap();
        let header = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        // Binary: cut inside a vertex (6 floats each). ASCII: cut at a line
        // end (a cut inside a line is a short vertex, also an error).
        let (cut, complete) = match vertex_bytes {
            Some(size) => (header + 1500, 1500 / size),
            None => {
                let end = header
                    + bytes[header..header + 1500]
                        .iter()
                        .rposition(|&b| b == b'\n')
                        .unwrap()
                    + 1;
                (
                    end,
                    bytes[header..end].iter().filter(|&&b| b == b'\n').count(),
                )
            }
        };
        let path = dir.path().join("cut.0001.ply");
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let line = user_error(&run_args(&dir.path().join("cut.####.ply"), &out, CHECK_64));
        assert_eq!(
            line,
            format!(
                "error: {}: truncated: expected 162 vertices, file ends in vertex {complete}",
                path.display()
            ),
            "{source}"
        );
        // Known good: the whole file.
        std::fs::write(&path, &bytes).unwrap();
        ok(&run_args(&dir.path().join("cut.####.ply"), &out, CHECK_64));
    }
}

#[test]
fn garbled_ply_header_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(interop("meshio_ascii.0001.ply")).unwrap();
    let path = dir.path().join("g.0001.ply");
    let pattern = dir.path().join("g.####.ply");
    for (from, to) in [
        ("element vertex 162", "element vertex abc"),
        ("format ascii 1.0", "format asci 1.0"),
        ("end_header", "end_headr"),
    ] {
        std::fs::write(&path, good.replacen(from, to, 1)).unwrap();
        let line = user_error(&run_args(&pattern, &dir.path().join("out"), CHECK_64));
        assert_contains(&line, &[&format!("error: {}: ", path.display())]);
        let line = user_error(&[Path::new("info"), &pattern]);
        assert_contains(&line, &[&path.display().to_string()]);
    }
    std::fs::write(&path, good).unwrap();
    ok(&[Path::new("info"), &pattern]);
}

#[test]
fn face_index_out_of_range_names_file_face_and_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = ascii_frames(dir.path(), &[1, 2]);
    let path = dir.path().join("in.0002.ply");
    let text = std::fs::read_to_string(&path).unwrap();
    // Face 88 is line 13 (header) + 162 (vertices) + 88 + 1.
    let mut lines: Vec<&str> = text.lines().collect();
    assert!(lines[13 + 162 + 88].starts_with("3 "));
    lines[13 + 162 + 88] = "3 0 9999 53";
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let line = user_error(&run_args(&pattern, &dir.path().join("out"), CHECK_64));
    assert!(
        line.starts_with(&format!(
            "error: {}: face 88 refers to vertex 9999, but the mesh has 162 vertices",
            path.display()
        )),
        "{line}"
    );
}

/// Bug: the one-line message repeats its cause, e.g.
/// `in.0002.ply: face 88 refers to vertex 9999, but the mesh has 162
/// vertices: face 88 refers to vertex 9999, but the mesh has 162 vertices`,
/// and `frame 1: 6 charts do not fit ...: 6 charts do not fit ...`.
#[test]
fn error_lines_do_not_repeat_their_cause() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = ascii_frames(dir.path(), &[1]);
    let path = dir.path().join("in.0001.ply");
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, text.replacen("\n3 0 137 53\n", "\n3 0 9999 53\n", 1)).unwrap();
    let line = user_error(&run_args(&pattern, &dir.path().join("out"), CHECK_64));
    assert_eq!(line.matches("refers to vertex 9999").count(), 1, "{line}");

    let pattern = ascii_frames(&dir.path().join("good"), &[1]);
    let line = user_error(&run_args(
        &pattern,
        &dir.path().join("out2"),
        &["--method", "atlas-check", "--atlas", "16", "--gutter", "64"],
    ));
    assert_eq!(line.matches("do not fit").count(), 1, "{line}");
}

#[test]
fn nan_velocity_names_the_file_and_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = ascii_frames(dir.path(), &[1]);
    let path = dir.path().join("in.0001.ply");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // Vertex 17: x y z vx vy vz; vx becomes NaN.
    let mut cols: Vec<&str> = lines[13 + 17].split(' ').collect();
    cols[3] = "nan";
    lines[13 + 17] = cols.join(" ");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    for method in ["erosion", "atlas-check"] {
        let line = user_error(&run_args(
            &pattern,
            &dir.path().join("out"),
            &["--method", method, "--atlas", "64"],
        ));
        assert!(
            line.starts_with(&format!("error: {}: vertex 17: ", path.display())),
            "{line}"
        );
        assert_contains(&line, &["non-finite"]);
    }
}

#[test]
fn bad_flags_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = interop("meshio_ascii.####.ply");
    let out = dir.path().join("out");
    let cases: &[(&[&str], &str)] = &[
        (
            &["--method", "magic"],
            "error: invalid value 'magic' for '--method <METHOD>' [possible values: erosion, advect, dual-rest, blend-deformable, atlas-check, optimization, lapped-rigid]",
        ),
        (
            &["--atlas", "0"],
            "error: --atlas 0: allowed 16 to 16384 texels",
        ),
        (
            &["--frames", "5-2"],
            "error: invalid frame range \"5-2\": first frame 5 is after last frame 2",
        ),
        (
            &["--delta-onset", "3.5"],
            "error: parameter delta_onset = 3.5 is out of range (allowed: [1, delta_max))",
        ),
        (
            &["--delta-onset", "3"],
            "error: parameter delta_onset = 3 is out of range (allowed: [1, delta_max))",
        ),
        (
            &["--transition", "9"],
            "error: parameter transition = 9 is out of range (allowed: 0..=8 frames)",
        ),
        (
            &["--channel", "displacement"],
            "error: --channel displacement: expected NAME=IMAGE, e.g. displacement=disp.exr",
        ),
    ];
    for (extra, expected) in cases {
        let line = user_error(&run_args(&pattern, &out, extra));
        assert_eq!(&line, expected);
        assert!(!out.exists(), "{extra:?} created the output folder");
    }
    // Known good: the same command without the bad flag.
    ok(&run_args(
        &pattern,
        &out,
        &["--method", "atlas-check", "--atlas", "16"],
    ));
    // The onset is checked against the δ_max of the same run.
    let _ = std::fs::remove_dir_all(&out);
    ok(&run_args(
        &pattern,
        &out,
        &["--delta-onset", "3", "--delta-max", "4", "--atlas", "16"],
    ));
}

#[test]
fn config_with_an_unknown_key_names_the_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("shot.toml");
    let out = dir.path().join("out");
    let good = "method = \"atlas-check\"\natlas = 64\n[erosion]\nepsilon = 0.1\nradius = 0.5\n";
    std::fs::write(&config, good.replace("radius", "radus")).unwrap();
    let mut args = run_args(&interop("meshio_ascii.####.ply"), &out, &[]);
    args.extend(["--config".into(), config.clone().into()]);
    let line = user_error(&args);
    assert!(
        line.starts_with(&format!(
            "error: {}: line 5: unknown field `radus`",
            config.display()
        )),
        "{line}"
    );
    assert!(!out.exists());
    std::fs::write(&config, good).unwrap();
    ok(&args);
}

#[test]
fn exemplar_and_channel_errors_name_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = interop("meshio_ascii.####.ply");
    let out = dir.path().join("out");
    let gravel = exemplar("gravel.png");
    let base = ["--frames", "1", "--atlas", "64"];

    let missing = dir.path().join("nope.png");
    let mut extra = base.to_vec();
    let m = missing.display().to_string();
    extra.extend(["--exemplar", &m]);
    let line = user_error(&run_args(&pattern, &out, &extra));
    assert_eq!(line, format!("error: {m}: file not found"));

    let write_grey = |name: &str, size: u32| {
        let path = dir.path().join(name);
        let t = fluidtex::texture::Texture::filled(size, size, 1, 0.5);
        fluidtex::io::image::write_png(&path, &t, &Default::default()).unwrap();
        path
    };
    let small = write_grey("small.png", 256);
    let (g, s) = (gravel.display().to_string(), small.display().to_string());
    let mut extra = base.to_vec();
    let spec = format!("disp={s}");
    extra.extend(["--exemplar", &g, "--channel", &spec]);
    let line = user_error(&run_args(&pattern, &out, &extra));
    assert_eq!(
        line,
        format!("error: {s} is 256x256 but the colour exemplar {g} is 512x512; they must match")
    );

    // Known good: a channel of the exemplar's size is synthesised with it.
    let same = write_grey("same.png", 512);
    let mut extra = base.to_vec();
    let spec = format!("disp={}", same.display());
    extra.extend(["--exemplar", &g, "--channel", &spec]);
    ok(&run_args(&pattern, &out, &extra));
    let disp = image(&out.join("disp.0001.png"));
    assert_eq!((disp.width, disp.height, disp.channels), (64, 64, 1));
}

#[test]
fn resume_onto_a_folder_of_other_settings_is_refused_and_touches_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = interop("meshio_ascii.####.ply");
    let out = dir.path().join("out");
    ok(&run_args(
        &pattern,
        &out,
        &[
            "--method",
            "atlas-check",
            "--atlas",
            "64",
            "--frames",
            "1-2",
        ],
    ));
    let before = files(&out);
    for other in [
        &[
            "--method",
            "atlas-check",
            "--atlas",
            "128",
            "--frames",
            "1-3",
        ][..],
        &["--method", "erosion", "--atlas", "64", "--frames", "1-3"],
    ] {
        let mut extra = other.to_vec();
        extra.push("--resume");
        let line = user_error(&run_args(&pattern, &out, &extra));
        assert_eq!(
            line,
            format!(
                "error: cannot resume: {} was written by a run with another configuration or \
                 method (atlas-check); rerun without --resume or with the same settings",
                out.join("state.bin").display()
            )
        );
        assert!(files(&out) == before, "a refused resume changed the folder");
    }
    // Known good: the same settings resume and add frame 3.
    ok(&run_args(
        &pattern,
        &out,
        &[
            "--method",
            "atlas-check",
            "--atlas",
            "64",
            "--frames",
            "1-3",
            "--resume",
        ],
    ));
    assert!(out.join("stats.0003.json").is_file());
}

/// Inputs named `mesh.####.obj` and `--out` their own folder: OBJ output
/// `mesh.F.obj` would replace the input. The run is refused and the input
/// keeps its bytes.
#[test]
fn output_that_would_replace_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    copy_interop(dir.path(), &[("trimesh.obj", "mesh.0002.obj")]);
    let input = dir.path().join("mesh.0002.obj");
    let original = std::fs::read(&input).unwrap();
    let line = user_error(&run_args(
        &dir.path().join("mesh.####.obj"),
        dir.path(),
        CHECK_64,
    ));
    assert_eq!(
        line,
        format!(
            "error: {}: refusing to overwrite an input of this run",
            input.display()
        )
    );
    assert!(
        std::fs::read(&input).unwrap() == original,
        "the input was changed"
    );
    // Known good: the same folder without OBJ output.
    let mut extra = CHECK_64.to_vec();
    extra.push("--no-obj");
    ok(&run_args(
        &dir.path().join("mesh.####.obj"),
        dir.path(),
        &extra,
    ));
    assert!(std::fs::read(&input).unwrap() == original);
    assert!(dir.path().join("mesh.0002.glb").is_file());
}
