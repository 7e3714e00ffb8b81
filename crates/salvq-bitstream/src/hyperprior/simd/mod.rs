//! The one place with `unsafe` code: the context MLP (spec §5.3) with x86-64 SIMD (and the
//! same kernel with WebAssembly SIMD, which needs none), the hash-grid corners (§5.1, §5.2)
//! with AVX2, and the lattices' dense product (§7.3) built for AVX2.
//!
//! Why: the context MLP is 365 multiply-adds per coded symbol and dominates decoding time
//! (`cargo bench --bench decode_throughput`); the compiler does not turn the safe loops into
//! `pmaddwd` on the baseline x86-64 target, and cannot use AVX2 without runtime detection.
//!
//! Same result on every path: §5.3 defines the sums modulo 2^32, so any order of the wrapping
//! additions gives the same bits; `pmaddwd` adds two i16 x i16 products into an i32, and the
//! only pair that exceeds i32, (-32768)^2 + (-32768)^2 = 2^31, comes out as 0x8000_0000,
//! which is 2^31 modulo 2^32. The tests of each path compare it with the portable definition,
//! extreme values included.
//!
//! - [`sse2::dot`]: one dot product, 8 lanes (every x86-64 CPU);
//! - [`avx2::Avx2Mlp`]: the whole MLP, 16 lanes, 8 rows at a time, selected once per stream
//!   when the CPU has AVX2; [`avx2_batch`] evaluates it for several anchors at once, and
//!   `avx512_batch` does with AVX-512 (F, BW, VNNI) where the CPU has it and the compiler
//!   its intrinsics (Rust 1.89 on; `build.rs` sets `cfg(salvq_avx512)`);
//! - `wasm::WasmMlp`: the same plan with WebAssembly SIMD (`simd128`), 8 lanes, 4 rows at a
//!   time, in builds for `wasm32` with that feature (the wasm package's, `.cargo/config.toml`);
//! - [`grid_avx2::Avx2Grid`]: §5.1's interpolation for grids of 4 channels, a level's
//!   corners in the lanes of one vector and their entries in one gather;
//! - `scale_avx512`: §5.4 step 3's scale indices of 8 values at once with AVX-512, where
//!   the CPU and the compiler have it (as `avx512_batch`);
//! - [`columns::dense_product`]: §7.3's `B u` for a dense B, built for AVX2 where the CPU
//!   has it (the same loop as the portable build);
//! - [`prefetch`]: a hint to load a hash-grid entry ahead of its use (§5.1's corners are
//!   scattered over megabytes of tables, and waiting for them was most of the
//!   interpolation's time). A hint changes no result.
//!
//! Every unsafe function here says in `# Safety` what its caller must guarantee (the CPU
//! features its `#[target_feature]` enables, and the bounds of what it reads and writes
//! through pointers or unchecked indexing), and every call says how it meets that. Inside an
//! unsafe function, the unsafe operations are in `unsafe` blocks that say why each is sound
//! (`unsafe_op_in_unsafe_fn`, denied in the workspace). The crate builds with Rust 1.80,
//! where every `std::arch` intrinsic is an unsafe function; from 1.87 on, those that need
//! only a target feature are safe inside a function that enables it. So the AVX2 kernels'
//! blocks hold their register operations too, next to the loads and stores, and the few
//! functions made of register operations alone allow `unused_unsafe` (a block newer
//! compilers do not need). The AVX-512 kernels build only with 1.89 or later, and their
//! blocks hold the unsafe operations alone.

#![allow(unsafe_code)]

pub mod columns;
pub use columns::dense_product;

#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub mod avx2;
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub mod avx2_batch;
// Built only where `build.rs` found Rust 1.89 or later, which its intrinsics need.
#[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
#[clippy::msrv = "1.89"]
pub mod avx512_batch;
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub mod grid_avx2;
#[cfg(all(feature = "simd", target_arch = "x86_64", salvq_avx512))]
#[clippy::msrv = "1.89"]
pub mod scale_avx512;
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub mod sse2;

#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub use sse2::dot;

// Natively in tests too, on emulated vectors (see its `emulated`).
#[cfg(any(
    test,
    all(feature = "simd", target_arch = "wasm32", target_feature = "simd128")
))]
pub mod wasm;

#[cfg(test)]
mod kernel_tests;

/// The whole-MLP kernel of this target (`avx2::Avx2Mlp` on x86-64, `wasm::WasmMlp` on
/// WebAssembly with SIMD), or one that is never made ([`NoKernel`]).
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub use avx2::Avx2Mlp as FastMlp;
#[cfg(all(feature = "simd", target_arch = "wasm32", target_feature = "simd128"))]
pub use wasm::WasmMlp as FastMlp;
#[cfg(not(any(
    all(feature = "simd", target_arch = "x86_64"),
    all(feature = "simd", target_arch = "wasm32", target_feature = "simd128")
)))]
pub use NoKernel as FastMlp;

