//! Model interchange (spec Annex A): one safetensors file holding the tensors of Table 2-1.
//!
//! Reading infers the dimensions from a few tensors' shapes (Annex A.2), then checks every
//! tensor's presence, dtype and shape against the table, then every value (§2.3, §2.6).
//! Writing is done here rather than by the `safetensors` crate so that the header's key
//! order, and with it the file's bytes, are fixed: the same model always gives the same file.

use std::io::Write;
use std::path::Path;

use safetensors::tensor::TensorView;
use safetensors::SafeTensors;

use crate::error::{Error, Result};
use salvq_bitstream::error::Field;
use salvq_bitstream::model::validate::{check_field, validate_model, MAX_COORD_BITS};
use salvq_bitstream::model::{
    names, tensor_table, Anchors, Basis, Dims, Dtype, GroupQuantizer, HashGrid, LatticeKind, Mlp,
    Region, SceneModel, TensorEntry,
};

/// Schema version written in the file's `__metadata__` (Annex A.1).
pub const SCHEMA_VERSION: &str = "0.2";

/// Metadata keys naming the lattice of the feature and scaling groups (Annex A.1, §7.1).
pub const META_FEAT_LATTICE: &str = "feat_lattice";
/// Metadata key of the scaling group's lattice.
pub const META_SCALING_LATTICE: &str = "scaling_lattice";

fn st_dtype(d: Dtype) -> safetensors::Dtype {
    match d {
        Dtype::F32 => safetensors::Dtype::F32,
        Dtype::I32 => safetensors::Dtype::I32,
        Dtype::U8 => safetensors::Dtype::U8,
        Dtype::I8 => safetensors::Dtype::I8,
    }
}

struct Reader<'a> {
    st: SafeTensors<'a>,
    /// The `__metadata__` lattice names (Annex A.1), when given.
    lattices: [Option<String>; 2],
}

impl<'a> Reader<'a> {
    fn get(&self, name: &'static str, dtype: Dtype) -> Result<TensorView<'a>> {
        let view = self
            .st
            .tensor(name)
            .map_err(|_| salvq::Error::TensorMissing { tensor: name })?;
        if view.dtype() != st_dtype(dtype) {
            return Err(salvq::Error::TensorDtype {
                tensor: name,
                expected: dtype,
                found: format!("{:?}", view.dtype()),
            }
            .into());
        }
        Ok(view)
    }

    /// The shape of a tensor that must have `rank` dimensions.
    fn shape(&self, name: &'static str, dtype: Dtype, rank: u8) -> Result<Vec<u64>> {
        let view = self.get(name, dtype)?;
        let shape: Vec<u64> = view.shape().iter().map(|&d| d as u64).collect();
        if shape.len() != usize::from(rank) {
            return Err(salvq::Error::TensorRank {
                tensor: name,
                expected: rank,
                found: shape.len().min(255) as u8,
            }
            .into());
        }
        Ok(shape)
    }

    /// Data of a table entry after its dtype and exact shape are checked.
    fn data(&self, e: &TensorEntry) -> Result<&'a [u8]> {
        let view = self.get(e.name, e.dtype)?;
        let found: Vec<u64> = view.shape().iter().map(|&d| d as u64).collect();
        if found != e.shape {
            return Err(salvq::Error::TensorShape {
                tensor: e.name,
                expected: e.shape.clone(),
                found,
            }
            .into());
        }
        Ok(view.data())
    }

    fn i32s(&self, name: &'static str) -> Result<Vec<i32>> {
        self.shape(name, Dtype::I32, 1)?;
        Ok(i32s(self.get(name, Dtype::I32)?.data()))
    }
}

fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn i32s(b: &[u8]) -> Vec<i32> {
    b.chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Reads an I32 configuration tensor's values as fields (Annex A.2), checking their range.
fn fields(r: &Reader<'_>, name: &'static str, field: Field) -> Result<Vec<u64>> {
    let values = r.i32s(name)?;
    let mut out = Vec::with_capacity(values.len());
    for (i, &v) in values.iter().enumerate() {
        let (min, max) = salvq_bitstream::model::validate::field_range(field);
        if v < 0 {
            return Err(salvq::Error::ValueInvalid {
                tensor: name,
                index: vec![i as u64],
                value: v.into(),
                allowed: if min == 1 && max == u64::from(u16::MAX) {
                    "1..=65535"
                } else {
                    "1..=24"
                },
            }
            .into());
        }
        out.push(check_field(field, v as u64)?);
    }
    Ok(out)
}

fn log2_field(field: Field, v: i32) -> Result<u8> {
    if v < 0 {
        return Err(salvq::Error::ValueInvalid {
            tensor: names::LOG2_SIZE,
            index: vec![u64::from(field == Field::Log2Size2d)],
            value: v.into(),
            allowed: "1..=24",
        }
        .into());
    }
    Ok(check_field(field, v as u64)? as u8)
}

/// Annex A.2: the dimensions, from the shapes of a few tensors.
fn infer_dims(r: &Reader<'_>) -> Result<Dims> {
    let feat = r.shape(names::FEAT, Dtype::F32, 2)?;
    let mask = r.shape(names::MASK, Dtype::U8, 2)?;
    let scaling = r.shape(names::SCALING, Dtype::F32, 2)?;
    let gains = r.shape(names::QUANT_FEAT[1], Dtype::F32, 1)?;
    let grid = r.shape(names::GRID_3D, Dtype::I8, 2)?;
    let ctx = r.shape(names::MLP_GRID[0], Dtype::F32, 2)?;
    let opa = r.shape(names::MLP_OPACITY[0], Dtype::F32, 2)?;
    let res = |name, f| -> Result<Vec<u16>> {
        Ok(fields(r, name, f)?.into_iter().map(|v| v as u16).collect())
    };
    let res_3d = res(names::RES_3D, Field::Resolution3d)?;
    let res_2d = res(names::RES_2D, Field::Resolution2d)?;
    let log2 = r.i32s(names::LOG2_SIZE)?;
    let [log2_3d, log2_2d] = log2[..] else {
        return Err(salvq::Error::TensorShape {
            tensor: names::LOG2_SIZE,
            expected: vec![2],
            found: vec![log2.len() as u64],
        }
        .into());
    };
    let feat_dim = check_field(Field::FeatDim, feat[1])?;
    let view_dims = opa[1]
        .checked_sub(feat_dim)
        .ok_or(salvq::Error::TensorShape {
            tensor: names::MLP_OPACITY[0],
            expected: vec![opa[0], feat_dim],
            found: opa.clone(),
        })?;
    // Annex A.1: a lattice named in the metadata, else a general basis exactly when its
    // factor tensors are present.
    let lattice = |named: &Option<String>, names: &[&'static str; 5]| -> Result<LatticeKind> {
        match named {
            Some(name) => LatticeKind::from_name(name).ok_or(Error::InterchangeFormat {
                detail: format!(
                    "metadata names an unknown lattice '{name}' (identity, dn, e8 or basis)"
                ),
            }),
            None if names[2..].iter().any(|n| r.st.tensor(n).is_ok()) => Ok(LatticeKind::General),
            None => Ok(LatticeKind::Identity),
        }
    };
    // §7.6: R − 1 regions after the first, from the shape of their start tensor.
    let regions = |name: &'static str, field: Field| -> Result<u16> {
        if r.st.tensor(name).is_err() {
            return Ok(1);
        }
        let shape = r.shape(name, Dtype::I32, 1)?;
        Ok(check_field(field, shape[0].saturating_add(1))? as u16)
    };
    let feat_regions = regions(names::QUANT_FEAT_REGIONS[0], Field::FeatRegions)?;
    let scaling_regions = regions(names::QUANT_SCALING_REGIONS[0], Field::ScalingRegions)?;
    let [feat_named, scaling_named] = &r.lattices;
    Ok(Dims {
        anchors: check_field(Field::AnchorCount, feat[0])? as u32,
        feat_dim: feat_dim as u16,
        offsets: check_field(Field::OffsetCount, mask[1])? as u16,
        scaling_dim: check_field(Field::ScalingDim, scaling[1])? as u16,
        rates: check_field(Field::RateCount, gains[0])? as u8,
        grid_channels: check_field(Field::GridChannels, grid[1])? as u8,
        res_3d,
        res_2d,
        log2_size_3d: log2_field(Field::Log2Size3d, log2_3d)?,
        log2_size_2d: log2_field(Field::Log2Size2d, log2_2d)?,
        context_hidden: check_field(Field::ContextHidden, ctx[0])? as u16,
        scaffold_hidden: check_field(Field::ScaffoldHidden, opa[0])? as u16,
        view_dims: check_field(Field::ViewDims, view_dims)? as u8,
        feat_lattice: lattice(feat_named, &names::QUANT_FEAT)?,
        scaling_lattice: lattice(scaling_named, &names::QUANT_SCALING)?,
        feat_regions,
        scaling_regions,
    })
}

