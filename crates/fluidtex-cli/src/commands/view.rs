//! `fluidtex view OUTDIR`: look at a result in a web browser.
//!
//! Why a local web page: every machine that runs fluidtex has a browser with
//! WebGL, and three.js draws the glb sequence `run` already writes (mesh,
//! atlas UVs and embedded colour atlas) without a conversion step, so what the
//! page shows is exactly what a glTF renderer downstream will get.
//!
//! The server is [`tiny_http`] on 127.0.0.1 only (never another interface:
//! the output folder is not meant to be published), one request at a time.
//! It serves
//! - `/`: the page (`assets/viewer/index.html`, `viewer.js`),
//! - `/vendor/three/...`: three.js, vendored from npm with its licence
//!   (`assets/viewer/vendor/three/`, see `VENDOR.md` there),
//! - `/api/frames`: the frames of the folder as JSON, found anew on every
//!   request so a run still writing shows its new frames on reload,
//! - `/files/NAME`: a plain file of the output folder, by bare name only
//!   (no `/`, no `..`, no hidden files), so nothing outside it is reachable.
//!
//! Everything the page needs is compiled into the binary with
//! `include_bytes!`: an installed `fluidtex` works offline, from any folder.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use serde::Serialize;
use tiny_http::{Header, Method, Request, Response, Server};

#[derive(Args, Debug)]
pub struct ViewArgs {
    /// Output folder of `fluidtex run` or `fluidtex demo`
    pub dir: PathBuf,
    /// Port on 127.0.0.1 \[0: any free port]
    #[arg(long, default_value_t = 0)]
    pub port: u16,
}

/// One frame of the output folder, as the page sees it: file names, `None`
/// where the run did not write that output.
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct FrameFiles {
    pub frame: i32,
    /// `mesh.F.glb` if written, else `mesh.F.obj`.
    pub mesh: String,
    pub color: Option<String>,
    pub patches: Option<String>,
    pub stats: Option<String>,
}

/// The page and three.js, compiled in: (URL path, bytes, content type).
const ASSETS: &[(&str, &[u8], &str)] = &[
    ("/", include_bytes!("../../assets/viewer/index.html"), HTML),
    (
        "/index.html",
        include_bytes!("../../assets/viewer/index.html"),
        HTML,
    ),
    (
        "/viewer.js",
        include_bytes!("../../assets/viewer/viewer.js"),
        JS,
    ),
    (
        "/vendor/three/build/three.module.js",
        include_bytes!("../../assets/viewer/vendor/three/build/three.module.js"),
        JS,
    ),
    (
        "/vendor/three/build/three.core.js",
        include_bytes!("../../assets/viewer/vendor/three/build/three.core.js"),
        JS,
    ),
    (
        "/vendor/three/addons/loaders/GLTFLoader.js",
        include_bytes!("../../assets/viewer/vendor/three/addons/loaders/GLTFLoader.js"),
        JS,
    ),
    (
        "/vendor/three/addons/loaders/OBJLoader.js",
        include_bytes!("../../assets/viewer/vendor/three/addons/loaders/OBJLoader.js"),
        JS,
    ),
    (
        "/vendor/three/addons/utils/BufferGeometryUtils.js",
        include_bytes!("../../assets/viewer/vendor/three/addons/utils/BufferGeometryUtils.js"),
        JS,
    ),
    (
        "/vendor/three/addons/utils/SkeletonUtils.js",
        include_bytes!("../../assets/viewer/vendor/three/addons/utils/SkeletonUtils.js"),
        JS,
    ),
    (
        "/vendor/three/addons/controls/OrbitControls.js",
        include_bytes!("../../assets/viewer/vendor/three/addons/controls/OrbitControls.js"),
        JS,
    ),
    (
        "/vendor/three/LICENSE",
        include_bytes!("../../assets/viewer/vendor/three/LICENSE"),
        TEXT,
    ),
];

const HTML: &str = "text/html; charset=utf-8";
const JS: &str = "text/javascript; charset=utf-8";
const TEXT: &str = "text/plain; charset=utf-8";

pub fn view(a: &ViewArgs) -> Result<()> {
    let dir = &a.dir;
    let frames = scan(dir)?;
    if frames.is_empty() {
        bail!(
            "{}: no mesh.F.glb or mesh.F.obj here; give the --out folder of `fluidtex run`",
            dir.display()
        );
    }
    let server = Server::http(("127.0.0.1", a.port))
        .map_err(|e| anyhow!("127.0.0.1:{}: cannot listen: {e}", a.port))?;
    let port = server
        .server_addr()
        .to_ip()
        .map(|s| s.port())
        .context("the server has no IP address")?;
    // The address goes to stdout, flushed, so a script (or a test) can read
    // it while the server runs.
    let mut stdout = std::io::stdout();
    writeln!(
        stdout,
        "fluidtex view: http://127.0.0.1:{port}/ shows {} ({} frames, {}-{}); Ctrl-C stops",
        dir.display(),
        frames.len(),
        frames.first().map_or(0, |f| f.frame),
        frames.last().map_or(0, |f| f.frame),
    )?;
    stdout.flush()?;
    for request in server.incoming_requests() {
        // A client that went away mid-answer is no reason to stop serving.
        if let Err(e) = answer(dir, request) {
            eprintln!("fluidtex view: {e}");
        }
    }
    Ok(())
}

