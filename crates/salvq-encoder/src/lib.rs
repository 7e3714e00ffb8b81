//! The encoder: validates a model, puts its anchors in canonical order, converts the context
//! MLP to fixed point, quantizes and entropy-codes the anchor attributes, and writes the
//! chunks in the order of spec Table 1-3. Encoding choices never change what a decoder must do.

#![warn(missing_docs)]

pub mod attributes;
pub mod auto;
pub mod context_precision;
pub mod convert;
pub mod entropy_analysis;
pub mod error;
pub mod explicit;
pub mod fit;
pub mod float_grid;
pub mod float_prior;
pub mod info;

pub mod lattice;
pub mod parsimony;
pub mod precision;
pub mod search;
pub mod writers;

use serde::{Deserialize, Serialize};

use salvq_bitstream::container::chunk::{write_chunk, ChunkTag};
use salvq_bitstream::container::payload::{ContextPrecision, ScaffoldPrecision};
use salvq_bitstream::container::preflight::Preflight;
use salvq_bitstream::container::signature::Signature;
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::error::Field;
use salvq_bitstream::hyperprior::prior::Prior;
use salvq_bitstream::hyperprior::{GridLayout, IntMlp};
use salvq_bitstream::model::validate::{check_lattices, validate_model};
use salvq_bitstream::model::{decoded_bytes, names, LatticeKind, SceneModel};
use salvq_bitstream::quantizer::GroupLattices;
use salvq_bitstream::tiles::TileTable;

pub use attributes::GroupStats;
pub use error::{Error, Result};
pub use search::{GroupSearch, GroupSearches, Search};

/// Options that change what the encoder writes.
#[derive(Debug, Clone, Default)]
pub struct EncodeOptions {
    /// Text for an `encd` ancillary chunk (§1.7); `None` writes no such chunk.
    pub encoder_note: Option<String>,
    /// The rates (indices into the gains) whose symbol layers the stream carries (§7.4), in
    /// any order; empty means rate 0 alone.
    pub rates: Vec<u8>,
    /// Write an `ests` ancillary chunk with the encoder's statistics after each layer (§1.7).
    pub statistics: bool,
    /// Code the feature group with this lattice instead of the model's (`--quantizer`):
    /// the identity, D_n, an E8 product, or the model's general basis.
    pub feat_lattice: Option<LatticeKind>,
    /// How the encoder picks lattice points (§7.3 leaves it free).
    pub search: Search,
    /// Anchors per tile (§10); 0: the reference's automatic tiles
    /// ([`crate::writers::tile_cut::cut_auto`]).
    pub tile_anchors: u32,
    /// Replace the feature group's lattice by a basis fitted to the anchors (the KLT,
    /// [`fit::fit_klt_basis`]); `feat_lattice` must then be `None` or the general kind.
    pub fit_basis: bool,
    /// With `fit_basis`: fit one basis per spatial region, this many regions of equal
    /// anchor count in Morton order (Sp-SALVQ, spec §7.6); 0 or 1: one basis.
    pub feat_regions: u16,
    /// Refit the context MLP's feature-scale rows to the coordinates of the lattice the
    /// features are coded with ([`fit::fit_feature_scales`]).
    pub fit_scales: bool,
    /// How to store the Scaffold-GS MLPs (§1.6.2); `None`: binary16 where its renders match
    /// binary32's within 8-bit rounding, or, for a model that does not render neurally, its
    /// outputs within tolerance ([`precision::choose`], Annex A.5.2).
    pub scaffold_precision: Option<salvq_bitstream::container::payload::ScaffoldPrecision>,
    /// How to store the context MLP's weights (§1.6.2 Table 1-7); `None`: i8 when the
    /// measured symbol cost is below the model bytes saved ([`context_precision::choose`],
    /// Annex A.5.4).
    pub context_precision: Option<salvq_bitstream::container::payload::ContextPrecision>,
}

