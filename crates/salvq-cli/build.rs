//! `salvq --version` names the commit it was built from (`SALVQ_COMMIT`): `git rev-parse` of
//! the checkout, or `unknown` outside one.

use std::path::Path;
use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=SALVQ_COMMIT={commit}");
    // Built again when HEAD moves: a checkout or a commit on the branch it names.
    let git = Path::new("../../.git");
    println!("cargo:rerun-if-changed=build.rs");
    if git.join("HEAD").exists() {
        println!("cargo:rerun-if-changed=../../.git/HEAD");
        if let Ok(head) = std::fs::read_to_string(git.join("HEAD")) {
            if let Some(reference) = head.trim().strip_prefix("ref: ") {
                println!("cargo:rerun-if-changed=../../.git/{reference}");
            }
        }
        if git.join("packed-refs").exists() {
            println!("cargo:rerun-if-changed=../../.git/packed-refs");
        }
    }
}
