//! The vector generator (`salvq make-vectors`): builds every vector, decodes each valid one
//! with the reference decoder (checked against the encoder's own prediction), and writes the
//! streams, the expected canonical forms, `manifest.json` and the coverage table. `--check`
//! regenerates in memory and compares byte for byte, so a stale vector or an unintended
//! format change fails CI.

use std::collections::BTreeMap;
use std::path::Path;

use sha2::{Digest, Sha256};

use super::canonical::{
    self, canonical_tensors, float_hash, integer_hash, FLOAT_TENSORS, SYMBOL_TENSORS,
};
use super::manifest::{
    ExpectedDecode, Manifest, RegionDecode, Tolerance, VectorEntry, VectorKind, MANIFEST_FILE,
};
use super::must_fail::must_fail_vectors;
use super::region_vectors::{anchors_tiles, region_cases, selected_tiles};
use super::vectors::{valid_vectors, BASE_SECTIONS};
use salvq_bitstream::container::signature::{FORMAT_MAJOR, FORMAT_MINOR};

use super::canonical::{explicit_canonical_tensors, EXPLICIT_INTEGER_TENSORS};
use super::explicit_edited::edited_valid_vectors;
use super::explicit_vectors::{
    explicit_must_fail_vectors, explicit_valid_vectors, EXPLICIT_SECTIONS,
};

/// Marks the generated coverage table inside `conformance/README.md`.
pub const COVERAGE_BEGIN: &str = "<!-- coverage:begin (salvq make-vectors writes this table) -->";
pub const COVERAGE_END: &str = "<!-- coverage:end -->";

/// Integer-domain tensors larger than this are not stored in the expected files (only
/// hashed), except symbols.
pub const OMIT_ABOVE_BYTES: usize = 16 * 1024;

/// Everything the generator writes into the vectors folder, by file name, and the coverage
/// table for the README.
pub struct Generated {
    pub files: BTreeMap<String, Vec<u8>>,
    pub manifest: Manifest,
    pub coverage: String,
}

fn sha256_hex(bytes: &[u8]) -> String {
    canonical::hex(&Sha256::digest(bytes))
}

/// A normative section of the spec: its number and title.
#[derive(Debug, Clone)]
pub struct SpecSection {
    pub number: String,
    pub title: String,
}

/// The numbered sections (`## §x.y` and `### §x.y.z` headings) of the normative files in
/// `spec_dir` (the `NN-*.md` files), leaving out those titled informative.
pub fn normative_sections(spec_dir: &Path) -> Result<Vec<SpecSection>, String> {
    let mut files: Vec<_> = std::fs::read_dir(spec_dir)
        .map_err(|e| format!("{}: {e}", spec_dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                n.as_bytes().first().is_some_and(u8::is_ascii_digit) && n.ends_with(".md")
            })
        })
        .collect();
    files.sort();
    let mut out = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).map_err(|e| format!("{}: {e}", f.display()))?;
        for line in text.lines() {
            let Some(rest) = line
                .strip_prefix("### ")
                .or_else(|| line.strip_prefix("## "))
            else {
                continue;
            };
            let Some((number, title)) = rest.split_once(' ') else {
                continue;
            };
            if !number.starts_with('§') || title.contains("(informative)") {
                continue;
            }
            out.push(SpecSection {
                number: number.to_string(),
                title: title.to_string(),
            });
        }
    }
    Ok(out)
}

/// Builds every vector. `spec_dir`: where to read the section list for the coverage table.
pub fn build(spec_dir: &Path) -> Result<Generated, String> {
    let mut files = BTreeMap::new();
    let mut entries = anchors_valid_entries(&mut files)?;
    entries.extend(explicit_valid_entries(&mut files)?);
    entries.extend(must_fail_entries(&mut files)?);
    let manifest = Manifest {
        format_version: format!("{FORMAT_MAJOR}.{FORMAT_MINOR}"),
        defined_in: "spec/11-conformance.md".into(),
        vectors: entries,
    };
    let coverage = coverage_table(&manifest, &normative_sections(spec_dir)?)?;
    let mut json = serde_json::to_string_pretty(&manifest)
        .map_err(|e| format!("writing the manifest: {e}"))?;
    json.push('\n');
    files.insert(MANIFEST_FILE.to_string(), json.into_bytes());
    Ok(Generated {
        files,
        manifest,
        coverage,
    })
}

