//! The one place with `unsafe` code: the context MLP (spec §5.3) with x86-64 SIMD.
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
//!   when the CPU has AVX2.

#![allow(unsafe_code)]

#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub mod avx2;
#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub mod sse2;

#[cfg(all(feature = "simd", target_arch = "x86_64"))]
pub use sse2::dot;
