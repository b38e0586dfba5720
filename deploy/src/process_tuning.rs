//! Process-wide settings applied once at start-up, before any thread exists.
//!
//! Both come from profiling `risktwin train` (perf + strace), where the candle update of small
//! networks allocates a fresh buffer per tensor op:
//! - glibc serves allocations from 128 KiB up with `mmap` and gives freed heap tops back with
//!   `brk`, so every 512 × 64 activation faulted its pages in anew: about a third of the CPU
//!   time was page faults. Raising both thresholds keeps those buffers in the heap.
//! - candle asks for its thread count on every matmul and, unless `RAYON_NUM_THREADS` is set,
//!   parses `/proc/cpuinfo` each time (num_cpus::get_physical). Setting it to the available
//!   parallelism (what rayon uses anyway) makes that a lookup. A user's own value is kept.

/// Allocations below this stay in the heap instead of `mmap` (bytes).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD_B: libc::c_int = 32 << 20;
/// Free heap top kept before trimming it back to the kernel (bytes).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TRIM_THRESHOLD_B: libc::c_int = 256 << 20;

/// Applies the settings.
///
/// # Safety
/// Must be called before any other thread exists (it sets an environment variable).
pub unsafe fn apply() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only adjusts allocator parameters; no allocation is in flight.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_B);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD_B);
    }
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        // SAFETY: the caller guarantees no other thread exists yet.
        unsafe { std::env::set_var("RAYON_NUM_THREADS", threads.to_string()) };
    }
}
