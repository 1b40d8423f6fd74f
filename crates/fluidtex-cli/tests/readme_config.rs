//! The README's run options agree with the code, both ways.
//!
//! The README's section "Texturing your own simulation" documents `run`:
//! a TOML example that names every config key, and a rule (a key's flag is
//! its name without the section, `_` written `-`) with a table of the
//! exceptions: flags and keys that are named differently, flags without a
//! key and keys without a flag. This test fails when
//! - a `run` flag (clap) or a config key (serde, `Config` and its nested
//!   parameter structs) is not covered by the rule or the table,
//! - a flag or key the README names does not exist (the TOML example must
//!   also parse as a config, with its unknown-key check),
//! - the TOML example leaves out a key,
//! - a flag does not set exactly the key the README pairs it with: each
//!   flag is applied alone to the default config and the changed keys are
//!   compared with the README's pairing (a flag "without a key" must change
//!   none), so a key "without a flag" really has none.
//!
//! Keys are found by serialising `Config::default()` and the README's
//! example; a key skipped when unset (`skip_serializing_if`) is found only
//! through the example, which is what the README must show anyway.

#![allow(clippy::unwrap_used)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use clap::{CommandFactory, Parser};
use fluidtex::methods::erosion;
use fluidtex_cli::config::Config;
use fluidtex_cli::{Cli, Command};
use serde_json::Value;

const SECTION: &str = "## Texturing your own simulation";

fn readme_section() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../README.md");
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text
        .find(SECTION)
        .unwrap_or_else(|| panic!("README.md: no section {SECTION:?}"));
    let rest = &text[start + SECTION.len()..];
    let end = rest.find("\n## ").unwrap_or(rest.len());
    rest[..end].to_string()
}

/// The section's first ```toml block.
fn toml_block(section: &str) -> String {
    let start = section
        .find("```toml\n")
        .expect("README: no ```toml block in the run section")
        + "```toml\n".len();
    let len = section[start..]
        .find("```")
        .expect("unclosed ```toml block");
    section[start..start + len].to_string()
}

/// Keys the TOML block names, `section.key`, counting commented-out
/// assignments (`# radius = 0.05`) as mentions.
fn toml_mentions(block: &str) -> BTreeSet<String> {
    let mut table = String::new();
    let mut keys = BTreeSet::new();
    for line in block.lines() {
        let line = line.trim_start().trim_start_matches('#').trim_start();
        if let Some(rest) = line.strip_prefix('[') {
            table = rest.split(']').next().unwrap().trim().to_string();
            keys.insert(table.clone());
            continue;
        }
        let Some((key, _)) = line.split_once('=') else {
            continue;
        };
        let key = key.trim();
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_lowercase() || c == '_') {
            continue;
        }
        keys.insert(if table.is_empty() {
            key.to_string()
        } else {
            format!("{table}.{key}")
        });
    }
    keys
}

/// Leaf keys of a serialised config, `section.key`; an empty table (the
/// user-named `channels`) is a leaf.
fn flatten(prefix: &str, v: &Value, out: &mut BTreeMap<String, Value>) {
    match v {
        Value::Object(map) if !map.is_empty() => {
            for (k, x) in map {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&key, x, out);
            }
        }
        _ => {
            out.insert(prefix.to_string(), v.clone());
        }
    }
}

fn leaves(config: &Config) -> BTreeMap<String, Value> {
    let mut out = BTreeMap::new();
    flatten("", &serde_json::to_value(config).unwrap(), &mut out);
    out
}

/// Collapses a key below a user-named table (`channels.displacement`) to
/// the table.
fn known_key(key: &str, keys: &BTreeSet<String>) -> String {
    keys.iter()
        .find(|k| key.starts_with(&format!("{k}.")))
        .cloned()
        .unwrap_or_else(|| key.to_string())
}

/// `--name` tokens of a text.
fn flag_tokens(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("--") {
        let after = &rest[at + 2..];
        let name: String = after
            .chars()
            .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '-')
            .collect();
        let before = rest[..at].chars().last();
        if name.starts_with(|c: char| c.is_ascii_lowercase())
            && before.is_none_or(|c| !c.is_ascii_alphanumeric() && c != '-')
        {
            out.push(name.clone());
        }
        rest = &after[name.len()..];
    }
    out
}

