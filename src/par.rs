//! Parallel building blocks whose results are those of the serial code,
//! bit for bit, whatever the number of threads.

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

/// `len` copies of `value`, written in parallel: a grid of dual numbers
/// filled on one thread is a serial part of every pass.
pub fn filled<T: Clone + Send + Sync>(len: usize, value: T) -> Vec<T> {
    (0..len).into_par_iter().with_min_len(4096).map(|_| value.clone()).collect()
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
}
