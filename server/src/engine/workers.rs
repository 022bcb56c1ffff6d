//! A fixed crew of worker threads that share the chunks of one job with the thread
//! that asks for it, allocation-free once built.
//!
//! [`Workers::run`]`(chunks, job)` calls `job(c)` once for every `c` in `0..chunks`
//! and returns when all calls have returned. The calling thread takes chunks too, from
//! the same counter as the workers, so a worker that is asleep, or has no core
//! because the machine is busy, only means the caller does more of the job: the call
//! never waits for a worker to wake, only for one already inside a chunk to finish it.
//! Which thread runs a chunk is left to chance, so a job must give the same result
//! whoever runs it: chunks write disjoint data and read nothing another chunk writes.
//!
//! Why not a general pool: a job injected into a work-stealing pool from outside it
//! goes through a queue that allocates a block every few dozen jobs, and the
//! mechanics tick allocates nothing (`no_alloc.rs`). Here a job is one pointer, one
//! counter and an epoch, set in place.
//!
//! Between jobs a worker spins for [`SPIN`] rounds (the gaps between the products
//! of one conjugate-gradient solve are microseconds), at most about a millisecond
//! (a pause instruction takes 10 to 140 cycles, by processor), then parks until the
//! next job unparks it: between 60 Hz ticks a worker costs at most a few percent of
//! a core.
//!
//! The protocol, all in sequentially consistent atomics:
//! - the caller stores the job and resets the counter, then opens the job by making
//!   `epoch` odd, and unparks the workers;
//! - a worker that sees a new odd epoch `e` registers in `busy`, then reads `epoch`
//!   again: if it is still `e` the caller cannot finish closing the job before this
//!   worker leaves `busy`, so the job is alive while it takes chunks; otherwise it
//!   leaves without touching the job;
//! - the caller, once the counter is exhausted, closes the job (`epoch` even) and
//!   waits for `busy` to reach zero. By the order of the two stores and two loads
//!   (store `busy`, load `epoch` in the worker; store `epoch`, load `busy` in the
//!   caller) either the worker sees the job closed or the caller sees it busy.

use std::cell::{Cell, UnsafeCell};
use std::fmt;
use std::marker::PhantomData;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::thread::{self, JoinHandle};

/// Spin rounds a worker waits for the next job before it parks, with a pause
/// instruction each.
pub const SPIN: u32 = 1 << 14;

/// The most threads a crew may have (the caller included): a limit of the scene
/// setting, far above the cores a station has.
pub const MAX_THREADS: usize = 64;

/// A job's call, its lifetime erased: valid while its epoch is open (see the module).
type JobPtr = *const (dyn Fn(usize) + Sync);

struct Shared {
    /// Odd while a job is open; each job makes it odd, then even.
    epoch: AtomicU64,
    /// The open job, written only by the caller while `epoch` is even and no worker is
    /// `busy`.
    job: UnsafeCell<Option<JobPtr>>,
    /// Number of chunks of the open job.
    chunks: AtomicUsize,
    /// The next chunk to take.
    next: AtomicUsize,
    /// Workers inside the open job.
    busy: AtomicUsize,
    /// A chunk run by a worker panicked.
    panicked: AtomicBool,
    stop: AtomicBool,
}

// SAFETY: `job` is written only by the caller (one thread, `Workers` is not `Sync`)
// while no worker may read it, and read by workers only while the protocol above
// keeps it alive and unchanged.
unsafe impl Sync for Shared {}
unsafe impl Send for Shared {}

/// The crew. Not `Sync`: one thread at a time asks it for work.
pub struct Workers {
    shared: Arc<Shared>,
    handles: Vec<JoinHandle<()>>,
    _not_sync: PhantomData<Cell<()>>,
}

/// The crew could not be built.
#[derive(Debug, thiserror::Error)]
pub enum WorkersError {
    #[error("threads = {0}: at least 1 and at most {MAX_THREADS}")]
    Count(usize),
    #[error("could not start a worker thread: {0}")]
    Spawn(#[from] std::io::Error),
}

impl Workers {
    /// A crew of `threads − 1` workers besides the caller (`threads = 1`: none, every
    /// job runs on the caller).
    pub fn new(threads: usize) -> Result<Self, WorkersError> {
        if !(1..=MAX_THREADS).contains(&threads) {
            return Err(WorkersError::Count(threads));
        }
        let shared = Arc::new(Shared {
            epoch: AtomicU64::new(0),
            job: UnsafeCell::new(None),
            chunks: AtomicUsize::new(0),
            next: AtomicUsize::new(0),
            busy: AtomicUsize::new(0),
            panicked: AtomicBool::new(false),
            stop: AtomicBool::new(false),
        });
        let mut crew = Workers {
            shared,
            handles: Vec::with_capacity(threads - 1),
            _not_sync: PhantomData,
        };
        for k in 1..threads {
            let shared = Arc::clone(&crew.shared);
            let handle = thread::Builder::new()
                .name(format!("laparo-worker-{k}"))
                .spawn(move || work(&shared))?;
            crew.handles.push(handle);
        }
        Ok(crew)
    }

