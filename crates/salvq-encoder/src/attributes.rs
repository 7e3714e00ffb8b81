//! Encoder side of the anchor attribute chunks (spec §6.6): lattice coordinates u of the
//! targets (x - μ) / Δ (§7.3; u = round((x - μ) / Δ) for the identity), coded against the
//! integer prior, the masks' slot probabilities, and the statistics `info`
//! reports (ideal information under the integer model and under the float model).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::writers::SymbolWriter;
use salvq_bitstream::attributes::mask_freq;
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::container::payload::METHOD_CODED;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::hyperprior::prior::{Group, Prior};
use salvq_bitstream::model::SceneModel;
use salvq_bitstream::tiles::{join_bodies, TileTable};

use super::float_prior::FloatPrior;
use super::search::GroupSearches;
use salvq_bitstream::quantizer::reconstruct_value;

/// What coding one attribute group cost (spec §6.6; reported by `salvq info --json`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GroupStats {
    /// The group (`feat`, `scaling`, `offsets`).
    pub group: String,
    /// Symbols coded.
    pub symbols: u64,
    /// Of those, symbols coded with an escape (§6.4).
    pub escapes: u64,
    /// Bytes of the chunk's payload.
    pub coded_bytes: u64,
    /// Σ -log2 p(u) under the stream's integer model and tables.
    pub ideal_bits_integer: f64,
    /// Σ -log2 p(u) under the float model (float interpolation, float MLP, exact
    /// discretized Gaussian), for the symbols that model would have chosen.
    pub ideal_bits_float: f64,
    /// Largest |x - x̂| / Δ over the group's coded values (≤ 0.5 up to binary32 rounding for
    /// the identity; up to the lattice's covering radius otherwise).
    pub max_error_steps: f64,
    /// Σ (x - x̂)^2 over the group's coded values.
    pub squared_error: f64,
}

/// The coded chunks and their statistics.
pub struct CodedAttributes {
    /// The payloads of `AFEA`, `ASCL`, `AOFF`.
    pub chunks: [Vec<u8>; 3],
    /// What each cost.
    pub stats: [GroupStats; 3],
    /// What a decoder reconstructs: features [N, F], scalings [N, S], offsets [N, K, 3].
    pub recon: [Vec<f32>; 3],
}

/// One anchor's symbols: (u, scale index) per coded value, per group, and the float model's
/// ideal bits per group.
struct AnchorSymbols {
    groups: [Vec<(i64, u8)>; 3],
    float_bits: [f64; 3],
    max_error_steps: [f64; 3],
    squared_error: [f64; 3],
    /// The decoder's reconstruction of every value of the anchor, per group (offsets: 3K,
    /// 0.0 where masked).
    recon: [Vec<f32>; 3],
}

fn symbols_of(
    m: &SceneModel,
    i: usize,
    prior: &Prior,
    float: &FloatPrior,
    searches: &[GroupSearches; 2],
    tables: &GaussianTables,
) -> Result<AnchorSymbols> {
    let d = &m.dims;
    let (f, s, k) = (
        usize::from(d.feat_dim),
        usize::from(d.scaling_dim),
        usize::from(d.offsets),
    );
    let mut ctx = prior.context();
    prior.eval(&m.grid, m.anchors.voxel[i], &mut ctx);
    let fctx = float.eval(m, m.anchors.voxel[i]);
    let a = &m.anchors;
    let mut out = AnchorSymbols {
        groups: [
            Vec::with_capacity(f),
            Vec::with_capacity(s),
            Vec::with_capacity(3 * k),
        ],
        float_bits: [0.0; 3],
        max_error_steps: [0.0; 3],
        squared_error: [0.0; 3],
        recon: [vec![0.0; f], vec![0.0; s], vec![0.0; 3 * k]],
    };
    let values: [(Group, &[f32], Vec<usize>); 3] = [
        (
            Group::Feature,
            &a.feat[i * f..(i + 1) * f],
            (0..f).collect(),
        ),
        (
            Group::Scaling,
            &a.scaling[i * s..(i + 1) * s],
            (0..s).collect(),
        ),
        (
            Group::Offsets,
            &a.offsets[i * 3 * k..(i + 1) * 3 * k],
            (0..3 * k).filter(|j| a.mask[i * k + j / 3] != 0).collect(),
        ),
    ];
    for (g, x, coded) in values {
        let gi = g as usize;
        let step = prior.step(&ctx.y, g);
        let delta = f64::from(step.delta);
        let mu: Vec<f32> = coded
            .iter()
            .map(|&j| prior.mean_f32(&ctx.y, g, j))
            .collect();
        // §7.3 (Annex A.4): targets t = (x − μ) / Δ, a lattice point u for them, and the
        // decoder's reconstruction μ + Δ·(B u).
        let t: Vec<f64> = coded
            .iter()
            .zip(&mu)
            .map(|(&j, &m)| (f64::from(x[j]) - f64::from(m)) / delta)
            .collect();
        let search = searches.get(gi).map(|g| g.for_anchor(i as u32));
        let ks: Vec<u8> = coded
            .iter()
            .map(|&j| prior.scale_index(&ctx.y, g, j, &step))
            .collect();
        let mut u = match search {
            Some(gs) => gs.quantize(&t, i as u64)?,
            None => t
                .iter()
                .map(|v| v.round().clamp(-9.0e18, 9.0e18) as i64)
                .collect(),
        };
        if let Some((gs, lambda)) = search.and_then(|gs| gs.rdo_lambda().map(|l| (gs, l))) {
            gs.refine_rd(&t, &mut u, &ks, tables, lambda);
        }
        let mut z = vec![0f32; u.len()];
        match search {
            Some(gs) => gs.matrix.apply(&u, &mut z),
            None => z.iter_mut().zip(&u).for_each(|(z, &u)| *z = u as f32),
        }
        for (c, &j) in coded.iter().enumerate() {
            let x_hat = reconstruct_value(mu[c], step.delta, z[c]);
            out.recon[gi][j] = x_hat;
            let err = f64::from(x[j]) - f64::from(x_hat);
            out.max_error_steps[gi] = out.max_error_steps[gi].max(err.abs() / delta);
            out.squared_error[gi] += err * err;
            out.groups[gi].push((u[c], ks[c]));
        }
        out.float_bits[gi] = match search {
            Some(gs) if !gs.matrix.is_identity() => {
                fctx.ideal_bits_lattice(g, x, |t| gs.quantize(t, i as u64).ok())
            }
            _ => coded.iter().map(|&j| fctx.ideal_bits(g, j, x[j])).sum(),
        };
    }
    Ok(out)
}

