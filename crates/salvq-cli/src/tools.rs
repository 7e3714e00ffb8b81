//! The conformance tools: `salvq conformance`, `salvq make-vectors`, and the hidden decoder
//! fault of `decode --inject-fault` (spec §11).

use std::path::Path;
use std::time::Instant;

use super::secs;

pub(crate) fn parse_fault(s: &str) -> Result<salvq::Fault, String> {
    let k = s
        .strip_prefix("table:")
        .and_then(|k| k.parse::<u8>().ok())
        .ok_or_else(|| format!("`{s}`: expected table:K"))?;
    Ok(salvq::Fault::FrequencyTable { scale: k })
}

pub(crate) fn conformance(
    decoder: Option<String>,
    region_decoder: Option<String>,
    vectors: &Path,
    filter: Option<&str>,
) -> Result<(), String> {
    // The reference decoder, unless another is named: then its region decodes run only
    // with a region decoder named too.
    let (template, region_template) = match decoder {
        Some(d) => (d, region_decoder),
        None => {
            let exe = std::env::current_exe().map_err(|e| e.to_string())?;
            let reference = format!(
                "{} decode {{in}} -o {{out}} --rate {{rate}} --canonical --strict",
                exe.display()
            );
            let region = region_decoder.unwrap_or(format!("{reference} --region {{region}}"));
            (reference, Some(region))
        }
    };
    let (_, report) =
        salvq_conformance::runner::run(vectors, &template, region_template.as_deref(), filter)?;
    for o in &report.outcomes {
        let verdict = if o.passed { "pass" } else { "FAIL" };
        out!("{verdict}  {:<32} {}", o.label, o.detail);
    }
    out!("{}", report.summary());
    if report.failed() > 0 {
        return Err(format!(
            "{} of {} conformance checks failed",
            report.failed(),
            report.outcomes.len()
        ));
    }
    Ok(())
}

pub(crate) fn make_vectors(
    out: &Path,
    readme: &Path,
    spec: &Path,
    check: bool,
) -> Result<(), String> {
    let t = Instant::now();
    let g = salvq_conformance::generate::build(spec)?;
    let bytes: usize = g.files.values().map(Vec::len).sum();
    if check {
        let diffs = salvq_conformance::generate::check(&g, out, readme);
        for d in &diffs {
            out!("stale: {d}");
        }
        if !diffs.is_empty() {
            return Err(format!(
                "{} conformance files differ from a fresh generation; run `salvq make-vectors` \
                 (and bump the format version if the format changed)",
                diffs.len()
            ));
        }
        out!(
            "{} vectors, {} files, {bytes} bytes: identical to a fresh generation ({:.1} s)",
            g.manifest.vectors.len(),
            g.files.len(),
            secs(t)
        );
        return Ok(());
    }
    salvq_conformance::generate::write(&g, out, readme)?;
    out!(
        "wrote {} vectors ({} files, {bytes} bytes) to {} in {:.1} s",
        g.manifest.vectors.len(),
        g.files.len(),
        out.display(),
        secs(t)
    );
    Ok(())
}