/// Answers one request.
fn answer(dir: &Path, request: Request) -> std::io::Result<()> {
    if *request.method() != Method::Get && *request.method() != Method::Head {
        return request.respond(Response::from_string("only GET").with_status_code(405));
    }
    // The query string (?frame=3) is for the page's script, not for us.
    let url = request.url().to_string();
    let path = url.split(['?', '#']).next().unwrap_or("/");
    if let Some((_, bytes, mime)) = ASSETS.iter().find(|(p, _, _)| *p == path) {
        return request.respond(Response::from_data(*bytes).with_header(content_type(mime)));
    }
    if path == "/api/frames" {
        let body = match scan(dir) {
            Ok(frames) => serde_json::json!({ "dir": dir.display().to_string(), "frames": frames }),
            Err(e) => serde_json::json!({ "error": crate::one_line(&e) }),
        };
        return request.respond(
            Response::from_string(body.to_string())
                .with_header(content_type("application/json"))
                .with_header(no_store()),
        );
    }
    if let Some(name) = path.strip_prefix("/files/") {
        let Some(name) = safe_name(name) else {
            return request.respond(Response::from_string("bad file name").with_status_code(400));
        };
        let file = dir.join(name);
        return match std::fs::File::open(&file) {
            Ok(f) if file.is_file() => request.respond(
                Response::from_file(f)
                    .with_header(content_type(mime_of(name)))
                    .with_header(no_store()),
            ),
            _ => request.respond(Response::from_string("not found").with_status_code(404)),
        };
    }
    request.respond(Response::from_string("not found").with_status_code(404))
}

/// `name` if it is a bare file name of the output folder: letters, digits,
/// `.`, `_`, `-`, not starting with a dot. Everything else (`..`, `/`,
/// `%2e%2e`, hidden files) is refused.
pub fn safe_name(name: &str) -> Option<&str> {
    let ok = !name.is_empty()
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'));
    ok.then_some(name)
}

fn mime_of(name: &str) -> &'static str {
    match name.rsplit('.').next() {
        Some("glb") => "model/gltf-binary",
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("obj" | "mtl") => TEXT,
        _ => "application/octet-stream",
    }
}

fn content_type(mime: &'static str) -> Header {
    Header::from_bytes("Content-Type", mime).expect("constant ASCII header")
}

/// Frames change while a run writes them: the browser must not cache them.
fn no_store() -> Header {
    Header::from_bytes("Cache-Control", "no-store").expect("constant ASCII header")
}

/// The frames of an output folder, in frame order: every `mesh.F.glb` or
/// `mesh.F.obj` (glb preferred), with the colour atlas, patch view and stats
/// of the same F where they exist.
pub fn scan(dir: &Path) -> Result<Vec<FrameFiles>> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))?;
    let mut names = std::collections::BTreeSet::new();
    for e in entries {
        let e = e.with_context(|| format!("{}", dir.display()))?;
        if let Some(n) = e.file_name().to_str() {
            names.insert(n.to_string());
        }
    }
    // frame number -> its 4-digit (or longer, or negative) spelling
    let mut frames: BTreeMap<i32, String> = BTreeMap::new();
    for n in &names {
        let Some(rest) = n.strip_prefix("mesh.") else {
            continue;
        };
        let Some(num) = rest
            .strip_suffix(".glb")
            .or_else(|| rest.strip_suffix(".obj"))
        else {
            continue;
        };
        if let Ok(f) = num.parse::<i32>() {
            frames.entry(f).or_insert_with(|| num.to_string());
        }
    }
    let has = |n: String| names.contains(&n).then_some(n);
    Ok(frames
        .into_iter()
        .filter_map(|(frame, num)| {
            let mesh = has(format!("mesh.{num}.glb")).or_else(|| has(format!("mesh.{num}.obj")))?;
            Some(FrameFiles {
                frame,
                mesh,
                color: has(format!("color.{num}.png")),
                patches: has(format!("patches.{num}.png")),
                stats: has(format!("stats.{num}.json")),
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_bare_names_of_the_folder_are_served() {
        for good in ["mesh.0001.glb", "stats.0012.json", "color.-001.png"] {
            assert_eq!(safe_name(good), Some(good));
        }
        for bad in [
            "",
            "..",
            "../secret",
            ".hidden",
            "a/b.png",
            "%2e%2e",
            "a\\b",
            "x y",
        ] {
            assert_eq!(safe_name(bad), None, "{bad}");
        }
    }

    #[test]
    fn scan_pairs_each_mesh_with_its_frame_files_and_prefers_glb() {
        let dir = tempfile::tempdir().expect("tempdir");
        for n in [
            "mesh.0001.glb",
            "mesh.0001.obj",
            "color.0001.png",
            "stats.0001.json",
            "patches.0001.png",
            "mesh.0010.obj",
            "color.0010.png",
            "color.0002.png", // no mesh: not a frame
            "mesh.abcd.glb",  // not a number
            "notes.txt",
        ] {
            std::fs::write(dir.path().join(n), b"x").expect("write");
        }
        let frames = scan(dir.path()).expect("scan");
        assert_eq!(
            frames,
            vec![
                FrameFiles {
                    frame: 1,
                    mesh: "mesh.0001.glb".into(),
                    color: Some("color.0001.png".into()),
                    patches: Some("patches.0001.png".into()),
                    stats: Some("stats.0001.json".into()),
                },
                FrameFiles {
                    frame: 10,
                    mesh: "mesh.0010.obj".into(),
                    color: Some("color.0010.png".into()),
                    patches: None,
                    stats: None,
                },
            ]
        );
    }

    #[test]
    fn every_embedded_asset_is_there() {
        for (path, bytes, _) in ASSETS {
            assert!(bytes.len() > 100, "{path} is nearly empty");
        }
    }
}