/// What the encoder measured for one layer (written to `ests` when asked; `salvq info`
/// shows it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EncodeReport {
    /// Anchors coded.
    pub anchors: u64,
    /// The rate.
    pub rate: u8,
    /// What each attribute group cost.
    pub groups: Vec<GroupStats>,
    /// Ideal bits of the offset masks.
    pub mask_bits: u64,
    /// Bytes of `AMSK`.
    pub mask_bytes: u64,
    /// Touched / total hash-grid entries (§5.2).
    pub grid_entries_stored: u64,
    /// Hash-grid entries in all.
    pub grid_entries_total: u64,
}

/// Mean squared difference of two value lists (binary64; 0 for empty lists): the distortion
/// the encoder's choices hold (Annex A.5.1–A.5.4).
pub fn values_mse(x: &[f32], y: &[f32]) -> f64 {
    x.iter()
        .zip(y)
        .map(|(p, q)| (f64::from(*p) - f64::from(*q)).powi(2))
        .sum::<f64>()
        / x.len().max(1) as f64
}

/// Encodes a model with default options.
pub fn encode(model: &SceneModel) -> Result<Vec<u8>> {
    encode_with_options(model, &EncodeOptions::default())
}

/// Encodes a model. Fails, writing nothing, if the model breaks any rule of spec §2.
pub fn encode_with_options(model: &SceneModel, options: &EncodeOptions) -> Result<Vec<u8>> {
    encode_with_report(model, options).map(|(s, _)| s)
}

/// Encodes a model and reports what each part cost.
pub fn encode_with_report(
    model: &SceneModel,
    options: &EncodeOptions,
) -> Result<(Vec<u8>, EncodeReport)> {
    encode_full(model, options).map(|mut e| (e.stream, e.layers.swap_remove(0).report))
}

/// One symbol layer as the encoder produced it.
#[derive(Debug)]
pub struct EncodedLayer {
    /// The layer's rate.
    pub rate: u8,
    /// What the encoder measured.
    pub report: EncodeReport,
    /// The model a conformant decoder must output for this rate, bit for bit.
    pub expected: SceneModel,
}

/// Everything the encoder produces: the stream and, per layer in stream order (rates
/// ascending), its report and the decoded model a conformant decoder must output, which
/// tests use as their oracle.
#[derive(Debug)]
pub struct Encoded {
    /// The stream.
    pub stream: Vec<u8>,
    /// Its layers, rates ascending.
    pub layers: Vec<EncodedLayer>,
    /// How the Scaffold-GS MLPs were stored, and why (Annex A.5.2).
    pub scaffold: precision::PrecisionChoice,
    /// How the context MLP's weights were stored, and why (Annex A.5.4).
    pub context: context_precision::ContextChoice,
}

impl Encoded {
    /// The report of the first layer (the lowest rate).
    pub fn report(&self) -> &EncodeReport {
        &self.layers[0].report
    }

    /// The expected decoded model of the first layer (what `decode` returns by default).
    pub fn expected(&self) -> &SceneModel {
        &self.layers[0].expected
    }
}

/// The lattice each of the feature and scaling groups is coded with, and the model with
/// the quantizers changed accordingly (an E8 or D_n asked for by the options replaces the
/// model's basis; a fitted basis replaces the lattice; fitted scale rows replace the
/// context MLP's, Annex A.5).
fn choose_lattices(model: &SceneModel, options: &EncodeOptions) -> Result<SceneModel> {
    let mut m = model.clone();
    if options.fit_basis {
        if !matches!(options.feat_lattice, None | Some(LatticeKind::General)) {
            return Err(Error::FitFailed {
                tensor: names::QUANT_FEAT[2],
                reason: "a fitted basis is a general lattice; another lattice was asked for".into(),
            });
        }
        let (basis, regions) = fit::fit_klt_regions(model, options.feat_regions.max(1))?;
        m.dims.feat_regions = (regions.len() + 1) as u16;
        m.quant_feat.basis = Some(basis);
        m.quant_feat.regions = regions;
        m.dims.feat_lattice = LatticeKind::General;
    } else if let Some(kind) = options.feat_lattice {
        if kind == LatticeKind::General && model.quant_feat.basis.is_none() {
            return Err(salvq::Error::TensorMissing {
                tensor: names::QUANT_FEAT[2],
            }
            .into());
        }
        m.dims.feat_lattice = kind;
        if kind != LatticeKind::General {
            m.quant_feat.basis = None;
            m.quant_feat.regions.clear();
            m.dims.feat_regions = 1;
        }
    }
    check_lattices(&m.dims)?;
    if options.fit_scales {
        let d = &m.dims;
        let lattices = GroupLattices::new(d.feat_lattice, usize::from(d.feat_dim), &m.quant_feat);
        fit::fit_feature_scales(&mut m, &lattices)?;
    }
    Ok(m)
}

