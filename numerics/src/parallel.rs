//! Independent jobs on a few threads: the one parallel loop of mrtwin's fits.

use std::cell::Cell;

thread_local! {
    /// Set on the threads [`map_indexed`] starts.
    static WORKER: Cell<bool> = const { Cell::new(false) };
}

/// Whether this thread runs one of [`map_indexed`]'s jobs on a thread of its own: its
/// siblings already share the cores, so it should not start more threads itself.
pub fn in_worker() -> bool {
    WORKER.with(Cell::get)
}

/// Whether a computation on this thread may take a second core: not inside a
/// [`map_indexed`] worker, on a machine with more than one.
pub fn spare_core() -> bool {
    !in_worker() && std::thread::available_parallelism().is_ok_and(|n| n.get() > 1)
}

/// `f(0)`, …, `f(n − 1)` on up to `threads` scoped threads, returned in index order.
/// Each thread takes the next index not yet taken (jobs of unequal length keep every
/// thread busy to the end); each job's result is its own, so the results do not depend on
/// the number of threads or on which thread ran a job. With one thread (or one job) it
/// runs inline.
pub fn map_indexed<T: Send>(n: usize, threads: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let threads = threads.clamp(1, n.max(1));
    if threads == 1 {
        return (0..n).map(&f).collect();
    }
    let mut out: Vec<Option<T>> = (0..n).map(|_| None).collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|s| {
        let (f, next) = (&f, &next);
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(move || {
                    WORKER.with(|w| w.set(true));
                    std::iter::from_fn(|| {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        (i < n).then(|| (i, f(i)))
                    })
                    .collect::<Vec<_>>()
                })
            })
            .collect();
        for h in handles {
            for (i, v) in h.join().expect("a parallel job panicked") {
                out[i] = Some(v);
            }
        }
    });
    out.into_iter()
        .map(|v| v.expect("every index computed"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_come_back_in_index_order_whatever_the_thread_count() {
        let one: Vec<u64> = map_indexed(17, 1, |i| (i as u64) * (i as u64) + 3);
        for threads in [2, 3, 8, 40] {
            assert_eq!(
                map_indexed(17, threads, |i| (i as u64) * (i as u64) + 3),
                one
            );
        }
        assert!(map_indexed(0, 4, |i| i).is_empty());
    }

    #[test]
    fn the_jobs_of_several_threads_know_they_are_workers() {
        assert!(!in_worker());
        assert_eq!(map_indexed(4, 2, |_| in_worker()), vec![true; 4]);
        // One thread runs the jobs inline, on the caller's thread.
        assert_eq!(map_indexed(4, 1, |_| in_worker()), vec![false; 4]);
        assert!(!in_worker());
    }
}
