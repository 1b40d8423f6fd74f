//! The `fluidtex` command line: a thin clap front end over the `fluidtex`
//! library. The binary only calls [`main_entry`]; integration tests call
//! [`run`] with an argument list, so they drive the whole tool in-process.

pub mod config;
pub mod progress;
pub mod test_hooks;
pub mod usd;

mod commands;

use std::ffi::OsString;

use anyhow::Result;
use clap::{Parser, Subcommand};

pub use commands::bench::BenchArgs;
pub use commands::reproduce::{Plan as ReproductionPlan, fingerprint as reproduction_fingerprint};
pub use commands::scene::SceneArgs;

/// Textures that ride animated fluid surfaces.
///
/// Reads a fluid mesh sequence with per-vertex velocity, writes per frame a
/// texture atlas and the mesh with atlas UVs (OBJ + MTL, glb).
#[derive(Parser, Debug)]
#[command(name = "fluidtex", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Describe a mesh sequence: frames, triangles, attributes, bounds, velocity range
    Info(commands::info::InfoArgs),
    /// Texture a mesh sequence
    Run(Box<commands::run::RunArgs>),
    /// Texture a built-in scene with the built-in pebbles exemplar, with previews
    Demo(commands::demo::DemoArgs),
    /// Generate a scene (analytic flows with exact velocity, or an SPH dam break)
    Scene(SceneArgs),
    /// Print per-stage timings on a generated surface
    Bench(BenchArgs),
    /// Run methods on scenes and measure them: report.json, report.md, report.html
    Compare(Box<commands::compare::CompareArgs>),
    /// Put each paper's headline comparison beside ours: writes docs/reproduction.md
    Reproduce(commands::reproduce::ReproduceArgs),
    /// Show an output folder in a web browser: play, scrub, texture / patch view, stats
    View(commands::view::ViewArgs),
    /// Run a shot on a render farm's scheduler (Slurm, Open Job Description), in two phases
    Farm(commands::farm::FarmArgs),
    /// Converts a USD stage to PLY frames (run by `--mesh FILE.usd`, in a
    /// child process so a damaged file cannot bring the tool down)
    #[command(hide = true)]
    UsdConvert(usd::UsdConvertArgs),
}

/// Runs the tool with `args` (the first element is the program name).
pub fn run<I, T>(args: I) -> Result<()>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = Cli::try_parse_from(args)?;
    match cli.command {
        Command::Info(a) => commands::info::info(&a),
        Command::Run(a) => commands::run::run(&a),
        Command::Demo(a) => commands::demo::demo(&a),
        Command::Scene(a) => commands::scene::scene(&a),
        Command::Bench(a) => commands::bench::bench(&a),
        Command::Compare(a) => commands::compare::compare(&a),
        Command::Reproduce(a) => commands::reproduce::reproduce(&a),
        Command::View(a) => commands::view::view(&a),
        Command::Farm(a) => commands::farm::farm(&a),
        Command::UsdConvert(a) => usd::usd_convert(&a),
    }
}

/// The binary's entry point: runs, prints an error as one line, returns the
/// process exit code.
pub fn main_entry() -> i32 {
    match run(std::env::args_os()) {
        Ok(()) => 0,
        Err(e) => {
            if let Some(clap_err) = e.downcast_ref::<clap::Error>() {
                use clap::error::ErrorKind;
                if matches!(
                    clap_err.kind(),
                    ErrorKind::DisplayHelp
                        | ErrorKind::DisplayVersion
                        | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
                ) {
                    // Help and version are not errors.
                    let _ = clap_err.print();
                } else {
                    eprintln!("{}", clap_one_line(clap_err));
                }
                return clap_err.exit_code();
            }
            eprintln!("error: {}", one_line(&e));
            1
        }
    }
}

/// A usage error of clap on one line, like every other error: the message
/// and the valid values, without the usage block and the pointer to --help.
pub fn clap_one_line(e: &clap::Error) -> String {
    e.render()
        .to_string()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("Usage:") && !l.starts_with("For more"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The error's context chain on one line, outermost first. Many of our
/// errors already print their source inside their own message; a cause
/// whose text the line already holds is not repeated.
pub fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line.replace('\n', " ")
}
