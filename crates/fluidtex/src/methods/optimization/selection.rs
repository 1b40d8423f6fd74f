//! The optimization method's selection of a frame: the synthesised value
//! of every lattice point (all channels), the lattice's steps per fluid
//! edge, the exemplar level the atlas shows and the frame's statistics.
//! The lattice is rebuilt from the frame's mesh and the atlas resampled
//! from the points, as the one-pass step does, so a frame is resampled
//! from its geometry alone; the synthesis, and the transport that needs
//! the frame before, are the selecting phase's.

use serde::{Deserialize, Serialize};

use super::Optimization;
use super::lattice::Lattice;
use crate::methods::{FrameContext, FrameResult, Method, MethodError, Selection};

/// What [`Optimization::select_frame`] writes (`m` = 0: no surface).
#[derive(Serialize, Deserialize)]
struct Selected {
    m: u32,
    values: Vec<f32>,
    lod: Option<f32>,
    /// `stats.F.json`'s method numbers, as JSON text (postcard cannot read
    /// an arbitrary JSON value back); serde_json's `float_roundtrip` reads
    /// every number back to the same bits.
    stats: String,
}

fn state_error(e: impl std::fmt::Display) -> MethodError {
    MethodError::State(format!("selection: {e}"))
}

impl Optimization {
    /// The frame synthesised as by [`Method::step`], not resampled.
    pub(super) fn select_frame(
        &mut self,
        ctx: &FrameContext<'_>,
    ) -> Result<Selection, MethodError> {
        self.selecting = true;
        let stepped = self.step(ctx);
        self.selecting = false;
        let result = stepped?;
        let stats = serde_json::to_string(&result.stats).map_err(state_error)?;
        let selected = Selected {
            m: if ctx.mesh.is_empty() { 0 } else { self.state.m },
            values: self.state.values.clone(),
            lod: self.last_lod,
            stats,
        };
        postcard::to_allocvec(&selected)
            .map(Selection::Own)
            .map_err(state_error)
    }

    /// Every channel of the frame from its selection.
    pub(super) fn resample_frame(
        &mut self,
        ctx: &FrameContext<'_>,
        selection: &Selection,
    ) -> Result<FrameResult, MethodError> {
        let Selection::Own(bytes) = selection else {
            return Err(state_error(
                "a replayed selection, which optimization does not write",
            ));
        };
        let selected: Selected = postcard::from_bytes(bytes).map_err(state_error)?;
        let mut result = FrameResult {
            stats: serde_json::from_str(&selected.stats).map_err(state_error)?,
            ..FrameResult::default()
        };
        let atlas = ctx.atlas;
        let k = self.exemplar.total_channels();
        if selected.m == 0 || ctx.mesh.is_empty() {
            result.channels = self.empty_channels(atlas);
            return Ok(result);
        }
        if !(selected.m.is_power_of_two() && selected.m <= 128) {
            return Err(state_error(format!(
                "{} lattice steps per edge",
                selected.m
            )));
        }
        let lattice = Lattice::new(ctx.mesh, selected.m);
        if lattice.len() * k != selected.values.len()
            || selected.values.iter().any(|v| !v.is_finite())
        {
            return Err(state_error(format!(
                "{} point values for {} points of {k} channels, or not finite",
                selected.values.len(),
                lattice.len()
            )));
        }
        self.resample_points(atlas, &lattice, &selected.values, selected.lod, &mut result);
        Ok(result)
    }
}
