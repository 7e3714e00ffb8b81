//! Data parallelism over tiles and anchors: rayon's when the `parallel` feature is on (the
//! default), else the same calls run in order on the caller's thread, which is what a
//! WebAssembly build without threads needs. Results do not depend on which: every parallel
//! loop of the decoder writes its own outputs, and errors are reported by tile order (§10.3).
//!
//! Loops over tiles go through [`map_largest_first`]: each thread takes the largest tile not
//! yet taken. Left to split by length, rayon stops splitting once each thread has a part, so
//! a thread works through runs of several tiles (each some milliseconds) while the other,
//! done, waits: playbot's 50 tiles on 2 threads left one idle for 26 ms of a 268 ms decode
//! (median of 20 decodes). Taken in index order one per job, a large tile late in that order
//! still finished alone: alti's last tile ended 4 ms after the one before it, in a 23 ms loop.

use std::cell::RefCell;
use std::sync::Mutex;

#[cfg(feature = "parallel")]
pub use rayon::prelude::*;
#[cfg(feature = "parallel")]
pub use rayon::{current_num_threads, join};

#[cfg(not(feature = "parallel"))]
pub use sequential::*;

#[cfg(not(feature = "parallel"))]
mod sequential {
    /// `into_par_iter`: the plain iterator.
    pub trait IntoParallelIterator: IntoIterator + Sized {
        /// The iterator itself, taken in order.
        fn into_par_iter(self) -> Self::IntoIter {
            self.into_iter()
        }
    }
    impl<I: IntoIterator> IntoParallelIterator for I {}

    /// The slice methods rayon adds, as the plain ones.
    pub trait ParallelSlice<T> {
        /// `chunks`.
        fn par_chunks(&self, n: usize) -> std::slice::Chunks<'_, T>;
        /// `chunks_mut`.
        fn par_chunks_mut(&mut self, n: usize) -> std::slice::ChunksMut<'_, T>;
    }
    impl<T> ParallelSlice<T> for [T] {
        fn par_chunks(&self, n: usize) -> std::slice::Chunks<'_, T> {
            self.chunks(n)
        }
        fn par_chunks_mut(&mut self, n: usize) -> std::slice::ChunksMut<'_, T> {
            self.chunks_mut(n)
        }
    }

    /// The iterator methods rayon adds, as their sequential meaning.
    pub trait ParallelIterator: Iterator + Sized {
        /// `for_each` with one state made by `init`.
        fn for_each_init<S>(self, init: impl Fn() -> S, mut f: impl FnMut(&mut S, Self::Item)) {
            let mut state = init();
            self.for_each(|item| f(&mut state, item));
        }
        /// `reduce`.
        fn reduce_with(
            self,
            f: impl FnMut(Self::Item, Self::Item) -> Self::Item,
        ) -> Option<Self::Item> {
            self.reduce(f)
        }
    }
    impl<I: Iterator> ParallelIterator for I {}

    /// Both closures, one after the other.
    pub fn join<A, B>(a: impl FnOnce() -> A, b: impl FnOnce() -> B) -> (A, B) {
        let ra = a();
        (ra, b())
    }

    /// One thread: the caller's.
    pub fn current_num_threads() -> usize {
        1
    }
}

/// Scratch buffers a thread keeps from job to job and from decode to decode: what a tile's
/// decode needs besides its output (megabytes for a large tile). Made afresh for every tile
/// or every decode, the allocator handed their pages back to the kernel and the next decode
/// faulted them in again: 2-thread decodes of fruit_drops took 334 page faults each, 1-thread
/// ones 17 (`perf stat`). Values are kept only up to
/// [`MAX_RETAINED_SCRATCH`] bytes, so one huge tile does not pin its buffers for the thread's
/// life; the threads of a `salvq::Decoder`'s own pool free theirs when it is dropped.
pub trait Scratch: Default {
    /// The bytes this value holds on to.
    fn retained_bytes(&self) -> usize;
}

impl<A: Scratch, B: Scratch> Scratch for (A, B) {
    fn retained_bytes(&self) -> usize {
        self.0.retained_bytes() + self.1.retained_bytes()
    }
}

/// The most a thread keeps of one kind of scratch between jobs.
pub const MAX_RETAINED_SCRATCH: usize = 64 << 20;

/// `f` with this thread's value of `key`, kept for its next job unless it grew past
/// [`MAX_RETAINED_SCRATCH`]. A job that runs inside another on the same thread (rayon may
/// run a stolen job while one waits) gets a new value.
pub fn with_thread_scratch<T: Scratch, R>(
    key: &'static std::thread::LocalKey<RefCell<T>>,
    f: impl FnOnce(&mut T) -> R,
) -> R {
    key.with(|cell| match cell.try_borrow_mut() {
        Ok(mut value) => {
            let out = f(&mut value);
            if value.retained_bytes() > MAX_RETAINED_SCRATCH {
                *value = T::default();
            }
            out
        }
        Err(_) => f(&mut T::default()),
    })
}