/// No kernel (a target without one, or the `simd` feature off): [`NoKernel::new`] never
/// makes one, so the prior always takes the portable path.
#[derive(Debug, Clone)]
pub enum NoKernel {}

#[allow(dead_code)]
impl NoKernel {
    /// None.
    pub fn new(_: &super::mlp::IntMlp) -> Option<NoKernel> {
        None
    }
    pub fn input_len(&self) -> usize {
        match *self {}
    }
    pub fn hidden_len(&self) -> usize {
        match *self {}
    }
    pub fn eval(&self, _: &[i16], _: &mut [i16], _: &mut [i32]) {
        match *self {}
    }
    pub fn batch_hidden_len(&self, _: usize) -> usize {
        match *self {}
    }
    pub fn eval_batch<const A: usize>(&self, _: &[i16], _: &mut [i16], _: &mut [i32]) {
        match *self {}
    }
}

/// The hash-grid interpolation kernel of this target (`grid_avx2::Avx2Grid` on x86-64), or
/// one that is never made ([`NoGrid`]).
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub use grid_avx2::Avx2Grid as FastGrid;
#[cfg(not(all(feature = "simd", target_arch = "x86_64")))]
pub use NoGrid as FastGrid;

/// No grid kernel: [`NoGrid::new`] never makes one, so the scalar loop always runs.
#[derive(Debug, Clone)]
pub enum NoGrid {}

#[allow(dead_code)]
impl NoGrid {
    /// None.
    pub fn new(_: &super::grid::GridLayout) -> Option<NoGrid> {
        None
    }
    pub fn interpolate(
        &self,
        _: &super::grid::GridLayout,
        _: &crate::model::HashGrid,
        _: [u32; 3],
        _: &mut [i16],
    ) {
        match *self {}
    }
    pub fn mark_touched(
        &self,
        _: &super::grid::GridLayout,
        _: &[[u32; 3]],
        _: &mut [Vec<bool>; 4],
    ) {
        match *self {}
    }
    pub fn prefetch(&self, _: &super::grid::GridLayout, _: &crate::model::HashGrid, _: [u32; 3]) {
        match *self {}
    }
    pub fn interpolate_signs(
        &self,
        _: &super::grid::GridLayout,
        _: &crate::model::HashGrid,
        _: &super::grid::GridSigns,
        _: [u32; 3],
        _: &mut [i16],
    ) {
        match *self {}
    }
}

/// Asks the CPU to bring the cache line of `data[index]` into its caches, where the index is
/// in bounds; nothing otherwise, and nothing on other targets.
#[cfg(feature = "simd")]
#[inline(always)]
pub fn prefetch(data: &[i8], index: usize) {
    #[cfg(all(feature = "simd", target_arch = "x86_64"))]
    if let Some(p) = data.get(index) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: `p` points into `data`; a prefetch reads nothing the program sees, cannot
        // fault, and needs only SSE, which every x86-64 CPU has.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(p)) }
    }
    #[cfg(not(all(feature = "simd", target_arch = "x86_64")))]
    let _ = (data, index);
}

/// For tests of a kernel: `detected`, whether this CPU has the kernel's instructions
/// (`what`). Where it has not, the test cannot compare the kernel with anything, so it says
/// that it skipped on stderr (written directly, so that `cargo test` shows it even though the
/// test passes; libtest's capture only takes `print!` / `eprint!`), and it fails instead when
/// the environment variable `require` is set (`.ci/run` sets `SALVQ_REQUIRE_AVX2` and
/// `SALVQ_REQUIRE_AVX512` on CPUs with those, so that a detection bug cannot turn the tests
/// into silent passes).
#[cfg(all(test, feature = "simd", target_arch = "x86_64"))]
pub(crate) fn detected_or_skip(test: &str, detected: bool, what: &str, require: &str) -> bool {
    use std::io::Write;
    if detected {
        return true;
    }
    assert!(
        std::env::var_os(require).is_none(),
        "{test}: no {what} detected on this CPU, and {require} is set"
    );
    let _ = writeln!(
        std::io::stderr(),
        "{test}: skipped: no {what} on this CPU, its kernel is not tested"
    );
    false
}

/// [`detected_or_skip`] for the AVX2 kernels.
#[cfg(all(test, feature = "simd", target_arch = "x86_64"))]
pub(crate) fn avx2_or_skip(test: &str) -> bool {
    let detected = std::arch::is_x86_feature_detected!("avx2");
    detected_or_skip(test, detected, "AVX2", "SALVQ_REQUIRE_AVX2")
}

/// [`detected_or_skip`] for the AVX-512 batch (F, BW and VNNI).
#[cfg(all(test, feature = "simd", target_arch = "x86_64", salvq_avx512))]
pub(crate) fn avx512_or_skip(test: &str) -> bool {
    let detected = std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512vnni");
    detected_or_skip(test, detected, "AVX-512 VNNI", "SALVQ_REQUIRE_AVX512")
}
