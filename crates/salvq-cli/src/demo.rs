//! `salvq demo`: the main job on an embedded default scene.

use std::path::Path;
use std::time::Instant;

use salvq::Limits;
use salvq_encoder::info::{inspect, ByteClass};
use salvq_encoder::Error;
use salvq_gen::{generate, GenParams};
use salvq_render::error::IoOp;
use salvq_render::interchange::write_model;

use super::files::Ctx;
use super::secs;

/// The files `demo --out DIR` keeps.
const KEPT: [&str; 3] = ["scene.safetensors", "scene.salvq", "decoded.safetensors"];

/// Generates a scene, encodes it, decodes it, checks the result, prints the tables.
pub(crate) fn demo(anchors: u32, seed: u64, out: Option<&Path>, ctx: Ctx) -> Result<(), Error> {
    let tmp;
    let dir = match out {
        Some(d) => kept_dir(d, &ctx)?,
        None => {
            tmp = tempfile::tempdir()
                .map_err(|e| Error::io(IoOp::CreateTemp, &std::env::temp_dir(), e))?;
            tmp.path().to_path_buf()
        }
    };
    out!(
        "salvq demo: format {}.{}, {anchors} anchors, seed {seed}, HAC-size model, USQ (identity basis), rate 0\n",
        salvq_bitstream::container::FORMAT_MAJOR,
        salvq_bitstream::container::FORMAT_MINOR
    );
    salvq_bitstream::model::validate::check_field(
        salvq_bitstream::error::Field::AnchorCount,
        anchors.into(),
    )?;
    let params = GenParams {
        feat_basis: false,
        ..GenParams::new(anchors, seed)
    };
    let t = Instant::now();
    let model = generate(&params);
    let t_gen = secs(t);
    let [model_name, stream_name, decoded_name] = KEPT;
    let model_path = dir.join(model_name);
    write_model(&model, &model_path)?;
    let input_bytes = std::fs::metadata(&model_path).map(|m| m.len()).unwrap_or(0);

    let options = salvq_encoder::EncodeOptions {
        statistics: true,
        ..Default::default()
    };
    let t = Instant::now();
    let encoded = salvq_encoder::encode_full(&model, &options)?;
    let t_enc = secs(t);
    let (stream, report) = (&encoded.stream, encoded.report());
    salvq_render::io::write_bytes_atomic(&dir.join(stream_name), stream)?;

    let t = Instant::now();
    let decoded = salvq::decode(stream).and_then(salvq::Scene::try_into_anchors)?;
    let t_dec = secs(t);
    write_model(&decoded, &dir.join(decoded_name))?;

    let info = inspect(stream, &Limits::desktop())?;
    out!("{:<10} {:>10}", "step", "seconds");
    out!("{:<10} {:>10.3}", "generate", t_gen);
    out!("{:<10} {:>10.3}", "encode", t_enc);
    out!("{:<10} {:>10.3}", "decode", t_dec);
    out!(
        "decode throughput: {:.0} anchors/s, {:.0} symbols/s\n",
        f64::from(anchors) / t_dec,
        report.groups.iter().map(|g| g.symbols).sum::<u64>() as f64 / t_dec
    );
    print_chunks(&info, anchors, input_bytes);
    crate::print_text(&salvq_encoder::info::groups_text(report));
    let (exact, bounded) = check(&model, &decoded, &encoded);
    if out.is_some() {
        out!("files kept in {}", dir.display());
    }
    if !(exact && bounded) {
        return Err(salvq::Error::ValueInvalid {
            tensor: "demo check",
            index: vec![],
            value: 0,
            allowed: "exact geometry and masks, errors within half a step",
        }
        .into());
    }
    Ok(())
}

/// `--out DIR`, created; files an earlier run kept there are replaced only with --force,
/// checked before any work.
fn kept_dir(d: &Path, ctx: &Ctx) -> Result<std::path::PathBuf, Error> {
    std::fs::create_dir_all(d).map_err(|e| Error::io(IoOp::Write, d, e))?;
    for name in KEPT {
        ctx.check(d.join(name), &[])?;
    }
    Ok(d.to_path_buf())
}

/// The stream's chunks: bytes, share and bits per anchor, then the totals.
fn print_chunks(info: &salvq_encoder::info::StreamInfo, anchors: u32, input_bytes: u64) {
    out!(
        "{:<6} {:<7} {:>12} {:>8} {:>12}",
        "chunk",
        "class",
        "bytes",
        "share",
        "bits/anchor"
    );
    let total = info.totals.file_bytes as f64;
    for c in &info.chunks {
        let class = match c.class {
            ByteClass::Model => "model",
            ByteClass::Anchor => "anchor",
            ByteClass::Other => "other",
        };
        out!(
            "{:<6} {:<7} {:>12} {:>7.2}% {:>12.2}",
            c.tag,
            class,
            c.total_bytes,
            100.0 * c.total_bytes as f64 / total,
            c.total_bytes as f64 * 8.0 / f64::from(anchors)
        );
    }
    let t = &info.totals;
    out!(
        "\nmodel bytes {} ({:.2}%), anchor bytes {} ({:.2}%), other {}; total {} bytes = {:.2} bits/anchor",
        t.model_bytes,
        100.0 * t.model_bytes as f64 / total,
        t.anchor_bytes,
        100.0 * t.anchor_bytes as f64 / total,
        t.other_bytes,
        t.file_bytes,
        t.bits_per_anchor
    );
    out!(
        "input model file {} bytes; stream / input = {:.4}\n",
        input_bytes,
        total / input_bytes.max(1) as f64
    );
}

/// Compares the decoded scene with the generated one, prints the errors per group, and
/// returns (geometry, masks, MLPs and quantizers exact; every value within half a step).
fn check(
    model: &salvq::SceneModel,
    decoded: &salvq::SceneModel,
    encoded: &salvq_encoder::Encoded,
) -> (bool, bool) {
    let report = encoded.report();
    // Verify: geometry and masks exact, the MLPs as stored, attributes within half a step.
    // The quantizer is lossless but for the base step the encoder may refine to hold the
    // distortion with i8 context-MLP weights (spec Annex A.5.4).
    let feat_quantizer = salvq_bitstream::model::GroupQuantizer {
        step: (f64::from(model.quant_feat.step) * encoded.context.step_factors[0]) as f32,
        ..model.quant_feat.clone()
    };
    let exact = decoded.anchors.voxel == model.anchors.voxel
        && decoded.anchors.mask == model.anchors.mask
        // Stored as Annex A.5.2 chose (binary16 where its renders match binary32's).
        && decoded.mlp_opacity
            == salvq_encoder::precision::rounded(&model.mlp_opacity, encoded.scaffold.precision)
        && decoded.quant_feat == feat_quantizer;
    let bounded = report
        .groups
        .iter()
        .all(|g| g.max_error_steps <= 0.5 + 1e-3);
    out!("\n{:<8} {:>12} {:>14}", "group", "RMSE", "max |err|/step");
    for g in &report.groups {
        out!(
            "{:<8} {:>12.3e} {:>14.4}",
            g.group,
            (g.squared_error / g.symbols.max(1) as f64).sqrt(),
            g.max_error_steps
        );
    }
    out!(
        "check: voxels, masks, Scaffold-GS MLPs and quantizers {}; every coded value within half a step: {}",
        if exact { "exact" } else { "DIFFER" },
        if bounded { "yes" } else { "NO" }
    );
    (exact, bounded)
}
