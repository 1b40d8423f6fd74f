//! The departures ledger (`fluidtex::departures`) against the parameters
//! and against `docs/departures.md`:
//!
//! - the file is exactly what `render()` writes (regenerate it with
//!   `FLUIDTEX_BLESS=1 cargo test -p fluidtex --test departures_ledger`);
//! - every parameter of every method's section of `MethodParams`
//!   (`section.key`, as in the config file) has exactly one place in the
//!   ledger, a departure or an `AS_PUBLISHED` row, and the ledger names no
//!   parameter that does not exist: a new parameter fails here until it is
//!   entered;
//! - a departure's default, as it states it, is the parameter's default,
//!   and its flag is the parameter's flag;
//! - every behaviour row (a departure without a parameter) names, in
//!   `pinned_by`, a `#[test]` function that exists where its module path
//!   says (`crates/fluidtex/src/...`, or `tests::FILE::NAME` for
//!   `crates/fluidtex/tests/FILE.rs`). That the test checks the row's
//!   number is for review; that it exists and runs is checked here. The
//!   switches themselves are run both ways by
//!   `fluidtex::departures::switch_tests`.
//!
//! The keys are read from serde, not listed by hand: the field names each
//! `Deserialize` struct asks for (so also those it leaves out when
//! serialising), cross-checked against a serialisation of the defaults.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use fluidtex::departures::{AS_PUBLISHED, DEPARTURES, FAMILIES, render};
use fluidtex::methods::atlas_check::AtlasCheckParams;
use fluidtex::methods::dual_rest::DualRestParams;
use fluidtex::methods::erosion::ErosionParams;
use fluidtex::methods::lapped_rigid::LappedRigidParams;
use fluidtex::methods::optimization::OptimizationParams;
use fluidtex::methods::registry::{MethodParams, field_names};

const BLESS: &str = "FLUIDTEX_BLESS=1 cargo test -p fluidtex --test departures_ledger";

fn ledger_file() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/departures.md")
}

/// The fields of the parameter section `section` of `MethodParams`.
fn section_fields(section: &str) -> &'static [&'static str] {
    match section {
        "erosion" => field_names::<ErosionParams>(),
        "atlas_check" => field_names::<AtlasCheckParams>(),
        "dual_rest" => field_names::<DualRestParams>(),
        "optimization" => field_names::<OptimizationParams>(),
        "lapped_rigid" => field_names::<LappedRigidParams>(),
        other => panic!(
            "MethodParams has a section `{other}` this test does not know: add it to \
             section_fields, and its parameters to the ledger in crates/fluidtex/src/departures/"
        ),
    }
}

/// Every parameter key of every method, `section.key`.
fn parameter_keys() -> BTreeSet<String> {
    let sections = field_names::<MethodParams>();
    assert!(sections.contains(&"erosion"), "introspection read nothing");
    let mut keys = BTreeSet::new();
    for section in sections {
        for field in section_fields(section) {
            keys.insert(format!("{section}.{field}"));
        }
    }
    keys
}

/// The defaults, `section.key` → value, read back from their JSON text
/// (so f32 values print as written, 0.04 and not 0.03999999910593033).
fn default_values() -> BTreeMap<String, serde_json::Value> {
    let text = serde_json::to_string(&MethodParams::default()).expect("defaults serialise");
    let value: serde_json::Value = serde_json::from_str(&text).expect("json");
    let mut out = BTreeMap::new();
    for (section, fields) in value.as_object().expect("an object") {
        for (field, v) in fields.as_object().expect("a section is an object") {
            out.insert(format!("{section}.{field}"), v.clone());
        }
    }
    out
}

