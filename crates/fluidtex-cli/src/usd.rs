//! USD input: `--mesh shot.usd|usda|usdc` reads one `Mesh` prim per time
//! sample, with its topology changing from sample to sample.
//!
//! Read with the `openusd` crate (pure Rust, text and binary crate files).
//! 0.6 is the newest release that builds with this workspace's Rust 1.95
//! (0.7 and 0.8 need 1.96).
//!
//! Why in a child process: on damaged binary files `openusd` 0.6 can panic
//! (index out of bounds, an unimplemented LZ4 chunk mode) or abort on an
//! absurd allocation. Measured: of 60 seeded byte-damaged copies of a
//! `usd-core` file, 3 panicked and 6 aborted. A panic could be caught, an
//! abort cannot; so `fluidtex` runs itself (`fluidtex usd-convert`, hidden)
//! to turn the stage into a temporary folder of binary PLY frames, and a
//! reader crash becomes one error line naming the file. The frames are then
//! read by the same PLY reader as any sequence, and deleted after the run.
//!
//! What is read, per time sample of `points` (a whole-number time code is
//! the frame number; a stage without samples is frame 0):
//! `points`, `faceVertexCounts`, `faceVertexIndices` and the velocity from
//! `velocities`, else the primvar `v` or `velocity`. Points are taken as
//! authored, in the prim's own space: transforms of the prim and its
//! ancestors are not applied (the outputs are then in that space too).
//!
//! Scalar primvars with one value per point (`interpolation = "vertex"` or
//! `"varying"`, type `float[]`, `double[]`, `half[]` or `int[]`, indexed or
//! not), e.g. `primvars:temperature`, are written as float properties of
//! the PLY frames under their name without `primvars:`, so that
//! [`ReadOptions::scalar_attributes`] (`--select-by temperature`) and
//! `fluidtex info` see them as in any PLY sequence. Primvars of other
//! interpolations (constant, uniform, faceVarying) or types are not
//! per-vertex scalars and are left out, as are names a PLY frame already
//! uses (`x`, `vx`, ...).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use fluidtex::io::ReadOptions;
use fluidtex::mesh::{TriMesh, ValidationReport};
use fluidtex::pipeline::{FrameSource, PipelineError, SequenceSource};
use openusd::sdf::Value;
use openusd::usd::{PrimPredicate, Stage, TimeCode};

/// Whether `path` names a USD file (by its extension).
pub fn is_usd(path: &str) -> bool {
    let lower = path.to_ascii_lowercase();
    [".usd", ".usda", ".usdc"]
        .iter()
        .any(|e| lower.ends_with(e))
}

/// A USD stage as a frame source: converted by a child process, then read
/// as a PLY sequence.
pub struct UsdSource {
    inner: SequenceSource,
    file: PathBuf,
    _frames_dir: tempfile::TempDir,
}

impl UsdSource {
    /// [`UsdSource::open_with`] with the default read options.
    pub fn open(file: &str, prim: Option<&str>, range: Option<&str>) -> Result<UsdSource> {
        UsdSource::open_with(file, prim, range, ReadOptions::default())
    }

    /// Converts `file`'s Mesh prim (`prim`, or the only one) and reads its
    /// frames over `range` with `options` (e.g. the scalar attributes to
    /// keep: the primvars of the same names).
    pub fn open_with(
        file: &str,
        prim: Option<&str>,
        range: Option<&str>,
        options: ReadOptions,
    ) -> Result<UsdSource> {
        let dir =
            tempfile::tempdir().context("cannot make a temporary folder for the USD frames")?;
        let exe = std::env::current_exe().context("cannot find the fluidtex program itself")?;
        let mut cmd = Command::new(exe);
        cmd.arg("usd-convert")
            .arg(file)
            .arg("--out")
            .arg(dir.path());
        if let Some(p) = prim {
            cmd.arg("--prim").arg(p);
        }
        let out = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .env("RUST_BACKTRACE", "0")
            .output()
            .context("cannot start the USD reader")?;
        if !out.status.success() {
            let stderr = String::from_utf8_lossy(&out.stderr);
            if let Some(line) = stderr.lines().find_map(|l| l.strip_prefix("error: ")) {
                bail!("{line}");
            }
            // A panic or an abort: its message, without the backtrace note.
            let why = stderr
                .lines()
                .map(str::trim)
                .find(|l| !l.is_empty() && !l.starts_with("thread ") && !l.starts_with("note:"))
                .unwrap_or("no message");
            bail!("{file}: the USD reader stopped on damaged data ({why})");
        }
        let pattern = dir.path().join("fluid.####.ply");
        let inner = SequenceSource::open(&pattern.to_string_lossy(), range, options)
            .with_context(|| file.to_string())?;
        Ok(UsdSource {
            inner,
            file: PathBuf::from(file),
            _frames_dir: dir,
        })
    }
}

