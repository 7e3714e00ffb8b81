//! BD-rate / BD-PSNR against the values the PyPI package `bjontegaard` 1.3.0 computed
//! (`tests/data/reference/bdrate_cases.csv`, inputs in `bdrate_inputs.csv`; its README says
//! how they were computed). The files are checked by SHA-256 below, so that a change to them
//! shows.

use std::collections::HashMap;

use salvq_bench::bdrate::{bd_psnr, bd_rate, overlap, Curve, Interpolation};

const INPUTS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/reference/bdrate_inputs.csv"
);
const CASES: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/reference/bdrate_cases.csv"
);

/// The reference files are byte for byte the ones the hashes in tests/data/reference/README.md
/// name.
#[test]
fn reference_copies_are_byte_identical() {
    use sha2::{Digest, Sha256};
    for (path, want) in [
        (
            CASES,
            "603031876244f29708f03fc08ef658e029a2747a8099ef304e18194b6f22c9a7",
        ),
        (
            INPUTS,
            "4348c04f5714d6bd1d2f1ceacdf6e0386291fe12fc1e35c58e6e6cf527206c34",
        ),
    ] {
        let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
        let got: String = Sha256::digest(&bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(got, want, "{path}");
    }
}

/// Number of cases (each computed with all three methods).
const N_CASES: usize = 11;

/// Header and rows of a plain CSV file (no quoted fields), as maps from column name to field.
fn read_csv(path: &str) -> Vec<HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| {
        panic!(
            "cannot read {path}: {e} (tests/data/reference/ holds bdrate_cases.csv and \
             bdrate_inputs.csv)"
        )
    });
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<String> = lines
        .next()
        .unwrap_or_else(|| panic!("{path} is empty"))
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|line| {
            assert!(
                !line.contains('"'),
                "{path}: unexpected quoting in {line:?}"
            );
            let fields: Vec<&str> = line.split(',').collect();
            assert_eq!(fields.len(), header.len(), "{path}: bad row {line:?}");
            header
                .iter()
                .cloned()
                .zip(fields.into_iter().map(str::to_string))
                .collect()
        })
        .collect()
}

fn num(row: &HashMap<String, String>, column: &str) -> f64 {
    let field = row
        .get(column)
        .unwrap_or_else(|| panic!("missing column {column}"));
    field
        .parse()
        .unwrap_or_else(|e| panic!("column {column}: cannot parse {field:?}: {e}"))
}

/// Rates and PSNR values of one curve.
type Points = (Vec<f64>, Vec<f64>);

/// `(anchor, test)` curve of every case, points in file order.
fn curves() -> HashMap<String, (Curve, Curve)> {
    let mut points: HashMap<String, [Points; 2]> = HashMap::new();
    for row in read_csv(INPUTS) {
        let slot = match row["role"].as_str() {
            "anchor" => 0,
            "test" => 1,
            other => panic!("unknown role {other:?}"),
        };
        let entry = points.entry(row["case"].clone()).or_default();
        entry[slot].0.push(num(&row, "size_mb"));
        entry[slot].1.push(num(&row, "psnr"));
    }
    points
        .into_iter()
        .map(|(case, [a, t])| {
            let anchor = Curve::new(a.0, a.1).unwrap_or_else(|e| panic!("{case} anchor: {e}"));
            let test = Curve::new(t.0, t.1).unwrap_or_else(|e| panic!("{case} test: {e}"));
            (case, (anchor, test))
        })
        .collect()
}

/// A fraction as the CSV prints it: rounded to 6 decimals.
fn rounded6(v: f64) -> f64 {
    format!("{v:.6}").parse().unwrap()
}

/// Checks every case of `method`: BD-rate within `rate_tol` percentage points, BD-PSNR within
/// `psnr_tol` dB, both overlap fractions to 1e-12 after rounding to the CSV's 6 decimals.
fn check(method: Interpolation, rate_tol: f64, psnr_tol: f64) {
    let curves = curves();
    let rows: Vec<_> = read_csv(CASES)
        .into_iter()
        .filter(|r| r["interp_method"] == method.name())
        .collect();
    assert_eq!(rows.len(), N_CASES, "{method}: expected {N_CASES} rows");
    let (mut worst_rate, mut worst_psnr, mut worst_overlap) = (0f64, 0f64, 0f64);
    let mut failures = Vec::new();
    for row in &rows {
        let case = &row["case"];
        let (anchor, test) = curves
            .get(case)
            .unwrap_or_else(|| panic!("{case}: no inputs"));
        assert_eq!(anchor.len() as f64, num(row, "n_points"), "{case}");
        assert_eq!(test.len() as f64, num(row, "n_points"), "{case}");

        let rate = bd_rate(anchor, test, method).unwrap_or_else(|e| panic!("{case}: {e}"));
        let psnr = bd_psnr(anchor, test, method).unwrap_or_else(|e| panic!("{case}: {e}"));
        let err_rate = (rate - num(row, "bd_rate_percent")).abs();
        let err_psnr = (psnr - num(row, "bd_psnr_db")).abs();
        worst_rate = worst_rate.max(err_rate);
        worst_psnr = worst_psnr.max(err_psnr);
        if err_rate.is_nan() || err_rate > rate_tol {
            failures.push(format!("{case}: BD-rate {rate} off by {err_rate:e}"));
        }
        if err_psnr.is_nan() || err_psnr > psnr_tol {
            failures.push(format!("{case}: BD-PSNR {psnr} off by {err_psnr:e}"));
        }

        let o = overlap(anchor, test);
        for (got, column) in [
            (o.psnr, "psnr_overlap_fraction"),
            (o.log_rate, "log_rate_overlap_fraction"),
        ] {
            let want = num(row, column);
            let err = (rounded6(got) - want).abs();
            worst_overlap = worst_overlap.max(err);
            let ok = err <= 1e-12 && (got - want).abs() <= 5e-7 + 1e-12;
            if !ok {
                failures.push(format!("{case}: {column} {got} vs {want}"));
            }
        }
    }
    println!(
        "{method}: {} cases, worst |Δ BD-rate| = {worst_rate:.3e} %, worst |Δ BD-PSNR| = \
         {worst_psnr:.3e} dB, worst |Δ overlap| (6 decimals) = {worst_overlap:.1e}",
        rows.len()
    );
    assert!(failures.is_empty(), "{method}:\n{}", failures.join("\n"));
}

#[test]
fn akima_matches_bjontegaard_1_3_0() {
    check(Interpolation::Akima, 1e-6, 1e-7);
}

#[test]
fn pchip_matches_bjontegaard_1_3_0() {
    check(Interpolation::Pchip, 1e-6, 1e-7);
}

/// numpy's `polyfit` in PSNR is ill-conditioned; the README's independent check agreed to
/// 1e-7 and suggests 1e-6.
#[test]
fn cubic_matches_bjontegaard_1_3_0() {
    check(Interpolation::Cubic, 1e-6, 1e-6);
}

#[test]
fn every_case_has_every_method() {
    let rows = read_csv(CASES);
    assert_eq!(rows.len(), N_CASES * Interpolation::ALL.len());
    let curves = curves();
    assert_eq!(curves.len(), N_CASES);
    for row in &rows {
        assert!(
            curves.contains_key(&row["case"]),
            "{}: no inputs",
            row["case"]
        );
        assert!(Interpolation::from_name(&row["interp_method"]).is_some());
    }
}