/// Scratch buffers handed from job to job within one call, freed with it. `map_init` makes a
/// new value for every rayon job, and with one tile per job that is one per tile: a tile's
/// buffers (megabytes for a large tile) were allocated afresh each time, and the kernel's
/// zeroing of their pages (`clear_page_erms`) took 5 … 12 % of a decode. A job takes a value
/// from the pool (or a new one) and gives it back when done, so there are at most as many as
/// jobs run at once.
pub(crate) struct Pool<T>(Mutex<Vec<T>>);

impl<T: Default> Pool<T> {
    /// An empty pool.
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

/// `f(i, item)` for every item, in parallel, results in item order. The items are taken
/// largest `cost` first (ties by index), each by whichever thread is free: the greedy order
/// that leaves the smallest items to fill the end, where they even out the threads' finish.
/// Which thread runs an item changes no result, only when it runs.
pub fn map_largest_first<I: Send, R: Send>(
    items: Vec<I>,
    cost: impl Fn(usize) -> usize,
    f: impl Fn(usize, I) -> R + Sync,
) -> Vec<R> {
    // One thread (or the build without rayon): in index order on the caller's thread.
    #[cfg(feature = "parallel")]
    {
        let threads = current_num_threads().min(items.len());
        if threads > 1 {
            return largest_first_on(threads, items, cost, f);
        }
    }
    #[cfg(not(feature = "parallel"))]
    let _ = cost;
    items
        .into_iter()
        .enumerate()
        .map(|(i, x)| f(i, x))
        .collect()
}

#[cfg(feature = "parallel")]
fn largest_first_on<I: Send, R: Send>(
    threads: usize,
    items: Vec<I>,
    cost: impl Fn(usize) -> usize,
    f: impl Fn(usize, I) -> R + Sync,
) -> Vec<R> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let order = largest_first_order(items.len(), cost);
    let slots: Vec<Mutex<Option<I>>> = items.into_iter().map(|x| Mutex::new(Some(x))).collect();
    let next = AtomicUsize::new(0);
    // One job per thread, each taking the next item in `order` until none is left.
    let done: Vec<Vec<(usize, R)>> = (0..threads)
        .into_par_iter()
        .with_max_len(1)
        .map(|_| {
            let mut out = Vec::new();
            while let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
                let item = slots[i].lock().ok().and_then(|mut slot| slot.take());
                if let Some(item) = item {
                    out.push((i, f(i, item)));
                }
            }
            out
        })
        .collect();
    let mut results: Vec<(usize, R)> = done.into_iter().flatten().collect();
    results.sort_unstable_by_key(|&(i, _)| i);
    results.into_iter().map(|(_, r)| r).collect()
}

/// The indices `0..n`, largest `cost` first, ties by index.
#[cfg_attr(not(feature = "parallel"), allow(dead_code))]
fn largest_first_order(n: usize, cost: impl Fn(usize) -> usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(cost(i)), i));
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_first_keeps_item_order_and_runs_each_once() {
        let items: Vec<u32> = (0..37).collect();
        let sizes: Vec<usize> = (0..37).map(|i| (i * 7919) % 13).collect();
        let runs = std::sync::atomic::AtomicUsize::new(0);
        let out = map_largest_first(
            items,
            |i| sizes[i],
            |i, x| {
                runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                (i, x * 2)
            },
        );
        assert_eq!(runs.into_inner(), 37);
        let want: Vec<(usize, u32)> = (0..37).map(|i| (i, i as u32 * 2)).collect();
        assert_eq!(out, want);
    }

    #[derive(Default)]
    struct Buffer(Vec<u8>);

    impl Scratch for Buffer {
        fn retained_bytes(&self) -> usize {
            self.0.capacity()
        }
    }

    thread_local! {
        static BUFFER: RefCell<Buffer> = RefCell::default();
    }

    #[test]
    fn thread_scratch_is_kept_up_to_the_cap_and_fresh_inside_itself() {
        // Kept from one job to the next on this thread.
        with_thread_scratch(&BUFFER, |b| b.0.extend_from_slice(&[7; 100]));
        let kept = with_thread_scratch(&BUFFER, |b| b.0.clone());
        assert_eq!(kept, [7; 100]);
        // A job that runs inside another gets a value of its own.
        with_thread_scratch(&BUFFER, |outer| {
            with_thread_scratch(&BUFFER, |inner| assert!(inner.0.is_empty()));
            assert_eq!(outer.0.len(), 100);
        });
        // Past the cap, the next job starts afresh.
        with_thread_scratch(&BUFFER, |b| b.0.reserve(MAX_RETAINED_SCRATCH + 1));
        assert_eq!(with_thread_scratch(&BUFFER, |b| b.0.capacity()), 0);
    }

    #[test]
    fn largest_first_order_is_by_cost_then_index() {
        let cost = [3, 9, 3, 0, 9, 5];
        assert_eq!(largest_first_order(6, |i| cost[i]), [1, 4, 5, 0, 2, 3]);
    }
}
