//! A sample of the conformance vectors through the whole-buffer and the streaming decoder:
//! the smallest valid vectors decode, and the smallest must-fail vectors fail with the class
//! the manifest gives (spec §11). Small enough to run under Miri, which checks the decoder's
//! memory accesses (CI: `cargo +nightly miri test -p salvq --no-default-features --test
//! vector_sample`, with `MIRIFLAGS=-Zmiri-disable-isolation` to read the files);
//! `SALVQ_SAMPLE=N` takes N of each kind (default 6).

use std::path::Path;

/// A vector: its name, its bytes, the rate to decode and the class it must fail with (None:
/// a valid vector).
type Vector = (String, Vec<u8>, Option<u8>, Option<String>);

/// The `n` smallest vectors of each kind.
fn sample(n: usize) -> Vec<Vector> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("conformance/vectors");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    let mut valid = Vec::new();
    let mut must_fail = Vec::new();
    for v in manifest["vectors"].as_array().unwrap() {
        let bytes = std::fs::read(dir.join(v["file"].as_str().unwrap())).unwrap();
        let class = v["error_class"].as_str().map(str::to_string);
        let entry = (
            v["name"].as_str().unwrap().to_string(),
            bytes,
            v["rate"].as_u64().map(|r| r as u8),
            class,
        );
        match v["kind"].as_str() {
            Some("must_fail") => must_fail.push(entry),
            _ => valid.push(entry),
        }
    }
    for list in [&mut valid, &mut must_fail] {
        list.sort_by_key(|(name, bytes, ..)| (bytes.len(), name.clone()));
        list.truncate(n);
    }
    valid.extend(must_fail);
    valid
}

#[test]
fn a_sample_of_vectors_decodes_as_the_manifest_says() {
    let n = std::env::var("SALVQ_SAMPLE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(6);
    let vectors = sample(n);
    assert_eq!(
        vectors.len(),
        2 * n,
        "the manifest has {n} vectors of each kind"
    );
    for (name, bytes, rate, class) in vectors {
        // The manifest's classes are those under the spec's reference limits (§9.1).
        let decoder = salvq::Decoder::builder()
            .limits(salvq::Limits::desktop())
            .rate(rate)
            .build();
        let whole = decoder.decode(&bytes);
        match (&whole, &class) {
            (Ok(scene), None) => {
                let count = match scene {
                    salvq::Scene::Gaussians(g) => g.gaussians.len(),
                    salvq::Scene::Anchors(m) => m.anchors.voxel.len(),
                };
                assert!(count > 0, "{name}: nothing decoded");
            }
            (Err(e), Some(class)) => assert_eq!(e.class(), class, "{name}: {e}"),
            _ => panic!("{name}: {whole:?}, the manifest says {class:?}"),
        }
        // Fed in pieces, the stream decodes to the same scene or fails with the same error.
        let mut stream = decoder.stream();
        let fed = bytes.chunks(97).try_for_each(|piece| stream.feed(piece));
        let streamed = fed.and_then(|()| stream.finish());
        assert_eq!(streamed, whole, "{name}: streamed");
    }
}
