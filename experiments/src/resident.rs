//! The process's resident memory and CPU time, sampled at the main job's phase boundaries (issue
//! 14: "what is resident at the peak", and where the CPU seconds go on a machine too busy for wall
//! times to mean much). Linux only (`/proc/self/status`, `getrusage`); elsewhere every sample is
//! `None`.
//!
//! Read-only on purpose: resetting the peak (`/proc/self/clear_refs`, as `truth_bench` does)
//! would also lower the peak that `getrusage` and `/usr/bin/time -v` report for the whole run.

use serde_json::json;

/// Resident memory at one instant, MB (10^6 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resident {
    /// Resident set now (`VmRSS`).
    pub rss_mb: f64,
    /// The process's peak resident set so far (`VmHWM`).
    pub peak_mb: f64,
    /// CPU seconds (user + system) of all the process's threads so far, lavapipe's included.
    pub cpu_s: f64,
}

impl Resident {
    /// Samples `/proc/self/status`; `None` where it is missing or unreadable.
    pub fn sample() -> Option<Self> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let kb = |key: &str| -> Option<f64> {
            let line = status.lines().find(|l| l.starts_with(key))?;
            line.split_whitespace().nth(1)?.parse::<f64>().ok()
        };
        Some(Self {
            rss_mb: kb("VmRSS:")? * 1024.0 / 1e6,
            peak_mb: kb("VmHWM:")? * 1024.0 / 1e6,
            cpu_s: cpu_seconds()?,
        })
    }

    /// `{"rss": .., "peak": .., "cpu_s": ..}`: MB with one decimal, CPU seconds so far with three.
    pub fn json(&self) -> serde_json::Value {
        let r = |v: f64| (v * 10.0).round() / 10.0;
        let ms = |v: f64| (v * 1000.0).round() / 1000.0;
        json!({ "rss": r(self.rss_mb), "peak": r(self.peak_mb), "cpu_s": ms(self.cpu_s) })
    }
}

/// User + system CPU seconds of the whole process so far (`getrusage(RUSAGE_SELF)`).
fn cpu_seconds() -> Option<f64> {
    // SAFETY: `getrusage` writes one `rusage` into the zeroed struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return None;
    }
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    Some(t(usage.ru_utime) + t(usage.ru_stime))
}

/// Returns the heap's free pages to the system (glibc `malloc_trim`; a no-op elsewhere). glibc
/// keeps freed memory of its arenas (one per thread that allocated: the rayon workers' too)
/// resident for reuse; after a frame's vertex stage and setup are freed that is hundreds of MB
/// that the next phase's own allocations (lavapipe's, say) may not reuse.
pub fn release_free_heap() {
    // A dropped render target's buffers, kept for the next target, are not free to the
    // allocator until released.
    forestlod_reference::raster::release_spare_buffers();
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only releases memory the allocator holds free; it has no
    // preconditions and no pointer arguments.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_os = "linux")]
    #[test]
    fn a_sample_sees_an_allocation_and_the_peak_never_falls() {
        let before = Resident::sample().expect("/proc/self/status on Linux");
        // 64 MB touched page by page, so that it is resident.
        let block = vec![1u8; 64 << 20];
        assert_eq!(
            block.iter().step_by(4096).map(|&b| b as u64).sum::<u64>(),
            16384
        );
        let during = Resident::sample().expect("sample");
        drop(block);
        let after = Resident::sample().expect("sample");
        assert!(
            during.rss_mb >= before.rss_mb + 60.0,
            "64 MB not seen: {before:?} -> {during:?}"
        );
        // The block was resident, so the peak holds it after it is freed (1 MB of slack: the
        // kernel batches its resident-page counters per CPU).
        assert!(
            after.peak_mb + 1.0 >= during.rss_mb,
            "peak {after:?} below {during:?}"
        );
        // Touching 64 MB took CPU time, and the clock never runs back.
        assert!(during.cpu_s > before.cpu_s && after.cpu_s >= during.cpu_s);
    }
}
