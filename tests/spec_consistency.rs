//! The code mirrors the spec's tables: error classes (Table 9-1), chunk order (Table 1-3),
//! tensor names (Table 2-1). A change to one without the other fails here.

use std::path::PathBuf;

use salvq::Error;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::error::{Field, Structure};
use salvq_bitstream::limits::LimitKind;
use salvq_bitstream::model::Dtype;

fn spec(file: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("spec")
        .join(file);
    std::fs::read_to_string(path).expect("spec file present")
}

/// First-column backticked names of the rows of the table that follows `caption`.
fn table_names(text: &str, caption: &str) -> Vec<String> {
    let start = text.find(caption).expect("table caption present");
    text[start..]
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .filter_map(|l| {
            let cell = l.split('|').nth(1)?.trim();
            let cell = cell.split('|').next()?;
            cell.strip_prefix('`')?
                .split('`')
                .next()
                .map(str::to_string)
        })
        .collect()
}

/// One value of every variant of the error enum, group by group.
fn every_error() -> Vec<Error> {
    [
        chunk_errors(),
        field_errors(),
        coding_errors(),
        tensor_value_errors(),
        model_errors(),
        tile_errors(),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// The signature and chunk framing (§1).
fn chunk_errors() -> Vec<Error> {
    let t = ChunkTag::HEAD;
    vec![
        Error::SignatureMismatch { found: [0; 8] },
        Error::Truncated {
            structure: Structure::Signature,
            needed: 12,
            available: 0,
        },
        Error::UnsupportedMajorVersion {
            found: 1,
            supported: 0,
        },
        Error::UnsupportedMinorVersion {
            major: 0,
            found: 2,
            supported: 1,
        },
        Error::ReservedBitsSet {
            field: Field::FileFlags,
            value: 1,
        },
        Error::ChunkLengthPastEnd {
            tag: t,
            length: 1,
            available: 0,
        },
        Error::ChunkCrcMismatch {
            tag: t,
            stored: 0,
            computed: 1,
        },
        Error::ChunkTagInvalid { tag: [0; 4] },
        Error::UnknownCriticalChunk { tag: t },
        Error::ChunkOrder {
            found: t,
            expected: t,
        },
        Error::TrailingData { bytes: 1 },
        Error::ChunkSizeMismatch {
            tag: t,
            expected: 1,
            found: 2,
        },
        Error::UnknownCodingMethod { tag: t, method: 9 },
    ]
}

/// Header fields, sizes, limits and coordinates (§1).
fn field_errors() -> Vec<Error> {
    let t = ChunkTag::HEAD;
    vec![
        Error::FieldOutOfRange {
            field: Field::FeatDim,
            value: 0,
            min: 1,
            max: 2,
        },
        Error::DecodedSizeMismatch {
            stated: 1,
            computed: 2,
        },
        Error::LimitExceeded {
            limit: LimitKind::Anchors,
            requested: 2,
            allowed: 1,
        },
        Error::PaddingBitsSet { tag: t },
        Error::CoordinateOutOfRange {
            anchor: 0,
            axis: 0,
            value: 9,
            coord_bits: 1,
        },
    ]
}

/// Entropy coding (§6), lattices (§7.1) and rates (§7.4).
fn coding_errors() -> Vec<Error> {
    let t = ChunkTag::HEAD;
    vec![
        Error::AnsStreamInvalid {
            tag: t,
            fault: salvq_bitstream::error::AnsFault::OutOfWords,
        },
        Error::EscapeOverflow {
            tag: t,
            symbol: 0,
            prefix_bits: 33,
        },
        Error::ScaleIndexOutOfRange {
            tag: t,
            symbol: 0,
            scale_index: -1,
            max: 63,
        },
        Error::LatticeDimension {
            field: salvq_bitstream::error::Field::FeatLattice,
            lattice: "e8",
            dim: 50,
            rule: "r",
        },
        Error::RateNotCoded {
            rate: 1,
            rate_mask: 1,
        },
    ]
}

/// Tensor values (§2, decoder and encoder alike).
fn tensor_value_errors() -> Vec<Error> {
    vec![
        Error::NonFiniteValue {
            tensor: "x",
            index: vec![0],
        },
        Error::ValueNotPositive {
            tensor: "x",
            index: vec![0],
            value: 0.0,
        },
        Error::ValueInvalid {
            tensor: "x",
            index: vec![0],
            value: 2,
            allowed: "0 or 1",
        },
    ]
}

/// Model interchange and validation (Annex A, §2).
fn model_errors() -> Vec<Error> {
    vec![
        Error::TensorMissing { tensor: "x" },
        Error::TensorUnexpected { name: "x".into() },
        Error::TensorDtype {
            tensor: "x",
            expected: Dtype::F32,
            found: "I8".into(),
        },
        Error::TensorRank {
            tensor: "x",
            expected: 2,
            found: 1,
        },
        Error::TensorShape {
            tensor: "x",
            expected: vec![1],
            found: vec![2],
        },
        Error::BasisSingular {
            tensor: "x",
            index: 0,
        },
        Error::BasisIllConditioned {
            tensor: "x",
            condition: 1e9,
            max: 1e6,
        },
        Error::BasisNotOrthogonal {
            tensor: "x",
            index: [0, 1],
            deviation: 0.1,
            tolerance: 1e-3,
        },
    ]
}

/// Tiles (§10.1) and the anchor octree (§8).
fn tile_errors() -> Vec<Error> {
    vec![
        Error::TileOrder { tile: 1 },
        Error::TileBoxMismatch {
            tile: 0,
            stated: [0; 6],
            actual: [0; 6],
        },
        Error::OctreeInvalid {
            rule: "x",
            depth: 1,
            count: 2,
            anchors: 1,
        },
    ]
}

/// The variants of `salvq::Error` as `crates/salvq-bitstream/src/error/mod.rs` declares them (the enum is
/// `#[non_exhaustive]`, so a match here cannot check that [`every_error`] lists them all).
fn declared_error_variants() -> Vec<String> {
    let src = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/salvq-bitstream/src/error/mod.rs"
    ))
    .expect("the error module");
    let start = src.find("pub enum Error {").expect("the error enum");
    let body = &src[start..];
    let body = &body[..body.find("\n}\n").expect("the enum's end")];
    body.lines()
        .filter_map(|l| {
            let name = l.strip_prefix("    ")?;
            let first = name.chars().next()?;
            if !first.is_ascii_uppercase() {
                return None;
            }
            let end = name
                .find(|c: char| !c.is_ascii_alphanumeric())
                .unwrap_or(name.len());
            Some(name[..end].to_string())
        })
        .collect()
}

