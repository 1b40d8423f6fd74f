//! Which texels and pixels a metric looks at.
//!
//! Chart texels are those with any provenance other than
//! [`SOURCE_OUTSIDE`]. In renders, flow and popping must stay away from
//! silhouettes: a pixel there mixes surfaces that move differently, and its
//! neighbourhood (search window, bilinear footprint) crosses onto the
//! background. [`interior_mask`] removes every pixel within a margin of the
//! background or of a depth discontinuity (a fold of the surface in front of
//! another part of it).

use super::{MetricsError, SOURCE_OUTSIDE, SilhouetteSettings, check_len};

/// `true` for texels inside a chart (covered or not).
pub fn chart_mask(source: &[u32]) -> Vec<bool> {
    source.iter().map(|&s| s != SOURCE_OUTSIDE).collect()
}

/// Pixels at least `settings.radius_px` (Chebyshev distance) away from any
/// background pixel, from the image border and from any depth edge.
///
/// `foreground[i]` is `true` where the surface was drawn. A depth edge lies
/// between 4-neighbours whose depths differ by more than
/// `settings.relative_depth_jump` times the nearer one; both pixels of such
/// a pair count as edge pixels. `depth` may be `None` for images with a
/// single unoccluded surface. Pixels outside the image count as background,
/// so a surface that fills the frame still gets a margin at the border (the
/// windows of the flow search would leave the image there).
pub fn interior_mask(
    width: u32,
    height: u32,
    foreground: &[bool],
    depth: Option<&[f32]>,
    settings: &SilhouetteSettings,
) -> Result<Vec<bool>, MetricsError> {
    check_len("foreground mask", foreground, width, height)?;
    if let Some(d) = depth {
        check_len("depth", d, width, height)?;
    }
    let (w, h) = (width as usize, height as usize);
    let mut edge: Vec<bool> = foreground.iter().map(|&f| !f).collect();
    if let Some(d) = depth {
        let jump = settings.relative_depth_jump;
        let breaks = |a: f32, b: f32| (a - b).abs() > jump * a.abs().min(b.abs());
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if !foreground[i] {
                    continue;
                }
                if x + 1 < w && foreground[i + 1] && breaks(d[i], d[i + 1]) {
                    edge[i] = true;
                    edge[i + 1] = true;
                }
                if y + 1 < h && foreground[i + w] && breaks(d[i], d[i + w]) {
                    edge[i] = true;
                    edge[i + w] = true;
                }
            }
        }
    }
    // Separable dilation of the edge set by the margin, with the outside of
    // the image as edge.
    let r = settings.radius_px as usize;
    let dilate_rows = |src: &[bool]| -> Vec<bool> {
        let mut out = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let lo = x.checked_sub(r);
                let hi = x + r;
                out[y * w + x] = lo.is_none()
                    || hi >= w
                    || src[y * w + lo.unwrap_or(0)..=y * w + hi].iter().any(|&e| e);
            }
        }
        out
    };
    let rows = dilate_rows(&edge);
    let mut near = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            near[y * w + x] = match (y.checked_sub(r), y + r < h) {
                (Some(lo), true) => (lo..=y + r).any(|yy| rows[yy * w + x]),
                _ => true,
            };
        }
    }
    Ok(near.iter().map(|&n| !n).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(radius_px: u32) -> SilhouetteSettings {
        SilhouetteSettings {
            radius_px,
            relative_depth_jump: 0.05,
        }
    }

    #[test]
    fn chart_mask_excludes_outside_only() {
        assert_eq!(chart_mask(&[SOURCE_OUTSIDE, 0, 3]), vec![false, true, true]);
    }

    #[test]
    fn margin_from_border_and_background() {
        // 7x5 all foreground but one background pixel at (5, 2).
        let (w, h) = (7u32, 5u32);
        let mut fg = vec![true; 35];
        fg[2 * 7 + 5] = false;
        let m = interior_mask(w, h, &fg, None, &settings(1)).expect("sizes");
        let expected: Vec<bool> = (0..35)
            .map(|i| {
                let (x, y) = (i % 7, i / 7);
                (1..=5).contains(&x) && (1..=3).contains(&y) && !(4..=6).contains(&x)
            })
            .collect();
        assert_eq!(m, expected);
    }

    #[test]
    fn depth_edges_are_silhouettes() {
        // Two depth plateaus split between columns 3 and 4 of a 8x8 image.
        let (w, h) = (8u32, 8u32);
        let fg = vec![true; 64];
        let depth: Vec<f32> = (0..64).map(|i| if i % 8 < 4 { 1.0 } else { 2.0 }).collect();
        let m = interior_mask(w, h, &fg, Some(&depth), &settings(1)).expect("sizes");
        for (i, &inside) in m.iter().enumerate() {
            let (x, y) = (i % 8, i / 8);
            let expect = (1..=6).contains(&y) && (x == 1 || x == 6);
            assert_eq!(inside, expect, "pixel ({x}, {y})");
        }
        // A smooth ramp has no edges.
        let ramp: Vec<f32> = (0..64).map(|i| 1.0 + 0.01 * (i % 8) as f32).collect();
        let m = interior_mask(w, h, &fg, Some(&ramp), &settings(0)).expect("sizes");
        assert!(m.iter().all(|&b| b));
    }

    #[test]
    fn wrong_length_is_named() {
        let err = interior_mask(4, 4, &[true; 15], None, &settings(1));
        assert!(matches!(
            err,
            Err(MetricsError::Length {
                what: "foreground mask",
                got: 15,
                ..
            })
        ));
    }
}
