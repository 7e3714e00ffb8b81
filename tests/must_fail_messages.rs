//! What a user reads when a stream is refused: the error line of every must-fail
//! conformance vector (spec §9.2), as a snapshot a reviewer reads. Each line must also name
//! the class the manifest gives.

#[test]
fn every_must_fail_vector_is_refused_with_a_line_that_names_its_rule() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("conformance/vectors");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    let mut lines = String::new();
    let mut count = 0;
    for v in manifest["vectors"].as_array().unwrap() {
        if v["kind"] != "must_fail" {
            continue;
        }
        let name = v["name"].as_str().unwrap();
        let class = v["error_class"].as_str().unwrap();
        let bytes = std::fs::read(dir.join(v["file"].as_str().unwrap())).unwrap();
        // The vectors' classes are those under the spec's reference limits (§9.1).
        let options = salvq::Decoder::builder()
            .limits(salvq::Limits::desktop())
            .rate(v["rate"].as_u64().map(|r| r as u8));
        let error = match options.build().decode(&bytes) {
            Ok(_) => panic!("{name} decoded; the manifest says {class}"),
            Err(e) => e,
        };
        assert_eq!(error.class(), class, "{name}: {error}");
        lines.push_str(&format!("{name}: {error}\n"));
        count += 1;
    }
    assert!(count > 100, "{count} must-fail vectors");
    insta::assert_snapshot!("must_fail_lines", lines);
}
