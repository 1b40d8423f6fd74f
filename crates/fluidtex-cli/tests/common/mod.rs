//! Helpers shared by the command-line tests: running the real binary,
//! reading its outputs, and the interop meshes of the library's test data.
//!
//! Every test drives `fluidtex` as a user would, through the binary
//! (`CARGO_BIN_EXE_fluidtex`), so argument parsing, exit codes and what
//! lands on stderr are part of what is tested.

#![allow(dead_code, clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `fluidtex` binary, with no inherited thread-count setting so tests
/// that set one are the only ones that do.
pub fn fluidtex() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_fluidtex"));
    c.env_remove("RAYON_NUM_THREADS");
    c
}

/// Runs the binary with `args`; fails the test unless it exits 0.
/// Returns stdout.
pub fn ok<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> String {
    let out = fluidtex().args(args).output().unwrap();
    check_ok(&out, args);
    String::from_utf8(out.stdout).unwrap()
}

pub fn check_ok<S: AsRef<std::ffi::OsStr>>(out: &Output, args: &[S]) {
    assert!(
        out.status.success(),
        "fluidtex {:?} failed ({:?}):\n{}",
        args.iter().map(|a| a.as_ref()).collect::<Vec<_>>(),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs the binary with `args` and expects a user error: a non-zero exit
/// that is not a panic (Rust exits 101 on a panic), and exactly one line on
/// stderr, starting with `error: `. Returns that line.
pub fn user_error<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> String {
    let out = fluidtex().args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let shown: Vec<_> = args.iter().map(|a| a.as_ref()).collect();
    let code = out.status.code();
    assert!(
        code.is_some_and(|c| c != 0 && c != 101),
        "fluidtex {shown:?}: exit {code:?}, expected a non-zero non-panic code; stderr:\n{stderr}"
    );
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(
        lines.len(),
        1,
        "fluidtex {shown:?}: expected one stderr line, got:\n{stderr}"
    );
    assert!(
        lines[0].starts_with("error: "),
        "fluidtex {shown:?}: {stderr}"
    );
    lines[0].to_string()
}

/// A file of the library's interop test data (see its README).
pub fn interop(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fluidtex/tests/data/interop")
        .join(name)
}

/// A file of the library's exemplar test data.
pub fn exemplar(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fluidtex/tests/data/exemplars")
        .join(name)
}

/// Copies interop files into `dir`, renamed: `(from, to)` pairs.
pub fn copy_interop(dir: &Path, files: &[(&str, &str)]) {
    std::fs::create_dir_all(dir).unwrap();
    for (from, to) in files {
        std::fs::copy(interop(from), dir.join(to)).unwrap();
    }
}

/// Every file in `dir` (hidden ones included), by name, with its bytes.
pub fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().into_string().unwrap(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

/// Names in `dir` that look like the atomic writer's temporaries
/// (`.<name>.<random>.tmp`).
pub fn temporaries(dir: &Path) -> Vec<String> {
    let mut t: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with('.') && n.ends_with(".tmp"))
        .collect();
    t.sort();
    t
}

/// A stats file with its wall-clock `seconds` removed: the only part of
/// the outputs that may differ between two runs of the same job.
pub fn stats_without_timings(bytes: &[u8]) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
    let map = v.as_object_mut().unwrap();
    assert!(map.remove("seconds").is_some(), "no seconds in {map:?}");
    v
}

/// A stats file without what differs between any two runs (the seconds)
/// and between a one-pass and a two-phase run's frame (the names of the
/// stages timed).
pub fn stats_without_stages(bytes: &[u8]) -> serde_json::Value {
    let mut v = stats_without_timings(bytes);
    v.as_object_mut().unwrap().remove("stage_order");
    v
}

/// Asserts that `two_phase` holds the files of the one-pass run in
/// `one_pass` with their bytes (stats without their timings), plus only
/// the selections (`selection.F.bin`); returns the two-phase files.
pub fn assert_two_phase_matches(one_pass: &Path, two_phase: &Path) -> BTreeMap<String, Vec<u8>> {
    let (one, two) = (files(one_pass), files(two_phase));
    let mut names: Vec<&String> = two.keys().collect();
    names.retain(|n| !n.starts_with("selection."));
    assert_eq!(
        one.keys().collect::<Vec<_>>(),
        names,
        "{} and {}: the same files",
        one_pass.display(),
        two_phase.display()
    );
    for (name, bytes) in &one {
        if name.starts_with("stats.") {
            assert_eq!(
                stats_without_stages(bytes),
                stats_without_stages(&two[name]),
                "{name} differs"
            );
        } else {
            assert!(bytes == &two[name], "{name} differs");
        }
    }
    two
}

/// `fluidtex scene vortex` at resolution 14, frames 0-5, into `dir/scene`:
/// a small sheared flow whose patches renew between frames. Returns the
/// frames' pattern.
pub fn small_vortex(dir: &Path) -> PathBuf {
    scene(dir, "vortex", Some("14"), "0-5")
}

/// `fluidtex scene NAME` (at `resolution`, or the scene's own) over
/// `frames` into `dir/scene`. Returns the frames' pattern.
pub fn scene(dir: &Path, name: &str, resolution: Option<&str>, frames: &str) -> PathBuf {
    let scene = dir.join("scene");
    let mut args: Vec<std::ffi::OsString> = vec!["scene".into(), name.into()];
    if let Some(r) = resolution {
        args.extend(["--resolution".into(), r.into()]);
    }
    args.extend(["--frames".into(), frames.into(), "--quiet".into()]);
    args.extend(["--out".into(), scene.clone().into()]);
    ok(&args);
    scene.join("fluid.####.ply")
}

/// Asserts that two output folders hold the same files with the same
/// bytes, except for the timings inside `stats.F.json`.
pub fn assert_same_outputs(a: &Path, b: &Path) {
    let fa = files(a);
    let fb = files(b);
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "{} and {} hold different files",
        a.display(),
        b.display()
    );
    for (name, bytes) in &fa {
        if name.starts_with("stats.") {
            assert_eq!(
                stats_without_timings(bytes),
                stats_without_timings(&fb[name]),
                "{name} differs"
            );
        } else {
            assert!(bytes == &fb[name], "{name} differs");
        }
    }
}

