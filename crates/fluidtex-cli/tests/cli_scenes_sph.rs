//! The SPH scenes through the binary: `fluidtex scene lava` at a tiny size,
//! then `fluidtex run` (erosion, the default method): once the lava is
//! solid, every frame's outputs (atlas, mesh, patch state aside) are the
//! same bytes — the texture stops when the lava stops (issue 12).

#![allow(clippy::unwrap_used)]

mod common;

use common::*;

#[test]
fn lava_still_frames_give_bit_identical_atlases() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    // 6 fps: the lava is solid from t = 4 s, frame 24.
    ok(&[
        "scene".as_ref(),
        "lava".as_ref(),
        "--resolution".as_ref(),
        "8".as_ref(),
        "--fps".as_ref(),
        "6".as_ref(),
        "--frames".as_ref(),
        "0-27".as_ref(),
        "--out".as_ref(),
        scene.as_os_str(),
        "--quiet".as_ref(),
    ]);
    let out = dir.path().join("out");
    let pattern = scene.join("fluid.####.ply");
    ok(&[
        "run".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--frames".as_ref(),
        "20-27".as_ref(),
        "--atlas".as_ref(),
        "128".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--quiet".as_ref(),
    ]);
    let written = files(&out);
    let get = |name: &str| {
        written
            .get(name)
            .unwrap_or_else(|| panic!("{name} not written"))
    };
    for kind in ["color.{}.png", "mesh.{}.glb"] {
        let at = |f: i32| get(&kind.replace("{}", &format!("{f:04}")));
        for f in 25..=27 {
            assert!(at(f) == at(24), "{kind}: frame {f} differs from frame 24");
        }
        // Control: while the lava still moves (slowly), the files change.
        assert!(at(22) != at(23), "{kind}: frames 22 and 23");
    }
    let inputs = files(&scene);
    let ply = |f: i32| &inputs[&format!("fluid.{f:04}.ply")];
    assert!(ply(27) == ply(24), "the scene itself is still");
}