impl FrameSource for UsdSource {
    fn frames(&self) -> Vec<i32> {
        self.inner.frames()
    }

    /// A frame; an error about the converted frame names the USD file and
    /// the frame instead of the temporary file.
    fn read(&mut self, f: i32) -> Result<(TriMesh, ValidationReport), PipelineError> {
        self.inner.read(f).map_err(|e| {
            let message = e.to_string();
            let temporary = self._frames_dir.path().join(format!("fluid.{f:04}.ply"));
            let temporary = temporary.display().to_string();
            if message.contains(&temporary) {
                let named = format!("{} (frame {f})", self.file.display());
                PipelineError::Source(message.replace(&temporary, &named))
            } else {
                e
            }
        })
    }

    fn input_paths(&self) -> Vec<PathBuf> {
        vec![self.file.clone()]
    }

    fn largest_frame(&mut self) -> Result<Option<fluidtex::mesh::TriMesh>, PipelineError> {
        self.inner.largest_frame()
    }
}

/// `fluidtex usd-convert FILE --out DIR \[--prim PATH]` (hidden): writes
/// `DIR/fluid.FFFF.ply` per time sample. Run by [`UsdSource`].
#[derive(Args, Debug)]
pub struct UsdConvertArgs {
    pub file: String,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long)]
    pub prim: Option<String>,
}

