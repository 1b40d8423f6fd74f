//! A seeded mutation fuzzer for the readers, on stable Rust.
//!
//! Every reader of user files (PLY, OBJ, VTK, exemplar images, `state.bin`,
//! the TOML config) is run on thousands of damaged copies of committed
//! fixtures. A case is one fixture with one to four mutations drawn from:
//! bit flips, bytes set to edge values, truncations, splices of another
//! fixture's bytes, deleted and repeated ranges, a number in the text
//! replaced by a troublesome token (`nan`, `inf`, `-1`, `4294967296`,
//! `1e300`, `1000000000000`, ...), and 1/2/4/8 bytes overwritten with edge
//! integers and floats (NaN, ±inf, `u32::MAX`, `i32::MIN`, ...) in either
//! byte order. Cases are derived from `(seed, reader, index)` only, so a
//! failure names a case that replays alone: [`Fuzz::replay`].
//!
//! A case fails when the reader panics or takes longer than the time limit
//! (2 s). A case that never returns (a hang) is caught by a watchdog that
//! prints the case and ends the process after [`HANG_SECONDS`].

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// The seed of the committed fuzz tests.
pub const SEED: u64 = 0x5eed_f1d7;

/// A case running this long is a hang: the watchdog ends the process.
pub const HANG_SECONDS: u64 = 30;

/// Tokens that break text formats: non-finite values, signs, huge and
/// out-of-range counts and indices.
const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "-1",
    "-2147483648",
    "2147483647",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "1000000000000",
    "1e300",
    "-1e300",
    "1e-320",
    "0",
    "-0",
    "3.5",
    "",
    "\"",
    "[",
    "=",
];

const EDGE_U64: &[u64] = &[
    0,
    1,
    0x7f,
    0x80,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    1_000_000_000_000,
    u64::MAX,
];

/// A failed case.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Failure {
    pub reader: String,
    pub case: u64,
    /// "panicked: ..." or "took 2.4 s".
    pub what: String,
    pub input_len: usize,
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} case {} ({} bytes): {} (replay: FLUIDTEX_FUZZ_CASE={} with the same seed)",
            self.reader, self.case, self.input_len, self.what, self.case
        )
    }
}

/// A fuzzing session over one reader's fixtures.
pub struct Fuzz {
    pub reader: String,
    pub seed: u64,
    pub fixtures: Vec<Vec<u8>>,
    /// A case slower than this fails.
    pub time_limit: Duration,
}

impl Fuzz {
    pub fn new(reader: &str, seed: u64, fixtures: Vec<Vec<u8>>) -> Fuzz {
        Fuzz {
            reader: reader.to_string(),
            seed,
            fixtures,
            time_limit: Duration::from_secs(2),
        }
    }

    /// The bytes of case `case`.
    pub fn case(&self, case: u64) -> Vec<u8> {
        let mut rng = Pcg64::seed_from_u64(mix(self.seed, &self.reader, case));
        let k = rng.random_range(0..self.fixtures.len().max(1));
        let mut bytes = self.fixtures.get(k).cloned().unwrap_or_default();
        let steps = rng.random_range(1..=4);
        for _ in 0..steps {
            mutate(&mut bytes, &self.fixtures, &mut rng);
        }
        bytes
    }

