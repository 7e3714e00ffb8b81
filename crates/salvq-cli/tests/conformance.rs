//! The conformance suite against the reference decoder (spec §11), one test per vector so a
//! failure names it, through the same command-line contract a third-party decoder uses; and
//! the proof that the suite can fail: a decoder with one wrong frequency-table entry.

use std::path::PathBuf;

use libtest_mimic::{Arguments, Failed, Trial};
use salvq_conformance::manifest::VectorKind;
use salvq_conformance::{generate, runner};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn vectors() -> PathBuf {
    root().join("conformance/vectors")
}

/// The reference decoder under the §11.5 contract, with extra decode arguments.
fn decoder(extra: &str) -> String {
    format!(
        "{} decode {{in}} -o {{out}} --rate {{rate}} --canonical --strict {extra}",
        env!("CARGO_BIN_EXE_salvq")
    )
}

fn run_one(name: &str) -> Result<(), Failed> {
    let (_, report) = runner::run_selected(
        &vectors(),
        &decoder(""),
        Some(&decoder("--region {region}")),
        &|v| v.name == name,
    )?;
    if report.outcomes.is_empty() {
        return Err(format!("no vector named {name}").into());
    }
    let failures: Vec<String> = report
        .outcomes
        .iter()
        .filter(|o| !o.passed)
        .map(|o| format!("{}: {}", o.label, o.detail))
        .collect();
    if failures.is_empty() {
        Ok(())
    } else {
        Err(failures.join("\n").into())
    }
}

/// `salvq make-vectors --check`: regenerating gives the committed bytes and coverage table.
fn vectors_are_fresh() -> Result<(), Failed> {
    let g = generate::build(&root().join("spec"))?;
    let diffs = generate::check(&g, &vectors(), &root().join("conformance/README.md"));
    if diffs.is_empty() {
        Ok(())
    } else {
        Err(format!("stale (run `salvq make-vectors`):\n{}", diffs.join("\n")).into())
    }
}

/// A decoder with one wrong cumulative frequency in one table must fail valid vectors, and
/// the failures must be reported as integer-domain mismatches or decode errors.
fn broken_decoder_fails() -> Result<(), Failed> {
    // Scale 20 (σ ≈ 1.7 steps) is used by every vector with a learned basis.
    let (_, report) = runner::run_selected(
        &vectors(),
        &decoder("--inject-fault table:20"),
        None,
        &|v| v.kind == VectorKind::Valid,
    )?;
    let failed: Vec<&str> = report
        .outcomes
        .iter()
        .filter(|o| !o.passed)
        .map(|o| o.label.as_str())
        .collect();
    println!(
        "broken decoder (table:20): {} of {} valid decodes fail: {}",
        failed.len(),
        report.outcomes.len(),
        failed.join(", ")
    );
    println!("{}", report.summary());
    for must in ["salvq-four-rates@0", "tiles-many", "hac-dimensions"] {
        if !failed.contains(&must) {
            return Err(format!("the broken decoder passes {must}").into());
        }
    }
    Ok(())
}

/// Mutation score of the suite: for each of the 64 frequency tables, the decoder with one
/// wrong entry in that table (in-process, same fault as `--inject-fault table:K`) must fail at
/// least one valid vector: an error, or an integer-domain hash that differs (§11.2).
fn every_table_fault_is_caught() -> Result<(), Failed> {
    use rayon::prelude::*;
    use salvq::Fault;
    use salvq_conformance::canonical::{canonical_tensors, integer_hash};
    let dir = vectors();
    let manifest = runner::read_manifest(&dir)?;
    let mut decodes = Vec::new();
    for v in manifest
        .vectors
        .iter()
        .filter(|v| v.kind == VectorKind::Valid)
    {
        let stream = std::fs::read(dir.join(&v.file)).map_err(|e| e.to_string())?;
        for e in v.decodes.iter().filter(|e| e.region.is_none()) {
            decodes.push((
                v.name.clone(),
                stream.clone(),
                e.rate,
                e.integer_sha256.clone(),
            ));
        }
    }
    let missed: Vec<u8> = (0..64u8)
        .into_par_iter()
        .filter(|&k| {
            !decodes.iter().any(|(_, stream, rate, hash)| {
                let options = salvq::Decoder::builder()
                    .rate(Some(*rate))
                    .fault(Some(Fault::FrequencyTable { scale: k }));
                match options.build().decode_with_symbols(stream) {
                    Err(_) => true,
                    Ok((m, sy)) => &integer_hash(&canonical_tensors(&m, &sy)) != hash,
                }
            })
        })
        .collect();
    if missed.is_empty() {
        Ok(())
    } else {
        Err(format!("no vector catches a wrong entry in tables {missed:?}").into())
    }
}

fn main() {
    let args = Arguments::from_args();
    let manifest = runner::read_manifest(&vectors()).expect("conformance/vectors/manifest.json");
    let mut trials: Vec<Trial> = manifest
        .vectors
        .iter()
        .map(|v| {
            let name = v.name.clone();
            Trial::test(format!("vector::{name}"), move || run_one(&name))
        })
        .collect();
    trials.push(Trial::test("vectors_are_fresh", vectors_are_fresh));
    trials.push(Trial::test("broken_decoder_fails", broken_decoder_fails));
    trials.push(Trial::test(
        "every_table_fault_is_caught",
        every_table_fault_is_caught,
    ));
    libtest_mimic::run(&args, trials).exit();
}
