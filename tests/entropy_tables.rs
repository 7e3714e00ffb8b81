//! The frequency tables are the data file `spec/tables/gaussian_tables.txt` (spec §6.3.5), and
//! the spec states its SHA-256 and constants. Regenerate the file after a deliberate change with
//! `SALVQ_BLESS_TABLES=1 cargo test --test entropy_tables`.

use std::path::PathBuf;

use salvq_bitstream::entropy::tables::{RADIUS_LIMIT, X_MAX_Q32};
use salvq_bitstream::entropy::{
    GaussianTables, PRECISION, R_MAX, SCALE_COUNT, SIGMA_Q16, TAIL_Q4, THRESHOLD_Q16,
};
use sha2::{Digest, Sha256};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn spec_text() -> String {
    std::fs::read_to_string(root().join("spec/06-entropy-coding.md")).expect("spec §6 present")
}

#[test]
fn data_file_is_the_tables_and_the_spec_states_its_sha256() {
    let text = GaussianTables::new(PRECISION).to_text();
    assert_eq!(text, GaussianTables::standard().to_text());
    let path = root().join("spec/tables/gaussian_tables.txt");
    if std::env::var_os("SALVQ_BLESS_TABLES").is_some() {
        std::fs::write(&path, &text).expect("write the data file");
        eprintln!(
            "wrote {} (SHA-256 {})",
            path.display(),
            sha256_hex(text.as_bytes())
        );
    }
    let file = std::fs::read(&path).expect("spec/tables/gaussian_tables.txt present");
    assert!(
        file == text.as_bytes(),
        "spec/tables/gaussian_tables.txt differs from GaussianTables::new({PRECISION}).to_text()"
    );
    let sha = sha256_hex(&file);
    let spec = spec_text();
    assert!(
        spec.contains(&format!("SHA-256 `{sha}`")),
        "spec/06-entropy-coding.md must state SHA-256 `{sha}` of gaussian_tables.txt"
    );
}

#[test]
fn data_file_parses_back_to_the_tables() {
    let tables = GaussianTables::standard();
    let text = tables.to_text();
    let rows: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(rows.len(), SCALE_COUNT);
    for (k, row) in rows.iter().enumerate() {
        let cols: Vec<&str> = row.split(' ').collect();
        assert_eq!(cols[0], k.to_string());
        assert_eq!(cols[1], SIGMA_Q16[k].to_string());
        let theta = if k == 0 {
            "-".to_string()
        } else {
            THRESHOLD_Q16[k - 1].to_string()
        };
        assert_eq!(cols[2], theta);
        let r: u32 = cols[3].parse().unwrap();
        let t = tables.scale(k as u8);
        assert_eq!(r, t.radius());
        let f: Vec<u32> = cols[4..].iter().map(|c| c.parse().unwrap()).collect();
        assert_eq!(f, t.frequencies());
        assert_eq!(f.len(), 2 * r as usize + 2);
        assert_eq!(f.iter().sum::<u32>(), 1 << PRECISION);
        // §6.3.5: at P = 16 every frequency fits in 16 bits.
        assert!(f.iter().all(|&x| (1..1 << 16).contains(&x)));
    }
}

#[test]
fn spec_states_the_constants() {
    let spec = spec_text();
    for needle in [
        format!("P = {PRECISION}"),
        format!("TAIL_Q4 = {TAIL_Q4}"),
        format!("R_MAX = {R_MAX}"),
        "C = 7359186146747302452".to_string(),
        format!("X_MAX_Q32 = {X_MAX_Q32}"),
    ] {
        assert!(spec.contains(&needle), "spec §6 must state `{needle}`");
    }
    const { assert!(R_MAX <= RADIUS_LIMIT) };
    // Table 6-1 lists every σ_k and θ_k.
    for k in 0..SCALE_COUNT {
        let theta = if k == 0 {
            "—".to_string()
        } else {
            THRESHOLD_Q16[k - 1].to_string()
        };
        let row = format!("| {k} | {} |", SIGMA_Q16[k]);
        let line = spec
            .lines()
            .find(|l| l.starts_with(&row))
            .unwrap_or_else(|| panic!("Table 6-1 row for k = {k}"));
        assert!(
            line.ends_with(&format!("| {theta} |")),
            "Table 6-1 row {k}: {line}"
        );
    }
}