/// Reads and validates a model from safetensors bytes (Annex A).
pub fn model_from_safetensors(bytes: &[u8]) -> Result<SceneModel> {
    let st = SafeTensors::deserialize(bytes).map_err(|e| Error::InterchangeFormat {
        detail: e.to_string(),
    })?;
    let lattices = SafeTensors::read_metadata(bytes)
        .ok()
        .and_then(|(_, meta)| meta.metadata().clone())
        .map(|m| [META_FEAT_LATTICE, META_SCALING_LATTICE].map(|k| m.get(k).cloned()))
        .unwrap_or_default();
    let r = Reader { st, lattices };
    let dims = infer_dims(&r)?;
    salvq_bitstream::model::validate::check_dims(&dims)?;
    let t = Tensors::read(&r, &dims)?;
    let origin = f32s(t.get(names::ORIGIN));
    let voxel = anchor_voxels(&i32s(t.get(names::VOXEL)), dims.anchors as usize)?;
    let i8s = |name: &str| t.get(name).iter().map(|&b| b as i8).collect::<Vec<i8>>();
    let model = SceneModel {
        origin: [origin[0], origin[1], origin[2]],
        voxel_size: f32s(t.get(names::VOXEL_SIZE))
            .first()
            .copied()
            .unwrap_or(f32::NAN),
        anchors: Anchors {
            voxel,
            mask: t.get(names::MASK).to_vec(),
            feat: f32s(t.get(names::FEAT)),
            scaling: f32s(t.get(names::SCALING)),
            offsets: f32s(t.get(names::OFFSETS)),
        },
        grid: HashGrid {
            grid_3d: i8s(names::GRID_3D),
            grid_xy: i8s(names::GRID_XY),
            grid_xz: i8s(names::GRID_XZ),
            grid_yz: i8s(names::GRID_YZ),
        },
        mlp_grid: t.mlp(names::MLP_GRID),
        mlp_opacity: t.mlp(names::MLP_OPACITY),
        mlp_cov: t.mlp(names::MLP_COV),
        mlp_color: t.mlp(names::MLP_COLOR),
        quant_feat: t.group(
            &names::QUANT_FEAT,
            &names::QUANT_FEAT_REGIONS,
            usize::from(dims.feat_dim),
            dims.feat_lattice.has_factors(),
        ),
        quant_scaling: t.group(
            &names::QUANT_SCALING,
            &names::QUANT_SCALING_REGIONS,
            usize::from(dims.scaling_dim),
            dims.scaling_lattice.has_factors(),
        ),
        quant_offsets: t.group(&names::QUANT_OFFSETS, &[""; 4], 3, false),
        dims,
    };
    validate_model(&model)?;
    Ok(model)
}