    /// Threads that take chunks, the caller included.
    pub fn threads(&self) -> usize {
        self.handles.len() + 1
    }

    /// Calls `job(c)` for every `c` in `0..chunks`, each once, on this thread and the
    /// workers, and returns when all have returned (their writes then visible here).
    /// A chunk that panics on a worker is re-raised here once the job is over.
    pub fn run(&self, chunks: usize, job: &(dyn Fn(usize) + Sync)) {
        if self.handles.is_empty() || chunks <= 1 {
            (0..chunks).for_each(job);
            return;
        }
        let s = &*self.shared;
        // SAFETY: the lifetime is erased for the workers' view only; the job is
        // closed, and no worker is inside it, before this call returns (see the
        // module). The epoch is even and `busy` zero: no worker reads `job` now.
        let erased: JobPtr = unsafe { std::mem::transmute(job as *const (dyn Fn(usize) + Sync)) };
        unsafe { *s.job.get() = Some(erased) };
        s.chunks.store(chunks, SeqCst);
        s.next.store(0, SeqCst);
        s.epoch.fetch_add(1, SeqCst);
        for h in &self.handles {
            h.thread().unpark();
        }
        // A chunk that panics here must not unwind past the workers still inside the
        // job: it is closed first, then the panic resumes.
        let mine = catch_unwind(AssertUnwindSafe(|| take_chunks(s, job)));
        s.epoch.fetch_add(1, SeqCst);
        while s.busy.load(SeqCst) != 0 {
            std::hint::spin_loop();
        }
        if let Err(panic) = mine {
            s.panicked.store(false, SeqCst);
            std::panic::resume_unwind(panic);
        }
        if s.panicked.swap(false, SeqCst) {
            panic!("a chunk of a parallel job panicked on a worker thread");
        }
    }
}

/// [`Workers::run`] on `workers`, or every chunk in order on this thread if there
/// are none.
pub fn share(workers: Option<&Workers>, chunks: usize, job: &(dyn Fn(usize) + Sync)) {
    match workers {
        Some(w) => w.run(chunks, job),
        None => (0..chunks).for_each(job),
    }
}

/// Takes and runs chunks until the counter is exhausted.
fn take_chunks(s: &Shared, job: &(dyn Fn(usize) + Sync)) {
    let chunks = s.chunks.load(SeqCst);
    loop {
        let c = s.next.fetch_add(1, SeqCst);
        if c >= chunks {
            return;
        }
        job(c);
    }
}

/// A worker's life: wait for an open job, take its chunks, repeat until told to stop.
fn work(s: &Shared) {
    let mut seen = 0u64;
    loop {
        let mut spins = 0u32;
        let epoch = loop {
            if s.stop.load(SeqCst) {
                return;
            }
            let e = s.epoch.load(SeqCst);
            if e != seen && e % 2 == 1 {
                break e;
            }
            if spins < SPIN {
                spins += 1;
                std::hint::spin_loop();
            } else {
                thread::park();
            }
        };
        seen = epoch;
        s.busy.fetch_add(1, SeqCst);
        if s.epoch.load(SeqCst) == epoch {
            // SAFETY: the job is open and stays so until this worker leaves `busy`.
            let job = unsafe { &*(*s.job.get()).expect("an open job is set") };
            if catch_unwind(AssertUnwindSafe(|| take_chunks(s, job))).is_err() {
                s.panicked.store(true, SeqCst);
                // The chunks this worker would have taken are left to the caller.
            }
        }
        s.busy.fetch_sub(1, SeqCst);
    }
}

impl Drop for Workers {
    fn drop(&mut self) {
        self.shared.stop.store(true, SeqCst);
        for h in &self.handles {
            h.thread().unpark();
        }
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

impl fmt::Debug for Workers {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Workers")
            .field("threads", &self.threads())
            .finish()
    }
}

/// A pointer through which chunks write disjoint parts of one slice.
///
/// Each chunk of a [`Workers::run`] job must write only the indices it owns (the
/// caller's partition says which), and no chunk may read an index another writes.
#[derive(Clone, Copy)]
pub struct Disjoint<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: chunks write disjoint indices (the type's contract), so sharing the pointer
// between threads is sharing disjoint `&mut T`s.
unsafe impl<T: Send> Sync for Disjoint<T> {}
unsafe impl<T: Send> Send for Disjoint<T> {}

impl<T> Disjoint<T> {
    pub fn new(slice: &mut [T]) -> Self {
        Disjoint {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
        }
    }

    /// The element at `i`, mutably.
    ///
    /// # Safety
    /// No other chunk of the job reads or writes index `i`, and the slice outlives
    /// the job.
    #[inline]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn at(&self, i: usize) -> &mut T {
        assert!(i < self.len, "index {i} out of {}", self.len);
        unsafe { &mut *self.ptr.add(i) }
    }

    /// The elements `range`, mutably.
    ///
    /// # Safety
    /// As [`at`](Self::at), for every index of `range`.
    #[inline]
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn range(&self, range: std::ops::Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }
}

#[cfg(test)]
mod tests;
