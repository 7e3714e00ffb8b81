//! `salvq info`'s byte accounting: the model parts add up to the model chunks'
//! payloads, and each rate's "stream bits per anchor" is the size of what `extract` writes.

use std::path::Path;

use salvq::Limits;
use salvq_encoder::info::inspect;

fn vector(name: &str) -> Vec<u8> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("conformance/vectors/{name}.salvq"));
    std::fs::read(p).expect("vector")
}

#[test]
fn model_parts_add_up_to_the_model_chunks() {
    for name in [
        "usq-one-rate",
        "salvq-four-rates",
        "fs-salvq",
        "sp-salvq-regions",
        "max-attributes",
        "max-grid",
        "hac-dimensions",
    ] {
        let info = inspect(&vector(name), &Limits::default()).unwrap();
        let parts: u64 = info.model_parts.iter().map(|p| p.bytes).sum();
        let payloads: u64 = info
            .chunks
            .iter()
            .filter(|c| ["HEAD", "MLPS", "QUAN", "GRID"].contains(&c.tag.as_str()))
            .map(|c| c.payload_bytes)
            .sum();
        assert_eq!(parts, payloads, "{name}");
    }
}

#[test]
fn per_rate_stream_size_is_the_extracted_stream() {
    let stream = vector("salvq-four-rates");
    let info = inspect(&stream, &Limits::default()).unwrap();
    assert_eq!(info.layers.len(), 4);
    let n = f64::from(info.head.as_ref().unwrap().dims.anchors);
    for l in &info.layers {
        let one = salvq::extract_rate(&stream, l.rate, &Limits::default()).unwrap();
        assert_eq!(
            l.stream_bits_per_anchor,
            one.len() as f64 * 8.0 / n,
            "rate {}",
            l.rate
        );
    }
    // Lower rates spend more symbol bits (larger gains are coarser steps in this model).
    assert!(info
        .layers
        .windows(2)
        .all(|w| w[0].symbol_bits_per_anchor > w[1].symbol_bits_per_anchor));
}
