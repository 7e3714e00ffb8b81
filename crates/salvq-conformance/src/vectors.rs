//! The valid conformance vectors (spec §11.4): each a small stream that exercises some syntax
//! element or option, built from a seeded model so that regenerating gives the same bytes.

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::limits::Limits;
use salvq_bitstream::model::{Dims, Region, SceneModel};
use salvq_bitstream::quantizer::LatticeKind;
use salvq_encoder::writers::surgery;
use salvq_encoder::Result;
use salvq_encoder::{encode_full, EncodeOptions, Encoded};
use salvq_gen::{generate, GenParams};

use super::models::synthetic_model;

/// Sections every valid vector exercises: the container, the model, the hyperprior, the
/// entropy coder, geometry, tiles and the canonical form. Vectors list what they add.
pub const BASE_SECTIONS: &[&str] = &[
    "§0.1", "§0.2", "§0.3", "§0.4", "§0.5", "§1.1", "§1.2", "§1.2.1", "§1.3", "§1.4", "§1.5",
    "§1.6", "§1.6.1", "§1.6.2", "§1.6.3", "§1.6.4", "§1.6.5", "§2.1", "§2.2", "§2.3", "§2.4",
    "§2.5", "§5.1", "§5.2", "§5.3", "§5.4", "§5.5", "§6.1", "§6.2", "§6.2.1", "§6.2.2", "§6.2.3",
    "§6.2.4", "§6.2.5", "§6.2.6", "§6.3", "§6.3.1", "§6.3.2", "§6.3.3", "§6.3.4", "§6.3.5", "§6.6",
    "§6.6.1", "§6.6.2", "§7.1", "§7.3", "§7.4", "§8.1", "§8.2", "§8.3", "§8.4", "§10.1", "§10.2",
    "§10.3", "§11.1", "§11.2", "§11.3", "§11.4", "§11.5",
];

/// A stream a conformant decoder must decode, at each of `rates`, to what the reference
/// decoder outputs; `oracle` holds the encoder's prediction of each of those decodes, which
/// the generator checks the reference decoder against.
pub struct ValidVector {
    pub name: &'static str,
    pub description: &'static str,
    /// Sections beyond [`BASE_SECTIONS`] that this vector exercises.
    pub sections: &'static [&'static str],
    pub stream: Vec<u8>,
    pub rates: Vec<u8>,
    pub oracle: Vec<SceneModel>,
}

fn vector(
    name: &'static str,
    description: &'static str,
    sections: &'static [&'static str],
    encoded: Encoded,
) -> ValidVector {
    let rates = encoded.layers.iter().map(|l| l.rate).collect();
    let oracle = encoded.layers.into_iter().map(|l| l.expected).collect();
    ValidVector {
        name,
        description,
        sections,
        stream: encoded.stream,
        rates,
        oracle,
    }
}

fn small(anchors: u32, seed: u64, feat_basis: bool) -> GenParams {
    GenParams {
        feat_basis,
        ..GenParams::small(anchors, seed)
    }
}

fn options(rates: &[u8]) -> EncodeOptions {
    EncodeOptions {
        rates: rates.to_vec(),
        ..Default::default()
    }
}

/// Every valid vector, in a fixed order.
pub fn valid_vectors() -> Result<Vec<ValidVector>> {
    let usq = generate(&small(40, 11, false));
    let mut out = rate_vectors(&usq)?;
    out.extend(lattice_vectors(&usq)?);
    out.extend(symbol_vectors(&usq)?);
    out.extend(tile_vectors()?);
    out.extend(scene_shape_vectors()?);
    out.extend(max_vectors()?);
    out.extend(precision_vectors(&usq)?);
    out.push(ancillary_vector(&usq)?);
    Ok(out)
}