/// The data of every tensor of Table 2-1, each checked for dtype and shape.
struct Tensors<'a> {
    /// Table 2-1 for the file's dimensions.
    table: Vec<TensorEntry>,
    /// Each entry's bytes, in the table's order.
    data: Vec<&'a [u8]>,
}

impl<'a> Tensors<'a> {
    /// Table 2-1's tensors for `dims` read from `r`: a tensor outside the table is refused
    /// first (the first by name), then each entry's presence, dtype and shape in table order.
    fn read(r: &Reader<'a>, dims: &Dims) -> Result<Tensors<'a>> {
        let table = tensor_table(dims);
        let mut unknown: Vec<String> =
            r.st.names()
                .into_iter()
                .filter(|n| !table.iter().any(|e| e.name == *n))
                .map(str::to_string)
                .collect();
        unknown.sort();
        if let Some(name) = unknown.into_iter().next() {
            return Err(salvq::Error::TensorUnexpected { name }.into());
        }
        let mut data = Vec::with_capacity(table.len());
        for e in &table {
            data.push(r.data(e)?);
        }
        Ok(Tensors { table, data })
    }

    /// The bytes of tensor `name` (none for a name outside the table).
    fn get(&self, name: &str) -> &'a [u8] {
        self.table
            .iter()
            .position(|e| e.name == name)
            .map_or(&[], |i| self.data[i])
    }

    /// The MLP whose layer weights and biases are the tensors `n` (§2.5).
    fn mlp(&self, n: [&str; 4]) -> Mlp {
        Mlp {
            w0: f32s(self.get(n[0])),
            b0: f32s(self.get(n[1])),
            w1: f32s(self.get(n[2])),
            b1: f32s(self.get(n[3])),
        }
    }

    /// A group's quantizer from its tensors `n` (step, gains, region 0's basis when `basis`)
    /// and its regions' tensors `rn` (starts, then stacked factors, §7.6) of `dim` values.
    fn group(&self, n: &[&str], rn: &[&str; 4], dim: usize, basis: bool) -> GroupQuantizer {
        // Region r's factors are slice r of each stacked tensor (shapes checked on reading).
        let starts = i32s(self.get(rn[0]));
        let (u, s, v) = (
            f32s(self.get(rn[1])),
            f32s(self.get(rn[2])),
            f32s(self.get(rn[3])),
        );
        let regions = starts
            .iter()
            .enumerate()
            .map(|(r, &start)| Region {
                start: start.max(0) as u32,
                basis: Basis {
                    u: u[r * dim * dim..(r + 1) * dim * dim].to_vec(),
                    s: s[r * dim..(r + 1) * dim].to_vec(),
                    v: v[r * dim * dim..(r + 1) * dim * dim].to_vec(),
                },
            })
            .collect();
        GroupQuantizer {
            step: f32s(self.get(n[0])).first().copied().unwrap_or(f32::NAN),
            gains: f32s(self.get(n[1])),
            basis: basis.then(|| Basis {
                u: f32s(self.get(n[2])),
                s: f32s(self.get(n[3])),
                v: f32s(self.get(n[4])),
            }),
            regions,
        }
    }
}

/// The anchors' voxel coordinates from the `voxel` tensor's values, each checked to be within
/// 0 … 2^MAX_COORD_BITS − 1 (§2.3, Annex A.2).
fn anchor_voxels(voxel_i: &[i32], n: usize) -> Result<Vec<[u32; 3]>> {
    let mut voxel = Vec::with_capacity(n);
    for (i, c) in voxel_i.chunks_exact(3).enumerate() {
        let mut v = [0u32; 3];
        for axis in 0..3 {
            if c[axis] < 0 || c[axis] >= 1 << MAX_COORD_BITS {
                return Err(salvq::Error::CoordinateOutOfRange {
                    anchor: i as u64,
                    axis: axis as u8,
                    value: c[axis].into(),
                    coord_bits: MAX_COORD_BITS,
                }
                .into());
            }
            v[axis] = c[axis] as u32;
        }
        voxel.push(v);
    }
    Ok(voxel)
}

