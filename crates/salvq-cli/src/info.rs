//! `salvq info`: what a stream holds (spec §1.5, §3), or, for a file the encoder reads, what
//! it is and how to encode it. The report is data: standard output.

use std::path::{Path, PathBuf};

use salvq::Limits;
use salvq_encoder::explicit::input::{input_kind, InputKind};
use salvq_encoder::explicit::prepare::{drop_invalid, value_changes, Dropped, ValueChange};
use salvq_encoder::info::inspect;
use salvq_encoder::Error;

use super::files;

/// `salvq info`'s arguments.
#[derive(clap::Args)]
pub(crate) struct InfoArgs {
    /// A stream, or a PLY or model file to encode (`-`: standard input).
    input: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// What `info` says of a PLY file.
#[derive(serde::Serialize)]
struct PlyInfo {
    kind: &'static str,
    gaussians: u64,
    sh_degree: u8,
    bytes: u64,
    bytes_per_gaussian: f64,
    bounds_min: [f32; 3],
    bounds_max: [f32; 3],
    ignored_properties: Vec<String>,
    /// What the encoder will change on input.
    changes_on_encode: Vec<ValueChange>,
    /// Gaussians with a value the format cannot hold (encode fails; `--drop-invalid`).
    invalid: Dropped,
    encode: String,
}

/// `salvq info`.
pub(crate) fn run(a: InfoArgs) -> Result<(), Error> {
    let bytes = files::read_input(&a.input)?;
    // Anything without the stream's magic (§1.2) is a file to encode, or named as what it is.
    let magic = salvq_bitstream::container::signature::MAGIC;
    let head = &bytes[..bytes.len().min(magic.len())];
    if head.is_empty() || !magic.starts_with(head) {
        return match input_kind(&bytes)? {
            InputKind::Ply => ply(&a.input, &bytes, a.json),
            InputKind::Model => Err(Error::UnsupportedInput {
                found: "an anchor model (safetensors, spec Annex A), not a stream".into(),
                hint: "`salvq encode MODEL` encodes it",
            }),
        };
    }
    if salvq_bitstream::container::is_explicit(&bytes) {
        let info = salvq_encoder::info::explicit::inspect_explicit(&bytes, &Limits::desktop())?;
        if a.json {
            files::print_json(&info);
        } else {
            crate::print_text(&info.to_text());
        }
        return Ok(());
    }
    let info = inspect(&bytes, &Limits::desktop())?;
    if a.json {
        files::print_json(&info);
    } else {
        crate::print_text(&info.to_text());
    }
    Ok(())
}

/// `info` of a 3DGS PLY: what it holds, what encoding it changes, how to encode it.
fn ply(path: &Path, bytes: &[u8], json: bool) -> Result<(), Error> {
    let g = salvq_render::ply::read_ply_lenient(bytes)?;
    let n = g.len() as u64;
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in g
        .positions
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
    {
        for a in 0..3 {
            min[a] = min[a].min(p[a]);
            max[a] = max[a].max(p[a]);
        }
    }
    let shown = if files::is_stdio(path) {
        "-".to_string()
    } else {
        path.display().to_string()
    };
    let info = PlyInfo {
        kind: "3DGS PLY",
        gaussians: n,
        sh_degree: g.sh_degree,
        bytes: bytes.len() as u64,
        bytes_per_gaussian: bytes.len() as f64 / n.max(1) as f64,
        bounds_min: min,
        bounds_max: max,
        ignored_properties: salvq_render::ply::unused_properties(bytes),
        changes_on_encode: value_changes(&g),
        invalid: drop_invalid(&g).1,
        encode: if files::is_stdio(path) {
            "salvq encode - -o scene.salvq".into()
        } else if path.with_extension("salvq") == path {
            // The default output name would be the input's own.
            format!("salvq encode {shown} -o scene.salvq")
        } else {
            format!("salvq encode {shown}")
        },
    };
    if json {
        files::print_json(&info);
        return Ok(());
    }
    let mut t = format!(
        "{shown}: a 3DGS PLY, not a stream: {} Gaussians, SH degree {}, {} bytes ({:.1} B/Gaussian)\n",
        info.gaussians, info.sh_degree, info.bytes, info.bytes_per_gaussian
    );
    if n > 0 {
        t.push_str(&format!(
            "positions from ({}, {}, {}) to ({}, {}, {})\n",
            min[0], min[1], min[2], max[0], max[1], max[2]
        ));
    }
    if !info.ignored_properties.is_empty() {
        t.push_str(&format!(
            "ignored properties (not part of a 3DGS Gaussian): {}\n",
            info.ignored_properties.join(", ")
        ));
    }
    for c in &info.changes_on_encode {
        t.push_str(&format!(
            "on encoding, {} {} values of {} become {}\n",
            c.count, c.property, c.was, c.became
        ));
    }
    if info.invalid.dropped > 0 {
        t.push_str(&format!(
            "{} Gaussians hold a value the format cannot hold ({}): encode stops at the first; \
             --drop-invalid drops them\n",
            info.invalid.dropped,
            by_property(&info.invalid)
        ));
    }
    if n == 0 {
        t.push_str("it holds no Gaussian: there is nothing to encode\n");
    } else {
        t.push_str(&format!(
            "encode it: {} (--psnr sets the rates' render-PSNR targets)\n",
            info.encode
        ));
    }
    crate::print_text(&t);
    Ok(())
}

/// `"f_rest_3: 10, opacity: 2"`.
pub(crate) fn by_property(d: &Dropped) -> String {
    d.by_property
        .iter()
        .map(|(p, k)| format!("{p}: {k}"))
        .collect::<Vec<_>>()
        .join(", ")
}