/// The vectors of one and several rates (§2.6, §7.5): USQ at one rate of two, a learned
/// feature basis at four rates, and rate 2 extracted from those four.
fn rate_vectors(usq: &SceneModel) -> Result<Vec<ValidVector>> {
    let salvq = generate(&GenParams {
        rates: 4,
        ..small(60, 12, true)
    });
    let four = encode_full(&salvq, &options(&[0, 1, 2, 3]))?;
    // §7.5: rate 2 taken out of the four-rate stream, without re-coding.
    let extracted = salvq::extract_rate(&four.stream, 2, &Limits::default())?;
    Ok(vec![
        vector(
            "usq-one-rate",
            "40 anchors, identity lattices (USQ), one rate of two",
            &[],
            encode_full(usq, &options(&[1]))?,
        ),
        ValidVector {
            name: "extract-rate-2",
            description: "rate 2 extracted from salvq-four-rates (salvq extract)",
            sections: &["§2.6", "§7.5"],
            stream: extracted,
            rates: vec![2],
            oracle: vec![four.layers[2].expected.clone()],
        },
        vector(
            "salvq-four-rates",
            "60 anchors, learned feature basis B = U diag(s) V^T, four symbol layers",
            &["§2.6"],
            four,
        ),
    ])
}

/// The vectors of each lattice and basis (§2.6, §7.2, §7.6): D_n, E8 product, FS-SALVQ and
/// Sp-SALVQ.
fn lattice_vectors(usq: &SceneModel) -> Result<Vec<ValidVector>> {
    let dn = EncodeOptions {
        feat_lattice: Some(LatticeKind::Dn),
        ..options(&[0])
    };
    let e8 = generate(&GenParams {
        feat_dim: 16,
        ..small(40, 13, false)
    });
    let e8_options = EncodeOptions {
        feat_lattice: Some(LatticeKind::E8Product),
        ..options(&[0, 1])
    };
    let fs = generate(&GenParams {
        scaling_basis: true,
        view_dims: 4,
        ..small(50, 14, true)
    });
    Ok(vec![
        vector(
            "dn-feature",
            "feature group on the D_8 lattice",
            &["§7.2"],
            encode_full(usq, &dn)?,
        ),
        vector(
            "e8-feature",
            "feature group on E8 x E8 (F = 16), two rates",
            &["§7.2"],
            encode_full(&e8, &e8_options)?,
        ),
        vector(
            "fs-salvq",
            "learned bases for the feature and the scaling group (FS-SALVQ); V = 4 view inputs",
            &["§2.6", "§7.6"],
            encode_full(&fs, &options(&[0, 1]))?,
        ),
        vector(
            "sp-salvq-regions",
            "three feature regions and two scaling regions, each with its own basis (Sp-SALVQ)",
            &["§2.6", "§7.6"],
            encode_full(&with_scaling_regions(&fs), &{
                let mut o = options(&[1]);
                o.fit_basis = true;
                o.feat_regions = 3;
                o
            })?,
        ),
    ])
}

/// The vectors of unusual symbols (§6.3.1, §6.4, §6.6.1): escapes, coarse steps, every mask
/// pattern.
fn symbol_vectors(usq: &SceneModel) -> Result<Vec<ValidVector>> {
    let mut coarse = usq.clone();
    for q in [
        &mut coarse.quant_feat,
        &mut coarse.quant_scaling,
        &mut coarse.quant_offsets,
    ] {
        q.step *= 24.0;
    }
    Ok(vec![
        vector(
            "escapes",
            "features far outside the tables: escapes with prefixes of 1 to 24 bits",
            &["§6.4"],
            encode_full(&with_escapes(usq), &options(&[0]))?,
        ),
        vector(
            "coarse-steps",
            "steps 24 times the model's: predicted deviations of a fraction of a step, the \
             smallest scale indices, mostly zero symbols",
            &["§6.3.1"],
            encode_full(&coarse, &options(&[0, 1]))?,
        ),
        vector(
            "mask-patterns",
            "every one of the 16 offset-mask patterns of K = 4, all-zero and all-one included",
            &["§6.6.1"],
            encode_full(
                &with_all_masks(&generate(&small(48, 15, false))),
                &options(&[0]),
            )?,
        ),
    ])
}