/// `` `a.b` `` tokens of a table cell that look like keys.
fn key_tokens(cell: &str) -> Vec<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .map(|t| t.trim_matches(|c| c == '[' || c == ']').to_string())
        .filter(|t| {
            !t.is_empty()
                && t.chars()
                    .all(|c| c.is_ascii_lowercase() || c == '_' || c == '.')
        })
        .collect()
}

/// The README's exceptions table (header `| flag | key |`): pairs, flags
/// without a key, keys without a flag.
struct Exceptions {
    pairs: Vec<(String, String)>,
    flag_only: Vec<String>,
    key_only: Vec<String>,
}

fn exceptions(section: &str) -> Exceptions {
    let mut lines = section.lines().skip_while(|l| {
        let cells: Vec<&str> = l.split('|').map(str::trim).collect();
        cells.get(1..3) != Some(&["flag", "key"][..])
    });
    assert!(
        lines.next().is_some(),
        "README: no `| flag | key |` table in the run section"
    );
    let mut e = Exceptions {
        pairs: Vec::new(),
        flag_only: Vec::new(),
        key_only: Vec::new(),
    };
    for row in lines.skip(1).take_while(|l| l.starts_with('|')) {
        let cells: Vec<&str> = row.split('|').collect();
        let (flags, keys) = (flag_tokens(cells[1]), key_tokens(cells[2]));
        match (flags.is_empty(), keys.is_empty()) {
            (false, true) => e.flag_only.extend(flags),
            (true, false) => e.key_only.extend(keys),
            (false, false) => {
                assert_eq!(
                    flags.len(),
                    keys.len(),
                    "README table row pairs flags with keys in order: {row}"
                );
                e.pairs.extend(flags.into_iter().zip(keys));
            }
            (true, true) => panic!("README table row names no flag and no key: {row}"),
        }
    }
    e
}

/// `run`'s flags (long names) and whether each takes a value.
fn run_flags() -> BTreeMap<String, bool> {
    let cli = Cli::command();
    let run = cli.find_subcommand("run").expect("a run subcommand");
    run.get_arguments()
        .filter_map(|a| Some((a.get_long()?.to_string(), a.get_action().takes_values())))
        .filter(|(name, _)| name != "help")
        .collect()
}

/// The config keys `run --flag [value]` changes from the default config,
/// for the first sample value the flag accepts that changes something
/// (none when no value changes anything).
fn keys_set_by(flag: &str, takes_value: bool, keys: &BTreeSet<String>) -> BTreeSet<String> {
    let default = leaves(&Config::default());
    let samples: &[&str] = if takes_value {
        // Three-value flags take three words (`--up-axis 0 1 0`).
        &[
            "7",
            "7 7 7",
            "global",
            "paper",
            "full",
            "random",
            "aligned",
            "a b c",
            "a=b.png",
            // Named settings accept only their names.
            "advect",
            "none",
            "distance",
            "histogram",
            "off",
            "kept",
            "repulsion",
            "7,7,7",
            "a,b,c",
            "select",
        ]
    } else {
        &[""]
    };
    let mut parsed_once = false;
    for sample in samples {
        let mut args = vec!["fluidtex".to_string(), "run".into(), format!("--{flag}")];
        args.extend(sample.split_whitespace().map(str::to_string));
        let Ok(Cli {
            command: Command::Run(a),
        }) = Cli::try_parse_from(&args)
        else {
            continue;
        };
        parsed_once = true;
        let mut config = Config::default();
        if a.flags.apply(&mut config).is_err() {
            continue;
        }
        let now = leaves(&config);
        let changed: BTreeSet<String> = now
            .iter()
            .filter(|(k, v)| default.get(*k) != Some(*v))
            .map(|(k, _)| known_key(k, keys))
            .chain(
                default
                    .keys()
                    .filter(|k| !now.contains_key(*k))
                    .map(|k| known_key(k, keys)),
            )
            .collect();
        if !changed.is_empty() {
            return changed;
        }
    }
    assert!(parsed_once, "--{flag}: no sample value parses");
    BTreeSet::new()
}