/// Encodes a model, returning the stream and, per layer, the report and expected model.
pub fn encode_full(model: &SceneModel, options: &EncodeOptions) -> Result<Encoded> {
    validate_model(model)?;
    let rates = coded_rates(options, model.dims.rates)?;
    // Canonical order first: regions (§7.6) and the fits are defined on it.
    let canonical;
    let model = if model.is_canonical() {
        model
    } else {
        canonical = model.to_canonical_order();
        &canonical
    };
    let chosen;
    let m = if options.feat_lattice.is_some() || options.fit_basis || options.fit_scales {
        chosen = choose_lattices(model, options)?;
        &chosen
    } else {
        model
    };
    // Annex A.5.4: the context MLP's weight storage, with the base steps that hold the
    // distortion when it is i8.
    let context = context_precision::choose(m, options, options.context_precision)?;
    let stepped = context.apply(m);
    let m: &SceneModel = &stepped;
    // Annex A.5.2: the Scaffold-GS MLPs' storage.
    let scaffold = precision::choose(m, options.scaffold_precision);
    let shared = SharedParts::new(m, options, context.precision)?;
    let mut out = Vec::with_capacity(1 << 20);
    let rate_mask = rates.iter().fold(0u64, |a, &r| a | 1 << r);
    write_shared_chunks(&mut out, m, options, &shared, rate_mask, scaffold.precision)?;
    let decoded = shared.decoded_model(m, scaffold.precision);
    // §7.4: one symbol layer per rate, rates ascending, each with its own `ests`.
    let mut layers = Vec::with_capacity(rates.len());
    for &rate in &rates {
        layers.push(encode_symbol_layer(
            &mut out, m, options, &shared, &decoded, rate,
        )?);
    }
    write_chunk(&mut out, ChunkTag::SEND, &[]);
    Ok(Encoded {
        stream: out,
        layers,
        scaffold,
        context,
    })
}

/// The rates the options ask for (rate 0 when none), ascending without repeats; fails on a
/// rate the model's `rates` gains do not have.
fn coded_rates(options: &EncodeOptions, model_rates: u8) -> Result<Vec<u8>> {
    let mut rates = if options.rates.is_empty() {
        vec![0]
    } else {
        options.rates.clone()
    };
    rates.sort_unstable();
    rates.dedup();
    if let Some(&r) = rates.iter().find(|&&r| r >= model_rates) {
        return Err(salvq::Error::FieldOutOfRange {
            field: Field::CodedRate,
            value: r.into(),
            min: 0,
            max: u64::from(model_rates) - 1,
        }
        .into());
    }
    Ok(rates)
}

/// What every symbol layer of a stream shares: the integer context MLP (§5), the grid
/// entries the anchors touch (§5.2), each group's lattice search (§7.2), the anchor tiles
/// (§10) and the coded offset masks.
struct SharedParts {
    /// Bits per anchor voxel coordinate.
    coord_bits: u8,
    /// How the context MLP's weights are stored.
    context_precision: ContextPrecision,
    /// The context MLP in fixed point, converted from the model's float one.
    int_mlp: IntMlp,
    /// Per grid (3D, xy, xz, yz), whether an anchor touches each entry.
    touched: [Vec<bool>; 4],
    /// The grid entries stored: those some anchor touches.
    grid_entries_stored: u64,
    /// The feature and scaling groups' lattice searches.
    searches: [GroupSearches; 2],
    /// Tiles of consecutive canonical anchors.
    tiles: TileTable,
    /// The `AMSK` payload.
    amsk: Vec<u8>,
}