/// Width and height of a decoded PNG or EXR (decoded in full, by the
/// library's exemplar reader).
pub fn image(path: &Path) -> fluidtex::texture::Texture {
    fluidtex::io::image_read::read_image(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .texture
}

/// A frame of a meshio ASCII PLY of the interop data, parsed here
/// independently of the library's reader: positions and velocities.
pub struct AsciiPly {
    pub positions: Vec<[f32; 3]>,
    pub velocities: Vec<[f32; 3]>,
    pub faces: usize,
}

pub fn read_meshio_ascii(path: &Path) -> AsciiPly {
    let text = std::fs::read_to_string(path).unwrap();
    let (header, body) = text.split_once("end_header\n").unwrap();
    let count = |element: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .unwrap()
            .trim()
            .parse()
            .unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let props: Vec<&str> = header
        .lines()
        .skip_while(|l| !l.starts_with("element vertex"))
        .skip(1)
        .take_while(|l| l.starts_with("property"))
        .map(|l| l.rsplit(' ').next().unwrap())
        .collect();
    assert_eq!(
        props,
        ["x", "y", "z", "vx", "vy", "vz"],
        "{}",
        path.display()
    );
    let mut ply = AsciiPly {
        positions: Vec::new(),
        velocities: Vec::new(),
        faces: nf,
    };
    for line in body.lines().take(nv) {
        let n: Vec<f32> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        ply.positions.push([n[0], n[1], n[2]]);
        ply.velocities.push([n[3], n[4], n[5]]);
    }
    assert_eq!(body.lines().count(), nv + nf);
    ply
}

/// The Khronos glTF validator (`.tools/node_modules/gltf-validator`, or
/// `FLUIDTEX_GLTF_VALIDATOR`), found as the library's `io_gltf` test finds
/// it. `None` when absent, unless `FLUIDTEX_REQUIRE_TOOLS=1`: then absent
/// fails the test.
pub fn gltf_validator() -> Option<(PathBuf, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = match std::env::var_os("FLUIDTEX_GLTF_VALIDATOR") {
        Some(d) => PathBuf::from(d),
        None => root.join(".tools/node_modules/gltf-validator"),
    };
    let node_ok = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    let script = root.join("crates/fluidtex/tests/gltf_validate.js");
    if node_ok && dir.join("package.json").is_file() {
        return Some((dir.canonicalize().unwrap(), script));
    }
    let msg = "Khronos glTF validator not found: run `npm install --prefix .tools \
               gltf-validator@2.0.0-dev.3.10` at the workspace root, or set FLUIDTEX_GLTF_VALIDATOR";
    missing_tool("skipping the glTF validation", msg);
    None
}

/// A program a test needs (Blender, ffmpeg, Chromium, the glTF validator)
/// is missing, `msg` saying which and how to install it. Under
/// `FLUIDTEX_REQUIRE_TOOLS=1` (CI) that fails the test; otherwise it prints
/// `note: {skipping}: {msg}` and the caller skips what needs the program.
#[track_caller]
pub fn missing_tool(skipping: &str, msg: &str) {
    if std::env::var("FLUIDTEX_REQUIRE_TOOLS").as_deref() == Ok("1") {
        panic!("{msg} (FLUIDTEX_REQUIRE_TOOLS=1)");
    }
    eprintln!("note: {skipping}: {msg}");
}

/// The validator's report on one file: `errors`, `warnings`, `messages`.
pub fn validate_glb(validator: &(PathBuf, PathBuf), file: &Path) -> serde_json::Value {
    let (dir, script) = validator;
    let out = Command::new("node")
        .arg(script)
        .arg(dir)
        .arg(file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "validator failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// A run held by a test hook (see `fluidtex_cli::test_hooks`): the child,
/// its standard input (drop it to let the run go on) and the hook's line.
pub struct Paused {
    pub child: std::process::Child,
    pub stdin: Option<std::process::ChildStdin>,
    pub line: String,
    /// The rest of stderr, read on a thread until the child ends.
    pub stderr: std::thread::JoinHandle<String>,
}

/// Starts `fluidtex args` with the hook variables `env` and waits until it
/// prints `fluidtex-test: paused ...` (no timing involved: the child waits
/// for us). Fails the test if the child ends without pausing.
pub fn spawn_paused<S: AsRef<std::ffi::OsStr>>(args: &[S], env: &[(&str, &str)]) -> Paused {
    use std::io::BufRead;
    let mut cmd = fluidtex();
    cmd.args(args)
        .stdin(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped());
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().unwrap();
    let stdin = child.stdin.take();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut seen = String::new();
    let mut line = String::new();
    loop {
        line.clear();
        if err.read_line(&mut line).unwrap() == 0 {
            let status = child.wait().unwrap();
            panic!("the run ended ({status:?}) without pausing; stderr:\n{seen}");
        }
        if line.starts_with("fluidtex-test: paused") {
            break;
        }
        seen.push_str(&line);
    }
    let stderr = std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = std::io::Read::read_to_string(&mut err, &mut rest);
        rest
    });
    Paused {
        child,
        stdin,
        line: line.trim_end().to_string(),
        stderr,
    }
}

impl Paused {
    /// SIGKILL, as a farm's scheduler or the OOM killer would.
    pub fn kill(mut self) {
        self.child.kill().unwrap();
        let status = self.child.wait().unwrap();
        assert!(!status.success());
    }

    /// Lets the run go on to its end; returns whether it succeeded and
    /// the rest of its stderr.
    pub fn resume(mut self) -> (bool, String) {
        drop(self.stdin.take());
        let status = self.child.wait().unwrap();
        (status.success(), self.stderr.join().unwrap())
    }
}

/// "69 MiB" or "1.3 GiB" (as the CLI prints sizes) in bytes.
pub fn size(text: &str) -> f64 {
    let (number, unit) = text.trim().split_once(' ').unwrap();
    let unit = match unit {
        "MiB" => 1u64 << 20,
        "GiB" => 1 << 30,
        other => panic!("unit {other:?} in {text:?}"),
    };
    number.parse::<f64>().unwrap() * unit as f64
}

/// The text of `line` between `start` and the next `end`.
pub fn between<'a>(line: &'a str, start: &str, end: &str) -> &'a str {
    let from = line
        .find(start)
        .unwrap_or_else(|| panic!("{start:?} in {line:?}"))
        + start.len();
    let to = line[from..]
        .find(end)
        .unwrap_or_else(|| panic!("{end:?} in {line:?}"));
    &line[from..from + to]
}

