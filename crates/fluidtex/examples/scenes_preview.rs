//! Measures every scene and draws a preview picture of each.
//!
//! ```text
//! cargo run --release -p fluidtex --example scenes_preview -- [--out docs/scenes] [--scene NAME]... [--resolution N] [--frames K]
//! ```
//!
//! Per scene: default resolution, triangles (min / max over the sampled
//! frames), time per frame, and the min-angle distribution of the raw
//! marching-cubes mesh and of the relaxed one (analytic scenes). `--frames K`
//! samples K frames evenly over the scene's range (default 5; the dam break
//! always runs every frame up to the last sampled one, as a simulation must).
//! With `--out DIR`, writes `DIR/NAME.png`: an orthographic view, flat
//! shaded, coloured by speed (blue = still, red = fastest in that frame).

use std::time::Instant;

use fluidtex::mesh::TriMesh;
use fluidtex::scenes::{self, QualityStats, analytic, triangle_quality};
use glam::{Mat3, Vec3};

type Error = Box<dyn std::error::Error>;

/// The command line.
struct Options {
    /// Folder for the preview pictures.
    out: Option<String>,
    /// Scenes to measure (all when empty).
    only: Vec<String>,
    resolution: Option<u32>,
    /// Frames sampled per scene.
    samples: usize,
}

impl Options {
    fn parse() -> Result<Options, Error> {
        let mut o = Options {
            out: None,
            only: Vec::new(),
            resolution: None,
            samples: 5,
        };
        let mut args = std::env::args().skip(1);
        while let Some(a) = args.next() {
            match a.as_str() {
                "--out" => o.out = args.next(),
                "--scene" => o.only.extend(args.next()),
                "--resolution" => o.resolution = args.next().and_then(|s| s.parse().ok()),
                "--frames" => o.samples = args.next().and_then(|s| s.parse().ok()).unwrap_or(5),
                other => return Err(format!("unknown argument {other}").into()),
            }
        }
        Ok(o)
    }
}

fn main() -> Result<(), Error> {
    let o = Options::parse()?;
    if let Some(dir) = &o.out {
        std::fs::create_dir_all(dir)?;
    }
    println!(
        "| scene | resolution | frames | triangles (min-max) | s/frame | min angle p5 / median raw MC | relaxed | <10° raw / relaxed | degenerate |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, _) in scenes::catalogue() {
        if !o.only.is_empty() && !o.only.iter().any(|x| x == name) {
            continue;
        }
        let mut params = scenes::default_params(name)?;
        if let Some(r) = o.resolution {
            params.resolution = r;
        }
        let plan = Plan::new(name, params, o.samples);
        let m = if scenes::SPH_SCENES.contains(name) {
            Measured::simulated(name, &plan)?
        } else {
            Measured::analytic(name, &plan)?
        };
        m.print_row(name, &params);
        if let (Some(dir), Some(mesh)) = (&o.out, m.preview) {
            let path = format!("{dir}/{name}.png");
            render(&mesh, view(name), 320, 240).save(&path)?;
            eprintln!("wrote {path} (frame {})", plan.preview_frame);
        }
    }
    Ok(())
}

/// Which frames of a scene are measured.
struct Plan {
    params: scenes::SceneParams,
    /// Frames sampled evenly over the scene's range.
    picks: Vec<i32>,
    /// The frame drawn in the preview.
    preview_frame: i32,
}

impl Plan {
    fn new(name: &str, params: scenes::SceneParams, samples: usize) -> Plan {
        let span = params.last - params.first;
        let picks: Vec<i32> = (0..samples)
            .map(|i| {
                params.first + (span as f64 * i as f64 / (samples.max(2) - 1) as f64).round() as i32
            })
            .collect();
        let preview_frame = params.first + preview_offset(name, span);
        Plan {
            params,
            picks,
            preview_frame,
        }
    }
}

/// What one scene's sampled frames measured.
struct Measured {
    /// Fewest and most triangles.
    tri_range: (usize, usize),
    /// Quality of the raw marching-cubes meshes (analytic scenes only).
    raw_q: Vec<QualityStats>,
    /// Quality of the meshes as the scene gives them.
    relaxed_q: Vec<QualityStats>,
    /// Seconds spent making the timed frames, and their count.
    seconds: f64,
    timed: usize,
    /// The frame drawn in the preview.
    preview: Option<TriMesh>,
}