/// Reads and validates a model file.
pub fn read_model(path: &Path) -> Result<SceneModel> {
    model_from_safetensors(&crate::io::read_file(path)?)
}

/// Values are turned into bytes a block at a time and written with one call per block: one
/// dynamic `write_all` per value took about a third of decoding a 1 M-anchor scene to a file.
const BLOCK: usize = 1 << 14;

/// Writes f32 values as little-endian bytes. On a little-endian target an f32 tensor's memory
/// is already its safetensors bytes, written as they are (no copy: 368 MB for a 1 M-anchor
/// model).
fn write_f32s(w: &mut dyn Write, v: &[f32]) -> std::io::Result<()> {
    if cfg!(target_endian = "little") {
        // In pieces of 1 MiB: written whole, a 1 M-anchor model's 200 MB feature tensor
        // made the first file a process wrote take 0.5 … 0.95 s here, against 0.10 s.
        for piece in bytemuck::cast_slice::<f32, u8>(v).chunks(1 << 20) {
            w.write_all(piece)?;
        }
        return Ok(());
    }
    let mut bytes = vec![0u8; 4 * BLOCK.min(v.len())];
    for block in v.chunks(BLOCK) {
        for (out, x) in bytes.chunks_exact_mut(4).zip(block) {
            out.copy_from_slice(&x.to_le_bytes());
        }
        w.write_all(&bytes[..4 * block.len()])?;
    }
    Ok(())
}

/// Writes i32 values as little-endian bytes, [`BLOCK`] values per call.
fn write_i32s(w: &mut dyn Write, v: &mut dyn Iterator<Item = i32>) -> std::io::Result<()> {
    let mut bytes = Vec::with_capacity(4 * BLOCK);
    for x in v {
        bytes.extend_from_slice(&x.to_le_bytes());
        if bytes.len() == 4 * BLOCK {
            w.write_all(&bytes)?;
            bytes.clear();
        }
    }
    w.write_all(&bytes)
}

/// Writes i8 values as their bytes.
fn write_i8s(w: &mut dyn Write, v: &[i8]) -> std::io::Result<()> {
    w.write_all(&v.iter().map(|&x| x as u8).collect::<Vec<u8>>())
}

