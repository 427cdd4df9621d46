//! The threads a bake may use: a fixed number, or a share of the machine's cores among the jobs
//! of a scene running at once, which grows as the others finish.
//!
//! A bake reads its share between frames. What it computes does not depend on it: every
//! parallel path of the solvers does the arithmetic of one thread, in the same order
//! (`NewtonSolver::with_threads`), so a share only changes how soon a bake ends.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Threads a bake may use.
#[derive(Debug, Clone, PartialEq)]
pub enum Threads {
    /// This many, throughout (at least one).
    Fixed(usize),
    /// The bake's share of the cores, now ([`CoreShare::threads`]).
    Shared(Arc<CoreShare>),
}

/// The machine's cores (1 when the system does not say).
pub fn available() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

impl Threads {
    /// The threads the bake may use from now on.
    pub fn now(&self) -> usize {
        match self {
            Threads::Fixed(n) => (*n).max(1),
            Threads::Shared(share) => share.threads(),
        }
    }

    /// The most threads the bake could be given: the fixed number, or every core of the share.
    pub fn most(&self) -> usize {
        match self {
            Threads::Fixed(n) => (*n).max(1),
            Threads::Shared(share) => share.cores,
        }
    }
}

impl From<usize> for Threads {
    fn from(n: usize) -> Self {
        Threads::Fixed(n)
    }
}

/// A machine's cores shared among the workers of a scene run, each taking one job after
/// another: a worker's job may use `cores / workers` threads (at least one), where `workers`
/// counts the workers still taking jobs. A worker that finds no job left [leaves](Self::leave),
/// and the jobs still running get its cores from their next frame on (a scene's longest job,
/// started first, ends on every core).
#[derive(Debug)]
pub struct CoreShare {
    cores: usize,
    workers: AtomicUsize,
}

impl CoreShare {
    /// `cores` shared among `workers` workers (each at least one).
    pub fn new(cores: usize, workers: usize) -> Arc<CoreShare> {
        Arc::new(CoreShare {
            cores: cores.max(1),
            workers: AtomicUsize::new(workers.max(1)),
        })
    }

    /// A worker has no job left: the others share its cores.
    pub fn leave(&self) {
        // Never below one: the last worker keeps every core.
        let _ = self
            .workers
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |w| {
                (w > 1).then(|| w - 1)
            });
    }

    /// Threads each running worker's job may use now.
    pub fn threads(&self) -> usize {
        (self.cores / self.workers.load(Ordering::SeqCst).max(1)).max(1)
    }
}

/// Two shares are equal when they are the same share.
impl PartialEq for CoreShare {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self, other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_share_grows_as_workers_leave_and_never_exceeds_the_cores() {
        let share = CoreShare::new(4, 3);
        let threads = Threads::Shared(Arc::clone(&share));
        assert_eq!((threads.now(), threads.most()), (1, 4));
        share.leave();
        assert_eq!(threads.now(), 2);
        share.leave();
        assert_eq!(threads.now(), 4);
        // The last worker keeps every core.
        share.leave();
        assert_eq!(threads.now(), 4);
        // More workers than cores: one thread each.
        assert_eq!(CoreShare::new(2, 5).threads(), 1);
        assert_eq!(Threads::from(0).now(), 1);
    }
}