/// §6.6.1: the slot probabilities P(mask = 1) in units of 2^-16, clamped to 1 ..= 65535.
fn slot_probabilities(m: &SceneModel) -> Vec<u16> {
    let k = usize::from(m.dims.offsets);
    let n = m.n().max(1) as u64;
    (0..k)
        .map(|slot| {
            let ones = (0..m.n())
                .filter(|i| m.anchors.mask[i * k + slot] != 0)
                .count() as u64;
            ((ones * 65536 + n / 2) / n).clamp(1, 65535) as u16
        })
        .collect()
}

/// §6.6.1: the `AMSK` payload (shared by every rate) of a canonical-order model.
pub fn code_masks(m: &SceneModel, tables: &GaussianTables, tiles: &TileTable) -> Vec<u8> {
    let p_one = slot_probabilities(m);
    let mut amsk = vec![METHOD_CODED];
    for p in &p_one {
        amsk.extend_from_slice(&p.to_le_bytes());
    }
    let freq: Vec<u32> = p_one
        .iter()
        .map(|&p| mask_freq(p, tables.precision()))
        .collect();
    // §10.2: one body per tile.
    let k = freq.len();
    let bodies: Vec<Vec<u8>> = (0..tiles.len())
        .map(|t| {
            let r = tiles.range(t);
            let mut w = SymbolWriter::new(ChunkTag::AMSK, tables);
            for (i, &b) in m.anchors.mask[r.start * k..r.end * k].iter().enumerate() {
                w.bit(b != 0, freq[i % k]);
            }
            w.finish()
        })
        .collect();
    amsk.extend_from_slice(&join_bodies(&bodies));
    amsk
}

/// Codes the three attribute groups of a canonical-order model at one rate (`prior` and
/// `float` are built for that rate): one symbol layer (§7.4).
pub fn code_attributes(
    m: &SceneModel,
    prior: &Prior,
    float: &FloatPrior,
    searches: &[GroupSearches; 2],
    tables: &GaussianTables,
    tiles: &TileTable,
) -> Result<CodedAttributes> {
    // Attributes (§6.6.2): symbols in parallel, coded in stream order, one body per tile
    // (§10.2).
    let new_writers = || {
        [ChunkTag::AFEA, ChunkTag::ASCL, ChunkTag::AOFF].map(|tag| SymbolWriter::new(tag, tables))
    };
    let mut bodies: [Vec<Vec<u8>>; 3] = Default::default();
    let mut stats: [GroupStats; 3] = Group::ALL.map(|g| GroupStats {
        group: g.name().to_string(),
        ..GroupStats::default()
    });
    let d = &m.dims;
    let widths = [
        usize::from(d.feat_dim),
        usize::from(d.scaling_dim),
        3 * usize::from(d.offsets),
    ];
    let mut recon = widths.map(|w| Vec::with_capacity(m.n() * w));
    const BLOCK: usize = 1 << 14;
    for t in 0..tiles.len() {
        let tile = tiles.range(t);
        let mut writers = new_writers();
        for start in tile.clone().step_by(BLOCK) {
            let end = (start + BLOCK).min(tile.end);
            let block: Vec<AnchorSymbols> = (start..end)
                .into_par_iter()
                .map(|i| symbols_of(m, i, prior, float, searches, tables))
                .collect::<Result<_>>()?;
            for a in block {
                for (r, v) in recon.iter_mut().zip(&a.recon) {
                    r.extend_from_slice(v);
                }
                for g in 0..3 {
                    for &(u, ki) in &a.groups[g] {
                        writers[g].symbol(u, ki)?;
                        let st = &mut stats[g];
                        st.symbols += 1;
                        st.ideal_bits_integer += tables.ideal_bits(ki, u);
                        if u.unsigned_abs() > u64::from(tables.radius(ki)) {
                            st.escapes += 1;
                        }
                    }
                    stats[g].ideal_bits_float += a.float_bits[g];
                    stats[g].max_error_steps = stats[g].max_error_steps.max(a.max_error_steps[g]);
                    stats[g].squared_error += a.squared_error[g];
                }
            }
        }
        for (b, w) in bodies.iter_mut().zip(writers) {
            b.push(w.finish());
        }
    }
    let chunks = bodies.map(|b| {
        let mut c = vec![METHOD_CODED];
        c.extend_from_slice(&join_bodies(&b));
        c
    });
    for (st, c) in stats.iter_mut().zip(&chunks) {
        st.coded_bytes = c.len() as u64;
    }
    Ok(CodedAttributes {
        chunks,
        stats,
        recon,
    })
}