/// The anchors-profile valid vectors' entries: each rate decoded by the reference decoder,
/// checked against the encoder's prediction, its canonical form and region decodes put in
/// `files` beside the stream.
fn anchors_valid_entries(
    files: &mut BTreeMap<String, Vec<u8>>,
) -> Result<Vec<VectorEntry>, String> {
    let mut entries = Vec::new();
    let valid = valid_vectors().map_err(|e| format!("building the valid vectors: {e}"))?;
    for v in valid {
        let file = format!("{}.salvq", v.name);
        let mut decodes = Vec::new();
        for (i, &rate) in v.rates.iter().enumerate() {
            let options = salvq::Decoder::builder().rate(Some(rate));
            let (model, symbols) = options
                .build()
                .decode_with_symbols(&v.stream)
                .map_err(|e| format!("{} rate {rate}: the reference decoder fails: {e}", v.name))?;
            if v.oracle.get(i) != Some(&model) {
                return Err(format!(
                    "{} rate {rate}: the reference decoder disagrees with the encoder's prediction",
                    v.name
                ));
            }
            let tensors = canonical_tensors(&model, &symbols);
            decodes.push(expected_decode(v.name, rate, &tensors, files));
        }
        decodes.extend(region_decodes(v.name, &v.stream, files)?);
        entries.push(VectorEntry {
            decodes,
            ..entry(
                v.name,
                VectorKind::Valid,
                &v.stream,
                v.description,
                v.sections,
            )
        });
        files.insert(file, v.stream);
    }
    Ok(entries)
}

/// The explicit-profile valid vectors' entries (the encoder's and the edited ones), as
/// [`anchors_valid_entries`]'s.
fn explicit_valid_entries(
    files: &mut BTreeMap<String, Vec<u8>>,
) -> Result<Vec<VectorEntry>, String> {
    let mut entries = Vec::new();
    let explicit = explicit_valid_vectors()
        .and_then(|mut v| {
            v.extend(edited_valid_vectors()?);
            Ok(v)
        })
        .map_err(|e| format!("building the explicit vectors: {e}"))?;
    for v in explicit {
        let file = format!("{}.salvq", v.name);
        let mut decodes = Vec::new();
        for (i, &rate) in v.rates.iter().enumerate() {
            let d = salvq::Decoder::builder()
                .limits(Default::default())
                .rate(Some(rate))
                .build()
                .decode(&v.stream)
                .and_then(salvq::Scene::try_into_gaussians)
                .map_err(|e| format!("{} rate {rate}: the reference decoder fails: {e}", v.name))?;
            if v.oracle.get(i) != Some(&d.gaussians) {
                return Err(format!(
                    "{} rate {rate}: the reference decoder disagrees with the encoder's prediction",
                    v.name
                ));
            }
            let tensors = explicit_canonical_tensors(&d);
            decodes.push(expected_decode(v.name, rate, &tensors, files));
        }
        decodes.extend(region_decodes(v.name, &v.stream, files)?);
        let mut sections = EXPLICIT_SECTIONS.to_vec();
        sections.extend(v.sections.iter().filter(|s| !EXPLICIT_SECTIONS.contains(s)));
        entries.push(VectorEntry {
            decodes,
            ..entry(
                v.name,
                VectorKind::Valid,
                &v.stream,
                v.description,
                &sections,
            )
        });
        files.insert(file, v.stream);
    }
    Ok(entries)
}

/// The must-fail vectors' entries, both profiles: each checked to fail in the reference
/// decoder with its error class (Table 9-1), its stream and region decodes put in `files`.
fn must_fail_entries(files: &mut BTreeMap<String, Vec<u8>>) -> Result<Vec<VectorEntry>, String> {
    let mut entries = Vec::new();
    for v in must_fail_vectors()
        .into_iter()
        .chain(explicit_must_fail_vectors())
    {
        let options = salvq::Decoder::builder().rate(Some(v.rate));
        match options.build().decode(&v.stream) {
            Err(e) if e.class() == v.class => {}
            other => {
                return Err(format!(
                    "{}: the reference decoder gives {:?}, not {}",
                    v.name,
                    other.map(|_| "success").map_err(|e| e.class()),
                    v.class
                ))
            }
        }
        let file = format!("{}.salvq", v.name);
        // Every must-fail vector tests its class's spelling and rule (Table 9-1).
        let mut sections = v.sections.to_vec();
        if !sections.contains(&"§9.2") {
            sections.push("§9.2");
        }
        entries.push(VectorEntry {
            decodes: region_decodes(v.name, &v.stream, files)?,
            rate: Some(v.rate),
            error_class: Some(v.class.to_string()),
            ..entry(
                v.name,
                VectorKind::MustFail,
                &v.stream,
                v.description,
                &sections,
            )
        });
        files.insert(file, v.stream);
    }
    Ok(entries)
}

/// The manifest's record of one expected decode, its file `<name>.r<rate>.safetensors` put
/// in `files`. Large lossless tensors (hash-grid tables, big MLPs) are left to the integer
/// hash, to keep the folder small; floats, symbols and the explicit profile's integer
/// tensors are always kept.
fn expected_decode(
    name: &str,
    rate: u8,
    tensors: &[canonical::CanonicalTensor],
    files: &mut BTreeMap<String, Vec<u8>>,
) -> ExpectedDecode {
    expected_file(format!("{name}.r{rate}.safetensors"), rate, tensors, files)
}

