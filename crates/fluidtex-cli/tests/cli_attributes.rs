//! Per-vertex scalar attributes through the binary (issue 40): `fluidtex
//! info` lists each with its range; `fluidtex scene dam-break` writes the
//! particles' `age`, read back by `info`; a USD stage's per-point scalar
//! primvars reach `info` as those of a PLY sequence do.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::*;

/// The attribute column of each row of `fluidtex info` (the words after
/// the speed column that name an attribute and its kind).
fn attribute_columns(stdout: &str) -> Vec<Vec<String>> {
    stdout
        .lines()
        .skip(2)
        .map(|l| {
            l.split_whitespace()
                .skip(6)
                .filter(|w| w.contains(':'))
                .map(str::to_string)
                .collect()
        })
        .collect()
}

/// `name:f[lo..hi]` → (lo, hi).
fn range(column: &[String], name: &str) -> (f32, f32) {
    let text = column
        .iter()
        .find_map(|c| c.strip_prefix(&format!("{name}:f[")))
        .unwrap_or_else(|| panic!("no {name} in {column:?}"));
    let (lo, hi) = text.trim_end_matches(']').split_once("..").unwrap();
    (lo.parse().unwrap(), hi.parse().unwrap())
}

#[test]
fn info_lists_scalar_attributes_with_their_range() {
    // meshio's density = linspace(0, 1, 162), v_x v_y v_z the velocity.
    let stdout = ok(&[Path::new("info"), &interop("houdini_style.ply")]);
    assert_eq!(
        attribute_columns(&stdout),
        [["density:f[0.000..1.000]", "velocity:vec3"].map(String::from)]
    );
    // Control: a file without scalar properties lists only the velocity.
    let stdout = ok(&[Path::new("info"), &interop("meshio_ascii.0001.ply")]);
    assert_eq!(attribute_columns(&stdout), [["velocity:vec3".to_string()]]);
}

#[test]
fn dam_break_frames_carry_an_age_that_info_reads() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = scene(dir.path(), "dam-break", Some("8"), "0-4");
    let stdout = ok(&[Path::new("info"), &pattern]);
    let rows = attribute_columns(&stdout);
    assert_eq!(rows.len(), 5, "{stdout}");
    assert_eq!(range(&rows[0], "age"), (0.0, 0.0), "{stdout}");
    // Frame 4 is t = 1/6 s: water has left the column, none for longer.
    let (lo, hi) = range(&rows[4], "age");
    assert_eq!(lo, 0.0, "{stdout}");
    assert!(hi > 0.0 && hi <= 0.167, "{stdout}");
    assert!(rows[4].contains(&"velocity:vec3".to_string()));
}

#[test]
fn usd_scalar_primvars_are_listed_by_info() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("hot.usda");
    std::fs::write(
        &file,
        r#"#usda 1.0
def Mesh "lava"
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    float[] primvars:temperature = [0.25, 0.5, 0.998] (
        interpolation = "vertex"
    )
    float[] primvars:flat = [4] (
        interpolation = "constant"
    )
}
"#,
    )
    .unwrap();
    let stdout = ok(&[Path::new("info"), &file]);
    assert_eq!(
        attribute_columns(&stdout),
        [["temperature:f[0.250..0.998]".to_string()]],
        "{stdout}"
    );
}
