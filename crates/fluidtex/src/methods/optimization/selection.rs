//! The optimization method's selection of a frame: the synthesised value
//! of every lattice point (all channels), the lattice's steps per fluid
//! edge, the exemplar level the atlas shows and the frame's statistics.
//! The lattice is rebuilt from the frame's mesh and the atlas resampled
//! from the points, as the one-pass step does, so a frame is resampled
//! from its geometry alone; the synthesis, and the transport that needs
//! the frame before, are the selecting phase's.

use serde::{Deserialize, Serialize};

use super::lattice::Lattice;
use super::{Optimization, Placement};
use crate::methods::{FrameContext, FrameResult, Method, MethodError, Selection};

/// What [`Optimization::select_frame`] writes (`m` = 0: no surface).
#[derive(Serialize, Deserialize)]
struct Selected {
    m: u32,
    values: Vec<f32>,
    lod: Option<f32>,
    /// `stats.F.json`'s method numbers.
    stats: Vec<(String, Json)>,
    /// Point spacing of scattered points (`placement = "repulsion"`),
    /// which are rebuilt from it and the mesh; `None` on a lattice.
    spacing: Option<f32>,
}

/// A JSON value in a form postcard reads back (it cannot read an
/// arbitrary `serde_json::Value`, which needs a self-describing format),
/// numbers kept exactly as they were: JSON text read back would round
/// some floats to a neighbouring value.
#[derive(Serialize, Deserialize)]
enum Json {
    Null,
    Bool(bool),
    Unsigned(u64),
    Signed(i64),
    Float(f64),
    Text(String),
    Array(Vec<Json>),
    Object(Vec<(String, Json)>),
}

impl Json {
    fn of(v: &serde_json::Value) -> Json {
        use serde_json::Value as V;
        match v {
            V::Null => Json::Null,
            V::Bool(b) => Json::Bool(*b),
            V::Number(n) => match (n.as_u64(), n.as_i64()) {
                (Some(u), _) => Json::Unsigned(u),
                (None, Some(i)) => Json::Signed(i),
                _ => Json::Float(n.as_f64().unwrap_or(f64::NAN)),
            },
            V::String(s) => Json::Text(s.clone()),
            V::Array(a) => Json::Array(a.iter().map(Json::of).collect()),
            V::Object(o) => Json::Object(o.iter().map(|(k, v)| (k.clone(), Json::of(v))).collect()),
        }
    }

    fn value(self) -> serde_json::Value {
        use serde_json::Value as V;
        match self {
            Json::Null => V::Null,
            Json::Bool(b) => V::Bool(b),
            Json::Unsigned(u) => V::from(u),
            Json::Signed(i) => V::from(i),
            // Not finite: JSON has no such number, as the writer says.
            Json::Float(f) => serde_json::Number::from_f64(f).map_or(V::Null, V::Number),
            Json::Text(s) => V::String(s),
            Json::Array(a) => V::Array(a.into_iter().map(Json::value).collect()),
            Json::Object(o) => V::Object(o.into_iter().map(|(k, v)| (k, v.value())).collect()),
        }
    }
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
        let stats = (result.stats.iter())
            .map(|(k, v)| (k.clone(), Json::of(v)))
            .collect();
        let selected = Selected {
            m: if ctx.mesh.is_empty() { 0 } else { self.state.m },
            values: self.state.values.clone(),
            lod: self.last_lod,
            stats,
            spacing: self
                .state
                .spacing
                .filter(|_| self.params.placement == Placement::Repulsion),
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
        let bytes = selection.own("optimization")?;
        let selected: Selected = postcard::from_bytes(bytes).map_err(state_error)?;
        self.show_frame(ctx.number);
        let mut result = FrameResult {
            stats: (selected.stats.into_iter())
                .map(|(k, v)| (k, v.value()))
                .collect(),
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
        let lattice = match (self.params.placement, selected.spacing) {
            (Placement::Lattice, None) => Lattice::new(ctx.mesh, selected.m),
            (Placement::Repulsion, Some(h)) if h.is_finite() && h > 0.0 => self.points(ctx.mesh, h),
            (_, h) => {
                return Err(state_error(format!(
                    "point spacing {h:?} does not fit placement {:?}",
                    self.params.placement
                )));
            }
        };
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