/// A run's stderr (without `--quiet`) ends with `peak memory P (estimated
/// E)`: the estimate made before the first frame bounds the peak it then
/// reached, by no more than twice. Returns (peak, estimate) in bytes.
pub fn assert_estimate_bounds_peak(stderr: &str, what: &str) -> (f64, f64) {
    let (measured, estimated) = peak_and_estimate(stderr, what);
    assert!(estimated >= measured, "{what}: {measured} > {estimated}");
    assert!(
        estimated <= 2.0 * measured,
        "{what}: {estimated} > 2 × {measured}"
    );
    (measured, estimated)
}

/// The (peak, estimate) in bytes of a run's `peak memory P (estimated E)`
/// line.
pub fn peak_and_estimate(stderr: &str, what: &str) -> (f64, f64) {
    let line = stderr
        .lines()
        .find(|l| l.starts_with("peak memory "))
        .unwrap_or_else(|| panic!("{what}: no peak memory line: {stderr}"));
    eprintln!("{what}: {line}");
    let measured = size(between(line, "peak memory ", " ("));
    let estimated = size(between(line, "(estimated ", ")"));
    (measured, estimated)
}

/// Appends the faces of an n × n grid of squares, two triangles each, over
/// vertices numbered row by row ((n + 1)² of them).
pub fn push_grid_faces(ply: &mut String, n: usize) {
    let w = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * w + i;
            ply.push_str(&format!("3 {a} {} {}\n", a + 1, a + w + 1));
            ply.push_str(&format!("3 {a} {} {}\n", a + w + 1, a + w));
        }
    }
}

/// Writes `frames` ASCII PLY frames of a flat 12×12 grid at rest with a
/// per-vertex `temperature` of `t(x, frame)`; returns the pattern.
pub fn cooling_grid(dir: &Path, frames: usize, t: impl Fn(f32, usize) -> f32) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let n = 12usize;
    for f in 0..frames {
        let mut ply = String::new();
        let verts = (n + 1) * (n + 1);
        ply.push_str(&format!(
            "ply\nformat ascii 1.0\nelement vertex {verts}\nproperty float x\nproperty float y\n\
             property float z\nproperty float vx\nproperty float vy\nproperty float vz\n\
             property float temperature\nelement face {}\nproperty list uchar int vertex_indices\n\
             end_header\n",
            2 * n * n
        ));
        for j in 0..=n {
            for i in 0..=n {
                let x = i as f32 / n as f32 - 0.5;
                let y = j as f32 / n as f32 - 0.5;
                ply.push_str(&format!("{x} {y} 0 0 0 0 {}\n", t(x, f)));
            }
        }
        push_grid_faces(&mut ply, n);
        std::fs::write(dir.join(format!("fluid.{f:04}.ply")), ply).unwrap();
    }
    dir.join("fluid.####.ply")
}
