use std::time::Instant;

use fluidtex::param::lscm;
use glam::Vec3;

fn grid(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut pos = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            pos.push(Vec3::new(x, y, 0.3 * (3.0 * x).sin() * (2.0 * y).cos()));
        }
    }
    let mut tris = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            tris.push([a, a + 1, a + n + 1]);
            tris.push([a, a + n + 1, a + n]);
        }
    }
    (pos, tris)
}

fn main() {
    let sizes: Vec<u32> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("n"))
        .collect();
    let sizes = if sizes.is_empty() {
        vec![4u32, 6, 8, 9, 10, 11, 12, 16, 24, 32, 46]
    } else {
        sizes
    };
    for n in sizes {
        let (pos, tris) = grid(n);
        let reps = (20000 / tris.len()).max(3);
        let t = Instant::now();
        for _ in 0..reps {
            std::hint::black_box(lscm(&pos, &tris).expect("ok"));
        }
        let dt = t.elapsed().as_secs_f64() / reps as f64;
        println!(
            "lscm {:5} triangles {:5} unknowns: {:9.1} us",
            tris.len(),
            2 * (n * n - 2),
            dt * 1e6
        );
    }
}
