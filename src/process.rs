//! Process-wide settings every binary applies first.

/// Keeps freed memory in the process instead of giving it back to the
/// system. A gradient pass allocates and frees grids of dual numbers of
/// tens of megabytes every update; by default glibc maps each anew and
/// unmaps it when freed, so every update pays for zeroed pages and for
/// unmapping, much of it on one thread (a serial part of every update).
/// Results are the same bits. Elsewhere than Linux with glibc it does nothing.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        extern "C" {
            fn mallopt(param: i32, value: i32) -> i32;
        }
        // glibc's <malloc.h>: M_TRIM_THRESHOLD and M_MMAP_THRESHOLD.
        const M_TRIM_THRESHOLD: i32 = -1;
        const M_MMAP_THRESHOLD: i32 = -3;
        // SAFETY: mallopt only sets allocator parameters; a value it refuses leaves the default.
        unsafe {
            mallopt(M_MMAP_THRESHOLD, 512 << 20);
            mallopt(M_TRIM_THRESHOLD, i32::MAX);
        }
    }
}
