//! The hand-off between the two threads of a parallel solver phase: one spins on a counter the
//! other advances, and a panicking thread releases the one waiting on it.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Spins (then yields) until `flag` reaches `k` (a panicking thread's [`PanicGuard`] sets it to
/// `usize::MAX`).
pub(crate) fn wait_for(flag: &AtomicUsize, k: usize) {
    let mut spins = 0u32;
    while flag.load(Ordering::Acquire) < k {
        if spins < 1 << 14 {
            std::hint::spin_loop();
            spins += 1;
        } else {
            std::thread::yield_now();
        }
    }
}

/// Releases the other thread of a parallel task, waiting on `flag`, when this one panics (it
/// then passes the panic on instead of waiting for it forever).
pub(crate) struct PanicGuard<'a>(pub(crate) &'a AtomicUsize);

impl Drop for PanicGuard<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(usize::MAX, Ordering::Release);
        }
    }
}
