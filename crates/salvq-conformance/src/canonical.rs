//! The canonical decoded form (spec §11.1) and its two hashes (§11.2): what a decoder under
//! test writes, and what the conformance runner compares.

use sha2::{Digest, Sha256};

use salvq_bitstream::attributes::Symbols;
use salvq_bitstream::model::{names, tensor_table, Dims, SceneModel};
use salvq_bitstream::quantizer::LatticeKind;
use salvq_render::interchange::write_tensor;

/// The reconstructed (floating-point) tensors (§11.2, §11.6): the anchors profile's three
/// and the explicit profile's six, compared within a tolerance; every other tensor of the
/// canonical form is compared bit for bit.
pub const FLOAT_TENSORS: [&str; 9] = [
    names::FEAT,
    names::SCALING,
    names::OFFSETS,
    "gaussian.position",
    "gaussian.log_scale",
    "gaussian.opacity",
    "gaussian.rotation",
    "gaussian.sh_dc",
    "gaussian.sh_rest",
];

/// The explicit profile's integer-domain tensors (§11.6 Table 11-2), in canonical order;
/// its float tensors follow them.
pub const EXPLICIT_INTEGER_TENSORS: [&str; 5] = [
    "gaussian.voxel",
    "symbols.coordinates",
    "symbols.rotation_index",
    "symbols.size_class",
    "symbols.refinement",
];

/// The symbol tensors of Table 11-1, after the model's.
pub const SYMBOL_TENSORS: [&str; 3] = ["symbols.feat", "symbols.scaling", "symbols.offsets"];

/// Element types of the canonical form: Table 2-1's, and I64 for symbols.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CanonicalDtype {
    F32,
    I32,
    U8,
    I8,
    I64,
}

impl CanonicalDtype {
    /// The safetensors spelling, also the one §11.2 hashes.
    pub fn name(self) -> &'static str {
        match self {
            CanonicalDtype::F32 => "F32",
            CanonicalDtype::I32 => "I32",
            CanonicalDtype::U8 => "U8",
            CanonicalDtype::I8 => "I8",
            CanonicalDtype::I64 => "I64",
        }
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            CanonicalDtype::F32 | CanonicalDtype::I32 => 4,
            CanonicalDtype::U8 | CanonicalDtype::I8 => 1,
            CanonicalDtype::I64 => 8,
        }
    }

    fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "F32" => CanonicalDtype::F32,
            "I32" => CanonicalDtype::I32,
            "U8" => CanonicalDtype::U8,
            "I8" => CanonicalDtype::I8,
            "I64" => CanonicalDtype::I64,
            _ => return None,
        })
    }
}

/// One tensor of the canonical form: little-endian element bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CanonicalTensor {
    pub name: String,
    pub dtype: CanonicalDtype,
    pub shape: Vec<u64>,
    pub data: Vec<u8>,
}

impl CanonicalTensor {
    /// The values as f32 (F32 tensors; empty otherwise).
    pub fn f32_values(&self) -> Vec<f32> {
        if self.dtype != CanonicalDtype::F32 {
            return Vec::new();
        }
        self.data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    }

    /// Element `i` as text, for mismatch reports.
    pub fn element_text(&self, i: usize) -> String {
        let size = self.dtype.size();
        let Some(b) = self.data.get(i * size..(i + 1) * size) else {
            return "(none)".into();
        };
        match self.dtype {
            CanonicalDtype::F32 => {
                let v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                format!("{v:e} (0x{:08x})", v.to_bits())
            }
            CanonicalDtype::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]).to_string(),
            CanonicalDtype::U8 => b[0].to_string(),
            CanonicalDtype::I8 => (b[0] as i8).to_string(),
            CanonicalDtype::I64 => {
                let mut a = [0u8; 8];
                a.copy_from_slice(b);
                i64::from_le_bytes(a).to_string()
            }
        }
    }

    /// The multi-index of flat element `i` in this tensor's shape.
    pub fn index_of(&self, mut i: usize) -> Vec<u64> {
        let mut idx = vec![0u64; self.shape.len()];
        for (slot, &d) in idx.iter_mut().zip(&self.shape).rev() {
            if d == 0 {
                break;
            }
            *slot = i as u64 % d;
            i /= d as usize;
        }
        idx
    }
}

