//! The shared model's bytes per stored tensor (`salvq info`, spec §1.4, §1.6.1-§1.6.3).

use serde::Serialize;

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::preflight::Preflight;

/// Bytes of one stored tensor (or header) of the shared model (`salvq info --json`:
/// `model_parts`; the byte accounting).
#[derive(Debug, Clone, Serialize)]
pub struct ModelPart {
    /// The tensor (Table 2-1 names where the stream stores one) or header.
    pub part: String,
    /// The group it belongs to, for the text report's subtotals (`mlp_grid`, `quant.feat`, …).
    pub group: String,
    /// The chunk it is stored in.
    pub chunk: String,
    /// Its bytes.
    pub bytes: u64,
}

/// The model bytes per stored tensor, from the preflight's dimensions and the chunk sizes
/// (spec §1.4, §1.6.1-§1.6.3).
pub(super) fn model_parts(
    p: &Preflight,
    chunk_bytes: impl Fn(ChunkTag) -> u64,
    scaffold_value_bytes: u64,
    context_weight_bytes: u64,
) -> Vec<ModelPart> {
    let mut parts = Parts(Vec::new());
    parts.push(
        "HEAD",
        "preflight",
        ChunkTag::HEAD,
        chunk_bytes(ChunkTag::HEAD),
    );
    context_mlp_parts(&mut parts, p, context_weight_bytes);
    scaffold_mlp_parts(&mut parts, p, scaffold_value_bytes);
    quant_parts(&mut parts, p);
    parts.push(
        "hyperprior.grid (touched entries, method byte)",
        "hyperprior.grid",
        ChunkTag::GRID,
        chunk_bytes(ChunkTag::GRID),
    );
    parts.0
}

/// The parts in the order the report lists them (the stream's order within each chunk).
struct Parts(Vec<ModelPart>);

impl Parts {
    /// Appends one part of `bytes` bytes, stored in `chunk` and subtotalled under `group`.
    fn push(&mut self, part: &str, group: &str, chunk: ChunkTag, bytes: u64) {
        self.0.push(ModelPart {
            part: part.to_string(),
            group: group.to_string(),
            chunk: chunk.to_string(),
            bytes,
        })
    }
}

/// The integer context MLP's header and tensors in `MLPS` (§5.3 Table 5-1); its weights take
/// `context_weight_bytes` each (the context precision, §1.6.2).
fn context_mlp_parts(parts: &mut Parts, p: &Preflight, context_weight_bytes: u64) {
    let d = &p.dims;
    let (cin, h, cout) = (
        d.context_input(),
        u64::from(d.context_hidden),
        d.context_output(),
    );
    let g = "mlp_grid (integer, §5.3)";
    let (wb, wt) = (
        context_weight_bytes,
        if context_weight_bytes == 1 {
            "i8"
        } else {
            "i16"
        },
    );
    parts.push(
        "coding_method, context_precision, a0, shift0, a1",
        g,
        ChunkTag::MLPS,
        4 + cout,
    );
    parts.push(
        &format!("mlp_grid.0.weight ({wt})"),
        g,
        ChunkTag::MLPS,
        wb * h * cin,
    );
    parts.push("mlp_grid.0.bias (i32)", g, ChunkTag::MLPS, 4 * h);
    parts.push(
        &format!("mlp_grid.2.weight ({wt})"),
        g,
        ChunkTag::MLPS,
        wb * cout * h,
    );
    parts.push("mlp_grid.2.bias (i32)", g, ChunkTag::MLPS, 4 * cout);
}

/// The scaffold MLPs' precision byte and tensors in `MLPS` (§1.6.2), each value
/// `scaffold_value_bytes` bytes.
fn scaffold_mlp_parts(parts: &mut Parts, p: &Preflight, scaffold_value_bytes: u64) {
    let d = &p.dims;
    let k = u64::from(d.offsets);
    let (si, hs) = (d.scaffold_input(), u64::from(d.scaffold_hidden));
    parts.push("scaffold_precision", "mlp_opacity", ChunkTag::MLPS, 1);
    let b = scaffold_value_bytes;
    for (name, o) in [("mlp_opacity", k), ("mlp_cov", 7 * k), ("mlp_color", 3 * k)] {
        parts.push(
            &format!("{name}.0.weight"),
            name,
            ChunkTag::MLPS,
            b * hs * si,
        );
        parts.push(&format!("{name}.0.bias"), name, ChunkTag::MLPS, b * hs);
        parts.push(
            &format!("{name}.2.weight"),
            name,
            ChunkTag::MLPS,
            b * o * hs,
        );
        parts.push(&format!("{name}.2.bias"), name, ChunkTag::MLPS, b * o);
    }
}

/// The quantizer parameters in `QUAN` (§1.6.3): per group its step, gains and, for a general
/// lattice, the region starts and bases.
fn quant_parts(parts: &mut Parts, p: &Preflight) {
    let d = &p.dims;
    let (f, s) = (u64::from(d.feat_dim), u64::from(d.scaling_dim));
    let m = u64::from(d.rates);
    parts.push("coding_method", "quant", ChunkTag::QUAN, 1);
    for (group, dim, general, regions) in [
        (
            "feat",
            f,
            d.feat_lattice.has_factors(),
            u64::from(d.feat_regions),
        ),
        (
            "scaling",
            s,
            d.scaling_lattice.has_factors(),
            u64::from(d.scaling_regions),
        ),
        ("offsets", 3, false, 1),
    ] {
        let g = format!("quant.{group}");
        parts.push(&format!("{g}.step"), &g, ChunkTag::QUAN, 4);
        parts.push(&format!("{g}.gains"), &g, ChunkTag::QUAN, 4 * m);
        if general {
            // One basis per region (§7.6); region 0's is `basis_*`, the others `regions.*`.
            if regions > 1 {
                parts.push(
                    &format!("{g}.regions.start"),
                    &g,
                    ChunkTag::QUAN,
                    4 * (regions - 1),
                );
            }
            parts.push(
                &format!("{g}.basis_u (all regions)"),
                &g,
                ChunkTag::QUAN,
                4 * regions * dim * dim,
            );
            parts.push(
                &format!("{g}.basis_s (all regions)"),
                &g,
                ChunkTag::QUAN,
                4 * regions * dim,
            );
            parts.push(
                &format!("{g}.basis_v (all regions)"),
                &g,
                ChunkTag::QUAN,
                4 * regions * dim * dim,
            );
        }
    }
}
