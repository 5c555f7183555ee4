//! Parallel building blocks whose results are those of the serial code,
//! bit for bit, whatever the number of threads.
//!
//! Loops whose items differ in cost cap their tasks (`with_max_len`):
//! rayon otherwise cuts a loop into about twice as many tasks as threads,
//! whatever they cost, and the thread left with the costly task keeps all
//! the others waiting at the end of the loop.

use rayon::prelude::*;

/// Below this many bytes, [`concat`] copies on one thread.
const SERIAL_BELOW_BYTES: usize = 1 << 18;

/// `parts` joined in order, copied in parallel. Joining the parts a
/// parallel loop returned on one thread is a serial part of every render:
/// with 64 dual lanes a photon power is 520 bytes, and the copy into fresh
/// pages costs as much as the loop on 16 threads.
pub fn concat<T: Clone + Send + Sync>(parts: Vec<Vec<T>>) -> Vec<T> {
    let mut offsets = Vec::with_capacity(parts.len() + 1);
    offsets.push(0);
    for part in &parts {
        offsets.push(offsets.last().unwrap() + part.len());
    }
    let total = *offsets.last().unwrap();
    if total * std::mem::size_of::<T>() < SERIAL_BELOW_BYTES {
        return parts.into_iter().flatten().collect();
    }
    (0..total)
        .into_par_iter()
        .with_min_len(1024)
        .map(|k| {
            let part = offsets.partition_point(|&o| o <= k) - 1;
            parts[part][k - offsets[part]].clone()
        })
        .collect()
}

/// Bytes per task of a loop that does as little per item as a copy
/// ([`cloned`], [`filled`], a maximum): waking the pool costs about as much
/// as copying this much, so a loop under two tasks' worth stays on the
/// calling thread.
pub const COPY_TASK_BYTES: usize = 1 << 18;

/// Items of `T` per task of such a loop ([`COPY_TASK_BYTES`]).
pub fn copy_task_len<T>() -> usize {
    (COPY_TASK_BYTES / std::mem::size_of::<T>().max(1)).max(1)
}

/// A copy of `values`, made in parallel where large: a grid of 64^3
/// numbers copied on one thread is a serial part of every update.
pub fn cloned<T: Clone + Send + Sync>(values: &[T]) -> Vec<T> {
    let task = copy_task_len::<T>();
    if values.len() < 2 * task {
        return values.to_vec();
    }
    values.par_iter().with_min_len(task).cloned().collect()
}

/// `len` copies of `value`, written in parallel: a grid of dual numbers
/// filled on one thread is a serial part of every pass.
pub fn filled<T: Clone + Send + Sync>(len: usize, value: T) -> Vec<T> {
    (0..len).into_par_iter().with_min_len(copy_task_len::<T>()).map(|_| value.clone()).collect()
}

/// `(a(), b())`, the two running side by side and feeding the same thread
/// pool, so that the serial parts and the last tasks of each overlap the
/// other's work (on 16 threads, one render alone leaves many of them idle
/// at the end of each of its parallel loops). Called from outside a pool, `a` runs on the calling thread and
/// `b` on a helper thread: unlike `rayon::join`, `a`'s large allocations
/// then come from the main thread's allocator arena, which keeps freed
/// memory ([`crate::process::keep_freed_memory`]), while a pool thread's
/// arena maps anything over 64 MiB anew each time.
pub fn alongside<A: Send, B: Send>(a: impl FnOnce() -> A + Send, b: impl FnOnce() -> B + Send) -> (A, B) {
    if rayon::current_thread_index().is_some() {
        // Inside a pool (a test's, say): both stay in it.
        return rayon::join(a, b);
    }
    std::thread::scope(|s| {
        let helper = s.spawn(b);
        let a = a();
        (a, helper.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concat_is_the_serial_join() {
        for sizes in [vec![], vec![0, 0], vec![3, 0, 5], vec![20_000, 0, 1, 30_000, 7]] {
            let parts: Vec<Vec<u64>> =
                sizes.iter().enumerate().map(|(p, &n)| (0..n as u64).map(|i| i * 31 + p as u64).collect()).collect();
            let serial: Vec<u64> = parts.iter().flatten().copied().collect();
            assert_eq!(concat(parts), serial, "sizes {sizes:?}");
        }
    }

    #[test]
    fn cloned_and_filled_are_the_serial_ones() {
        // Under and over two tasks' worth of 8 and of 520 bytes.
        for len in [0, 5, 100_000] {
            let values: Vec<u64> = (0..len as u64).map(|i| i * 2_654_435_761 % 1009).collect();
            assert_eq!(cloned(&values), values, "len {len}");
        }
        for len in [0, 5, 2_000] {
            assert_eq!(filled(len, [7u64; 65]), vec![[7u64; 65]; len], "len {len}");
        }
    }

    #[test]
    fn alongside_gives_both_results_in_and_outside_a_pool() {
        let work = |k: u64| (0..100_000u64).into_par_iter().map(|i| i * i % (k + 7)).sum::<u64>();
        let serial = |k: u64| (0..100_000u64).map(|i| i * i % (k + 7)).sum::<u64>();
        assert_eq!(alongside(|| work(1), || work(2)), (serial(1), serial(2)));
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        assert_eq!(pool.install(|| alongside(|| work(3), || work(4))), (serial(3), serial(4)));
    }
}