/// The vectors of tiling (§10, §11.7): many tiles, tiles with regions, a tile per anchor.
fn tile_vectors() -> Result<Vec<ValidVector>> {
    // Region decodes (§10.3.1) of this vector are listed by `region_vectors`.
    let regions = generate(&GenParams {
        scaling_basis: true,
        ..small(360, 17, true)
    });
    Ok(vec![
        vector(
            "tiles-many",
            "600 anchors cut into tiles of at most 40 anchors",
            &[],
            encode_full(
                &generate(&small(600, 16, true)),
                &EncodeOptions {
                    tile_anchors: 40,
                    ..options(&[0])
                },
            )?,
        ),
        vector(
            "tiles-regions",
            "360 anchors in tiles of at most 40, three feature and two scaling regions (Sp-SALVQ): \
             region decodes at tile faces, across region boundaries, and of no tile",
            &["§7.6", "§10.3.1", "§11.7"],
            encode_full(&with_scaling_regions(&regions), &{
                let mut o = options(&[0]);
                o.fit_basis = true;
                o.feat_regions = 3;
                o.tile_anchors = 40;
                o
            })?,
        ),
        vector(
            "tiles-one-anchor",
            "a tile per anchor (tile_anchors = 1), cells down to a single voxel",
            &[],
            encode_full(
                &generate(&small(12, 17, false)),
                &EncodeOptions {
                    tile_anchors: 1,
                    ..options(&[0])
                },
            )?,
        ),
    ])
}

/// The vectors of scene shapes (§2.6, §8.4): shared voxels, one anchor, HAC's dimensions,
/// no 2D grid levels.
fn scene_shape_vectors() -> Result<Vec<ValidVector>> {
    Ok(vec![
        vector(
            "shared-voxels",
            "anchors sharing voxels, 1 to 6 per voxel (voxel counts, all count contexts)",
            &[],
            encode_full(
                &with_shared_voxels(&generate(&small(20, 18, false))),
                &options(&[0]),
            )?,
        ),
        vector(
            "one-anchor",
            "a single anchor",
            &[],
            encode_full(&generate(&small(1, 19, false)), &options(&[0]))?,
        ),
        vector(
            "hac-dimensions",
            "HAC's dimensions: F = 50, K = 10, 12 + 3x4 grid levels with dense and hashed levels",
            &["§2.6"],
            encode_full(&generate(&GenParams::new(120, 20)), &options(&[0]))?,
        ),
        vector(
            "no-2d-levels",
            "3D grid levels only (L2 = 0), dense and hashed",
            &[],
            encode_full(
                &generate(&GenParams {
                    res_2d: vec![],
                    res_3d: vec![2, 3, 12],
                    log2_size_3d: 7,
                    ..small(30, 21, false)
                }),
                &options(&[0]),
            )?,
        ),
    ])
}

/// The vectors of the largest dimensions Table 1-4 allows (§2.6, §7.2): for the attributes,
/// the grid and the MLPs.
fn max_vectors() -> Result<Vec<ValidVector>> {
    Ok(vec![
        vector(
            "max-attributes",
            "largest F = 1024 (E8 product), K = 256, S = 64 (basis), M = 64 with rates 0 and 63, \
             V = 8, coord_bits = 21",
            &["§2.6", "§7.2"],
            encode_full(&max_attributes_model(), &options(&[0, 63]))?,
        ),
        vector(
            "max-grid",
            "largest grid: C = 16, L3 = 32, L2 = 32 (context input 2 048), dense and hashed \
             levels; feature on D_2, scaling (S = 8) on E8",
            &["§7.2"],
            encode_full(&max_grid_model(), &options(&[0]))?,
        ),
        vector(
            "max-hidden",
            "largest MLPs: context hidden H = 4 096, Scaffold-GS hidden Hs = 4 096",
            &[],
            encode_full(&max_hidden_model(), &options(&[0]))?,
        ),
    ])
}

/// The largest attributes: F = 1024 (E8 product), K = 256, S = 64 (basis), M = 64, V = 8,
/// coordinates of 21 bits.
fn max_attributes_model() -> SceneModel {
    synthetic_model(
        Dims {
            anchors: 0,
            feat_dim: 1024,
            offsets: 256,
            scaling_dim: 64,
            rates: 64,
            grid_channels: 1,
            res_3d: vec![1],
            res_2d: vec![],
            log2_size_3d: 3,
            log2_size_2d: 1,
            context_hidden: 1,
            scaffold_hidden: 1,
            view_dims: 8,
            feat_lattice: LatticeKind::E8Product,
            scaling_lattice: LatticeKind::General,
            feat_regions: 1,
            scaling_regions: 1,
        },
        vec![[0, 0, 0], [(1 << 21) - 1, 5, (1 << 21) - 1]],
        22,
    )
}