/// Every name the canonical form may hold, in canonical order (§11.1: Table 2-1's order, then
/// the symbol tensors): the order the hashes of §11.2 walk.
pub fn canonical_order() -> Vec<&'static str> {
    // Dimensions under which every optional row of Table 2-1 is present.
    let all = Dims {
        anchors: 2,
        feat_dim: 8,
        offsets: 1,
        scaling_dim: 8,
        rates: 1,
        grid_channels: 1,
        res_3d: vec![1],
        res_2d: vec![1],
        log2_size_3d: 1,
        log2_size_2d: 1,
        context_hidden: 1,
        scaffold_hidden: 1,
        view_dims: 0,
        feat_lattice: LatticeKind::General,
        scaling_lattice: LatticeKind::General,
        feat_regions: 2,
        scaling_regions: 2,
    };
    tensor_table(&all)
        .into_iter()
        .map(|e| e.name)
        .chain(SYMBOL_TENSORS)
        .chain(EXPLICIT_INTEGER_TENSORS)
        .chain(FLOAT_TENSORS[3..].iter().copied())
        .collect()
}

/// The canonical form of an explicit-profile decode (§11.6).
pub fn explicit_canonical_tensors(d: &salvq::DecodedGaussians) -> Vec<CanonicalTensor> {
    let g = &d.gaussians;
    let n = g.len() as u64;
    let values: u64 = d.groups.iter().map(|g| g.dim as u64).sum();
    let i32s = |name: &str, shape: Vec<u64>, v: &mut dyn Iterator<Item = i32>| CanonicalTensor {
        name: name.into(),
        dtype: CanonicalDtype::I32,
        shape,
        data: v.flat_map(i32::to_le_bytes).collect(),
    };
    let u8s = |name: &str, v: &[u8]| CanonicalTensor {
        name: name.into(),
        dtype: CanonicalDtype::U8,
        shape: vec![n],
        data: v.to_vec(),
    };
    let f32s = |name: &str, shape: Vec<u64>, v: &mut dyn Iterator<Item = f32>| CanonicalTensor {
        name: name.into(),
        dtype: CanonicalDtype::F32,
        shape,
        data: v.flat_map(f32::to_le_bytes).collect(),
    };
    let mut out = vec![
        i32s(
            EXPLICIT_INTEGER_TENSORS[0],
            vec![n, 3],
            &mut d.voxels.iter().flatten().map(|&c| c as i32),
        ),
        i32s(
            EXPLICIT_INTEGER_TENSORS[1],
            vec![n, values],
            &mut d.symbols.coords.iter().copied(),
        ),
        u8s(EXPLICIT_INTEGER_TENSORS[2], &d.symbols.rotation_index),
        u8s(EXPLICIT_INTEGER_TENSORS[3], &d.symbols.size_class),
        i32s(
            EXPLICIT_INTEGER_TENSORS[4],
            vec![n, 3],
            &mut d.symbols.refinement.iter().flatten().map(|&c| c as i32),
        ),
        f32s(
            FLOAT_TENSORS[3],
            vec![n, 3],
            &mut g.positions.iter().flatten().copied(),
        ),
        f32s(
            FLOAT_TENSORS[4],
            vec![n, 3],
            &mut g.log_scales.iter().flatten().copied(),
        ),
        f32s(
            FLOAT_TENSORS[5],
            vec![n],
            &mut g.opacity_logit.iter().copied(),
        ),
        f32s(
            FLOAT_TENSORS[6],
            vec![n, 4],
            &mut g.rotations.iter().flatten().copied(),
        ),
        f32s(
            FLOAT_TENSORS[7],
            vec![n, 3],
            &mut g.f_dc.iter().flatten().copied(),
        ),
    ];
    let rest = g.rest_per_channel() as u64 * 3;
    if rest > 0 {
        out.push(f32s(
            FLOAT_TENSORS[8],
            vec![n, rest],
            &mut g.f_rest.iter().copied(),
        ));
    }
    out
}