/// Where the ledger and the parameters `keys` disagree, one line each.
fn disagreements(
    keys: &BTreeSet<String>,
    departures: &[Option<&str>],
    as_published: &[&str],
) -> Vec<String> {
    let mut count: BTreeMap<&str, usize> = BTreeMap::new();
    for k in departures.iter().flatten().chain(as_published) {
        *count.entry(k).or_default() += 1;
    }
    let mut problems = Vec::new();
    for k in keys {
        match count.get(k.as_str()) {
            None => problems.push(format!(
                "parameter {k} is not in the ledger: add it to DEPARTURES or AS_PUBLISHED in \
                 crates/fluidtex/src/departures/ (the file of its paper), then run {BLESS}"
            )),
            Some(&n) if n > 1 => problems.push(format!(
                "parameter {k} is in the ledger {n} times, not once"
            )),
            Some(_) => {}
        }
    }
    for k in count.keys().filter(|k| !keys.contains(**k)) {
        problems.push(format!(
            "the ledger names {k}, which is no method parameter"
        ));
    }
    problems
}

fn ledger_departure_keys() -> Vec<Option<&'static str>> {
    DEPARTURES.iter().map(|d| d.key).collect()
}

fn ledger_published_keys() -> Vec<&'static str> {
    AS_PUBLISHED.iter().map(|(k, _)| *k).collect()
}