impl Measured {
    fn new() -> Measured {
        Measured {
            tri_range: (usize::MAX, 0),
            raw_q: Vec::new(),
            relaxed_q: Vec::new(),
            seconds: 0.0,
            timed: 0,
            preview: None,
        }
    }

    fn count_triangles(&mut self, mesh: &TriMesh) {
        self.tri_range = (
            self.tri_range.0.min(mesh.triangle_count()),
            self.tri_range.1.max(mesh.triangle_count()),
        );
    }

    /// A simulated scene: every frame up to the last sampled one, as a
    /// simulation must run them.
    fn simulated(name: &str, plan: &Plan) -> Result<Measured, Error> {
        let (params, picks, preview_frame) = (plan.params, &plan.picks, plan.preview_frame);
        let mut m = Measured::new();
        let mut scene = scenes::by_name(name, Some(params))?;
        let last = *picks.iter().max().unwrap_or(&params.first);
        let last = last.max(preview_frame.min(params.last));
        for f in params.first..=last {
            let start = Instant::now();
            let mesh = scene.frame(f)?;
            m.seconds += start.elapsed().as_secs_f64();
            m.timed += 1;
            if picks.contains(&f) || f == preview_frame {
                m.count_triangles(&mesh);
                m.relaxed_q.push(triangle_quality(&mesh));
            }
            if f == preview_frame {
                m.preview = Some(mesh);
            }
        }
        Ok(m)
    }

    /// An analytic scene: the sampled frames only, each raw and relaxed.
    fn analytic(name: &str, plan: &Plan) -> Result<Measured, Error> {
        let (params, preview_frame) = (plan.params, plan.preview_frame);
        let mut m = Measured::new();
        let mut scene = analytic::by_name(name, params).ok_or("unknown analytic scene")?;
        let mut frames = plan.picks.clone();
        if !frames.contains(&preview_frame) {
            frames.push(preview_frame);
        }
        for &f in &frames {
            let t = params.time(f);
            scene.set_relax_iterations(0);
            let (raw, _) = scene.mesh_at(t);
            scene.set_relax_iterations(fluidtex::scenes::relax::RELAX_ITERATIONS);
            let start = Instant::now();
            let (mesh, _) = scene.mesh_at(t);
            m.seconds += start.elapsed().as_secs_f64();
            m.timed += 1;
            m.count_triangles(&mesh);
            m.raw_q.push(triangle_quality(&raw));
            m.relaxed_q.push(triangle_quality(&mesh));
            if f == preview_frame {
                m.preview = Some(mesh);
            }
        }
        Ok(m)
    }

    /// The scene's row of the table.
    fn print_row(&self, name: &str, params: &scenes::SceneParams) {
        let (raw_a, raw_b, _) = quality_cells(&self.raw_q);
        let (rel_a, rel_b, deg) = quality_cells(&self.relaxed_q);
        println!(
            "| {name} | {} | {}-{} | {}-{} | {:.3} | {raw_a} | {rel_a} | {raw_b} / {rel_b} | {deg} |",
            params.resolution,
            params.first,
            params.last,
            self.tri_range.0,
            self.tri_range.1,
            self.seconds / self.timed.max(1) as f64
        );
    }
}

/// The min-angle cells of a row (p5 / median, share below 10°) and the
/// degenerate triangle count.
fn quality_cells(q: &[QualityStats]) -> (String, String, usize) {
    if q.is_empty() {
        return ("-".to_string(), "-".to_string(), 0);
    }
    // Worst sampled frame for the tails, median frame for the median.
    let p5 = q.iter().map(|s| s.p5).fold(f32::INFINITY, f32::min);
    let med = q.iter().map(|s| s.median).fold(f32::INFINITY, f32::min);
    let b10 = q.iter().map(|s| s.below_10).fold(0.0f32, f32::max);
    let deg = q.iter().map(|s| s.degenerate).sum();
    (
        format!("{p5:.1}° / {med:.1}°"),
        format!("{:.1}%", 100.0 * b10),
        deg,
    )
}

