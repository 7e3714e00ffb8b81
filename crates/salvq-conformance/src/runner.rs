//! The conformance runner (spec §11.5): runs a decoder under test on every vector through the
//! command-line contract and compares what it writes with the manifest.
//!
//! Contract: the command is split on whitespace; the arguments `{in}`, `{out}` and `{rate}`
//! are replaced by the stream's path, the output path and the rate (decimal); a command with
//! none of them gets the three appended. On success the decoder exits with status 0 and has
//! written the canonical form (§11.1) to `{out}`; on a stream it rejects, it exits with a
//! status from 1 to 125 and names the error class (Table 9-1) in its standard error.
//!
//! Region decodes (§11.7) run through a second command, the region decoder, in which
//! `{region}` is also replaced (by `x0,y0,z0,x1,y1,z1`); without one they are skipped.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::canonical::{from_safetensors, integer_hash, CanonicalTensor, FLOAT_TENSORS};
use super::manifest::{ExpectedDecode, Manifest, VectorEntry, VectorKind, MANIFEST_FILE};

/// How long one decode may take before it counts as a failure.
pub const DECODE_TIMEOUT: Duration = Duration::from_secs(120);

/// The outcome of one decode of one vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// `name` or `name@rate` for valid vectors with several rates.
    pub label: String,
    pub passed: bool,
    /// Why it failed, or how it passed (`bit-exact`, `within tolerance …`, the error class).
    pub detail: String,
    /// Whether the vector is a must-fail one (and this its rejection, not a region decode).
    pub must_fail: bool,
    /// Whether this is a region decode (§11.7).
    pub region: bool,
}

/// Every outcome, in manifest order.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    pub outcomes: Vec<Outcome>,
    /// Region decodes not run: no region decoder was given.
    pub regions_skipped: usize,
}

impl Report {
    pub fn failed(&self) -> usize {
        self.outcomes.iter().filter(|o| !o.passed).count()
    }

    /// `conformance: P passed, F failed (V decodes of valid vectors and R region decodes, B of
    /// them bit-exact; X must-fail vectors)`, and how many region decodes were skipped.
    pub fn summary(&self) -> String {
        let must_fail = self.outcomes.iter().filter(|o| o.must_fail).count();
        let regions = self.outcomes.iter().filter(|o| o.region).count();
        let bit_exact = self
            .outcomes
            .iter()
            .filter(|o| o.passed && o.detail.starts_with("bit-exact"))
            .count();
        let skipped = if self.regions_skipped > 0 {
            format!(
                "; {} region decodes skipped: no --region-decoder (§11.7)",
                self.regions_skipped
            )
        } else {
            String::new()
        };
        format!(
            "conformance: {} passed, {} failed ({} decodes of valid vectors and {regions} region \
             decodes, {bit_exact} of them bit-exact; {must_fail} must-fail vectors){skipped}",
            self.outcomes.len() - self.failed(),
            self.failed(),
            self.outcomes.len() - must_fail - regions,
        )
    }
}

/// Reads `manifest.json` from a vectors folder.
pub fn read_manifest(dir: &Path) -> Result<Manifest, String> {
    let p = dir.join(MANIFEST_FILE);
    let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))
}

/// The argument vector for one decode (the contract above).
pub fn command_line(template: &str, input: &Path, output: &Path, rate: u8) -> Vec<String> {
    region_command_line(template, input, output, rate, None)
}

/// `{region}`'s text: the box's six numbers, comma-separated, each the shortest decimal that
/// reads back as the same binary64 (§11.7).
pub fn region_text(b: &[f64; 6]) -> String {
    // Debug, not Display: the same shortest digits, with an exponent where it is shorter.
    b.iter()
        .map(|x| format!("{x:?}"))
        .collect::<Vec<_>>()
        .join(",")
}