#[test]
fn every_error_lists_every_declared_variant() {
    let mut declared = declared_error_variants();
    let mut listed: Vec<String> = every_error()
        .iter()
        .map(|e| e.class().to_string())
        .collect();
    declared.sort();
    listed.sort();
    assert_eq!(declared, listed);
}

#[test]
fn error_classes_match_table_9_1() {
    let mut spec_classes = table_names(&spec("09-limits-errors.md"), "Table 9-1:");
    let mut code: Vec<String> = every_error()
        .iter()
        .map(|e| e.class().to_string())
        .collect();
    spec_classes.sort();
    code.sort();
    assert_eq!(spec_classes, code);
}

#[test]
fn every_message_ends_with_its_section() {
    for e in every_error() {
        let msg = e.to_string();
        assert!(msg.ends_with(&format!("[{}]", e.spec_section())), "{msg}");
        assert!(!msg.contains("{ "), "Display must not be Debug: {msg}");
    }
}

#[test]
fn critical_chunks_match_table_1_3() {
    let spec_tags = table_names(&spec("01-container.md"), "Table 1-3:");
    let mut code: Vec<String> = ChunkTag::CRITICAL_ORDER
        .iter()
        .map(|t| t.to_string())
        .collect();
    code.push(ChunkTag::ENCD.to_string());
    code.push(ChunkTag::ESTS.to_string());
    assert_eq!(spec_tags, code);
}

#[test]
fn tensor_names_match_table_2_1() {
    let text = spec("02-scene-model.md");
    let start = text.find("Table 2-1:").unwrap();
    let rows: Vec<&str> = text[start..]
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .skip(2)
        .collect();
    // Expand the spec's brace shorthand, e.g. `mlp_cov.{0,2}.{weight,bias}`.
    let mut spec_names = Vec::new();
    for row in rows {
        let name = row.split('|').nth(2).unwrap().trim().trim_matches('`');
        let mut names = vec![String::new()];
        let mut rest = name;
        while let Some(open) = rest.find('{') {
            let close = rest.find('}').unwrap();
            let prefix = &rest[..open];
            let options: Vec<&str> = rest[open + 1..close].split(',').collect();
            names = names
                .iter()
                .flat_map(|n| options.iter().map(move |o| format!("{n}{prefix}{o}")))
                .collect();
            rest = &rest[close + 1..];
        }
        spec_names.extend(names.into_iter().map(|n| format!("{n}{rest}")));
    }
    let mut dims = salvq_gen::generate(&salvq_gen::GenParams::small(1, 1)).dims;
    dims.feat_lattice = salvq_bitstream::model::LatticeKind::General;
    dims.scaling_lattice = salvq_bitstream::model::LatticeKind::General;
    dims.feat_regions = 2;
    dims.scaling_regions = 2;
    let code: Vec<String> = salvq_bitstream::model::tensor_table(&dims)
        .iter()
        .map(|e| e.name.to_string())
        .collect();
    // The spec lists each MLP as {0,2} x {weight,bias}: 0.weight, 0.bias, 2.weight, 2.bias.
    let mut spec_sorted = spec_names.clone();
    let mut code_sorted = code.clone();
    spec_sorted.sort();
    code_sorted.sort();
    assert_eq!(spec_sorted, code_sorted);
    assert_eq!(code.len(), 50);
}