#[test]
fn every_run_flag_and_config_key_is_in_the_readme_and_the_readme_names_only_real_ones() {
    let problems = disagreements(&readme_section());
    assert!(
        problems.is_empty(),
        "README.md ({SECTION}) and the run configuration disagree:\n  {}",
        problems.join("\n  ")
    );
}

/// Known-bad controls: the README's section with one mistake each.
#[test]
fn a_readme_that_leaves_out_mispairs_or_invents_is_caught() {
    let section = readme_section();
    let cases = [
        (
            "normal_dot = 0.9",
            "",
            "erosion.normal_dot is not in the README's TOML example",
        ),
        (
            "`outputs.obj`, `outputs.glb`",
            "`outputs.glb`, `outputs.obj`",
            "--no-obj sets {\"outputs.obj\"}, the README pairs it with {\"outputs.glb\"}",
        ),
        (
            "`--resume`, `--quiet`",
            "`--resume`, `--quiet`, `--fast`",
            "README's table names --fast, which is no `run` flag",
        ),
        (
            ", `erosion.normal_dot`",
            "",
            "config key erosion.normal_dot: no flag --normal-dot",
        ),
        ("seed = 0", "seeds = 0", "not a valid config"),
    ];
    for (from, to, expect) in cases {
        assert!(
            section.contains(from),
            "the README no longer holds {from:?}"
        );
        let problems = disagreements(&section.replacen(from, to, 1));
        assert!(
            problems.iter().any(|p| p.contains(expect)),
            "replacing {from:?} by {to:?}: expected {expect:?} among {problems:#?}"
        );
    }
}

/// What the README's run section says that the code does not do, one line
/// each.
/// Settings the README documents in their own sections (the `optimization`
/// and `lapped-rigid` methods' parameter tables, the artist options under
/// "Looking at the result") rather than in the run section's key/flag
/// pairing; their config sections are left out of the file when at their
/// defaults, which this check cannot see yet. Bringing them under it is an
/// open item of issue 9.
const OWN_SECTIONS: &[&str] = &["optimization.", "lapped_rigid."];

/// Whether `--flag` belongs to one of those settings.
fn documented_elsewhere(flag: &str) -> bool {
    flag.starts_with("rigid-")
        || [
            "mask",
            "points",
            "exemplar-texels",
            "levels",
            "levels-after-first",
            "sizes",
            "search",
            "search-grid",
            "checks",
            "rerank",
            "iterations",
            "convergence",
            "centre-spacing",
            "coherence",
            "robust",
            "histogram",
            "passes-after-first",
            "orientation-iterations",
            "orientation-smoothing",
            "relaxation",
            "upsample-diffusion",
            "point-placement",
            "transport",
            "preview-video",
            "prim",
        ]
        .contains(&flag)
}