/// The canonical form of a model decoded at one rate with that rate's symbols (§11.1).
pub fn canonical_tensors(model: &SceneModel, symbols: &Symbols) -> Vec<CanonicalTensor> {
    let n = u64::from(model.dims.anchors);
    let (f, s, k) = (
        u64::from(model.dims.feat_dim),
        u64::from(model.dims.scaling_dim),
        u64::from(model.dims.offsets),
    );
    let mut out: Vec<CanonicalTensor> = tensor_table(&model.dims)
        .into_iter()
        .map(|e| {
            let mut data = Vec::with_capacity(e.bytes() as usize);
            // Writing into a Vec cannot fail.
            let _ = write_tensor(model, e.name, &mut data);
            CanonicalTensor {
                name: e.name.to_string(),
                dtype: CanonicalDtype::from_name(&e.dtype.to_string())
                    .unwrap_or(CanonicalDtype::F32),
                shape: e.shape,
                data,
            }
        })
        .collect();
    let symbol = |name: &str, shape: Vec<u64>, values: &[i64]| CanonicalTensor {
        name: name.to_string(),
        dtype: CanonicalDtype::I64,
        shape,
        data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    };
    out.push(symbol(SYMBOL_TENSORS[0], vec![n, f], &symbols.feat));
    out.push(symbol(SYMBOL_TENSORS[1], vec![n, s], &symbols.scaling));
    out.push(symbol(SYMBOL_TENSORS[2], vec![n, k, 3], &symbols.offsets));
    out
}

/// §11.2: SHA-256 over the records of the selected tensors, in canonical order. A record is
/// the name's length (u32) and UTF-8 bytes, the dtype's name's length (u32) and bytes, the
/// rank (u32), each dimension (u64), the data's length in bytes (u64) and the data, all
/// little-endian.
fn hash_records<'a>(tensors: impl Iterator<Item = &'a CanonicalTensor>) -> String {
    let mut h = Sha256::new();
    for t in tensors {
        h.update((t.name.len() as u32).to_le_bytes());
        h.update(t.name.as_bytes());
        let dtype = t.dtype.name();
        h.update((dtype.len() as u32).to_le_bytes());
        h.update(dtype.as_bytes());
        h.update((t.shape.len() as u32).to_le_bytes());
        for d in &t.shape {
            h.update(d.to_le_bytes());
        }
        h.update((t.data.len() as u64).to_le_bytes());
        h.update(&t.data);
    }
    hex(&h.finalize())
}

/// Lower-case hexadecimal.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The integer-domain hash (§11.2): every tensor but [`FLOAT_TENSORS`], canonical order.
/// `tensors` must already be in canonical order ([`sort_canonical`]).
pub fn integer_hash(tensors: &[CanonicalTensor]) -> String {
    hash_records(
        tensors
            .iter()
            .filter(|t| !FLOAT_TENSORS.contains(&t.name.as_str())),
    )
}

/// The float hash (§11.2): the [`FLOAT_TENSORS`] alone, bit for bit — equal only for a decoder
/// that follows the reference's binary32 order exactly.
pub fn float_hash(tensors: &[CanonicalTensor]) -> String {
    hash_records(
        tensors
            .iter()
            .filter(|t| FLOAT_TENSORS.contains(&t.name.as_str())),
    )
}