/// [`command_line`] for a region decode: `{region}` replaced too (appended after the three
/// others when no argument names any mark).
pub fn region_command_line(
    template: &str,
    input: &Path,
    output: &Path,
    rate: u8,
    region: Option<&[f64; 6]>,
) -> Vec<String> {
    let mut argv: Vec<String> = template.split_whitespace().map(String::from).collect();
    let mut marks = vec!["{in}", "{out}", "{rate}"];
    if region.is_some() {
        marks.push("{region}");
    }
    if !argv.iter().any(|a| marks.iter().any(|m| a.contains(m))) {
        argv.extend(marks.iter().map(|m| m.to_string()));
    }
    let region = region.map(region_text).unwrap_or_default();
    argv.iter()
        .map(|a| {
            a.replace("{in}", &input.to_string_lossy())
                .replace("{out}", &output.to_string_lossy())
                .replace("{rate}", &rate.to_string())
                .replace("{region}", &region)
        })
        .collect()
}

struct Run {
    status: Option<i32>,
    stderr: String,
    timed_out: bool,
}

fn run_decoder(argv: &[String]) -> Result<Run, String> {
    let (program, args) = argv.split_first().ok_or("empty decoder command")?;
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start `{program}`: {e}"))?;
    // Read stderr on its own thread so a chatty decoder cannot block on a full pipe.
    let mut pipe = child.stderr.take();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        if let Some(p) = pipe.as_mut() {
            let _ = p.read_to_string(&mut s);
        }
        s
    });
    let start = Instant::now();
    let (status, timed_out) = loop {
        match child.try_wait() {
            Ok(Some(st)) => break (st.code(), false),
            Ok(None) if start.elapsed() > DECODE_TIMEOUT => {
                let _ = child.kill();
                let _ = child.wait();
                break (None, true);
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(2)),
            Err(e) => return Err(format!("waiting for the decoder: {e}")),
        }
    };
    let stderr = reader.join().unwrap_or_default();
    Ok(Run {
        status,
        stderr,
        timed_out,
    })
}

fn first_line(s: &str) -> &str {
    s.lines()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("")
        .trim()
}

