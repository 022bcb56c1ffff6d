//! The crew runs every chunk once, returns only when all are done, and survives a
//! panicking chunk.

use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use super::*;

/// Every chunk of many jobs in a row runs exactly once, and its write is visible to
/// the caller when `run` returns, for crews of 1 to 4 threads and jobs of 0 to 97
/// chunks (more and fewer chunks than threads).
#[test]
fn every_chunk_runs_once_and_is_seen() {
    for threads in 1..=4 {
        let crew = Workers::new(threads).unwrap();
        assert_eq!(crew.threads(), threads);
        for round in 0..300usize {
            let chunks = round % 98;
            let mut seen = vec![0usize; chunks];
            let cells = Disjoint::new(&mut seen);
            let calls = AtomicUsize::new(0);
            crew.run(chunks, &|c| {
                calls.fetch_add(1, Relaxed);
                // SAFETY: chunk `c` alone writes index `c`.
                unsafe { *cells.at(c) += round + 1 };
            });
            assert_eq!(
                calls.load(Relaxed),
                chunks,
                "{threads} threads, round {round}"
            );
            assert!(
                seen.iter().all(|&s| s == round + 1),
                "{threads} threads, round {round}"
            );
        }
    }
}

/// With two threads, chunks that wait for each other finish: the worker takes chunks
/// while the caller is inside one (so the job is shared, not run by the caller
/// alone), shown by a chunk that spins until another chunk has started.
#[test]
fn a_worker_takes_chunks_while_the_caller_works() {
    let crew = Workers::new(2).unwrap();
    let caller = std::thread::current().id();
    let (started, by_worker) = (AtomicUsize::new(0), AtomicUsize::new(0));
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    crew.run(2, &|_| {
        if std::thread::current().id() != caller {
            by_worker.fetch_add(1, Relaxed);
        }
        started.fetch_add(1, Relaxed);
        while started.load(Relaxed) < 2 && std::time::Instant::now() < deadline {
            std::hint::spin_loop();
        }
    });
    assert_eq!(started.load(Relaxed), 2);
    assert_eq!(by_worker.load(Relaxed), 1, "the worker took one chunk");
}

/// A chunk that panics on a worker or on the caller makes `run` panic, after the
/// job is over; the crew still runs the next job in full.
#[test]
fn a_panicking_chunk_is_raised_and_the_crew_goes_on() {
    let crew = Workers::new(3).unwrap();
    for bad in [0usize, 5, 39] {
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            crew.run(40, &|c| {
                if c == bad {
                    panic!("chunk {c} fails");
                }
            })
        }));
        assert!(outcome.is_err(), "chunk {bad}'s panic was raised");
        let calls = AtomicUsize::new(0);
        crew.run(40, &|_| {
            calls.fetch_add(1, Relaxed);
        });
        assert_eq!(calls.load(Relaxed), 40);
    }
}

/// Counts outside `1..=MAX_THREADS` are refused with the limit named.
#[test]
fn thread_counts_are_bounded() {
    for bad in [0, MAX_THREADS + 1] {
        let err = Workers::new(bad).unwrap_err().to_string();
        assert!(err.contains(&MAX_THREADS.to_string()), "{err}");
    }
}

/// Workers park when idle and wake for the next job: a job after a pause longer
/// than the spin runs in full.
#[test]
fn parked_workers_wake_for_the_next_job() {
    let crew = Workers::new(2).unwrap();
    for _ in 0..3 {
        std::thread::sleep(std::time::Duration::from_millis(20));
        let calls = AtomicUsize::new(0);
        crew.run(16, &|_| {
            calls.fetch_add(1, Relaxed);
        });
        assert_eq!(calls.load(Relaxed), 16);
    }
}
