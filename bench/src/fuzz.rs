//! `lineflow bench fuzz`: every parser a user's file reaches, fed mutated copies of valid files (bytes flipped,
//! set, inserted, deleted, repeated, truncated, and tokens of the formats spliced in), counting panics and the
//! slowest call. A mutation fuzzer from seeds of every format that runs on any build, deterministic from its seed so
//! that a panic it finds is found again; the coverage-guided one is the libFuzzer harness in `fuzz/` (`fuzz/run`),
//! on the same targets (`lineflow_fuzzing::TARGETS`).
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Result;
use lineflow_fuzzing::{scratch, Target, TARGETS};
use lineflow_photogrammetry::random::Rng;

/// What one target's run found.
#[derive(Debug, Clone)]
pub struct Found {
    /// The target's name.
    pub name: &'static str,
    /// Calls made.
    pub executions: u64,
    /// Calls that panicked.
    pub panics: u64,
    /// The first input that panicked and the panic's message.
    pub first_panic: Option<(Vec<u8>, String)>,
    /// The slowest call.
    pub slowest: Duration,
    /// All calls, with writing their inputs.
    pub elapsed: Duration,
}

static PANIC_AT: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// Tokens the formats are made of, spliced into the inputs.
const TOKENS: &[&[u8]] = &[
    b",",
    b"\n",
    b"\r\n",
    b"=",
    b"\"",
    b"[",
    b"]",
    b"[[",
    b"{",
    b"}",
    b"nan",
    b"inf",
    b"-inf",
    b"-1e308",
    b"1e308",
    b"0",
    b"-0",
    b"18446744073709551615",
    b"-1",
    b"4294967295",
    b"v ",
    b"l ",
    b"f ",
    b"#",
    b"\0",
    b"\xff\xff\xff\xff",
];

/// A mutated copy of `seed`: one to four mutations.
pub fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let n = b.len();
        let at = if n == 0 { 0 } else { rng.below(n) };
        match rng.below(8) {
            0 if n > 0 => b[at] ^= 1 << rng.below(8),
            1 if n > 0 => b[at] = rng.below(256) as u8,
            2 => b.insert(at, rng.below(256) as u8),
            3 if n > 0 => {
                let len = 1 + rng.below((n - at).min(64));
                b.drain(at..at + len);
            }
            4 if n > 0 => {
                let len = 1 + rng.below((n - at).min(64));
                let piece = b[at..at + len].to_vec();
                b.splice(at..at, piece);
            }
            5 => b.truncate(at),
            _ => {
                let t = TOKENS[rng.below(TOKENS.len())];
                b.splice(at..at, t.iter().copied());
            }
        }
    }
    b
}

/// Runs `executions` mutated inputs through each target (one thread; files in `dir`).
pub fn fuzz(targets: &[Target], executions: u64, seed: u64, dir: &Path) -> Result<Vec<Found>> {
    let hook = std::panic::take_hook();
    // Where the last panic happened: the message alone rarely names the parser at fault.
    std::panic::set_hook(Box::new(|info| {
        if let Some(l) = info.location() {
            *PANIC_AT.lock().unwrap_or_else(|e| e.into_inner()) = format!("{}:{}", l.file(), l.line());
        }
    }));
    let result = targets
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let mut rng = Rng::new(seed, k as u64);
            let path = dir.join(t.file);
            let mut found = Found {
                name: t.name,
                executions: 0,
                panics: 0,
                first_panic: None,
                slowest: Duration::ZERO,
                elapsed: Duration::ZERO,
            };
            let started = Instant::now();
            for e in 0..executions {
                // The seed itself first, then mutations.
                let input = if e == 0 { t.seed.to_vec() } else { mutate(t.seed, &mut rng) };
                std::fs::write(&path, &input)?;
                let start = Instant::now();
                let outcome = catch_unwind(AssertUnwindSafe(|| (t.parse)(&path)));
                found.slowest = found.slowest.max(start.elapsed());
                found.executions += 1;
                if let Err(panic) = outcome {
                    found.panics += 1;
                    if found.first_panic.is_none() {
                        let message = panic
                            .downcast_ref::<String>()
                            .cloned()
                            .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                            .unwrap_or_default();
                        let at = PANIC_AT.lock().map(|s| s.clone()).unwrap_or_default();
                        found.first_panic = Some((input, format!("{message} at {at}")));
                    }
                }
            }
            found.elapsed = started.elapsed();
            Ok(found)
        })
        .collect();
    std::panic::set_hook(hook);
    result
}

/// `lineflow bench fuzz`: a table of every target; exit status 1 when any panicked or took more than a second.
pub fn bench_fuzz(executions: u64, seed: u64) -> Result<std::process::ExitCode> {
    let dir = scratch()?;
    let targets = TARGETS;
    println!("{executions} mutated inputs per parser (seed {seed}), one thread:\n");
    println!("| parser | executions | per second | panics | slowest (ms) |");
    println!("|---|---|---|---|---|");
    let mut bad = false;
    for (t, found) in targets.iter().zip(fuzz(targets, executions, seed, dir.path())?) {
        let rate = found.executions as f64 / found.elapsed.as_secs_f64();
        println!(
            "| {} | {} | {rate:.0} | {} | {:.2} |",
            found.name,
            found.executions,
            found.panics,
            found.slowest.as_secs_f64() * 1e3
        );
        if let Some((input, message)) = &found.first_panic {
            // Kept in the working folder: the scratch folder goes with the run.
            let kept = Path::new(&format!("fuzz-panic-{}", t.file)).to_owned();
            std::fs::write(&kept, input)?;
            eprintln!("{}: {message} (input kept as {})", t.name, kept.display());
        }
        bad |= found.panics > 0 || found.slowest > Duration::from_secs(1);
    }
    Ok(if bad {
        std::process::ExitCode::FAILURE
    } else {
        std::process::ExitCode::SUCCESS
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_and_change_the_input() {
        let seed = b"id,X,Y\n1,2,3\n";
        let a: Vec<Vec<u8>> = (0..50).scan(Rng::new(1, 0), |r, _| Some(mutate(seed, r))).collect();
        let b: Vec<Vec<u8>> = (0..50).scan(Rng::new(1, 0), |r, _| Some(mutate(seed, r))).collect();
        assert_eq!(a, b);
        assert!(a.iter().filter(|m| m.as_slice() != seed).count() > 40);
    }

    /// With seed 2026 this found the mcap crate's unchecked chunk arithmetic (`recordings`' `Guarded`): it stays
    /// as that panic's regression test.
    #[test]
    fn every_parser_survives_mutated_files_without_a_panic() {
        let dir = scratch().unwrap();
        let targets = TARGETS;
        for found in fuzz(targets, 300, 2026, dir.path()).unwrap() {
            assert_eq!(found.executions, 300);
            assert!(
                found.panics == 0,
                "{} panicked {} times, first on {} bytes: {:?}",
                found.name,
                found.panics,
                found.first_panic.as_ref().map_or(0, |(input, _)| input.len()),
                found.first_panic.as_ref().map(|(_, message)| message)
            );
        }
    }
}
