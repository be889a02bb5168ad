//! Fuzzing of the regression and PAR 2D entry points.
//!
//! `cargo test` runs a fixed set of cases (the test below); a time-boxed run with another seed:
//! `cargo run --release -p vplace-core --example fuzz -- [seconds] [seed]`.
//!
//! Inputs are random and hostile: NaN, inf, subnormal and huge values, duplicated, constant and
//! collinear columns, zero-length and mismatched arrays; degenerate, non-convex, tiny, far-away
//! and overlapping polygons; points on edges and vertices. Every call must return `Ok` with
//! finite numbers or an `Err`: a panic, or a non-finite `Ok`, is a failure, printed with the
//! case's seed so it can become a regression test.

use glam::DVec2;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};
use vplace_core::fit::regression::{fit, FitParams};
use vplace_core::par2d::{Method, Scene2d};
use vplace_core::rng::Rng;

fn hostile(r: &mut Rng) -> f64 {
    match r.next_u32() % 16 {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => -f64::INFINITY,
        3 => 0.0,
        4 => f64::MIN_POSITIVE / 3.0,
        5 => 1e300,
        6 => -1e-300,
        _ => (r.next_f32() as f64 - 0.5) * 10f64.powi(r.next_u32() as i32 % 17 - 8),
    }
}

fn regression_case(r: &mut Rng) -> Result<(), String> {
    let n = (r.next_u32() % 40) as usize;
    let p = (r.next_u32() % 8) as usize;
    let nasty = r.next_u32() % 4 == 0;
    let mut x = vec![0.0; n * p];
    for v in x.iter_mut() {
        *v = if nasty {
            hostile(r)
        } else {
            r.next_f32() as f64 * 2.0 - 1.0
        };
    }
    if p >= 3 && n > 0 && r.next_u32() % 2 == 0 {
        for i in 0..n {
            x[i * p + 2] = x[i * p] + x[i * p + 1]; // exactly collinear
        }
    }
    if p >= 2 && r.next_u32() % 3 == 0 {
        for i in 0..n {
            x[i * p + 1] = 4.0; // constant
        }
    }
    let y_len = if r.next_u32() % 10 == 0 { n + 1 } else { n };
    let y: Vec<f64> = (0..y_len)
        .map(|_| {
            if nasty && r.next_u32() % 8 == 0 {
                hostile(r)
            } else {
                r.next_f32() as f64
            }
        })
        .collect();
    let params = if r.next_u32() % 2 == 0 {
        FitParams::DEFAULT
    } else {
        FitParams::PLAIN_OLS
    };
    let p_claimed = if r.next_u32() % 12 == 0 { p + 1 } else { p };
    if let Ok(f) = fit(&x, &y, p_claimed, &params) {
        let preds = f
            .predict(&x)
            .map_err(|e| format!("predict on the fitted design: {e}"))?;
        if preds.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "non-finite prediction (n={n}, p={p}): x {x:?} y {y:?} preds {preds:?} fit {f:?}"
            ));
        }
        let wsum: f64 = f.weights.iter().sum();
        if !(wsum == 0.0 || (wsum - 1.0).abs() < 1e-9) {
            return Err(format!("weights sum to {wsum}"));
        }
    }
    Ok(())
}

fn polygon(r: &mut Rng) -> Vec<DVec2> {
    let k = 1 + r.next_u32() % 7;
    let centre = DVec2::new(
        r.next_f32() as f64 * 4.0 - 2.0,
        r.next_f32() as f64 * 4.0 - 2.0,
    );
    let scale = 10f64.powi(r.next_u32() as i32 % 9 - 6);
    let offset = if r.next_u32() % 8 == 0 { 1e6 } else { 0.0 };
    (0..k)
        .map(|i| {
            let a = if r.next_u32() % 5 == 0 {
                r.next_f32() as f64 * 6.3 // random order: often non-convex
            } else {
                i as f64 / k as f64 * std::f64::consts::TAU
            };
            let v = centre + DVec2::new(a.cos(), a.sin()) * scale + DVec2::splat(offset);
            if r.next_u32() % 50 == 0 {
                DVec2::new(hostile(r), v.y)
            } else {
                v
            }
        })
        .collect()
}

