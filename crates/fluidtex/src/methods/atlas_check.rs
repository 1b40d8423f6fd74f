//! `atlas-check`: fills the atlas with a procedural world-space 3-D checker.
//!
//! No texture synthesis at all: this method exists so that the chain read →
//! atlas → write → view can be looked at on its own. A correct atlas shows
//! square, unstretched checker cells continuing across chart seams; a wrong
//! one shows it at once (sheared cells, seams, holes).

use super::{
    ChannelFormat, ChannelSpec, FrameContext, FrameResult, Method, MethodError, Selection,
    StageClock, check_range, paint_charts,
};

crate::methods::params::params! {
    /// Parameters of the checker.
    pub struct AtlasCheckParams {
        /// Checker cell size in world units. `None`: the first non-empty frame's
        /// bounding-box diagonal / `cells_per_diagonal`.
        pub cell: Option<f32> = None,
        /// Default number of cells along the bounding-box diagonal \[24].
        pub cells_per_diagonal: f32 = 24.0,
    }
}

impl AtlasCheckParams {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), MethodError> {
        if let Some(c) = self.cell {
            check_range("cell", c, f32::MIN_POSITIVE, f32::MAX, "> 0")?;
        }
        check_range(
            "cells_per_diagonal",
            self.cells_per_diagonal,
            1.0,
            1e6,
            "[1, 1e6]",
        )
    }
}

/// The checker method.
pub struct AtlasCheck {
    params: AtlasCheckParams,
    cell: Option<f32>,
}

impl AtlasCheck {
    pub fn new(params: AtlasCheckParams) -> Result<AtlasCheck, MethodError> {
        params.validate()?;
        Ok(AtlasCheck {
            cell: params.cell,
            params,
        })
    }
}

/// The checker colour at world point `p` for cell size `cell`: two tones per
/// parity, tinted by the cell's position so neighbouring cells are told apart.
pub fn checker(p: glam::Vec3, cell: f32) -> [f32; 3] {
    let c = (p / cell).floor();
    let parity = (c.x as i64 + c.y as i64 + c.z as i64).rem_euclid(2);
    let base = if parity == 0 { 0.9 } else { 0.25 };
    let tint = |k: f32| 0.08 * ((k * 0.37).sin());
    [
        base + tint(c.x),
        base + tint(c.y + 1.0),
        base + tint(c.z + 2.0),
    ]
    .map(|v| v.clamp(0.0, 1.0))
}

impl AtlasCheck {
    /// The cell size, fixed on the first frame with a surface (a
    /// `cells_per_diagonal`-th of its bounding-box diagonal); 1 before.
    fn fix_cell(&mut self, mesh: &crate::mesh::TriMesh) -> f32 {
        if self.cell.is_none() && !mesh.is_empty() {
            let (lo, hi) = mesh.bounding_box().unwrap_or_default();
            self.cell =
                Some((lo.distance(hi) / self.params.cells_per_diagonal).max(f32::MIN_POSITIVE));
        }
        self.cell.unwrap_or(1.0)
    }
}

impl Method for AtlasCheck {
    fn name(&self) -> &'static str {
        "atlas-check"
    }

    fn needs_velocity(&self) -> bool {
        false
    }

    fn memory_model(
        &self,
        _: &crate::atlas::AtlasParams,
        _: Option<&crate::mesh::TriMesh>,
    ) -> super::MemoryModel {
        // A colour per chart and nothing kept between frames; its charts'
        // colours and the uv of each texel are all it adds.
        super::MemoryModel {
            fixed: 0,
            per_triangle: 200,
            per_texel: 8,
            per_thread: 0,
        }
    }

    fn channel_specs(&self) -> Vec<ChannelSpec> {
        vec![ChannelSpec {
            name: "color".into(),
            format: ChannelFormat::Png8,
        }]
    }

    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let mut clock = StageClock::default();
        let mesh = ctx.mesh;
        let atlas = ctx.atlas;
        let cell = self.fix_cell(mesh);
        let (colour, source) = paint_charts(atlas, 3, |span, bary, texel| {
            let [a, b, c] = mesh.corners(span.triangle as usize);
            let p = a * bary[0] + b * bary[1] + c * bary[2];
            texel.copy_from_slice(&checker(p, cell));
        });
        clock.lap("fill");
        let mut result = FrameResult {
            channels: vec![colour],
            source: Some(source),
            ..Default::default()
        };
        result.stats.insert("cell".into(), serde_json::json!(cell));
        result.timings = clock.stages;
        Ok(result)
    }

    /// The checker's cell, fixed on the first frame with a surface, is the
    /// whole selection: resampling paints the frame with it.
    fn select(&mut self, ctx: &FrameContext<'_>) -> Result<Selection, MethodError> {
        self.fix_cell(ctx.mesh);
        Ok(Selection::Own(self.save_state()?))
    }

    fn resample(
        &mut self,
        ctx: &FrameContext<'_>,
        selection: &Selection,
    ) -> Result<FrameResult, MethodError> {
        let bytes = selection.own(self.name())?;
        self.load_state(bytes)
            .map_err(|e| MethodError::selection("atlas-check", e))?;
        self.step(ctx)
    }

    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        serde_json::to_vec(&self.cell).map_err(|e| MethodError::State(e.to_string()))
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
        self.cell = serde_json::from_slice(bytes).map_err(|e| MethodError::State(e.to_string()))?;
        Ok(())
    }
}
