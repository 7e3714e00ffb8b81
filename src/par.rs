//! Data parallelism over tiles and anchors: rayon's when the `parallel` feature is on (the
//! default), else the same calls run in order on the caller's thread, which is what a
//! WebAssembly build without threads needs. Results do not depend on which: every parallel
//! loop of the decoder writes its own outputs, and errors are reported by tile order (§10.3).
//!
//! Loops over tiles run one tile per job (`with_max_len(1)`). Left to split by length, rayon
//! stops splitting once each thread has a part, so a thread works through runs of several
//! tiles (each some milliseconds) while the other, done, waits: playbot's 50 tiles on 2
//! threads left one idle for 26 ms of a 268 ms decode (median of 20 decodes).

use std::sync::Mutex;

#[cfg(feature = "parallel")]
pub(crate) use rayon::prelude::*;
#[cfg(feature = "parallel")]
pub(crate) use rayon::{current_num_threads, join};

#[cfg(not(feature = "parallel"))]
pub(crate) use sequential::*;

#[cfg(not(feature = "parallel"))]
mod sequential {
    /// `into_par_iter`: the plain iterator.
    pub(crate) trait IntoParallelIterator: IntoIterator + Sized {
        fn into_par_iter(self) -> Self::IntoIter {
            self.into_iter()
        }
    }
    impl<I: IntoIterator> IntoParallelIterator for I {}

    /// The slice methods rayon adds, as the plain ones.
    pub(crate) trait ParallelSlice<T> {
        fn par_iter(&self) -> std::slice::Iter<'_, T>;
        fn par_chunks(&self, n: usize) -> std::slice::Chunks<'_, T>;
        fn par_chunks_mut(&mut self, n: usize) -> std::slice::ChunksMut<'_, T>;
    }
    impl<T> ParallelSlice<T> for [T] {
        fn par_iter(&self) -> std::slice::Iter<'_, T> {
            self.iter()
        }
        fn par_chunks(&self, n: usize) -> std::slice::Chunks<'_, T> {
            self.chunks(n)
        }
        fn par_chunks_mut(&mut self, n: usize) -> std::slice::ChunksMut<'_, T> {
            self.chunks_mut(n)
        }
    }

    /// The iterator methods rayon adds, as their sequential meaning.
    pub(crate) trait ParallelIterator: Iterator + Sized {
        /// How rayon splits the work: nothing to split here.
        fn with_max_len(self, _: usize) -> Self {
            self
        }
        fn for_each_init<S>(self, init: impl Fn() -> S, mut f: impl FnMut(&mut S, Self::Item)) {
            let mut state = init();
            self.for_each(|item| f(&mut state, item));
        }
        fn reduce_with(
            self,
            f: impl FnMut(Self::Item, Self::Item) -> Self::Item,
        ) -> Option<Self::Item> {
            self.reduce(f)
        }
    }
    impl<I: Iterator> ParallelIterator for I {}

    /// Both closures, one after the other.
    pub(crate) fn join<A, B>(a: impl FnOnce() -> A, b: impl FnOnce() -> B) -> (A, B) {
        let ra = a();
        (ra, b())
    }

    /// One thread: the caller's.
    pub(crate) fn current_num_threads() -> usize {
        1
    }
}

/// Scratch buffers handed from job to job. `map_init` makes a new value for every rayon job,
/// and with one tile per job that is one per tile: a tile's buffers (megabytes for a large
/// tile) were allocated afresh each time, and the kernel's zeroing of their pages
/// (`clear_page_erms`) took 5 … 12 % of a decode. A job takes a value from the pool (or a
/// new one) and gives it back when done, so there are at most as many as jobs run at once.
pub(crate) struct Pool<T>(Mutex<Vec<T>>);

impl<T: Default> Pool<T> {
    pub(crate) fn new() -> Self {
        Pool(Mutex::new(Vec::new()))
    }

    /// `f` with a value from the pool, given back afterwards. A poisoned lock (a job that
    /// panicked) only means a new value.
    pub(crate) fn with<R>(&self, f: impl FnOnce(&mut T) -> R) -> R {
        let taken = self.0.lock().ok().and_then(|mut free| free.pop());
        let mut value = taken.unwrap_or_default();
        let out = f(&mut value);
        if let Ok(mut free) = self.0.lock() {
            free.push(value);
        }
        out
    }
}
