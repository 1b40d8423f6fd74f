//! `fluidtex view` as a user meets it: the real binary serves a real run's
//! output folder, and headless Chromium (Debian's `chromium`) draws the page.
//!
//! What the browser test checks, on the 3-D part of 960×600 screenshots:
//! - the surface is drawn (a share of pixels differs from the background),
//! - it is textured: neighbouring surface pixels differ as much as the
//!   pebbles do, where a known-bad control (the same mesh as OBJ without its
//!   atlas, drawn untextured by the same page) stays smooth,
//! - the patch view draws other colours than the texture view,
//! - two frames differ where the liquid moved (the interop sphere falls
//!   1/8 of its diameter from frame 1 to 3: its silhouette moves),
//! - each frame's stats.F.json is in the side panel.
//!
//! Chromium and Node (which drives it, `view_screenshot.js`) are optional
//! tools: without them the browser test prints a note and passes, unless
//! `FLUIDTEX_REQUIRE_TOOLS=1`, in which case it fails. The HTTP tests need
//! neither.

#![allow(clippy::unwrap_used)]

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use common::*;

const W: u32 = 960;
const H: u32 = 600;
/// The page's side panel and player bar (assets/viewer/index.html).
const SIDE: u32 = 280;
const BAR: u32 = 48;
/// The page's background colour (#1e1e24).
const BACKGROUND: [i32; 3] = [0x1e, 0x1e, 0x24];

/// `fluidtex view DIR` running in the background; killed when dropped, so a
/// failing test leaves no server behind.
struct Server {
    child: Child,
    url: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `fluidtex view dir` on a free port and reads its address line.
fn serve(dir: &Path) -> Server {
    let mut child = fluidtex()
        .arg("view")
        .arg(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://127.0.0.1:"))
        .unwrap_or_else(|| panic!("no address in {line:?}"))
        .to_string();
    Server { child, url }
}

/// A textured 3-frame run of the interop sphere (falls 1/16 per frame).
fn small_run(out: &Path) {
    let pattern = interop("meshio_ascii.####.ply");
    ok(&[
        Path::new("run"),
        Path::new("--mesh"),
        &pattern,
        Path::new("--atlas"),
        Path::new("256"),
        Path::new("--quiet"),
        Path::new("--out"),
        out,
    ]);
}

/// GET over plain HTTP/1.0: (status code, body).
fn get(url: &str, path: &str) -> (u16, Vec<u8>) {
    let addr = address(url);
    let (code, _, body) = request(url, path, Some(&addr));
    (code, body)
}

/// `127.0.0.1:PORT` of a server URL.
fn address(url: &str) -> String {
    url.trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string()
}

/// A raw HTTP/1.0 GET of `target` with `Host: host` (none when `None`):
/// (status code, header block, body).
fn request(url: &str, target: &str, host: Option<&str>) -> (u16, String, Vec<u8>) {
    let mut s = TcpStream::connect(address(url)).unwrap();
    let host_line = host.map_or(String::new(), |h| format!("Host: {h}\r\n"));
    write!(s, "GET {target} HTTP/1.0\r\n{host_line}\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("header end");
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let code = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap();
    (code, head, raw[split + 4..].to_vec())
}

/// DNS rebinding: a page elsewhere that points its own name at 127.0.0.1
/// sends its own name as Host. Only the server's own names are answered,
/// only in origin form, and every answer carries the protective headers.
#[test]
fn view_answers_only_its_own_names() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    small_run(&out);
    let server = serve(&out);
    let addr = address(&server.url);
    let port = addr.rsplit_once(':').unwrap().1.to_string();
    for host in [addr.clone(), format!("localhost:{port}")] {
        let (code, head, body) = request(&server.url, "/files/stats.0001.json", Some(&host));
        assert_eq!(code, 200, "{host}");
        assert!(serde_json::from_slice::<serde_json::Value>(&body).is_ok());
        let head = head.to_ascii_lowercase();
        assert!(head.contains("x-content-type-options: nosniff"), "{head}");
        assert!(
            head.contains("content-security-policy: default-src 'none'"),
            "{head}"
        );
    }
    for host in [
        Some("evil.example".to_string()),
        Some(format!("evil.example:{port}")),
        Some("127.0.0.1:1".to_string()),
        None,
    ] {
        for target in ["/api/frames", "/files/stats.0001.json", "/"] {
            let (code, head, body) = request(&server.url, target, host.as_deref());
            assert_eq!(code, 403, "{host:?} {target}");
            assert!(!String::from_utf8_lossy(&body).contains("frames"));
            assert!(head.to_ascii_lowercase().contains("nosniff"));
        }
    }
    // An absolute URL as the target, even with our own Host.
    let target = format!("http://{addr}/files/stats.0001.json");
    let (code, _, _) = request(&server.url, &target, Some(&addr));
    assert_eq!(code, 400);
}

#[test]
fn view_serves_the_frames_and_nothing_outside_the_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    small_run(&out);
    std::fs::write(tmp.path().join("secret.txt"), "outside").unwrap();
    let server = serve(&out);

    let (code, body) = get(&server.url, "/api/frames");
    assert_eq!(code, 200);
    let list: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let frames = list["frames"].as_array().unwrap();
    let numbers: Vec<i64> = frames
        .iter()
        .map(|f| f["frame"].as_i64().unwrap())
        .collect();
    assert_eq!(numbers, [1, 2, 3]);
    assert_eq!(frames[0]["mesh"], "mesh.0001.glb");
    assert_eq!(frames[2]["patches"], "patches.0003.png");
    assert_eq!(frames[1]["stats"], "stats.0002.json");

    // Files come back byte for byte.
    let (code, glb) = get(&server.url, "/files/mesh.0002.glb");
    assert_eq!(code, 200);
    assert_eq!(glb, std::fs::read(out.join("mesh.0002.glb")).unwrap());
    // The page and three.js come from the binary.
    let (code, page) = get(&server.url, "/?frame=2");
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&page).contains("/vendor/three/build/three.module.js"));
    let (code, three) = get(&server.url, "/vendor/three/build/three.core.js");
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&three[..200]).contains("Three.js Authors"));

    // Nothing outside the folder, hidden, or absent.
    for (path, want) in [
        ("/files/../secret.txt", 400),
        ("/files/..%2fsecret.txt", 400),
        ("/files/%2e%2e/secret.txt", 400),
        ("/../secret.txt", 404),
        ("/files/.hidden", 400),
        ("/files/mesh.0009.glb", 404),
        ("/nothing", 404),
    ] {
        let (code, body) = get(&server.url, path);
        assert_eq!(code, want, "{path}");
        assert!(
            !String::from_utf8_lossy(&body).contains("outside"),
            "{path}"
        );
    }
}

