//! `toy`, a method that exists only in tests: every covered texel shows one
//! grey level. It is added to the registry exactly as a real method is
//! (this module, one line in `registry!`, one in `sections!`), so the
//! generic tests that loop over `MethodKind::ALL` (built under its name,
//! resampled selection equal to its step, several exemplars refused) and
//! the flag test below hold the steps written in [`super::registry`] to
//! account.

use super::registry::{Exemplars, MethodSpec};
use super::{
    ChannelFormat, ChannelSpec, FrameContext, FrameResult, Method, MethodError, check_range,
};

super::params::params! {
    /// Parameters of the toy method.
    pub struct ToyParams {
        /// The grey level of every covered texel \[0.5], in \[0, 1].
        pub grey: f32 = 0.5
            => "toy-grey" : "toy: the grey level of every covered texel [0.5]",
    }
}

impl ToyParams {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), MethodError> {
        check_range("toy.grey", self.grey, 0.0, 1.0, "[0, 1]")
    }
}

/// The registry's view of the toy.
pub const SPEC: MethodSpec = MethodSpec {
    name: "toy",
    exemplars: Exemplars::One,
    validate: |p| p.toy.validate(),
    build: |p, _, _| Ok(Box::new(Toy::new(p.toy.clone())?)),
};

/// The toy method: its grey, and how many frames it has shown (its state).
pub struct Toy {
    params: ToyParams,
    frames: u64,
}

impl Toy {
    pub fn new(params: ToyParams) -> Result<Toy, MethodError> {
        params.validate()?;
        Ok(Toy { params, frames: 0 })
    }
}

impl Method for Toy {
    fn name(&self) -> &'static str {
        SPEC.name
    }

    fn needs_velocity(&self) -> bool {
        false
    }

    fn channel_specs(&self) -> Vec<ChannelSpec> {
        vec![ChannelSpec {
            name: "color".into(),
            format: ChannelFormat::Png8,
        }]
    }

    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let grey = self.params.grey;
        let (colour, source) = super::paint_charts(ctx.atlas, 3, |_, _, texel| texel.fill(grey));
        self.frames += 1;
        let mut result = FrameResult {
            channels: vec![colour],
            source: Some(source),
            ..Default::default()
        };
        result
            .stats
            .insert("frames_shown".into(), serde_json::json!(self.frames));
        Ok(result)
    }

    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        Ok(self.frames.to_le_bytes().to_vec())
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
        let bytes: [u8; 8] = bytes
            .try_into()
            .map_err(|_| MethodError::State(format!("toy: {} state bytes, not 8", bytes.len())))?;
        self.frames = u64::from_le_bytes(bytes);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use clap::{Args, FromArgMatches};

    use super::*;
    use crate::methods::flags::MethodFlags;
    use crate::methods::registry::{MethodKind, MethodParams};
    use crate::methods::test_clip;
    use crate::named::Named;

    /// `run`'s method flags as the CLI reads them.
    fn flags(args: &[&str]) -> Result<MethodFlags, clap::Error> {
        let cmd = MethodFlags::augment_args(clap::Command::new("run"));
        let matches =
            cmd.try_get_matches_from(std::iter::once("run").chain(args.iter().copied()))?;
        MethodFlags::from_arg_matches(&matches)
    }

    #[test]
    fn the_toy_is_named_parsed_and_built_through_the_registry() {
        let kind: MethodKind = "toy".parse().expect("the registry names it");
        assert!(MethodKind::ALL.contains(&kind));
        let given = flags(&["--toy-grey", "0.25"]).expect("the CLI parses its flag");
        let mut params = MethodParams::default();
        given.apply(&mut params).expect("a valid grey");
        assert_eq!(params.toy.grey, 0.25);
        // Its range is checked before the method is built, and its value
        // is refused when it is not a number.
        let mut bad = params.clone();
        bad.toy.grey = 2.0;
        assert!(bad.validate(kind).is_err());
        assert!(flags(&["--toy-grey", "grey"]).is_err());
        // Its config section is the table `[toy]`, read as the CLI's config
        // reads every section (a config's other keys are not the
        // sections' business), and a typo in it is placed on its line.
        let from_file: MethodParams = toml::from_str("[toy]\ngrey = 0.25\n").expect("[toy]");
        assert_eq!(from_file, params);
        assert!(MethodParams::check_sections("atlas = 1\n[toy]\ngrey = 0.25\n").is_ok());
        let typo = MethodParams::check_sections("atlas = 1\n[toy]\ngray = 0.25\n")
            .expect_err("an unknown key of its section");
        assert!(typo.message().contains("`gray`"), "{typo}");
        assert_eq!(typo.span().map(|s| s.start), Some(16), "{typo}");

        let mut method = params
            .build(kind, 0, || {
                Ok::<_, MethodError>(Arc::new(test_clip::grey_exemplar(16, |_, _| 0.5)))
            })
            .expect("built through the registry");
        assert_eq!(method.name(), "toy");
        let clip = test_clip::scene("enright", 16, 2, 64);
        let results = clip.run(method.as_mut());
        let last = results.last().expect("two frames");
        let source = last.source.as_ref().expect("a source per texel");
        let covered: Vec<usize> = (0..source.len())
            .filter(|&t| source[t] != crate::methods::SOURCE_OUTSIDE)
            .collect();
        assert!(!covered.is_empty());
        for t in covered {
            assert_eq!(&last.channels[0].data[t * 3..t * 3 + 3], &[0.25; 3]);
        }
        assert_eq!(last.stats["frames_shown"], serde_json::json!(2));
    }
}
