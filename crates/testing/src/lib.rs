//! Test support shared by the armature crates (not published).
//!
//! [`Counting`] is a global allocator that counts the allocations made on the current thread
//! while [`allocations_during`] watches a closure; a test binary installs it with
//!
//! ```
//! use armature_testing::{Counting, allocations_during};
//!
//! #[global_allocator]
//! static GLOBAL: Counting = Counting;
//!
//! let mut v: Vec<f64> = Vec::with_capacity(4);
//! assert_eq!(allocations_during(|| v.push(1.0)), 0);
//! assert_eq!(allocations_during(|| drop(vec![1.0; 8])), 1);
//! ```
//!
//! Only the watching thread counts: work sent to other threads (a rayon pool) is not seen.

#![warn(missing_docs)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static WATCHING: Cell<bool> = const { Cell::new(false) };
    /// This thread's count: tests watching on other threads at the same time (the test
    /// harness runs them in parallel) do not add to it.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// The system allocator, counting allocations and reallocations made on a watching thread.
#[derive(Debug)]
pub struct Counting;

// SAFETY: every call is forwarded unchanged to the system allocator; the counting touches
// only an atomic and a thread-local flag, neither of which allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

fn count() {
    // `try_with`: during thread teardown the locals may be gone; nothing is watched then.
    if WATCHING.try_with(|w| w.get()).unwrap_or(false) {
        let _ = ALLOCATIONS.try_with(|a| a.set(a.get() + 1));
    }
}

/// Runs `f` and returns how many allocations it made on this thread (with [`Counting`]
/// installed as the global allocator; 0 otherwise).
pub fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    WATCHING.with(|w| w.set(true));
    f();
    WATCHING.with(|w| w.set(false));
    ALLOCATIONS.with(Cell::get) - before
}