/// §3.7 Table 3-2 lists the explicit profile's critical chunks in the order the decoder
/// expects them (a progressive stream of two layers shown), and Table 3-3 its groups with
/// their value counts.
#[test]
fn explicit_profile_tables_match_the_code() {
    use salvq_bitstream::container::order::Profile;
    use salvq_bitstream::explicit::{GroupKind, GROUP_KINDS};
    let text = spec("03-explicit.md");
    let chunks: Vec<String> = table_names(&text, "Table 3-2:")
        .into_iter()
        .filter(|t| t.chars().next().is_some_and(|c| c.is_ascii_uppercase()))
        .collect();
    let code: Vec<String> = (0..9)
        .map(|i| Profile::Explicit.expected(i, 2, true).as_str().to_string())
        .collect();
    assert_eq!(chunks, code);
    // Table 3-3: `| g | group | d | ...`, d as SH degree 3 gives it (3B = 45 for rest).
    let start = text.find("Table 3-3:").expect("Table 3-3");
    let rows: Vec<(String, String)> = text[start..]
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            (cells[2].trim_matches('`').to_string(), cells[3].to_string())
        })
        .collect();
    assert_eq!(rows.len(), GROUP_KINDS.len());
    for ((name, d), kind) in rows.iter().zip(GROUP_KINDS) {
        assert_eq!(name, kind.name());
        let dim = kind.dim(3);
        let stated = if d == "3B" {
            45
        } else {
            d.parse().expect("a count")
        };
        assert_eq!(stated, dim, "{name}");
    }
    assert_eq!(GroupKind::present(0).len(), 4);
}

/// One value of every class of the reference tools' own errors (encoder, model files, PLY,
/// renderer, files).
fn every_tool_error() -> Vec<salvq_encoder::Error> {
    use salvq_render::error::IoOp;
    use salvq_render::Error as R;
    let files = |e: R| salvq_encoder::Error::from(e);
    vec![
        salvq_encoder::Error::UnsupportedInput {
            found: "x".into(),
            hint: "y",
        },
        salvq_encoder::Error::TargetUnreachable {
            rate: 0,
            target_db: 200.0,
            ceiling_db: 90.0,
        },
        salvq_encoder::Error::OptionUnsupported {
            option: "x",
            reason: "y",
            hint: "z",
        },
        salvq_encoder::Error::LatticeSearchFailed {
            tensor: "x",
            anchor: Some(1),
            reason: "y".into(),
        },
        salvq_encoder::Error::FitFailed {
            tensor: "x",
            reason: "y".into(),
        },
        files(R::InterchangeFormat { detail: "x".into() }),
        files(R::PlyHeaderInvalid { line: 1, rule: "x" }),
        files(R::PlyPropertyMissing { property: "x" }),
        files(R::PlyShCoefficients { count: 1 }),
        files(R::PlyTruncated {
            element: "vertex".into(),
            count: 1,
            stride: 4,
            available: 0,
        }),
        files(R::PlyValueNotFinite {
            vertex: 0,
            property: "x".into(),
        }),
        files(R::NeuralGaussiansUnsupported {
            field: Field::ViewDims,
            value: 5,
            rule: "x",
        }),
        files(R::RenderSettingInvalid {
            setting: "x",
            value: 0.0,
            rule: "x",
        }),
        files(R::CameraFileInvalid {
            path: "cameras.txt".into(),
            line: 3,
            field: "MODEL",
            problem: "x".into(),
        }),
        files(R::OutputExists { path: "x".into() }),
        files(R::OutputIsInput {
            path: "x".into(),
            input: "y".into(),
        }),
        files(R::OutputExtension {
            path: "x".into(),
            what: "y",
            extensions: "z",
        }),
        salvq_encoder::Error::io(
            IoOp::Read,
            std::path::Path::new("x"),
            std::io::Error::from(std::io::ErrorKind::NotFound),
        ),
    ]
}

#[test]
fn tool_error_classes_match_tables_a_9_and_c_6() {
    let mut spec_classes = table_names(&spec("annex-a-interchange.md"), "Table A-9:");
    spec_classes.extend(table_names(&spec("annex-c-rendering.md"), "Table C-6:"));
    let mut code: Vec<String> = every_tool_error()
        .iter()
        .map(|e| e.class().to_string())
        .collect();
    spec_classes.sort();
    code.sort();
    assert_eq!(spec_classes, code);
    // No tool class is also a stream class (Table 9-1 keeps what a decoder can report).
    let stream = table_names(&spec("09-limits-errors.md"), "Table 9-1:");
    assert!(code.iter().all(|c| !stream.contains(c)), "{code:?}");
    for e in every_tool_error() {
        let msg = e.to_string();
        assert!(msg.ends_with(&format!("[{}]", e.spec_section())), "{msg}");
    }
}