pub fn usd_convert(a: &UsdConvertArgs) -> Result<()> {
    let file = a.file.as_str();
    if !Path::new(file).is_file() {
        bail!("{file}: file not found");
    }
    let stage = Stage::open(file)
        .map_err(|e| anyhow!("{file}: cannot read the USD stage: {}", crate::one_line(&e)))?;
    let path = mesh_prim(file, &stage, a.prim.as_deref())?;
    let prim = stage.prim(path.clone());
    let at = |name: &str, t: Option<f64>| -> Result<Option<Value>> {
        prim.attribute(name)
            .get_at::<Value>(t.map(TimeCode::new))
            .map_err(|e| anyhow!("{file}: {path}.{name}: {}", crate::one_line(&e)))
    };
    let times = prim
        .attribute("points")
        .time_sample_times()
        .map_err(|e| anyhow!("{file}: {path}.points: {}", crate::one_line(&e)))?;
    let primvars = scalar_primvar_names(file, &path, &prim)?;
    let samples: Vec<Option<f64>> = if times.is_empty() {
        vec![None]
    } else {
        times.into_iter().map(Some).collect()
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    for t in samples {
        let frame = match t {
            None => 0,
            Some(t) if t.fract() == 0.0 && (-1e6..=1e6).contains(&t) => t as i32,
            Some(t) => bail!("{file}: {path}.points: time code {t} is not a whole frame number"),
        };
        let whose = format!("{file}: {path}");
        let sample = MeshSample::read(&whose, t, &at)?;
        let scalars = scalar_primvars(&whose, t, &at, &primvars, sample.points.len())?;
        let ply = a.out.join(format!("fluid.{frame:04}.ply"));
        let velocity = sample.velocity.as_deref();
        write_ply(
            &ply,
            &sample.points,
            velocity,
            &scalars,
            &sample.counts,
            &sample.indices,
        )
        .with_context(|| format!("{}", ply.display()))?;
    }
    Ok(())
}

/// The Mesh prim to convert: the one named by `--prim`, else the stage's
/// only Mesh prim.
fn mesh_prim(file: &str, stage: &Stage, want: Option<&str>) -> Result<openusd::sdf::Path> {
    let mut all = Vec::new();
    stage
        .traverse(PrimPredicate::DEFAULT, |p| all.push(p.clone()))
        .map_err(|e| anyhow!("{file}: cannot read the USD stage: {}", crate::one_line(&e)))?;
    let type_of = |p: &openusd::sdf::Path| -> Result<String> {
        let t = stage
            .prim(p.clone())
            .type_name()
            .map_err(|e| anyhow!("{file}: {p}: {}", crate::one_line(&e)))?;
        Ok(t.map(|t| t.to_string()).unwrap_or_default())
    };
    let mut meshes = Vec::new();
    for p in &all {
        if type_of(p)? == "Mesh" {
            meshes.push(p.clone());
        }
    }
    let list = |m: &[openusd::sdf::Path]| {
        m.iter()
            .map(|p| p.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    match want {
        Some(want) => {
            let Some(p) = all.iter().find(|p| p.to_string() == *want) else {
                bail!(
                    "{file}: no prim {want} (Mesh prims: {})",
                    if meshes.is_empty() {
                        "none".to_string()
                    } else {
                        list(&meshes)
                    }
                );
            };
            let t = type_of(p)?;
            if t != "Mesh" {
                bail!("{file}: prim {want} is a {t}, not a Mesh");
            }
            Ok(p.clone())
        }
        None => match meshes.as_slice() {
            [] => bail!("{file}: no Mesh prim in the stage"),
            [one] => Ok(one.clone()),
            many => bail!(
                "{file}: {} Mesh prims ({}); choose one with --prim",
                many.len(),
                list(many)
            ),
        },
    }
}

/// The prim's primvars that may be per-vertex scalars: those with one
/// value per point (vertex or varying interpolation), in name order; their
/// type is checked per sample ([`scalar_primvars`]).
fn scalar_primvar_names(
    file: &str,
    path: &openusd::sdf::Path,
    prim: &openusd::usd::Prim,
) -> Result<Vec<String>> {
    let names = prim
        .property_names()
        .map_err(|e| anyhow!("{file}: {path}: {}", crate::one_line(&e)))?;
    let mut out = Vec::new();
    for name in names {
        let name = name.to_string();
        let Some(short) = name.strip_prefix("primvars:") else {
            continue;
        };
        if short.ends_with(":indices") || TAKEN.contains(&short) {
            continue;
        }
        let interpolation = prim
            .attribute(name.as_str())
            .get_metadata::<Value>("interpolation")
            .map_err(|e| anyhow!("{file}: {path}.{name}: {}", crate::one_line(&e)))?;
        let per_point = match &interpolation {
            Some(Value::Token(t)) => ["vertex", "varying"].contains(&t.as_str()),
            Some(Value::String(t)) => ["vertex", "varying"].contains(&t.as_str()),
            _ => false,
        };
        if per_point {
            out.push(name);
        }
    }
    out.sort();
    Ok(out)
}

/// Property names of the PLY frames that a primvar cannot take.
const TAKEN: [&str; 6] = ["x", "y", "z", "vx", "vy", "vz"];

/// The scalar primvars of `names` at `t` as (name without `primvars:`,
/// one value per point), expanded through their `:indices` when they have
/// them; primvars of a non-scalar type are left out.
fn scalar_primvars(
    whose: &str,
    t: Option<f64>,
    at: &AttributeAt<'_>,
    names: &[String],
    points: usize,
) -> Result<Vec<(String, Vec<f32>)>> {
    let when = t.map_or("(default)".to_string(), |t| format!("at time {t}"));
    let mut out = Vec::new();
    for name in names {
        let values: Vec<f32> = match at(name, t)? {
            Some(Value::FloatVec(v)) => v,
            Some(Value::DoubleVec(v)) => v.into_iter().map(|x| x as f32).collect(),
            Some(Value::HalfVec(v)) => v.into_iter().map(f32::from).collect(),
            Some(Value::IntVec(v)) => v.into_iter().map(|x| x as f32).collect(),
            _ => continue,
        };
        let values = match ints(at(&format!("{name}:indices"), t)?)
            .with_context(|| format!("{whose}.{name}:indices {when}"))?
        {
            Some(indices) => indices
                .iter()
                .enumerate()
                .map(|(i, &k)| {
                    usize::try_from(k)
                        .ok()
                        .and_then(|k| values.get(k).copied())
                        .ok_or_else(|| {
                            anyhow!(
                                "{whose}.{name}:indices {when}: [{i}] = {k}, outside the {} values",
                                values.len()
                            )
                        })
                })
                .collect::<Result<Vec<f32>>>()?,
            None => values,
        };
        if values.len() != points {
            bail!(
                "{whose}.{name} {when}: {} values for {points} points",
                values.len()
            );
        }
        let short = name.strip_prefix("primvars:").unwrap_or(name);
        out.push((short.to_string(), values));
    }
    Ok(out)
}

/// Reads an attribute of the prim at a time (`None`: its default value).
type AttributeAt<'a> = dyn Fn(&str, Option<f64>) -> Result<Option<Value>> + 'a;

/// A Mesh prim at one time sample.
struct MeshSample {
    points: Vec<[f32; 3]>,
    counts: Vec<i32>,
    indices: Vec<i32>,
    velocity: Option<Vec<[f32; 3]>>,
}

impl MeshSample {
    /// Reads the sample at `t` through `at` (attribute name, time → value);
    /// `whose` ("FILE: PRIM") starts every message.
    fn read(whose: &str, t: Option<f64>, at: &AttributeAt<'_>) -> Result<MeshSample> {
        let when = t.map_or("(default)".to_string(), |t| format!("at time {t}"));
        let points = vec3s(at("points", t)?)
            .with_context(|| format!("{whose}.points {when}"))?
            .with_context(|| format!("{whose}.points {when}: no value"))?;
        let counts = ints(at("faceVertexCounts", t)?)
            .with_context(|| format!("{whose}.faceVertexCounts {when}"))?
            .with_context(|| format!("{whose}.faceVertexCounts {when}: no value"))?;
        let indices = ints(at("faceVertexIndices", t)?)
            .with_context(|| format!("{whose}.faceVertexIndices {when}"))?
            .with_context(|| format!("{whose}.faceVertexIndices {when}: no value"))?;
        let mut velocity = None;
        for name in ["velocities", "primvars:v", "primvars:velocity"] {
            if let Some(v) =
                vec3s(at(name, t)?).with_context(|| format!("{whose}.{name} {when}"))?
            {
                if v.len() != points.len() {
                    bail!(
                        "{whose}.{name} {when}: {} vectors for {} points",
                        v.len(),
                        points.len()
                    );
                }
                velocity = Some(v);
                break;
            }
        }
        check_topology(&counts, &indices, points.len())
            .map_err(|e| anyhow!("{whose} {when}: {e}"))?;
        Ok(MeshSample {
            points,
            counts,
            indices,
            velocity,
        })
    }
}

/// Points or vectors, as `f32` triples.
fn vec3s(v: Option<Value>) -> Result<Option<Vec<[f32; 3]>>> {
    Ok(match v {
        None => None,
        Some(Value::Vec3fVec(v)) => Some(v.into_iter().map(Into::into).collect()),
        Some(Value::Vec3dVec(v)) => Some(
            v.into_iter()
                .map(|d| {
                    let d: [f64; 3] = d.into();
                    [d[0] as f32, d[1] as f32, d[2] as f32]
                })
                .collect(),
        ),
        Some(other) => bail!("expected an array of 3-vectors, found {}", kind(&other)),
    })
}

fn ints(v: Option<Value>) -> Result<Option<Vec<i32>>> {
    Ok(match v {
        None => None,
        Some(Value::IntVec(v)) => Some(v),
        Some(other) => bail!("expected int[], found {}", kind(&other)),
    })
}

/// Where the type name ends in a value's `Debug` text.
const TYPE_NAME_END: [char; 3] = ['(', ' ', '{'];

/// The type of a USD value, for messages (its `Debug` name).
fn kind(v: &Value) -> String {
    let debug = format!("{v:?}");
    debug
        .split(TYPE_NAME_END)
        .next()
        .unwrap_or("another type")
        .to_string()
}

/// Face sizes ≥ 3 that add up to the index count, indices within the points.
pub fn check_topology(counts: &[i32], indices: &[i32], points: usize) -> Result<()> {
    let mut total: usize = 0;
    for (f, &c) in counts.iter().enumerate() {
        if c < 3 {
            bail!("faceVertexCounts[{f}] = {c}: a face needs at least 3 vertices");
        }
        total += c as usize;
    }
    if total != indices.len() {
        bail!(
            "faceVertexCounts add up to {total} but faceVertexIndices has {}",
            indices.len()
        );
    }
    if let Some((i, &v)) = indices
        .iter()
        .enumerate()
        .find(|&(_, &v)| v < 0 || v as usize >= points)
    {
        bail!("faceVertexIndices[{i}] = {v}: outside the {points} points");
    }
    Ok(())
}

/// Binary little-endian PLY with `vx vy vz` when there is a velocity, a
/// float property per scalar primvar, and polygons as authored (the reader
/// triangulates them).
fn write_ply(
    path: &Path,
    points: &[[f32; 3]],
    velocity: Option<&[[f32; 3]]>,
    scalars: &[(String, Vec<f32>)],
    counts: &[i32],
    indices: &[i32],
) -> Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment converted from USD by fluidtex\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        points.len()
    )?;
    if velocity.is_some() {
        write!(
            out,
            "property float vx\nproperty float vy\nproperty float vz\n"
        )?;
    }
    for (name, _) in scalars {
        writeln!(out, "property float {name}")?;
    }
    write!(
        out,
        "element face {}\nproperty list int int vertex_indices\nend_header\n",
        counts.len()
    )?;
    for (i, p) in points.iter().enumerate() {
        for c in p {
            out.write_all(&c.to_le_bytes())?;
        }
        if let Some(v) = velocity {
            for c in &v[i] {
                out.write_all(&c.to_le_bytes())?;
            }
        }
        for (_, values) in scalars {
            out.write_all(&values[i].to_le_bytes())?;
        }
    }
    let mut next = 0;
    for &c in counts {
        out.write_all(&c.to_le_bytes())?;
        for &v in &indices[next..next + c as usize] {
            out.write_all(&v.to_le_bytes())?;
        }
        next += c as usize;
    }
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn usd_files_are_told_by_their_extension() {
        for yes in ["a.usd", "b.USDA", "dir/c.usdc"] {
            assert!(is_usd(yes), "{yes}");
        }
        for no in ["a.ply", "a.usdz", "fluid.####.ply", "usd"] {
            assert!(!is_usd(no), "{no}");
        }
    }

    /// A stage with scalar primvars of each kind: the per-point ones
    /// (float, double, int, indexed half) reach the PLY frames under their
    /// short names; the constant, faceVarying and vector ones do not.
    #[test]
    fn per_point_scalar_primvars_become_ply_properties() {
        let dir = tempfile::tempdir().expect("tmp");
        let file = dir.path().join("hot.usda");
        std::fs::write(
            &file,
            r#"#usda 1.0
def Mesh "lava"
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    float[] primvars:temperature = [0.25, 0.5, 1] (
        interpolation = "vertex"
    )
    double[] primvars:age = [0, 1.5, 3] (
        interpolation = "varying"
    )
    int[] primvars:id = [7, 8, 9] (
        interpolation = "vertex"
    )
    half[] primvars:crust = [0, 1] (
        interpolation = "vertex"
    )
    int[] primvars:crust:indices = [1, 1, 0]
    float[] primvars:flat = [4] (
        interpolation = "constant"
    )
    float[] primvars:corner = [1, 2, 3] (
        interpolation = "faceVarying"
    )
    float3[] primvars:dir = [(1, 0, 0), (0, 1, 0), (0, 0, 1)] (
        interpolation = "vertex"
    )
}
"#,
        )
        .expect("write");
        let out = dir.path().join("frames");
        usd_convert(&UsdConvertArgs {
            file: file.display().to_string(),
            out: out.clone(),
            prim: None,
        })
        .expect("convert");
        let every = ReadOptions {
            all_scalar_attributes: true,
            ..Default::default()
        };
        let (mesh, _) = fluidtex::io::read_mesh(&out.join("fluid.0000.ply"), &every).expect("read");
        let get = |n: &str| match mesh.attributes.get(n) {
            Some(fluidtex::mesh::Attribute::Scalar(v)) => v.clone(),
            other => panic!("{n}: {other:?}"),
        };
        let names: Vec<&str> = mesh.attributes.keys().map(String::as_str).collect();
        assert_eq!(names, ["age", "crust", "id", "temperature"]);
        assert_eq!(get("temperature"), [0.25, 0.5, 1.0]);
        assert_eq!(get("age"), [0.0, 1.5, 3.0]);
        assert_eq!(get("id"), [7.0, 8.0, 9.0]);
        assert_eq!(get("crust"), [1.0, 1.0, 0.0]);
        // A primvar with one value too few is an error naming it.
        let bad = std::fs::read_to_string(&file)
            .expect("read")
            .replace("[0.25, 0.5, 1]", "[0.25, 0.5]");
        std::fs::write(&file, bad).expect("write");
        let err = usd_convert(&UsdConvertArgs {
            file: file.display().to_string(),
            out,
            prim: None,
        })
        .expect_err("short primvar");
        assert!(
            err.to_string()
                .ends_with("/lava.primvars:temperature (default): 2 values for 3 points"),
            "{err}"
        );
    }

    #[test]
    fn bad_topology_is_named_by_element() {
        assert!(check_topology(&[3, 4], &[0, 1, 2, 0, 1, 2, 3], 4).is_ok());
        let e = check_topology(&[3, 2], &[0, 1, 2, 0, 1], 3).expect_err("2-gon");
        assert!(e.to_string().contains("faceVertexCounts[1] = 2"), "{e}");
        let e = check_topology(&[3], &[0, 1], 3).expect_err("short");
        assert!(e.to_string().contains("add up to 3 but"), "{e}");
        let e = check_topology(&[3], &[0, 1, 7], 3).expect_err("index");
        assert!(e.to_string().contains("faceVertexIndices[2] = 7"), "{e}");
        let e = check_topology(&[3], &[0, -1, 2], 3).expect_err("negative");
        assert!(e.to_string().contains("faceVertexIndices[1] = -1"), "{e}");
    }
}