fn disagreements(section: &str) -> Vec<String> {
    let block = toml_block(section);
    // As written: its `preset` key names the key, not the keys the preset
    // would fill in.
    let example = match toml::from_str::<Config>(&block) {
        Ok(c) => c,
        Err(e) => {
            return vec![format!(
                "README's TOML example is not a valid config: {e:#}"
            )];
        }
    };

    // Every key, from the code (default) and from the example (keys that
    // are skipped when unset).
    let mut all = leaves(&Config::default());
    all.extend(leaves(&example));
    // outputs.switch_map, erosion.transition and the erosion keys of the
    // paper's steps are left out of the serialized config at their
    // defaults (so older runs keep their settings fingerprint): ask for
    // them set.
    let mut switch_on = Config::default();
    switch_on.outputs.switch_map = true;
    let e = &mut switch_on.params.erosion;
    e.transition = 1;
    e.patch_region = erosion::PatchRegion::Paper;
    e.seed_corners = erosion::SeedCorners::Paper;
    e.seed_texel = erosion::SeedTexel::Paper;
    e.feature_filter = erosion::FeatureFilter::Full;
    e.eroded_triangles = erosion::ErodedTriangles::Kept;
    e.bound = erosion::Bound::Paper;
    all.extend(leaves(&switch_on));
    let mut keys: BTreeSet<String> = BTreeSet::new();
    for k in all.keys() {
        let parent = k.rsplit_once('.').map(|(p, _)| p.to_string());
        // `channels.displacement` of the example is the `channels` table.
        if parent
            .as_ref()
            .is_some_and(|p| leaves(&Config::default()).contains_key(p))
        {
            continue;
        }
        keys.insert(k.clone());
    }
    let tables: BTreeSet<String> = keys
        .iter()
        .filter_map(|k| k.rsplit_once('.').map(|(p, _)| p.to_string()))
        .collect();
    let flags = run_flags();
    let mut problems = Vec::new();

    // The TOML example names every key, and only keys.
    let mentioned = toml_mentions(&block);
    for k in keys.iter().filter(|k| !mentioned.contains(*k)) {
        problems.push(format!(
            "config key {k} is not in the README's TOML example"
        ));
    }
    for k in mentioned
        .iter()
        .filter(|k| !keys.contains(*k) && !tables.contains(*k))
        .filter(|k| !keys.contains(&known_key(k, &keys)))
    {
        problems.push(format!(
            "README's TOML example names {k}, which is no config key"
        ));
    }

    // Every --flag the section mentions exists (cargo's own aside).
    let without_cargo: String = section
        .split('`')
        .filter(|span| !span.starts_with("cargo "))
        .collect::<Vec<_>>()
        .join("`");
    for f in flag_tokens(&without_cargo) {
        if f != "help" && !flags.contains_key(&f) {
            problems.push(format!("README names --{f}, which is no `run` flag"));
        }
    }

    // The pairing the README states: the rule plus the exceptions table.
    let e = exceptions(section);
    let mut expected: BTreeMap<String, Option<String>> = BTreeMap::new();
    for (f, k) in &e.pairs {
        expected.insert(f.clone(), Some(k.clone()));
    }
    for f in &e.flag_only {
        expected.insert(f.clone(), None);
    }
    for k in e.pairs.iter().map(|(_, k)| k).chain(&e.key_only) {
        if !keys.contains(k) {
            problems.push(format!(
                "README's table names key {k}, which is no config key"
            ));
        }
    }
    for f in expected.keys() {
        if !flags.contains_key(f) {
            problems.push(format!(
                "README's table names --{f}, which is no `run` flag"
            ));
        }
    }
    let excepted_keys: BTreeSet<&String> =
        e.pairs.iter().map(|(_, k)| k).chain(&e.key_only).collect();
    for k in keys.iter().filter(|k| !excepted_keys.contains(k)) {
        let leaf = k.rsplit('.').next().unwrap();
        let flag = leaf.replace('_', "-");
        if flags.contains_key(&flag) && !expected.contains_key(&flag) {
            expected.insert(flag, Some(k.clone()));
        } else {
            problems.push(format!(
                "config key {k}: no flag --{flag}, and the README's table does not say which flag sets it or that none does"
            ));
        }
    }
    for f in flags
        .keys()
        .filter(|f| !expected.contains_key(*f) && !documented_elsewhere(f))
    {
        problems.push(format!(
            "--{f}: no config key of that name, and the README's table does not say which key it sets or that it has none"
        ));
    }

    // Each flag sets exactly the key it is paired with (or none).
    for (f, key) in &expected {
        let Some(&takes_value) = flags.get(f) else {
            continue;
        };
        let set: BTreeSet<String> = keys_set_by(f, takes_value, &keys)
            .into_iter()
            .filter(|k| !OWN_SECTIONS.iter().any(|s| k.starts_with(s)))
            .collect();
        let want: BTreeSet<String> = key.iter().cloned().collect();
        if set != want {
            problems.push(format!(
                "--{f} sets {set:?}, the README pairs it with {want:?}"
            ));
        }
    }

    problems
}
