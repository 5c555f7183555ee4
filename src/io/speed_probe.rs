//! How fast the machine was: a fixed workload, timed into every manifest,
//! so that wall times measured on different machines (or on one shared
//! with other work) can be compared. It runs none of the project's code,
//! so it reads the same across revisions.

use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

/// Seconds the fixed workload took, median of 3 runs: once on one thread,
/// and once with one copy on every worker thread at the same time (as long
/// as one copy on an idle machine with enough cores).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct SpeedProbe {
    /// One copy on one thread.
    pub one_thread_s: f64,
    /// One copy per worker thread, all at once.
    pub all_threads_s: f64,
}

/// Times the workload now.
pub fn speed_probe() -> SpeedProbe {
    let median_of_3 = |run: &dyn Fn()| {
        let mut t: Vec<f64> = (0..3)
            .map(|_| {
                let start = Instant::now();
                run();
                start.elapsed().as_secs_f64()
            })
            .collect();
        t.sort_by(f64::total_cmp);
        t[1]
    };
    let threads = rayon::current_num_threads() as u64;
    SpeedProbe {
        one_thread_s: median_of_3(&|| {
            black_box(workload(1));
        }),
        all_threads_s: median_of_3(&|| {
            black_box((0..threads).into_par_iter().map(workload).sum::<f64>());
        }),
    }
}

/// Arithmetic like a ray march's: random table lookups, `exp`, multiply-adds.
fn workload(seed: u64) -> f64 {
    let table: Vec<f64> = (0..1 << 16).map(|i| (i as f64).sqrt()).collect();
    let (mut x, mut acc) = (seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1, 0.0);
    for _ in 0..8_000_000 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        acc = acc * 0.999 + (-table[(x & 0xffff) as usize] * 1e-3).exp();
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_probe_gives_finite_positive_times() {
        let p = speed_probe();
        assert!(p.one_thread_s.is_finite() && p.one_thread_s > 0.0, "{p:?}");
        assert!(p.all_threads_s.is_finite() && p.all_threads_s > 0.0, "{p:?}");
    }
}
