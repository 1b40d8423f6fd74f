//! Coverage and ghost fraction: counts over the provenance of chart texels.
//!
//! Both are shares of *chart* texels (provenance other than
//! [`SOURCE_OUTSIDE`]), unweighted: every texel counts once. The same
//! functions take a render's per-pixel provenance, where
//! [`SOURCE_OUTSIDE`] is the background.

use super::{MetricsError, SOURCE_OUTSIDE, SOURCE_UNCOVERED};

/// Chart texels and how many of them no patch reached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coverage {
    pub chart_texels: usize,
    pub uncovered: usize,
}

impl Coverage {
    /// The metric: uncovered / chart texels (NaN without chart texels).
    pub fn share(&self) -> f64 {
        share(self.uncovered, self.chart_texels)
    }
}

/// Chart texels and how many of them show two or more layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ghosting {
    pub chart_texels: usize,
    pub ghosted: usize,
}

impl Ghosting {
    /// The metric: ghosted / chart texels (NaN without chart texels).
    pub fn share(&self) -> f64 {
        share(self.ghosted, self.chart_texels)
    }
}

fn share(count: usize, of: usize) -> f64 {
    if of == 0 {
        f64::NAN
    } else {
        count as f64 / of as f64
    }
}

/// Counts chart texels with provenance [`SOURCE_UNCOVERED`].
pub fn coverage(source: &[u32]) -> Coverage {
    let mut c = Coverage {
        chart_texels: 0,
        uncovered: 0,
    };
    for &s in source {
        if s != SOURCE_OUTSIDE {
            c.chart_texels += 1;
            c.uncovered += usize::from(s == SOURCE_UNCOVERED);
        }
    }
    c
}

/// Counts chart texels whose number of significant layers (`layers`, one
/// per texel; see [`layers_from_weights`]) is 2 or more. A method that
/// never blends has one layer everywhere and needs no array: its ghost
/// fraction is 0 by construction, which the report may state without
/// calling this.
pub fn ghosting(source: &[u32], layers: &[u8]) -> Result<Ghosting, MetricsError> {
    if layers.len() != source.len() {
        return Err(MetricsError::Length {
            what: "layer counts",
            expected: source.len(),
            got: layers.len(),
        });
    }
    let mut g = Ghosting {
        chart_texels: 0,
        ghosted: 0,
    };
    for (&s, &n) in source.iter().zip(layers) {
        if s != SOURCE_OUTSIDE {
            g.chart_texels += 1;
            g.ghosted += usize::from(n >= 2);
        }
    }
    Ok(g)
}

/// Per texel, the number of layers with weight ≥ `min_weight`, from
/// texel-major weights: `weights[texel * layers_per_texel + k]`. Counts
/// saturate at 255.
pub fn layers_from_weights(
    weights: &[f32],
    layers_per_texel: usize,
    min_weight: f32,
) -> Result<Vec<u8>, MetricsError> {
    if layers_per_texel == 0 || !weights.len().is_multiple_of(layers_per_texel) {
        return Err(MetricsError::Invalid {
            name: "weights per texel",
            value: layers_per_texel as f64,
            allowed: "a divisor (>= 1) of the number of weights",
        });
    }
    Ok(weights
        .chunks_exact(layers_per_texel)
        .map(|w| w.iter().filter(|&&x| x >= min_weight).count().min(255) as u8)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_counts_only_chart_texels() {
        let source = [SOURCE_OUTSIDE, 1, 2, SOURCE_UNCOVERED, 7, SOURCE_OUTSIDE];
        let c = coverage(&source);
        assert_eq!(
            c,
            Coverage {
                chart_texels: 4,
                uncovered: 1
            }
        );
        assert_eq!(c.share(), 0.25);
        assert!(coverage(&[SOURCE_OUTSIDE]).share().is_nan());
    }

    #[test]
    fn layer_counts_use_an_inclusive_weight_floor() {
        let w = [1.0, 0.0, 0.5, 0.5, 0.95, 0.05, 0.96, 0.049_999];
        assert_eq!(
            layers_from_weights(&w, 2, 0.05).expect("pairs"),
            vec![1, 2, 2, 1]
        );
        assert!(layers_from_weights(&w, 3, 0.05).is_err());
        assert!(layers_from_weights(&w, 0, 0.05).is_err());
    }

    #[test]
    fn ghosting_ignores_outside_texels() {
        let source = [SOURCE_OUTSIDE, 1, 1, 1];
        let g = ghosting(&source, &[5, 2, 1, 0]).expect("lengths");
        assert_eq!(g.ghosted, 1);
        assert_eq!(g.chart_texels, 3);
        assert!(ghosting(&source, &[1, 1]).is_err());
    }
}
