//! Process CPU time, to tell how much of a timed run the machine actually gave the
//! process (Embree's harness prints the same share as `cpu`).

/// CPU seconds used so far by the whole process, all threads together; `None` where
/// the platform has no such clock.
pub fn process_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `clock_gettime` writes one `timespec` through the valid pointer.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
        (rc == 0).then_some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The share of `threads` cores the process used over `wall` seconds in which it
/// used `cpu` CPU seconds: 1.0 when every thread ran all the time, well below where
/// other load took cores away. NaN without a CPU clock.
pub fn utilisation(cpu: Option<f64>, wall: f64, threads: usize) -> f64 {
    match cpu {
        Some(c) if wall > 0.0 => c / (wall * threads.max(1) as f64),
        _ => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Busy work advances the clock, by no more than all cores could do in the time.
    #[test]
    fn busy_work_advances_the_clock_within_the_cores_wall_time() {
        // The wall window encloses the CPU window (started before the first CPU read,
        // ended after the second): other tests run on the other threads of this
        // process, so with every core busy the CPU time may reach cores x wall, and a
        // CPU window wider than the wall one (as this test first had it) could exceed
        // that bound by the gap between the reads.
        let start = std::time::Instant::now();
        let Some(c0) = process_cpu_seconds() else {
            eprintln!("SKIPPED: no process CPU clock on this platform");
            return;
        };
        let mut x = 0u64;
        while start.elapsed().as_secs_f64() < 0.05 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        let used = process_cpu_seconds().unwrap() - c0;
        let wall = start.elapsed().as_secs_f64();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        assert!(used > 0.0, "no CPU time counted for 50 ms of busy work");
        // Slack: the process clock folds the runtime of the process's *other* running
        // threads (other tests) in at their scheduler ticks, so the first read can miss
        // up to a tick (10 ms at HZ = 100, the coarsest Linux setting) of each other
        // core's work that the second read then counts; seen: 0.1018 s of CPU in 0.0500
        // s on 2 cores with a 1 ms slack. A CPU clock in the wrong unit, or counting a
        // thread twice, still fails by far more.
        assert!(
            used <= wall * cores + 0.010 * (cores - 1.0) + 1e-3,
            "{used} s of CPU in {wall} s on {cores} cores"
        );
        assert_eq!(utilisation(Some(1.5), 1.0, 2), 0.75);
        assert!(utilisation(None, 1.0, 2).is_nan());
    }
}