#[test]
fn view_refuses_a_folder_without_frames_in_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let line = user_error(&[Path::new("view"), tmp.path()]);
    assert!(line.contains("no mesh.F.glb or mesh.F.obj"), "{line}");
    assert!(line.contains(&tmp.path().display().to_string()), "{line}");
    let missing = tmp.path().join("nope");
    let line = user_error(&[Path::new("view"), &missing]);
    assert!(line.contains("nope"), "{line}");
}

/// Chromium's command name, if one is installed.
fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
        })
}

fn node_ok() -> bool {
    Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Screenshots `(url, out)` pairs; returns the driver's JSON line per shot.
fn screenshots(chrome: &str, shots: &[(String, PathBuf)]) -> Vec<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/view_screenshot.js");
    let mut cmd = Command::new("node");
    cmd.arg(script)
        .arg(chrome)
        .arg(W.to_string())
        .arg(H.to_string());
    for (url, out) in shots {
        cmd.arg(url).arg(out);
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "screenshot driver failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The 3-D part of a screenshot: left of the side panel, above the bar.
struct Shot {
    px: Vec<[i32; 3]>,
    w: usize,
    h: usize,
}

impl Shot {
    fn load(p: &Path) -> Shot {
        let img = image::open(p).unwrap().to_rgb8();
        assert_eq!((img.width(), img.height()), (W, H), "{}", p.display());
        let (w, h) = ((W - SIDE) as usize, (H - BAR) as usize);
        let mut px = Vec::with_capacity(w * h);
        for y in 0..h as u32 {
            for x in 0..w as u32 {
                let p = img.get_pixel(x, y).0;
                px.push([p[0].into(), p[1].into(), p[2].into()]);
            }
        }
        Shot { px, w, h }
    }

    /// Pixels that are not the page's flat background. The tolerance is
    /// small: the texture's own dark gaps come near the background colour.
    fn surface(&self) -> Vec<bool> {
        self.px
            .iter()
            .map(|p| (0..3).any(|c| (p[c] - BACKGROUND[c]).abs() > 3))
            .collect()
    }

    fn coverage(&self) -> f64 {
        self.surface().iter().filter(|&&s| s).count() as f64 / self.px.len() as f64
    }

    /// Mean |Δ luminance| between horizontal neighbours that are both
    /// surface: texture detail, where smooth shading gives ~1.
    fn detail(&self) -> f64 {
        let s = self.surface();
        let lum = |p: &[i32; 3]| f64::from(p[0] + p[1] + p[2]) / 3.0;
        let (mut sum, mut n) = (0.0, 0usize);
        for y in 0..self.h {
            for x in 1..self.w {
                let (a, b) = (y * self.w + x - 1, y * self.w + x);
                if s[a] && s[b] {
                    sum += (lum(&self.px[a]) - lum(&self.px[b])).abs();
                    n += 1;
                }
            }
        }
        sum / n.max(1) as f64
    }
}

/// Share of `a`'s surface pixels whose surface/background state differs in
/// `b` (the silhouette moved).
fn silhouette_change(a: &Shot, b: &Shot) -> f64 {
    let (sa, sb) = (a.surface(), b.surface());
    let moved = sa.iter().zip(&sb).filter(|(x, y)| x != y).count();
    moved as f64 / sa.iter().filter(|&&s| s).count().max(1) as f64
}

/// Mean colour difference over pixels that are surface in both.
fn colour_change(a: &Shot, b: &Shot) -> f64 {
    let (sa, sb) = (a.surface(), b.surface());
    let (mut sum, mut n) = (0.0, 0usize);
    for i in 0..a.px.len() {
        if sa[i] && sb[i] {
            sum += (0..3)
                .map(|c| f64::from((a.px[i][c] - b.px[i][c]).abs()))
                .sum::<f64>()
                / 3.0;
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

#[test]
fn chromium_draws_a_textured_animated_surface_with_stats() {
    let (Some(chrome), true) = (chromium(), node_ok()) else {
        let msg = "chromium or node not found: `apt-get install chromium nodejs` to test `fluidtex view` in a browser";
        missing_tool("skipping", msg);
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    small_run(&out);
    // Known-bad control: frame 1 as OBJ without its atlas, drawn untextured.
    let bare = tmp.path().join("bare");
    std::fs::create_dir(&bare).unwrap();
    std::fs::copy(out.join("mesh.0001.obj"), bare.join("mesh.0001.obj")).unwrap();

    let run = serve(&out);
    let control = serve(&bare);
    let shot = |name: &str| tmp.path().join(name);
    let results = screenshots(
        chrome,
        &[
            (format!("{}?frame=1", run.url), shot("f1.png")),
            (format!("{}?frame=3", run.url), shot("f3.png")),
            (format!("{}?frame=3&view=patches", run.url), shot("f3p.png")),
            (format!("{}?frame=1", control.url), shot("bare.png")),
        ],
    );
    for (r, frame) in results.iter().zip([1, 3, 3, 1]) {
        assert_eq!(r["status"], format!("ready: frame {frame}"), "{r}");
    }
    // stats.F.json in the side panel (34 keys in frame 1; the coherence
    // numbers join from frame 2 on); the control has none.
    let rows: Vec<u64> = results
        .iter()
        .map(|r| r["stats_rows"].as_u64().unwrap())
        .collect();
    assert!(rows[0] >= 20 && rows[1] > rows[0], "{rows:?}");
    assert_eq!(rows[3], 0);

    let [f1, f3, f3p, bare] =
        ["f1.png", "f3.png", "f3p.png", "bare.png"].map(|n| Shot::load(&shot(n)));
    let cover = [f1.coverage(), f3.coverage(), bare.coverage()];
    let detail = [f1.detail(), f3.detail(), bare.detail()];
    let silhouette = silhouette_change(&f1, &f3);
    let patches_vs_texture = colour_change(&f3, &f3p);
    let same_frame = silhouette_change(&f3, &f3p);
    eprintln!(
        "coverage {cover:.3?}, detail {detail:.2?}, silhouette change 1->3 {silhouette:.3}, \
         same frame other view {same_frame:.4}, patch vs texture colour change {patches_vs_texture:.1}"
    );
    for c in cover {
        assert!((0.05..0.6).contains(&c), "coverage {cover:?}");
    }
    // Measured: 3.1-3.2 textured, 1.1 for the control (smooth shading);
    // silhouette change 0.29 for frames 1 -> 3, 0.001 for one frame in two views.
    assert!(
        detail[0] > 2.0 && detail[1] > 2.0,
        "not textured: {detail:?}"
    );
    assert!(
        detail[2] < 1.5,
        "the untextured control looks textured: {detail:?}"
    );
    // The liquid moved; the same frame in another view did not.
    assert!(silhouette > 0.05, "{silhouette}");
    assert!(same_frame < 0.01, "{same_frame}");
    assert!(patches_vs_texture > 20.0, "{patches_vs_texture}");
}
