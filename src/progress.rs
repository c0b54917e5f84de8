//! Progress of long work, reported by the library without printing: the work
//! adds the steps it will take to a shared [`WorkCounter`] and counts each one
//! done; the command line reads the counter to draw its bar (on a terminal).

use std::sync::atomic::{AtomicU64, Ordering};

/// Steps of some work: how many are known so far and how many are done.
/// Shared (`Arc`) between the work, possibly on several threads, and whoever
/// watches it.
#[derive(Debug, Default)]
pub struct WorkCounter {
    total: AtomicU64,
    done: AtomicU64,
}

impl WorkCounter {
    /// A counter with no steps.
    pub fn new() -> WorkCounter {
        WorkCounter::default()
    }

    /// `steps` more steps are to be done.
    pub fn add_total(&self, steps: u64) {
        self.total.fetch_add(steps, Ordering::Relaxed);
    }

    /// One step is done.
    pub fn step(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
    }

    /// Steps known so far.
    pub fn total(&self) -> u64 {
        self.total.load(Ordering::Relaxed)
    }

    /// Steps done so far (at most [`WorkCounter::total`] when the work adds
    /// its steps before doing them).
    pub fn done(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }
}

impl PartialEq for WorkCounter {
    /// The same counter (settings that carry one compare equal when they
    /// report to the same watcher).
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self, other)
    }
}

impl WorkCounter {
    /// `steps` steps are done at once.
    pub fn step_by(&self, steps: u64) {
        self.done.fetch_add(steps, Ordering::Relaxed);
    }

    /// The work is over: done becomes the total (an estimate the work did not
    /// need to the end).
    pub fn finish(&self) {
        let total = self.total();
        self.done.fetch_max(total, Ordering::Relaxed);
    }
}

/// Counts one step on `counter`, if there is one.
pub fn step(counter: Option<&std::sync::Arc<WorkCounter>>) {
    if let Some(c) = counter {
        c.step();
    }
}