/// The largest grid: C = 16, L3 = 32, L2 = 32; feature on D_2, scaling (S = 8) on E8.
fn max_grid_model() -> SceneModel {
    synthetic_model(
        Dims {
            anchors: 0,
            feat_dim: 2,
            offsets: 1,
            scaling_dim: 8,
            rates: 1,
            grid_channels: 16,
            res_3d: (0..32).map(|l| 1 + l % 4).collect(),
            res_2d: (0..32).map(|l| 1 + l % 8).collect(),
            log2_size_3d: 4,
            log2_size_2d: 4,
            context_hidden: 1,
            scaffold_hidden: 1,
            view_dims: 0,
            feat_lattice: LatticeKind::Dn,
            scaling_lattice: LatticeKind::E8Product,
            feat_regions: 1,
            scaling_regions: 1,
        },
        vec![[1, 2, 3], [7, 0, 4], [0, 6, 6]],
        23,
    )
}

/// The largest MLPs: context hidden H = 4 096, Scaffold-GS hidden Hs = 4 096.
fn max_hidden_model() -> SceneModel {
    synthetic_model(
        Dims {
            anchors: 0,
            feat_dim: 1,
            offsets: 1,
            scaling_dim: 1,
            rates: 1,
            grid_channels: 1,
            res_3d: vec![3],
            res_2d: vec![],
            log2_size_3d: 8,
            log2_size_2d: 1,
            context_hidden: 4096,
            scaffold_hidden: 4096,
            view_dims: 0,
            feat_lattice: LatticeKind::Identity,
            scaling_lattice: LatticeKind::Identity,
            feat_regions: 1,
            scaling_regions: 1,
        },
        vec![[0, 1, 0], [1, 1, 1]],
        24,
    )
}

/// The vectors of stored precisions (§1.6.2, §5.3, §5.4): Scaffold-GS MLPs in binary16, the
/// context MLP in i16, unit exponents up to 68.
fn precision_vectors(usq: &SceneModel) -> Result<Vec<ValidVector>> {
    Ok(vec![
        vector(
            "scaffold-f16",
            "Scaffold-GS MLPs stored in binary16 (scaffold_precision 1)",
            &["§1.6.2"],
            encode_full(
                usq,
                &EncodeOptions {
                    scaffold_precision: Some(
                        salvq_bitstream::container::payload::ScaffoldPrecision::F16,
                    ),
                    ..options(&[0])
                },
            )?,
        ),
        vector(
            "context-i16",
            "the context MLP's weights stored as i16 (context_precision 0; the reference encoder \
             stores them as i8 when that is smaller, Annex A.5.4)",
            &["§1.6.2", "§5.3"],
            encode_full(
                usq,
                &EncodeOptions {
                    context_precision: Some(
                        salvq_bitstream::container::payload::ContextPrecision::I16,
                    ),
                    ..options(&[0])
                },
            )?,
        ),
        vector(
            "extreme-exponents",
            "tiny context-MLP weights: unit exponents E up to 8 + 30 + 30 on the step-adjustment \
             outputs, where a 64-bit rounding shift would overflow",
            &["§5.3", "§5.4"],
            encode_full(&with_tiny_context_weights(usq), &options(&[0]))?,
        ),
    ])
}

/// The vector of ancillary chunks to skip (§1.7): `encd`, `ests` and unknown ones.
fn ancillary_vector(usq: &SceneModel) -> Result<ValidVector> {
    let base = encode_full(
        usq,
        &EncodeOptions {
            encoder_note: Some("salvq conformance".into()),
            statistics: true,
            ..options(&[0, 1])
        },
    )?;
    let stream = with_unknown_ancillary(&base.stream);
    Ok(ValidVector {
        name: "ancillary-chunks",
        description: "encd and ests chunks, and unknown ancillary chunks after HEAD and before \
                      SEND, all skipped",
        sections: &["§1.7"],
        stream,
        rates: base.layers.iter().map(|l| l.rate).collect(),
        oracle: base.layers.into_iter().map(|l| l.expected).collect(),
    })
}

