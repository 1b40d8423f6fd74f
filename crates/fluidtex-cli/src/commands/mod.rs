//! One module per subcommand.

pub mod bench;
pub mod compare;
pub mod demo;
pub mod farm;
pub mod info;
pub mod preview_video;
pub mod reproduce;
pub mod run;
pub mod scene;
pub mod view;