/// [`expected_decode`] into the file `expected`.
fn expected_file(
    expected: String,
    rate: u8,
    tensors: &[canonical::CanonicalTensor],
    files: &mut BTreeMap<String, Vec<u8>>,
) -> ExpectedDecode {
    let (kept, omitted): (Vec<_>, Vec<_>) = tensors.iter().cloned().partition(|t| {
        FLOAT_TENSORS.contains(&t.name.as_str())
            || SYMBOL_TENSORS.contains(&t.name.as_str())
            || EXPLICIT_INTEGER_TENSORS.contains(&t.name.as_str())
            || t.data.len() <= OMIT_ABOVE_BYTES
    });
    files.insert(expected.clone(), canonical::to_safetensors(&kept));
    ExpectedDecode {
        rate,
        expected,
        integer_sha256: integer_hash(tensors),
        float_sha256: float_hash(tensors),
        tolerance: Tolerance::STANDARD,
        omitted: omitted.into_iter().map(|t| t.name).collect(),
        region: None,
    }
}

/// The region decodes of a vector (§10.3.1, §11.7), each into
/// `<name>.r<rate>.region<k>.safetensors`. For a valid anchors-profile vector, each is
/// checked against the whole decode: the selected tiles' anchors, in order.
fn region_decodes(
    name: &str,
    stream: &[u8],
    files: &mut BTreeMap<String, Vec<u8>>,
) -> Result<Vec<ExpectedDecode>, String> {
    let mut out = Vec::new();
    for (k, case) in region_cases(name, stream).into_iter().enumerate() {
        let rate = case.rate;
        let fail = |e: salvq::Error| format!("{name} region {k}: the reference decoder fails: {e}");
        let tiles = selected_tiles(stream, rate, case.region);
        let (tensors, count) = if salvq_bitstream::container::is_explicit(stream) {
            let d = salvq::Decoder::builder()
                .limits(Default::default())
                .rate(Some(rate))
                .region(Some(case.region))
                .build()
                .decode(stream)
                .and_then(salvq::Scene::try_into_gaussians)
                .map_err(fail)?;
            (explicit_canonical_tensors(&d), d.gaussians.len() as u64)
        } else {
            let options = salvq::Decoder::builder()
                .rate(Some(rate))
                .region(Some(case.region));
            let (model, symbols) = options.build().decode_with_symbols(stream).map_err(fail)?;
            if let Ok(whole) = (options.clone().region(None))
                .build()
                .decode(stream)
                .and_then(salvq::Scene::try_into_anchors)
            {
                check_region_rows(name, k, stream, &whole, &model, &tiles)?;
            }
            (
                canonical_tensors(&model, &symbols),
                u64::from(model.dims.anchors),
            )
        };
        let mut e = expected_file(
            format!("{name}.r{rate}.region{k}.safetensors"),
            rate,
            &tensors,
            files,
        );
        e.region = Some(RegionDecode {
            region: case.region.to_array(),
            tiles,
            count,
            pins: case.pins.to_string(),
        });
        out.push(e);
    }
    Ok(out)
}

/// A region decode holds the whole decode's anchors of the selected tiles, in order.
fn check_region_rows(
    name: &str,
    k: usize,
    stream: &[u8],
    whole: &salvq::SceneModel,
    part: &salvq::SceneModel,
    tiles: &[u32],
) -> Result<(), String> {
    let table = anchors_tiles(stream);
    let rows: Vec<usize> = tiles
        .iter()
        .flat_map(|&t| table.range(t as usize))
        .collect();
    let f = usize::from(whole.dims.feat_dim);
    let same = part.anchors.voxel.len() == rows.len()
        && rows.iter().enumerate().all(|(i, &a)| {
            part.anchors.voxel[i] == whole.anchors.voxel[a]
                && part.anchors.feat[i * f..(i + 1) * f]
                    .iter()
                    .zip(&whole.anchors.feat[a * f..(a + 1) * f])
                    .all(|(x, y)| x.to_bits() == y.to_bits())
        });
    if same {
        Ok(())
    } else {
        Err(format!(
            "{name} region {k}: the region decode is not the whole decode's rows of tiles {tiles:?}"
        ))
    }
}

/// A manifest entry's common fields (no decodes, rate or class yet).
fn entry(
    name: &str,
    kind: VectorKind,
    stream: &[u8],
    description: &str,
    sections: &[&str],
) -> VectorEntry {
    VectorEntry {
        name: name.to_string(),
        kind,
        file: format!("{name}.salvq"),
        bytes: stream.len() as u64,
        sha256: sha256_hex(stream),
        description: description.to_string(),
        sections: sections.iter().map(|s| s.to_string()).collect(),
        decodes: Vec::new(),
        rate: None,
        error_class: None,
    }
}