/// Frame (from the first) shown in the preview: where the scene is most telling.
fn preview_offset(name: &str, span: i32) -> i32 {
    match name {
        "enright" | "vortex" | "split-merge" => span / 2,
        "stop" => span * 2 / 3,
        "dam-break" => span / 5,
        _ => span / 4,
    }
}

/// Camera rotation per scene (world → view; view z points at the viewer).
fn view(name: &str) -> Mat3 {
    let (yaw, pitch) = match name {
        "vortex" | "stop" | "shear" => (0.0f32, 0.5f32),
        "dam-break" => (-0.5, -0.35),
        _ => (0.6, 0.45),
    };
    let base = if scenes::SPH_SCENES.contains(&name) {
        // The SPH scenes are y-up; the analytic scenes are z-up.
        Mat3::IDENTITY
    } else {
        Mat3::from_rotation_x(-std::f32::consts::FRAC_PI_2)
    };
    Mat3::from_rotation_x(pitch) * Mat3::from_rotation_y(yaw) * base
}

/// Orthographic z-buffer rendering, flat Lambert shading tinted by speed.
fn render(mesh: &TriMesh, rot: Mat3, w: u32, h: u32) -> image::RgbImage {
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let p: Vec<Vec3> = mesh.positions.iter().map(|&x| rot * x).collect();
    let Some(first) = p.first() else {
        return img;
    };
    let (lo, hi) = p
        .iter()
        .fold((*first, *first), |(a, b), &x| (a.min(x), b.max(x)));
    let scale = 0.92 * (w as f32 / (hi.x - lo.x)).min(h as f32 / (hi.y - lo.y));
    let centre = 0.5 * (lo + hi);
    let to_px = |v: Vec3| {
        Vec3::new(
            (v.x - centre.x) * scale + 0.5 * w as f32,
            (centre.y - v.y) * scale + 0.5 * h as f32,
            v.z,
        )
    };
    let speeds: Vec<f32> = mesh
        .velocity()
        .map(|v| v.iter().map(|x| x.length()).collect())
        .unwrap_or_else(|| vec![0.0; p.len()]);
    let vmax = speeds.iter().copied().fold(0.0f32, f32::max).max(1e-12);
    let light = Vec3::new(-0.3, 0.5, 1.0).normalize();
    let mut depth = vec![f32::NEG_INFINITY; (w * h) as usize];
    for tri in &mesh.triangles {
        let [a, b, c] = tri.map(|i| to_px(p[i as usize]));
        let n = (p[tri[1] as usize] - p[tri[0] as usize])
            .cross(p[tri[2] as usize] - p[tri[0] as usize])
            .normalize_or_zero();
        // Two-sided lighting so open sheets read well from below too.
        let shade = 0.25 + 0.75 * n.dot(light).abs();
        let s = tri.iter().map(|&i| speeds[i as usize]).sum::<f32>() / (3.0 * vmax);
        let base = Vec3::new(
            0.35 + 0.6 * s,
            0.55 + 0.2 * (1.0 - (2.0 * s - 1.0).abs()),
            0.95 - 0.6 * s,
        );
        let colour = (base * shade * 255.0).min(Vec3::splat(255.0));
        let (x0, x1) = (
            a.x.min(b.x).min(c.x).floor().max(0.0) as i32,
            a.x.max(b.x).max(c.x).ceil().min(w as f32 - 1.0) as i32,
        );
        let (y0, y1) = (
            a.y.min(b.y).min(c.y).floor().max(0.0) as i32,
            a.y.max(b.y).max(c.y).ceil().min(h as f32 - 1.0) as i32,
        );
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if area.abs() < 1e-12 {
            continue;
        }
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area;
                let w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                let k = (y as u32 * w + x as u32) as usize;
                if z > depth[k] {
                    depth[k] = z;
                    img.put_pixel(
                        x as u32,
                        y as u32,
                        image::Rgb([colour.x as u8, colour.y as u8, colour.z as u8]),
                    );
                }
            }
        }
    }
    img
}