/// The model with its scaling group split into two regions (§7.6), the second with the first
/// region's basis turned by a permutation of U's rows (still orthogonal).
fn with_scaling_regions(m: &SceneModel) -> SceneModel {
    let mut m = m.clone();
    if let Some(b) = m.quant_scaling.basis.clone() {
        let s = usize::from(m.dims.scaling_dim);
        let mut turned = b;
        let rows: Vec<f32> = turned.u.clone();
        for r in 0..s {
            let from = (r + 1) % s;
            turned.u[r * s..(r + 1) * s].copy_from_slice(&rows[from * s..(from + 1) * s]);
        }
        m.quant_scaling.regions = vec![Region {
            start: m.dims.anchors / 2,
            basis: turned,
        }];
        m.dims.scaling_regions = 2;
    }
    m
}

/// The context MLP's layer 0 scaled by 2^−26, its step-adjustment rows by 2^−30 and its output
/// biases zeroed, so the encoder's fixed-point form takes the largest fractional bits §5.3
/// allows.
fn with_tiny_context_weights(m: &SceneModel) -> SceneModel {
    let mut m = m.clone();
    let g = &mut m.mlp_grid;
    for w in g.w0.iter_mut().chain(g.b0.iter_mut()) {
        *w *= (-26f32).exp2();
    }
    let hidden = g.b0.len();
    let cout = g.b1.len();
    for o in cout.saturating_sub(3)..cout {
        for w in &mut g.w1[o * hidden..(o + 1) * hidden] {
            *w *= (-30f32).exp2();
        }
    }
    // Biases are in units of 2^−E_o: with E_o ≥ 38 only tiny ones fit i32.
    g.b1.fill(0.0);
    m
}

/// Feature values far from any mean, so their symbols escape (§6.4) with prefixes of many
/// lengths.
fn with_escapes(m: &SceneModel) -> SceneModel {
    let mut m = m.clone();
    let f = usize::from(m.dims.feat_dim);
    let step = m.quant_feat.step;
    for (i, x) in m
        .anchors
        .feat
        .iter_mut()
        .step_by(f + 1)
        .take(24)
        .enumerate()
    {
        let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
        *x = sign * step * (1u32 << i) as f32 * 3.0;
    }
    m
}

/// Masks cycling through every pattern of the first four offsets.
fn with_all_masks(m: &SceneModel) -> SceneModel {
    let mut m = m.clone();
    let k = usize::from(m.dims.offsets);
    for (i, row) in m.anchors.mask.chunks_mut(k).enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = u8::from(j < 4 && (i % 16) >> j & 1 == 1);
        }
    }
    m
}

/// Anchor `i` repeated `1 + i % 6` times with perturbed attributes: several anchors per voxel.
fn with_shared_voxels(m: &SceneModel) -> SceneModel {
    let mut out = m.clone();
    let a = &m.anchors;
    let (f, s, k) = (
        usize::from(m.dims.feat_dim),
        usize::from(m.dims.scaling_dim),
        usize::from(m.dims.offsets),
    );
    let b = &mut out.anchors;
    (b.voxel, b.mask, b.feat, b.scaling, b.offsets) = (vec![], vec![], vec![], vec![], vec![]);
    for i in 0..m.n() {
        for copy in 0..=i % 6 {
            let nudge = 1.0 + 0.05 * copy as f32;
            b.voxel.push(a.voxel[i]);
            b.mask.extend_from_slice(&a.mask[i * k..(i + 1) * k]);
            b.feat
                .extend(a.feat[i * f..(i + 1) * f].iter().map(|x| x * nudge));
            b.scaling.extend_from_slice(&a.scaling[i * s..(i + 1) * s]);
            b.offsets.extend(
                a.offsets[i * 3 * k..(i + 1) * 3 * k]
                    .iter()
                    .map(|x| x * nudge),
            );
        }
    }
    out.dims.anchors = b.voxel.len() as u32;
    out
}

/// The stream with unknown ancillary chunks (§1.5: skipped) after `HEAD` and before `SEND`.
fn with_unknown_ancillary(stream: &[u8]) -> Vec<u8> {
    let Ok(mut chunks) = surgery::chunks(stream) else {
        return stream.to_vec();
    };
    chunks.insert(1, (ChunkTag(*b"zZz9"), b"skip me".to_vec()));
    let send = chunks.len() - 1;
    chunks.insert(send, (ChunkTag(*b"qual"), vec![0u8; 5]));
    surgery::assemble(stream, &chunks)
}