/// Puts tensors in canonical order; a name the canonical form does not define is an error.
pub fn sort_canonical(mut tensors: Vec<CanonicalTensor>) -> Result<Vec<CanonicalTensor>, String> {
    let order = canonical_order();
    let mut keyed = Vec::with_capacity(tensors.len());
    for t in tensors.drain(..) {
        let Some(at) = order.iter().position(|&n| n == t.name) else {
            return Err(format!(
                "tensor `{}` is not part of the canonical form (§11.1)",
                t.name
            ));
        };
        keyed.push((at, t));
    }
    keyed.sort_by_key(|(at, _)| *at);
    Ok(keyed.into_iter().map(|(_, t)| t).collect())
}

/// The canonical form as a safetensors file (§11.1; metadata `format` = `salvq-decoded`).
pub fn to_safetensors(tensors: &[CanonicalTensor]) -> Vec<u8> {
    let mut header = String::from(r#"{"__metadata__":{"format":"salvq-decoded"}"#);
    let mut offset = 0usize;
    for t in tensors {
        let shape: Vec<String> = t.shape.iter().map(u64::to_string).collect();
        header.push_str(&format!(
            r#","{}":{{"dtype":"{}","shape":[{}],"data_offsets":[{},{}]}}"#,
            t.name,
            t.dtype.name(),
            shape.join(","),
            offset,
            offset + t.data.len()
        ));
        offset += t.data.len();
    }
    header.push('}');
    while header.len() % 8 != 0 {
        header.push(' ');
    }
    let mut out = Vec::with_capacity(8 + header.len() + offset);
    out.extend_from_slice(&(header.len() as u64).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for t in tensors {
        out.extend_from_slice(&t.data);
    }
    out
}

/// Reads a canonical form written by any decoder: any safetensors layout, tensors returned in
/// canonical order. Errors are one line for the runner's report.
pub fn from_safetensors(bytes: &[u8]) -> Result<Vec<CanonicalTensor>, String> {
    let st = safetensors::SafeTensors::deserialize(bytes)
        .map_err(|e| format!("output is not a safetensors file: {e}"))?;
    let mut tensors = Vec::new();
    for (name, view) in st.tensors() {
        let dtype_name = format!("{:?}", view.dtype());
        let dtype = CanonicalDtype::from_name(&dtype_name)
            .ok_or_else(|| format!("tensor `{name}` has dtype {dtype_name}"))?;
        tensors.push(CanonicalTensor {
            name,
            dtype,
            shape: view.shape().iter().map(|&d| d as u64).collect(),
            data: view.data().to_vec(),
        });
    }
    sort_canonical(tensors)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_order_lists_every_row_once() {
        let order = canonical_order();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), order.len());
        assert!(order.contains(&"quant.scaling.regions.basis_v"));
        let offsets = order.iter().position(|n| *n == "symbols.offsets");
        // The anchors' symbols end their profile's list; the explicit profile's follow.
        assert_eq!(offsets, Some(order.len() - 12));
        assert_eq!(order.last(), Some(&"gaussian.sh_rest"));
    }

    #[test]
    fn safetensors_round_trip_and_hash_split() {
        let model = salvq_gen::generate(&salvq_gen::GenParams::small(5, 3));
        let sy = Symbols {
            feat: vec![1; 5 * 8],
            scaling: vec![-2; 5 * 6],
            offsets: vec![0; 5 * 4 * 3],
        };
        let t = canonical_tensors(&model, &sy);
        let back = from_safetensors(&to_safetensors(&t)).unwrap();
        assert_eq!(back, t);
        // Changing a float tensor changes the float hash only; a symbol, the integer hash only.
        let (ih, fh) = (integer_hash(&t), float_hash(&t));
        let mut t2 = t.clone();
        let feat = t2.iter_mut().find(|x| x.name == names::FEAT).unwrap();
        feat.data[0] ^= 1;
        assert_eq!(integer_hash(&t2), ih);
        assert_ne!(float_hash(&t2), fh);
        let mut t3 = t.clone();
        t3.last_mut().unwrap().data[0] ^= 1;
        assert_ne!(integer_hash(&t3), ih);
        assert_eq!(float_hash(&t3), fh);
    }
}