    /// Runs cases `0..cases` through `read`; returns every failure.
    pub fn run<T>(&self, cases: u64, read: impl Fn(&[u8]) -> T) -> Vec<Failure> {
        let started = Arc::new(AtomicU64::new(0)); // ms since `origin` + 1; 0 = idle
        let origin = Instant::now();
        let watch = Arc::clone(&started);
        let reader = self.reader.clone();
        let current = Arc::new(AtomicU64::new(0));
        let watch_case = Arc::clone(&current);
        let done = Arc::new(AtomicU64::new(0));
        let watch_done = Arc::clone(&done);
        let watchdog = std::thread::spawn(move || {
            while watch_done.load(Ordering::SeqCst) == 0 {
                std::thread::sleep(Duration::from_millis(100));
                let s = watch.load(Ordering::SeqCst);
                if s > 0 {
                    let ms = origin.elapsed().as_millis() as u64 + 1 - s;
                    if ms > HANG_SECONDS * 1000 {
                        eprintln!(
                            "fuzz: {reader} case {} hangs (over {HANG_SECONDS} s); \
                             replay it with FLUIDTEX_FUZZ_CASE",
                            watch_case.load(Ordering::SeqCst)
                        );
                        std::process::exit(3);
                    }
                }
            }
        });
        let mut failures = Vec::new();
        for case in 0..cases {
            let bytes = self.case(case);
            current.store(case, Ordering::SeqCst);
            started.store(origin.elapsed().as_millis() as u64 + 1, Ordering::SeqCst);
            let t = Instant::now();
            let outcome = catch_unwind(AssertUnwindSafe(|| {
                let _ = read(&bytes);
            }));
            let took = t.elapsed();
            started.store(0, Ordering::SeqCst);
            let what = match outcome {
                Err(payload) => Some(format!("panicked: {}", panic_text(&payload))),
                Ok(()) if took > self.time_limit => {
                    Some(format!("took {:.2} s", took.as_secs_f64()))
                }
                Ok(()) => None,
            };
            if let Some(what) = what {
                failures.push(Failure {
                    reader: self.reader.clone(),
                    case,
                    what,
                    input_len: bytes.len(),
                });
            }
        }
        done.store(1, Ordering::SeqCst);
        let _ = watchdog.join();
        failures
    }

    /// Runs one case (for replaying a failure under a debugger).
    pub fn replay<T>(&self, case: u64, read: impl Fn(&[u8]) -> T) -> T {
        read(&self.case(case))
    }
}

fn panic_text(payload: &Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "(non-text panic)".into()
    }
}

/// One seed per (seed, reader, case): FNV-1a over the three.
fn mix(seed: u64, reader: &str, case: u64) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in seed
        .to_le_bytes()
        .iter()
        .chain(reader.as_bytes())
        .chain(&case.to_le_bytes())
    {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// Applies one random mutation to `bytes`.
fn mutate(bytes: &mut Vec<u8>, fixtures: &[Vec<u8>], rng: &mut Pcg64) {
    let len = bytes.len();
    let at = |rng: &mut Pcg64| rng.random_range(0..=len);
    match rng.random_range(0..9) {
        // Bit flip.
        0 if len > 0 => {
            let i = rng.random_range(0..len);
            bytes[i] ^= 1 << rng.random_range(0..8);
        }
        // A byte set to an edge value.
        1 if len > 0 => {
            let i = rng.random_range(0..len);
            bytes[i] = [0u8, 0xff, 0x7f, 0x80, b'-', b'\n', b' ', b'9'][rng.random_range(0..8)];
        }
        // Truncation.
        2 => bytes.truncate(at(rng)),
        3 => splice_fixture(bytes, fixtures, rng),
        // Delete a range.
        4 if len > 0 => {
            let i = rng.random_range(0..len);
            let j = rng.random_range(i..=len.min(i + 64));
            bytes.drain(i..j);
        }
        // Repeat a range.
        5 if len > 0 => {
            let i = rng.random_range(0..len);
            let j = rng.random_range(i..=len.min(i + 64));
            let piece = bytes[i..j].to_vec();
            let times = rng.random_range(1..=8);
            for _ in 0..times {
                bytes.splice(j..j, piece.iter().copied());
            }
        }
        6 | 7 => replace_number(bytes, rng),
        _ if len > 0 => overwrite_edge(bytes, rng),
        _ => {}
    }
}

/// Splice: a range of another fixture (or this one) over a range here.
fn splice_fixture(bytes: &mut Vec<u8>, fixtures: &[Vec<u8>], rng: &mut Pcg64) {
    let len = bytes.len();
    if fixtures.is_empty() {
        return;
    }
    let other = &fixtures[rng.random_range(0..fixtures.len())];
    if other.is_empty() {
        return;
    }
    let a = rng.random_range(0..other.len());
    let b = rng.random_range(a..=other.len().min(a + 256));
    let piece = other[a..b].to_vec();
    let i = rng.random_range(0..=len);
    let j = rng.random_range(i..=len.min(i + 256));
    bytes.splice(i..j, piece);
}

/// A number in the text replaced by a troublesome token.
fn replace_number(bytes: &mut Vec<u8>, rng: &mut Pcg64) {
    let len = bytes.len();
    let starts: Vec<usize> = (0..len)
        .filter(|&i| bytes[i].is_ascii_digit() && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric()))
        .collect();
    if starts.is_empty() {
        return;
    }
    let i = starts[rng.random_range(0..starts.len())];
    let mut j = i;
    while j < len && (bytes[j].is_ascii_digit() || matches!(bytes[j], b'.' | b'e' | b'-' | b'+')) {
        j += 1;
    }
    let token = TOKENS[rng.random_range(0..TOKENS.len())];
    bytes.splice(i..j, token.bytes());
}