/// The README's coverage table: each normative section and the vectors that exercise it.
/// Every normative section must have one, else the generator fails.
pub fn coverage_table(manifest: &Manifest, sections: &[SpecSection]) -> Result<String, String> {
    let valid = manifest
        .vectors
        .iter()
        .filter(|v| v.kind == VectorKind::Valid)
        .count();
    let mut out = String::from("| section | title | vectors |\n|---|---|---|\n");
    let mut uncovered = Vec::new();
    for s in sections {
        let mut names: Vec<String> = manifest
            .vectors
            .iter()
            .filter(|v| v.sections.contains(&s.number))
            .map(|v| format!("`{}`", v.name))
            .collect();
        if BASE_SECTIONS.contains(&s.number.as_str()) {
            names.insert(0, format!("every valid vector ({valid})"));
        }
        if names.is_empty() {
            uncovered.push(s.number.clone());
        }
        // Long lists of must-fail vectors are cut to keep the table readable.
        let shown = if names.len() > 8 {
            let more = names.len() - 6;
            let mut v = names[..6].to_vec();
            v.push(format!("and {more} more"));
            v
        } else {
            names
        };
        out.push_str(&format!(
            "| {} | {} | {} |\n",
            s.number,
            s.title.replace('|', "\\|"),
            shown.join(", ")
        ));
    }
    if uncovered.is_empty() {
        Ok(out)
    } else {
        Err(format!(
            "no vector exercises these normative sections: {}",
            uncovered.join(", ")
        ))
    }
}

/// Writes the generated files into `dir` (created if needed), removes stale `.salvq` and
/// `.safetensors` files there, and puts the coverage table into `readme` between the markers.
pub fn write(g: &Generated, dir: &Path, readme: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for (name, _) in stale_files(g, dir)? {
        let p = dir.join(&name);
        std::fs::remove_file(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    for (name, bytes) in &g.files {
        salvq_render::io::write_bytes_atomic(&dir.join(name), bytes).map_err(|e| e.to_string())?;
    }
    let text = std::fs::read_to_string(readme).map_err(|e| format!("{}: {e}", readme.display()))?;
    let updated = with_coverage(&text, &g.coverage)
        .ok_or_else(|| format!("{}: no coverage markers", readme.display()))?;
    salvq_render::io::write_bytes_atomic(readme, updated.as_bytes()).map_err(|e| e.to_string())
}

/// Files in `dir` the generator would not write (left over from removed vectors).
fn stale_files(g: &Generated, dir: &Path) -> Result<Vec<(String, ())>, String> {
    let Ok(listing) = std::fs::read_dir(dir) else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for e in listing.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let ours =
            name.ends_with(".salvq") || name.ends_with(".safetensors") || name == MANIFEST_FILE;
        if ours && !g.files.contains_key(&name) {
            out.push((name, ()));
        }
    }
    out.sort();
    Ok(out)
}

fn with_coverage(readme: &str, table: &str) -> Option<String> {
    let begin = readme.find(COVERAGE_BEGIN)? + COVERAGE_BEGIN.len();
    let end = readme.find(COVERAGE_END)?;
    (begin <= end).then(|| format!("{}\n{}{}", &readme[..begin], table, &readme[end..]))
}

/// Compares the generated files with `dir` and the README: every difference, one line each
/// (empty: up to date).
pub fn check(g: &Generated, dir: &Path, readme: &Path) -> Vec<String> {
    let mut out = Vec::new();
    for (name, bytes) in &g.files {
        match std::fs::read(dir.join(name)) {
            Ok(b) if &b == bytes => {}
            Ok(_) => out.push(format!("{name}: differs from a fresh generation")),
            Err(_) => out.push(format!("{name}: missing")),
        }
    }
    match stale_files(g, dir) {
        Ok(stale) => out.extend(
            stale
                .into_iter()
                .map(|(n, _)| format!("{n}: not generated any more")),
        ),
        Err(e) => out.push(e),
    }
    match std::fs::read_to_string(readme) {
        Ok(text) if with_coverage(&text, &g.coverage).as_deref() == Some(text.as_str()) => {}
        Ok(_) => out.push(format!("{}: coverage table is stale", readme.display())),
        Err(e) => out.push(format!("{}: {e}", readme.display())),
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_markers_replace_only_the_table() {
        let r = format!("a\n{COVERAGE_BEGIN}\nold\n{COVERAGE_END}\nb\n");
        let n = with_coverage(&r, "| new |\n").unwrap();
        assert_eq!(
            n,
            format!("a\n{COVERAGE_BEGIN}\n| new |\n{COVERAGE_END}\nb\n")
        );
        assert_eq!(with_coverage(&n, "| new |\n").unwrap(), n);
    }
}