impl SharedParts {
    /// The shared parts of `m` (anchors in canonical order) under `options`, its context MLP
    /// stored at `context_precision`.
    fn new(
        m: &SceneModel,
        options: &EncodeOptions,
        context_precision: ContextPrecision,
    ) -> Result<SharedParts> {
        let d = &m.dims;
        let coord_bits = m.coord_bits();
        // §5: the integer prior, converted from the model's float context MLP.
        let layout = GridLayout::new(d, coord_bits);
        let x = convert::grid_inputs(m, &layout);
        let int_mlp = convert::convert_context_mlp_for(
            &m.mlp_grid,
            layout.features(),
            &x,
            context_precision,
        )?;
        drop(x);
        let touched = layout.touched(&m.anchors.voxel, d.entries_3d(), d.entries_2d());
        // §7.2: each group's lattice, and the encoder's search for it.
        let searches = [
            (
                d.feat_lattice,
                usize::from(d.feat_dim),
                &m.quant_feat,
                names::QUANT_FEAT[0],
            ),
            (
                d.scaling_lattice,
                usize::from(d.scaling_dim),
                &m.quant_scaling,
                names::QUANT_SCALING[0],
            ),
        ]
        .map(|(kind, dim, q, tensor)| {
            GroupSearches::new(&GroupLattices::new(kind, dim, q), options.search, tensor)
        });
        let [fs, ss] = searches;
        let searches = [fs?, ss?];
        // §10: tiles of consecutive canonical anchors.
        let tiles = match options.tile_anchors {
            0 => crate::writers::cut_auto(&m.anchors.voxel),
            per => crate::writers::cut(&m.anchors.voxel, per),
        };
        let amsk = attributes::code_masks(m, GaussianTables::standard(), &tiles);
        let grid_entries_stored = touched
            .iter()
            .map(|t| t.iter().filter(|&&u| u).count() as u64)
            .sum();
        Ok(SharedParts {
            coord_bits,
            context_precision,
            int_mlp,
            touched,
            grid_entries_stored,
            searches,
            tiles,
            amsk,
        })
    }

    /// The decoded model's shared parts: the integer MLP's values, +1 at untouched grid
    /// entries (§5.2), and the Scaffold-GS MLPs as stored at `scaffold`.
    fn decoded_model(&self, m: &SceneModel, scaffold: ScaffoldPrecision) -> SceneModel {
        let c = usize::from(m.dims.grid_channels);
        let touched = &self.touched;
        let keep = |t: &[i8], used: &[bool]| -> Vec<i8> {
            t.iter()
                .enumerate()
                .map(|(i, &v)| if used[i / c] { v } else { 1 })
                .collect()
        };
        SceneModel {
            grid: salvq_bitstream::model::HashGrid {
                grid_3d: keep(&m.grid.grid_3d, &touched[0]),
                grid_xy: keep(&m.grid.grid_xy, &touched[1]),
                grid_xz: keep(&m.grid.grid_xz, &touched[2]),
                grid_yz: keep(&m.grid.grid_yz, &touched[3]),
            },
            mlp_grid: self.int_mlp.to_float(),
            mlp_opacity: precision::rounded(&m.mlp_opacity, scaffold),
            mlp_cov: precision::rounded(&m.mlp_cov, scaffold),
            mlp_color: precision::rounded(&m.mlp_color, scaffold),
            ..m.clone()
        }
    }
}