/// 1, 2, 4 or 8 bytes of a non-empty input overwritten with an edge
/// integer or float.
fn overwrite_edge(bytes: &mut [u8], rng: &mut Pcg64) {
    let width = [1usize, 2, 4, 8][rng.random_range(0..4)];
    let value: u64 = match rng.random_range(0..3) {
        0 => EDGE_U64[rng.random_range(0..EDGE_U64.len())],
        1 => [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -1.0,
            1e30,
            f32::MIN_POSITIVE,
        ][rng.random_range(0..6)]
        .to_bits() as u64,
        _ => [f64::NAN, f64::INFINITY, -1.0, 1e300][rng.random_range(0..4)].to_bits(),
    };
    let raw = if rng.random_bool(0.5) {
        value.to_le_bytes()
    } else {
        value.to_be_bytes()
    };
    let piece: &[u8] = if rng.random_bool(0.5) {
        &raw[..width]
    } else {
        &raw[8 - width..]
    };
    let i = rng.random_range(0..bytes.len());
    for (k, b) in piece.iter().enumerate() {
        if let Some(slot) = bytes.get_mut(i + k) {
            *slot = *b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_depend_on_seed_reader_and_index_only() {
        let f = Fuzz::new("r", 1, vec![b"ply 12 3.5 x".to_vec(), vec![0u8; 40]]);
        assert_eq!(f.case(7), f.case(7));
        let distinct: std::collections::HashSet<Vec<u8>> = (0..200).map(|c| f.case(c)).collect();
        assert!(distinct.len() > 150, "{}", distinct.len());
        let g = Fuzz::new("s", 1, f.fixtures.clone());
        assert!((0..20).any(|c| f.case(c) != g.case(c)));
    }

    #[test]
    fn the_harness_catches_a_planted_panic_and_a_slow_case() {
        let f = Fuzz::new(
            "planted",
            SEED,
            vec![b"element vertex 10\n1 2 3\n".to_vec()],
        );
        // Panics on cases where a mutation put a NaN token or byte 0xff in.
        let failures = f.run(300, |b: &[u8]| {
            if b.windows(3).any(|w| w == b"nan") || b.contains(&0xff) {
                panic!("planted");
            }
        });
        assert!(!failures.is_empty(), "no planted panic was caught");
        assert!(failures.iter().all(|x| x.what == "panicked: planted"));
        // Each failure replays alone.
        let first = &failures[0];
        let replayed = catch_unwind(AssertUnwindSafe(|| {
            f.replay(first.case, |b: &[u8]| {
                assert!(!b.contains(&0xff) && !b.windows(3).any(|w| w == b"nan"))
            })
        }));
        assert!(replayed.is_err());
        // A case over the time limit fails too.
        let mut slow = Fuzz::new("slow", SEED, vec![b"x".to_vec()]);
        slow.time_limit = Duration::from_millis(5);
        let failures = slow.run(2, |_: &[u8]| std::thread::sleep(Duration::from_millis(20)));
        assert_eq!(failures.len(), 2);
        assert!(failures[0].what.starts_with("took 0.0"), "{}", failures[0]);
    }
}
