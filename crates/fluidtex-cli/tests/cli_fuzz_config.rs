//! Seeded mutation fuzzing of the TOML run config (see
//! `fluidtex::fuzz`; the other readers are fuzzed in the library's
//! `fuzz_readers`): parsing, the erosion parameters' validation and the
//! fingerprint, on damaged copies of a config that sets every key.
//! Fails on a panic, a case over 2 s, or an error of more than one line.
//!
//! [`CI_CASES`] cases in CI (under a second); a longer developer run:
//! `FLUIDTEX_FUZZ_CASES=200000 cargo test --release -p fluidtex-cli --test cli_fuzz_config`.

#![allow(clippy::unwrap_used)]

use std::path::Path;

use fluidtex::fuzz::{Fuzz, SEED};
use fluidtex_cli::config::Config;

const CI_CASES: u64 = 10_000;

#[test]
fn fuzz_toml_config() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz_config.toml");
    let good = std::fs::read(&fixture).unwrap();
    // Known good: the fixture parses, with every section set.
    let config = Config::parse(std::str::from_utf8(&good).unwrap(), &fixture).unwrap();
    assert_eq!(config.outputs.preview_every, 8);
    assert_eq!(config.channels.len(), 1);
    let cases = std::env::var("FLUIDTEX_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(CI_CASES);
    let f = Fuzz::new("toml-config", SEED, vec![good]);
    let failures = f.run(cases, |b: &[u8]| {
        // A config file that is not UTF-8 is refused when read; the text
        // reader only ever sees text.
        let text = String::from_utf8_lossy(b);
        match Config::parse(&text, Path::new("shot.toml")) {
            Ok(c) => {
                let _ = c.fingerprint();
                let _ = c.params.erosion.validate();
            }
            Err(e) => {
                let line = fluidtex_cli::one_line(&e);
                assert!(!line.contains('\n'), "{line}");
            }
        }
    });
    eprintln!(
        "fuzz toml-config: {cases} cases, seed {SEED:#x}, {} failures",
        failures.len()
    );
    let list: Vec<String> = failures.iter().take(20).map(|x| x.to_string()).collect();
    assert!(failures.is_empty(), "{}", list.join("\n"));
}