/// Whether `text` holds `word` not glued to other identifier characters.
fn contains_word(text: &str, word: &str) -> bool {
    text.match_indices(word).any(|(at, _)| {
        let before = text[..at].chars().next_back();
        let after = text[at + word.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
        !ident(before) && !ident(after)
    })
}

/// Compares a decoder's canonical form with the expected one (§11.2, §11.3).
fn compare(
    got: &[CanonicalTensor],
    expected: &[CanonicalTensor],
    e: &ExpectedDecode,
) -> Result<String, String> {
    for name in expected.iter().map(|t| &t.name).chain(&e.omitted) {
        if !got.iter().any(|g| &g.name == name) {
            return Err(format!("tensor `{name}` missing"));
        }
    }
    for g in got {
        if !expected.iter().any(|t| t.name == g.name) && !e.omitted.contains(&g.name) {
            return Err(format!("tensor `{}` is not expected", g.name));
        }
    }
    let mut max_diff = 0f64;
    for t in expected {
        let Some(g) = got.iter().find(|g| g.name == t.name) else {
            continue;
        };
        if g.dtype != t.dtype || g.shape != t.shape {
            return Err(format!(
                "tensor `{}`: {} {:?}, expected {} {:?}",
                t.name,
                g.dtype.name(),
                g.shape,
                t.dtype.name(),
                t.shape
            ));
        }
        if FLOAT_TENSORS.contains(&t.name.as_str()) {
            let tol = e.tolerance;
            for (i, (a, b)) in g.f32_values().iter().zip(t.f32_values()).enumerate() {
                if a.is_finite() && b.is_finite() {
                    max_diff = max_diff.max((f64::from(*a) - f64::from(b)).abs());
                }
                if !tol.matches(*a, b) {
                    return Err(format!(
                        "`{}`{:?}: {}, expected {} (tolerance {:e}·|x| + {:e}, §11.3)",
                        t.name,
                        t.index_of(i),
                        g.element_text(i),
                        t.element_text(i),
                        tol.relative,
                        tol.absolute
                    ));
                }
            }
        } else if g.data != t.data {
            let size = t.dtype.size();
            let i = g
                .data
                .chunks(size)
                .zip(t.data.chunks(size))
                .position(|(a, b)| a != b)
                .unwrap_or(0);
            return Err(format!(
                "`{}`{:?}: {}, expected {} (integer domain, §11.2)",
                t.name,
                t.index_of(i),
                g.element_text(i),
                t.element_text(i)
            ));
        }
    }
    let ih = integer_hash(got);
    if ih != e.integer_sha256 {
        return Err(format!(
            "integer-domain SHA-256 {ih}, manifest says {} (is the expected file stale?)",
            e.integer_sha256
        ));
    }
    if super::canonical::float_hash(got) == e.float_sha256 {
        Ok("bit-exact".into())
    } else {
        Ok(format!(
            "within tolerance (largest difference {max_diff:e})"
        ))
    }
}

fn check_valid(
    dir: &Path,
    v: &VectorEntry,
    e: &ExpectedDecode,
    template: &str,
    work: &Path,
) -> Result<String, String> {
    let expected_bytes =
        std::fs::read(dir.join(&e.expected)).map_err(|err| format!("{}: {err}", e.expected))?;
    let expected = from_safetensors(&expected_bytes)?;
    let out = work.join(&e.expected);
    let region = e.region.as_ref().map(|r| &r.region);
    let argv = region_command_line(template, &dir.join(&v.file), &out, e.rate, region);
    let run = run_decoder(&argv)?;
    if run.timed_out {
        return Err(format!("no result within {} s", DECODE_TIMEOUT.as_secs()));
    }
    if run.status != Some(0) {
        return Err(format!(
            "decoder failed (status {:?}): {}",
            run.status,
            first_line(&run.stderr)
        ));
    }
    let got_bytes = std::fs::read(&out).map_err(|err| format!("no output: {err}"))?;
    let _ = std::fs::remove_file(&out);
    let got = from_safetensors(&got_bytes)?;
    compare(&got, &expected, e)
}

fn check_must_fail(
    dir: &Path,
    v: &VectorEntry,
    template: &str,
    work: &Path,
) -> Result<String, String> {
    let class = v.error_class.as_deref().unwrap_or("");
    let out = work.join(format!("{}.safetensors", v.name));
    let argv = command_line(template, &dir.join(&v.file), &out, v.rate.unwrap_or(0));
    let run = run_decoder(&argv)?;
    if run.timed_out {
        return Err(format!("no result within {} s", DECODE_TIMEOUT.as_secs()));
    }
    match run.status {
        Some(0) => Err(format!("decoded a stream that must fail with {class}")),
        Some(1..=125) if contains_word(&run.stderr, class) => Ok(class.to_string()),
        Some(1..=125) => Err(format!(
            "rejected, but not with {class}: {}",
            first_line(&run.stderr)
        )),
        other => Err(format!(
            "crashed (status {other:?}) instead of reporting {class}: {}",
            first_line(&run.stderr)
        )),
    }
}

/// Runs `template` on every vector of `dir` whose name contains `filter` (all when `None`),
/// and `region_template` on their region decodes (skipped when `None`).
pub fn run(
    dir: &Path,
    template: &str,
    region_template: Option<&str>,
    filter: Option<&str>,
) -> Result<(Manifest, Report), String> {
    run_selected(dir, template, region_template, &|v| {
        filter.is_none_or(|f| v.name.contains(f))
    })
}

/// One decode the runner makes.
enum Job<'a> {
    /// A whole or region decode that must succeed.
    Decode(&'a ExpectedDecode),
    /// A must-fail vector's rejection.
    Reject,
}

/// Runs `template` on the vectors of `dir` that `select` picks, and `region_template` on
/// their region decodes (skipped when `None`).
pub fn run_selected(
    dir: &Path,
    template: &str,
    region_template: Option<&str>,
    select: &(dyn Fn(&VectorEntry) -> bool + Sync),
) -> Result<(Manifest, Report), String> {
    let manifest = read_manifest(dir)?;
    let work = tempfile::tempdir().map_err(|e| format!("temporary folder: {e}"))?;
    let work: PathBuf = work.path().to_path_buf();
    let mut jobs: Vec<(&VectorEntry, Job)> = Vec::new();
    let mut regions_skipped = 0;
    for v in manifest.vectors.iter().filter(|v| select(v)) {
        if v.kind == VectorKind::MustFail {
            jobs.push((v, Job::Reject));
        }
        for e in &v.decodes {
            if e.region.is_some() && region_template.is_none() {
                regions_skipped += 1;
            } else {
                jobs.push((v, Job::Decode(e)));
            }
        }
    }
    let outcomes = jobs
        .par_iter()
        .map(|(v, job)| {
            let (label, result, region) = match job {
                Job::Decode(e) => {
                    let whole = v.decodes.iter().filter(|d| d.region.is_none()).count();
                    let mut label = if whole > 1 || e.region.is_some() {
                        format!("{}@{}", v.name, e.rate)
                    } else {
                        v.name.clone()
                    };
                    let t = match &e.region {
                        Some(_) => {
                            let k = v
                                .decodes
                                .iter()
                                .filter(|d| d.region.is_some())
                                .position(|d| std::ptr::eq(d, *e))
                                .unwrap_or(0);
                            label.push_str(&format!(" region {k}"));
                            region_template.unwrap_or(template)
                        }
                        None => template,
                    };
                    (label, check_valid(dir, v, e, t, &work), e.region.is_some())
                }
                Job::Reject => (
                    v.name.clone(),
                    check_must_fail(dir, v, template, &work),
                    false,
                ),
            };
            let must_fail = matches!(job, Job::Reject);
            let (passed, detail) = match result {
                Ok(detail) => (true, detail),
                Err(detail) => (false, detail),
            };
            Outcome {
                label,
                passed,
                detail,
                must_fail,
                region,
            }
        })
        .collect();
    Ok((
        manifest,
        Report {
            outcomes,
            regions_skipped,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_line_substitutes_or_appends() {
        let (i, o) = (Path::new("/v/a.salvq"), Path::new("/t/a.st"));
        assert_eq!(
            command_line("dec --x {in} -o {out} --rate {rate}", i, o, 3),
            ["dec", "--x", "/v/a.salvq", "-o", "/t/a.st", "--rate", "3"]
        );
        assert_eq!(
            command_line("python3 -m dec", i, o, 0),
            ["python3", "-m", "dec", "/v/a.salvq", "/t/a.st", "0"]
        );
        let b = [-0.5, 0.1, 1e-300, 2.0, 1.0, 3.0];
        assert_eq!(
            region_command_line("dec {in} {out} --region={region}", i, o, 0, Some(&b)),
            [
                "dec",
                "/v/a.salvq",
                "/t/a.st",
                "--region=-0.5,0.1,1e-300,2.0,1.0,3.0"
            ]
        );
        assert_eq!(
            region_command_line("dec", i, o, 2, Some(&b))[4],
            "-0.5,0.1,1e-300,2.0,1.0,3.0"
        );
        // Each number reads back as the same binary64.
        let back: Vec<f64> = region_text(&b)
            .split(',')
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(back, b);
    }

    #[test]
    fn class_names_match_as_words() {
        assert!(contains_word(
            "salvq: error[Truncated]: stream ends",
            "Truncated"
        ));
        assert!(!contains_word("NotTruncated", "Truncated"));
        assert!(!contains_word("Truncated_x", "Truncated"));
    }
}