#[test]
fn docs_departures_md_is_generated_from_the_ledger() {
    let file = ledger_file();
    let text = render();
    if std::env::var_os("FLUIDTEX_BLESS").is_some_and(|v| v == "1") {
        std::fs::write(&file, &text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        return;
    }
    let on_disk = std::fs::read_to_string(&file)
        .unwrap_or_else(|e| panic!("{}: {e}; write it with: {BLESS}", file.display()));
    if on_disk != text {
        let line = on_disk
            .lines()
            .zip(text.lines())
            .position(|(a, b)| a != b)
            .map_or(on_disk.lines().count().min(text.lines().count()), |i| i)
            + 1;
        panic!(
            "{} is not what fluidtex::departures::render() writes (first difference on line \
             {line}). Edit crates/fluidtex/src/departures.rs and departures/, not the file, then run\n  {BLESS}",
            file.display()
        );
    }
}

#[test]
fn every_parameter_has_exactly_one_place_in_the_ledger() {
    let keys = parameter_keys();
    // Both sides were really read: a known key of each section.
    for k in [
        "erosion.delta_onset",
        "erosion.transition",
        "optimization.histogram",
        "lapped_rigid.sink_fade_rate",
        "dual_rest.period",
        "atlas_check.cell",
    ] {
        assert!(keys.contains(k), "{k} not found by introspection");
    }
    // What serde writes of the defaults is a subset of what it reads (a
    // field left out at its default, such as erosion.transition, is not).
    for k in default_values().keys() {
        assert!(keys.contains(k), "{k} serialised but not introspected");
    }
    let problems = disagreements(&keys, &ledger_departure_keys(), &ledger_published_keys());
    assert!(problems.is_empty(), "{problems:#?}");
}

/// Known-bad controls: a parameter missing from the ledger, one entered
/// twice and a ledger key naming no parameter are each reported.
#[test]
fn a_missing_doubled_or_unknown_key_is_caught() {
    let keys = parameter_keys();
    let departures = ledger_departure_keys();
    let published = ledger_published_keys();

    let fewer: Vec<&str> = published
        .iter()
        .copied()
        .filter(|k| *k != "erosion.epsilon")
        .collect();
    let p = disagreements(&keys, &departures, &fewer);
    assert!(
        p.iter()
            .any(|l| l.contains("parameter erosion.epsilon is not in the ledger")),
        "{p:#?}"
    );

    let mut more_keys = keys.clone();
    more_keys.insert("erosion.invented".into());
    let p = disagreements(&more_keys, &departures, &published);
    assert!(
        p.iter()
            .any(|l| l.contains("parameter erosion.invented is not in the ledger")),
        "{p:#?}"
    );

    let mut doubled = published.clone();
    doubled.push("erosion.weights");
    let p = disagreements(&keys, &departures, &doubled);
    assert!(
        p.iter()
            .any(|l| l.contains("erosion.weights is in the ledger 2 times")),
        "{p:#?}"
    );

    let mut unknown = published.clone();
    unknown.push("erosion.no_such_key");
    let p = disagreements(&keys, &departures, &unknown);
    assert!(
        p.iter()
            .any(|l| l.contains("names erosion.no_such_key, which is no method parameter")),
        "{p:#?}"
    );
}

/// The flag of a parameter, by the CLI's naming rule (`--key-with-dashes`,
/// `--rigid-...` for lapped_rigid), with its exceptions; `None` for keys
/// set in the file only.
fn flag_of(key: &str) -> Option<String> {
    let (section, leaf) = key.split_once('.').expect("section.key");
    let dashed = leaf.replace('_', "-");
    match key {
        "erosion.random_rotation" => Some("--no-rotation".into()),
        "lapped_rigid.random_rotation" => Some("--rigid-no-rotation".into()),
        "lapped_rigid.mask" => Some("--mask".into()),
        "optimization.placement" => Some("--point-placement".into()),
        "erosion.radius_fraction" | "erosion.exemplar_scale" | "erosion.normal_dot" => None,
        _ => match section {
            "lapped_rigid" => Some(format!("--rigid-{dashed}")),
            "atlas_check" => None,
            _ => Some(format!("--{dashed}")),
        },
    }
}

#[test]
fn each_departure_states_its_parameters_default_and_flag() {
    let defaults = default_values();
    let mut problems = Vec::new();
    for d in DEPARTURES {
        for (name, text) in [
            ("method", d.method),
            ("paper", d.paper),
            ("what", d.what),
            ("ours", d.ours),
            ("paper_setting", d.paper_setting),
            ("effect", d.effect),
            ("measure", d.measure),
        ] {
            if text.trim().is_empty() {
                problems.push(format!("{}: {name} is empty", d.what));
            }
        }
        if !FAMILIES.iter().any(|(year, _)| d.paper.starts_with(year)) {
            problems.push(format!(
                "{}: paper {:?} starts with no year of FAMILIES, so no table shows it",
                d.what, d.paper
            ));
        }
        let Some(key) = d.key else { continue };
        let leaf = key.split_once('.').map_or(key, |(_, l)| l);
        let stated = match defaults.get(key) {
            Some(serde_json::Value::String(s)) => Some(s.clone()),
            Some(serde_json::Value::Bool(b)) => Some(b.to_string()),
            Some(serde_json::Value::Number(n)) => Some(match n.as_f64() {
                Some(x) if x.fract() == 0.0 && x.abs() < 1e15 => format!("{}", x as i64),
                _ => n.to_string(),
            }),
            // No default value (an unset option) or a list: nothing to state.
            _ => None,
        };
        if let Some(value) = stated {
            let needle = format!("`{leaf} = {value}`");
            if !d.ours.contains(&needle) {
                problems.push(format!(
                    "{key}: `ours` should state the default as {needle}: {:?}",
                    d.ours
                ));
            }
        }
        if let Some(flag) = d.flag {
            let first = flag.split_whitespace().next().unwrap_or("");
            match flag_of(key) {
                Some(expected) if expected == first => {}
                expected => problems.push(format!(
                    "{key}: flag {flag:?} is not the parameter's flag ({expected:?})"
                )),
            }
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
}

/// The crate's root directory (`crates/fluidtex`).
fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Whether `text` defines a function `name` marked `#[test]` (other
/// attributes may stand between the two).
fn has_test_fn(text: &str, name: &str) -> bool {
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let signature = format!("fn {name}(");
    lines.iter().enumerate().any(|(i, line)| {
        if !line.starts_with(&signature) {
            return false;
        }
        let above = lines[..i].iter().rev();
        for attr in above.take_while(|l| l.starts_with("#[") || l.starts_with("///")) {
            if *attr == "#[test]" {
                return true;
            }
        }
        false
    })
}

/// The files a module path can live in, innermost first: for
/// `a::b::c`, `src/a/b/c.rs`, `src/a/b/c/mod.rs`, `src/a/b.rs` (an
/// inline `mod c`), `src/a/b/mod.rs`, ... For `tests::f`, `tests/f.rs`.
fn module_files(root: &std::path::Path, module: &[&str]) -> Vec<PathBuf> {
    if let ["tests", file] = module {
        return vec![root.join("tests").join(format!("{file}.rs"))];
    }
    let mut out = Vec::new();
    for n in (1..=module.len()).rev() {
        let dir: PathBuf = module[..n - 1].iter().collect();
        let leaf = module[n - 1];
        out.push(root.join("src").join(&dir).join(format!("{leaf}.rs")));
        out.push(root.join("src").join(&dir).join(leaf).join("mod.rs"));
    }
    out
}

/// What is wrong with a row's `pinned_by` (`None`: nothing), looking for
/// the test under `root`.
fn pin_problem(
    root: &std::path::Path,
    what: &str,
    key: Option<&str>,
    pinned_by: &str,
) -> Option<String> {
    if pinned_by.is_empty() {
        return key.is_none().then(|| {
            format!("{what}: a behaviour row (no parameter) must name the test that pins it")
        });
    }
    let parts: Vec<&str> = pinned_by.split("::").collect();
    let Some((name, module)) = parts.split_last().filter(|(_, m)| !m.is_empty()) else {
        return Some(format!(
            "{what}: pinned_by {pinned_by:?} is not module::path::test_name"
        ));
    };
    let found = module_files(root, module)
        .iter()
        .any(|f| std::fs::read_to_string(f).is_ok_and(|text| has_test_fn(&text, name)));
    (!found).then(|| {
        format!(
            "{what}: pinned_by {pinned_by:?}: no #[test] fn {name} where the module path points"
        )
    })
}

#[test]
fn every_behaviour_row_names_a_test_that_exists() {
    let root = crate_dir();
    let problems: Vec<String> = DEPARTURES
        .iter()
        .filter_map(|d| pin_problem(&root, d.what, d.key, d.pinned_by))
        .collect();
    assert!(problems.is_empty(), "{problems:#?}");
    // Both sides were really read: behaviour rows exist, and name tests.
    let pinned = DEPARTURES.iter().filter(|d| d.key.is_none()).count();
    assert!(pinned >= 18, "{pinned} behaviour rows");
}

/// Known-bad controls: a row naming a missing test, a function that is
/// not a test, a test in another module, or nothing at all is reported;
/// a real test in an inline test module and one in an integration test
/// pass.
#[test]
fn a_missing_or_misplaced_pinning_test_is_caught() {
    let root = crate_dir();
    let problem = |key: Option<&str>, pin: &str| pin_problem(&root, "fake row", key, pin);
    let missing = problem(
        None,
        "methods::optimization::behaviour_tests::no_such_test_anywhere",
    );
    assert!(missing.is_some_and(|p| p.contains("no #[test] fn no_such_test_anywhere")));
    // A helper, not a test.
    assert!(problem(None, "methods::optimization::behaviour_tests::flat_level").is_some());
    // A real test, named under the wrong module.
    assert!(
        problem(
            None,
            "methods::erosion::behaviour_tests::a_frame_without_motion_skips_synthesis"
        )
        .is_some()
    );
    assert!(problem(None, "").is_some_and(|p| p.contains("must name the test")));
    assert!(problem(None, "just_a_name").is_some());
    // A parameter row may leave it empty.
    assert_eq!(problem(Some("erosion.weights"), ""), None);
    assert_eq!(
        problem(
            None,
            "methods::lapped_rigid::trackers::tests::rebuild_keeps_t_at_half_r_perpendicular_to_n"
        ),
        None
    );
    assert_eq!(
        problem(
            None,
            "tests::departures_ledger::a_missing_or_misplaced_pinning_test_is_caught"
        ),
        None
    );
}