/// A tensor's little-endian bytes, streamed to `w`.
pub fn write_tensor(m: &SceneModel, name: &str, w: &mut dyn Write) -> std::io::Result<()> {
    let d = &m.dims;
    let mlps = [
        (names::MLP_GRID, &m.mlp_grid),
        (names::MLP_OPACITY, &m.mlp_opacity),
        (names::MLP_COV, &m.mlp_cov),
        (names::MLP_COLOR, &m.mlp_color),
    ];
    for (n, mlp) in mlps {
        if let Some(p) = n.iter().position(|&x| x == name) {
            return write_f32s(w, [&mlp.w0, &mlp.b0, &mlp.w1, &mlp.b1][p]);
        }
    }
    let groups: [(&[&str], &GroupQuantizer); 3] = [
        (&names::QUANT_FEAT, &m.quant_feat),
        (&names::QUANT_SCALING, &m.quant_scaling),
        (&names::QUANT_OFFSETS, &m.quant_offsets),
    ];
    let region_groups = [
        (&names::QUANT_FEAT_REGIONS, &m.quant_feat),
        (&names::QUANT_SCALING_REGIONS, &m.quant_scaling),
    ];
    for (n, q) in region_groups {
        match n.iter().position(|&x| x == name) {
            Some(0) => return write_i32s(w, &mut q.regions.iter().map(|r| r.start as i32)),
            Some(p) => {
                for r in &q.regions {
                    write_f32s(w, [&r.basis.u, &r.basis.s, &r.basis.v][p - 1])?;
                }
                return Ok(());
            }
            None => {}
        }
    }
    for (n, q) in groups {
        match n.iter().position(|&x| x == name) {
            Some(0) => return write_f32s(w, &[q.step]),
            Some(1) => return write_f32s(w, &q.gains),
            Some(p) => {
                let basis = q.basis.as_ref().map(|b| [&b.u, &b.s, &b.v][p - 2]);
                return write_f32s(w, basis.map_or(&[][..], |v| &v[..]));
            }
            None => {}
        }
    }
    match name {
        names::ORIGIN => write_f32s(w, &m.origin),
        names::VOXEL_SIZE => write_f32s(w, &[m.voxel_size]),
        names::VOXEL => write_i32s(w, &mut m.anchors.voxel.iter().flatten().map(|&c| c as i32)),
        names::MASK => w.write_all(&m.anchors.mask),
        names::FEAT => write_f32s(w, &m.anchors.feat),
        names::SCALING => write_f32s(w, &m.anchors.scaling),
        names::OFFSETS => write_f32s(w, &m.anchors.offsets),
        names::RES_3D => write_i32s(w, &mut d.res_3d.iter().map(|&r| r.into())),
        names::RES_2D => write_i32s(w, &mut d.res_2d.iter().map(|&r| r.into())),
        names::LOG2_SIZE => write_i32s(
            w,
            &mut [d.log2_size_3d, d.log2_size_2d].into_iter().map(i32::from),
        ),
        names::GRID_3D => write_i8s(w, &m.grid.grid_3d),
        names::GRID_XY => write_i8s(w, &m.grid.grid_xy),
        names::GRID_XZ => write_i8s(w, &m.grid.grid_xz),
        names::GRID_YZ => write_i8s(w, &m.grid.grid_yz),
        _ => Ok(()),
    }
}

/// Writes the model as safetensors (Annex A.1): header keys in Table 2-1 order, data
/// contiguous in the same order, header padded with spaces to a multiple of 8 bytes.
pub fn write_safetensors(m: &SceneModel, w: &mut dyn Write) -> std::io::Result<()> {
    let table = tensor_table(&m.dims);
    let mut header = String::from("{\"__metadata__\":{\"format\":\"salvq-model\",\"schema\":\"");
    header.push_str(SCHEMA_VERSION);
    header.push_str(&format!(
        "\",\"{META_FEAT_LATTICE}\":\"{}\",\"{META_SCALING_LATTICE}\":\"{}\"}}",
        m.dims.feat_lattice.name(),
        m.dims.scaling_lattice.name()
    ));
    let mut offset = 0u64;
    for e in &table {
        let shape: Vec<String> = e.shape.iter().map(u64::to_string).collect();
        let end = offset + e.bytes();
        header.push_str(&format!(
            ",\"{}\":{{\"dtype\":\"{}\",\"shape\":[{}],\"data_offsets\":[{},{}]}}",
            e.name,
            e.dtype,
            shape.join(","),
            offset,
            end
        ));
        offset = end;
    }
    header.push('}');
    while header.len() % 8 != 0 {
        header.push(' ');
    }
    w.write_all(&(header.len() as u64).to_le_bytes())?;
    w.write_all(header.as_bytes())?;
    for e in &table {
        write_tensor(m, e.name, w)?;
    }
    Ok(())
}

/// The model as safetensors bytes.
pub fn model_to_safetensors(m: &SceneModel) -> Vec<u8> {
    let mut out = Vec::new();
    // Writing into a Vec cannot fail.
    let _ = write_safetensors(m, &mut out);
    out
}

/// Writes the model atomically to `path` as it is (Annex A.3: a decoded model is written
/// without the encoder-only checks; the encoder validates its input when it reads it).
pub fn write_model(m: &SceneModel, path: &Path) -> Result<()> {
    crate::io::write_atomic(path, |w| write_safetensors(m, w))
}