fn par2d_case(r: &mut Rng) -> Result<(), String> {
    let n = (r.next_u32() % 6) as usize;
    let polys: Vec<Vec<DVec2>> = (0..n).map(|_| polygon(r)).collect();
    let emission: Vec<[f64; 3]> = (0..n)
        .map(|_| {
            if r.next_u32() % 2 == 0 {
                [0.0; 3]
            } else {
                [r.next_f32() as f64 * 3.0, 1.0, 0.5]
            }
        })
        .collect();
    let Ok(scene) = Scene2d::build(&polys, &emission) else {
        return Ok(());
    };
    for _ in 0..8 {
        let p = if r.next_u32() % 3 == 0 && !polys.is_empty() {
            let poly = &polys[(r.next_u32() as usize) % polys.len()];
            let a = poly[(r.next_u32() as usize) % poly.len()];
            let b = poly[(r.next_u32() as usize) % poly.len()];
            a.lerp(b, r.next_f32() as f64) // on a vertex, an edge or a chord
        } else {
            DVec2::new(
                r.next_f32() as f64 * 6.0 - 3.0,
                r.next_f32() as f64 * 6.0 - 3.0,
            )
        };
        for method in [Method::Exact, Method::Par, Method::monte_carlo(16)] {
            if let Ok(v) = scene.irradiance_at(p, method) {
                if v.iter().any(|c| !c.is_finite() || *c < -1e-12) {
                    return Err(format!("{method:?} at {p:?} gave {v:?}"));
                }
            }
        }
    }
    Ok(())
}

/// What a fuzzing run found: cases per target and the failures, one line each.
#[derive(Debug, Default)]
struct Report {
    cases: [u64; 2],
    failures: Vec<String>,
}

/// Runs cases `1, 2, ...` of both targets from `seed` while `go(case)` says so. Each case has
/// its own random stream, so a failure is reproduced by its seed and case number alone.
fn fuzz(seed: u64, mut go: impl FnMut(u64) -> bool) -> Report {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {})); // panics are counted below, not printed twice
    let mut report = Report::default();
    let mut case = 0u64;
    while go(case + 1) {
        case += 1;
        for (t, target) in [
            regression_case as fn(&mut Rng) -> Result<(), String>,
            par2d_case,
        ]
        .into_iter()
        .enumerate()
        {
            let mut r = Rng::new(seed, case * 2 + t as u64);
            report.cases[t] += 1;
            match catch_unwind(AssertUnwindSafe(|| target(&mut r))) {
                Ok(Ok(())) => {}
                Ok(Err(msg)) => report
                    .failures
                    .push(format!("FAIL target {t} seed {seed} case {case}: {msg}")),
                Err(_) => report
                    .failures
                    .push(format!("PANIC target {t} seed {seed} case {case}")),
            }
        }
    }
    std::panic::set_hook(hook);
    report
}

/// `[seconds] [seed]`: fuzz for that long (default 60 s, seed 1); exits with 1 on a failure.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seconds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(60);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let report = fuzz(seed, |_| Instant::now() < deadline);
    for f in &report.failures {
        println!("{f}");
    }
    println!(
        "fuzzed {seconds} s: {} regression cases, {} PAR 2D cases, {} failures",
        report.cases[0],
        report.cases[1],
        report.failures.len()
    );
    std::process::exit(i32::from(!report.failures.is_empty()));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cases per target `cargo test` runs: a fixed, deterministic set (seed 1, cases 1 to
    /// 15000), about 5 s in a debug build. Longer runs: `cargo run --release --example fuzz`.
    const CASES: u64 = 15_000;

    #[test]
    fn fixed_cases_neither_panic_nor_return_non_finite_values() {
        let report = fuzz(1, |case| case <= CASES);
        assert_eq!(report.cases, [CASES; 2]);
        assert!(
            report.failures.is_empty(),
            "{} failures:\n{}",
            report.failures.len(),
            report.failures.join("\n")
        );
    }
}