/// Writes the signature and the chunks before the first symbol layer (Table 1-3): `HEAD`
/// (with `rate_mask`), `ENCD` when the options carry a note, `MLPS`, `QUAN`, `TILS`,
/// `APOS`, `GRID`, `AMSK`.
fn write_shared_chunks(
    out: &mut Vec<u8>,
    m: &SceneModel,
    options: &EncodeOptions,
    shared: &SharedParts,
    rate_mask: u64,
    scaffold: ScaffoldPrecision,
) -> Result<()> {
    let d = &m.dims;
    let tables = GaussianTables::standard();
    let head = Preflight {
        dims: d.clone(),
        coord_bits: shared.coord_bits,
        origin: m.origin,
        voxel_size: m.voxel_size,
        decoded_bytes: decoded_bytes(d),
        rate_mask,
    };
    out.extend_from_slice(&Signature::current().to_bytes());
    write_chunk(out, ChunkTag::HEAD, &head.to_payload());
    if let Some(note) = &options.encoder_note {
        write_chunk(out, ChunkTag::ENCD, note.as_bytes());
    }
    let mlps = crate::writers::write_mlps(&shared.int_mlp, shared.context_precision, m, scaffold);
    write_chunk(out, ChunkTag::MLPS, &mlps);
    write_chunk(out, ChunkTag::QUAN, &crate::writers::write_quan(m));
    write_chunk(out, ChunkTag::TILS, &shared.tiles.to_payload());
    write_chunk(
        out,
        ChunkTag::APOS,
        &crate::writers::write_apos(&m.anchors, &shared.tiles, tables)?,
    );
    write_chunk(
        out,
        ChunkTag::GRID,
        &crate::writers::write_grid(&m.grid, &shared.touched, usize::from(d.grid_channels)),
    );
    write_chunk(out, ChunkTag::AMSK, &shared.amsk);
    Ok(())
}

/// Codes the symbol layer of `rate` (§7.4) onto `out`: `AFEA`, `ASCL`, `AOFF` and, when
/// the options ask, its `ests`. Returns its report and the model it decodes to, `decoded`
/// with the layer's anchor attributes.
fn encode_symbol_layer(
    out: &mut Vec<u8>,
    m: &SceneModel,
    options: &EncodeOptions,
    shared: &SharedParts,
    decoded: &SceneModel,
    rate: u8,
) -> Result<EncodedLayer> {
    let d = &m.dims;
    let r = usize::from(rate);
    let quant = [&m.quant_feat, &m.quant_scaling, &m.quant_offsets];
    let prior = Prior::new(d, shared.coord_bits, shared.int_mlp.clone(), quant, r);
    let float = float_prior::FloatPrior::new(m, shared.coord_bits, r);
    let tables = GaussianTables::standard();
    let coded =
        attributes::code_attributes(m, &prior, &float, &shared.searches, tables, &shared.tiles)?;
    let report = EncodeReport {
        anchors: d.anchors.into(),
        rate,
        groups: coded.stats.to_vec(),
        mask_bits: m.anchors.mask.len() as u64,
        mask_bytes: shared.amsk.len() as u64,
        grid_entries_stored: shared.grid_entries_stored,
        grid_entries_total: d.entries_3d() + 3 * d.entries_2d(),
    };
    let [afea, ascl, aoff] = &coded.chunks;
    write_chunk(out, ChunkTag::AFEA, afea);
    write_chunk(out, ChunkTag::ASCL, ascl);
    write_chunk(out, ChunkTag::AOFF, aoff);
    if options.statistics {
        let json = serde_json::to_vec(&report).unwrap_or_default();
        write_chunk(out, ChunkTag::ESTS, &json);
    }
    let [feat, scaling, offsets] = coded.recon;
    let expected = SceneModel {
        anchors: salvq_bitstream::model::Anchors {
            voxel: m.anchors.voxel.clone(),
            mask: m.anchors.mask.clone(),
            feat,
            scaling,
            offsets,
        },
        ..decoded.clone()
    };
    Ok(EncodedLayer {
        rate,
        report,
        expected,
    })
}
