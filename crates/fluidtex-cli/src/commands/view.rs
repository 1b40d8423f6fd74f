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
//!
//! **Only this machine's browser.** Listening on 127.0.0.1 keeps other
//! machines out, but not a web page the user visits elsewhere: it can
//! rebind its own host name to 127.0.0.1 (DNS rebinding) and read the
//! served folder through the user's browser, under its own name. So, as
//! Jupyter and Vite do, a request is answered only when its `Host` is
//! `127.0.0.1:PORT` or `localhost:PORT` (403 otherwise, or without one),
//! and only in origin form (`GET /path`; an absolute URL as the target is
//! refused with 400). Every response says `X-Content-Type-Options:
//! nosniff` and carries a Content-Security-Policy that lets the page load
//! scripts, styles, images and data from this server alone (plus the
//! blob: URLs three.js makes for the textures inside a glb), nothing from
//! outside; the page uses no CDN.

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
        if let Err(e) = answer(dir, port, request) {
            eprintln!("fluidtex view: {e}");
        }
    }
    Ok(())
}

/// Answers one request on `port`, with [`guarded`] headers.
fn answer(dir: &Path, port: u16, request: Request) -> std::io::Result<()> {
    let host = request
        .headers()
        .iter()
        .find(|h| h.field.equiv("Host"))
        .map(|h| h.value.as_str().to_string());
    if !host_allowed(host.as_deref(), port) {
        let r = Response::from_string("this server answers only http://127.0.0.1 and localhost");
        return request.respond(guarded(r.with_status_code(403)));
    }
    if !request.url().starts_with('/') {
        let r = Response::from_string("origin-form request targets only");
        return request.respond(guarded(r.with_status_code(400)));
    }
    if *request.method() != Method::Get && *request.method() != Method::Head {
        return request.respond(guarded(
            Response::from_string("only GET").with_status_code(405),
        ));
    }
    // The query string (?frame=3) is for the page's script, not for us.
    let url = request.url().to_string();
    let path = url.split(['?', '#']).next().unwrap_or("/");
    if let Some((_, bytes, mime)) = ASSETS.iter().find(|(p, _, _)| *p == path) {
        return request.respond(guarded(
            Response::from_data(*bytes).with_header(content_type(mime)),
        ));
    }
    if path == "/api/frames" {
        let body = match scan(dir) {
            Ok(frames) => serde_json::json!({ "dir": dir.display().to_string(), "frames": frames }),
            Err(e) => serde_json::json!({ "error": crate::one_line(&e) }),
        };
        return request.respond(guarded(
            Response::from_string(body.to_string())
                .with_header(content_type("application/json"))
                .with_header(no_store()),
        ));
    }
    if let Some(name) = path.strip_prefix("/files/") {
        let Some(name) = safe_name(name) else {
            return request.respond(guarded(
                Response::from_string("bad file name").with_status_code(400),
            ));
        };
        let file = dir.join(name);
        return match std::fs::File::open(&file) {
            Ok(f) if file.is_file() => request.respond(guarded(
                Response::from_file(f)
                    .with_header(content_type(mime_of(name)))
                    .with_header(no_store()),
            )),
            _ => request.respond(guarded(
                Response::from_string("not found").with_status_code(404),
            )),
        };
    }
    request.respond(guarded(
        Response::from_string("not found").with_status_code(404),
    ))
}

/// Whether a request's `Host` header names this server: `127.0.0.1:PORT`
/// or `localhost:PORT` (any case), nothing else, and not its absence.
pub fn host_allowed(host: Option<&str>, port: u16) -> bool {
    let Some(host) = host else {
        return false;
    };
    let Some((name, p)) = host.trim().rsplit_once(':') else {
        return false;
    };
    p == port.to_string() && (name == "127.0.0.1" || name.eq_ignore_ascii_case("localhost"))
}

/// The page's one inline script is its import map (three.js's modules
/// import `three` by name); its SHA-256 lets the policy allow exactly it.
const IMPORT_MAP_HASH: &str = "sha256-F7vMP3gbsWsT14rqIj7ZO3yz/P/BTaBO+/htkjmg8wE=";

/// What the page may load: from this server only (scripts also the import
/// map by its hash, images and data also the blob: URLs three.js makes for
/// a glb's embedded textures), inline styles, no frames, no forms.
pub fn content_security_policy() -> String {
    format!(
        "default-src 'none'; script-src 'self' '{IMPORT_MAP_HASH}'; \
         style-src 'self' 'unsafe-inline'; img-src 'self' blob: data:; \
         connect-src 'self' blob: data:; base-uri 'none'; form-action 'none'; \
         frame-ancestors 'none'"
    )
}

/// `response` with the headers every answer carries.
fn guarded<R: std::io::Read>(response: Response<R>) -> Response<R> {
    let nosniff =
        Header::from_bytes("X-Content-Type-Options", "nosniff").expect("constant ASCII header");
    let csp = Header::from_bytes("Content-Security-Policy", content_security_policy())
        .expect("constant ASCII header");
    response.with_header(nosniff).with_header(csp)
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
    fn only_this_servers_own_names_are_answered() {
        for ok in [
            "127.0.0.1:8123",
            "localhost:8123",
            "LocalHost:8123",
            " localhost:8123 ",
        ] {
            assert!(host_allowed(Some(ok), 8123), "{ok}");
        }
        for bad in [
            None,
            Some("evil.example"),
            Some("evil.example:8123"),
            Some("127.0.0.1"),
            Some("127.0.0.1:80"),
            Some("localhost:81230"),
            Some("127.0.0.2:8123"),
            Some("localhost.evil.example:8123"),
            Some("[::1]:8123"),
            Some(""),
        ] {
            assert!(!host_allowed(bad, 8123), "{bad:?}");
        }
    }

    #[test]
    fn the_policy_allows_exactly_the_pages_import_map() {
        use base64::Engine as _;
        use sha2::Digest as _;
        let page = std::str::from_utf8(include_bytes!("../../assets/viewer/index.html"))
            .expect("utf-8 page");
        let open = r#"<script type="importmap">"#;
        let start = page.find(open).expect("an import map") + open.len();
        let end = start + page[start..].find("</script>").expect("its end");
        let digest = sha2::Sha256::digest(&page.as_bytes()[start..end]);
        let hash = base64::engine::general_purpose::STANDARD.encode(digest);
        assert_eq!(IMPORT_MAP_HASH, format!("sha256-{hash}"));
        // The only inline script: everything else comes from this server.
        assert_eq!(page.matches("<script").count(), 2);
        assert!(page.contains(r#"<script type="module" src="/viewer.js">"#));
        assert!(!page.contains("http://") && !page.contains("https://"));
        let csp = content_security_policy();
        assert!(csp.starts_with("default-src 'none'; script-src 'self' 'sha256-"));
        assert!(!csp.contains("unsafe-eval") && !csp.contains('*'), "{csp}");
    }

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
