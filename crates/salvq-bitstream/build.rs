//! Turns on the AVX-512 kernels (`cfg(salvq_avx512)`) where the compiler has their intrinsics
//! and target features, stable from Rust 1.89; the decoder itself builds with 1.80
//! (`rust-version`), where they are left out and the AVX2 kernels serve every x86-64 CPU.

use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=RUSTC");
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let minor = Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .and_then(|out| String::from_utf8(out.stdout).ok())
        .and_then(|v| minor_version(&v));
    if minor.is_some_and(|m| m >= 89) {
        println!("cargo:rustc-cfg=salvq_avx512");
    }
}

/// The minor version of `rustc --version`'s "rustc 1.M.P ..." (any channel).
fn minor_version(version: &str) -> Option<u32> {
    let number = version.split_whitespace().nth(1)?;
    let mut parts = number.split('.');
    (parts.next()? == "1").then_some(())?;
    parts.next()?.parse().ok()
}
