//! `GQUA` (spec §3.3): the explicit profile's attribute groups, each with a lattice, a mean
//! per value, a base step and one gain per rate.

use half::f16;

use crate::container::bytes::PayloadReader;
use crate::container::chunk::ChunkTag;
use crate::container::payload::{body, METHOD_RAW};
use crate::error::{Error, Result};
use crate::explicit::rest_per_channel;
use crate::model::Basis;
use crate::quantizer::{LatticeKind, LatticeMatrix};

/// Table 3-3: the attribute groups, in stream order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GroupKind {
    /// The natural logarithms of the three axis scales (first: the size class of §3.5
    /// follows from it).
    Scale,
    /// The opacity logit (1 value).
    Opacity,
    /// The rotation: the three smallest quaternion components (§3.6).
    Rotation,
    /// SH band 0, one per colour channel.
    Dc,
    /// The higher SH bands, `3·B` values, channel-major as the PLY's `f_rest_*`.
    Rest,
}

/// Every group kind in stream order (Table 3-3).
pub const GROUP_KINDS: [GroupKind; 5] = [
    GroupKind::Scale,
    GroupKind::Opacity,
    GroupKind::Rotation,
    GroupKind::Dc,
    GroupKind::Rest,
];

impl GroupKind {
    /// Values per Gaussian (Table 3-3).
    pub fn dim(self, sh_degree: u8) -> usize {
        match self {
            GroupKind::Opacity => 1,
            GroupKind::Rest => 3 * rest_per_channel(sh_degree),
            _ => 3,
        }
    }

    /// The group's name in Table 3-3 and in reports.
    pub fn name(self) -> &'static str {
        match self {
            GroupKind::Opacity => "opacity",
            GroupKind::Scale => "scale",
            GroupKind::Rotation => "rotation",
            GroupKind::Dc => "sh_dc",
            GroupKind::Rest => "sh_rest",
        }
    }

    /// The groups a stream of this SH degree carries (Rest only above degree 0).
    pub fn present(sh_degree: u8) -> Vec<GroupKind> {
        GROUP_KINDS
            .into_iter()
            .filter(|g| g.dim(sh_degree) > 0)
            .collect()
    }
}

/// Table 3-3's lattice codes of the explicit profile.
pub const LATTICE_IDENTITY: u8 = 0;
/// `B = U·diag(s)`, U and s stored in binary16 (§3.3).
pub const LATTICE_SCALED_ORTHOGONAL: u8 = 4;

/// One group's quantizer (§3.3).
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Which attributes the group holds.
    pub kind: GroupKind,
    /// Values per Gaussian.
    pub dim: usize,
    /// Base step.
    pub step: f32,
    /// One gain per rate (M).
    pub gains: Vec<f32>,
    /// The value each coordinate is coded around, per value.
    pub mean: Vec<f32>,
    /// `U` (row-major d × d) and `s` of `B = U·diag(s)`, binary16; `None`: the identity.
    pub basis: Option<(Vec<f16>, Vec<f16>)>,
}

impl Group {
    /// §3.3: `G = step ⊗ gain_r` (binary32).
    pub fn rate_step(&self, rate: u8) -> f32 {
        self.step * self.gains[usize::from(rate)]
    }

    /// The lattice matrix `B` (§3.3, §7.2 with V = I: `B[i][j] = U[i][j] ⊗ s_j`).
    pub fn matrix(&self) -> LatticeMatrix {
        match &self.basis {
            None => LatticeMatrix::new(LatticeKind::Identity, self.dim, None),
            Some((u, s)) => {
                let d = self.dim;
                let mut v = vec![0.0f32; d * d];
                for i in 0..d {
                    v[i * d + i] = 1.0;
                }
                let basis = Basis {
                    u: u.iter().map(|x| x.to_f32()).collect(),
                    s: s.iter().map(|x| x.to_f32()).collect(),
                    v,
                };
                LatticeMatrix::new(LatticeKind::General, d, Some(&basis))
            }
        }
    }
}

// The index is a borrowed array, copied only into an error: a `GQUA` of SH degree 3 checks
// over 2 000 basis values, and one allocation each took longer than the rest of the chunk.
fn finite(tensor: &'static str, index: &[u64], v: f32) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Error::NonFiniteValue {
            tensor,
            index: index.to_vec(),
        })
    }
}

fn positive(tensor: &'static str, index: &[u64], v: f32) -> Result<()> {
    finite(tensor, index, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(Error::ValueNotPositive {
            tensor,
            index: index.to_vec(),
            value: v,
        })
    }
}

/// §3.3: reads and checks `GQUA` for a stream of `sh_degree` and `rates` rates.
pub fn read_gqua(payload: &[u8], sh_degree: u8, rates: u8) -> Result<Vec<Group>> {
    let tag = ChunkTag::GQUA;
    let body = body(tag, payload, METHOD_RAW)?;
    let mut r = PayloadReader::new(tag, body);
    let mut groups = Vec::new();
    for (gi, kind) in GroupKind::present(sh_degree).into_iter().enumerate() {
        let g = gi as u64;
        let dim = kind.dim(sh_degree);
        // Step 1: the lattice code.
        let lattice = r.u8()?;
        if lattice != LATTICE_IDENTITY && lattice != LATTICE_SCALED_ORTHOGONAL {
            return Err(Error::ValueInvalid {
                tensor: "GQUA.lattice",
                index: vec![g],
                value: lattice.into(),
                allowed: "0 (identity) or 4 (scaled orthogonal basis), §3.3",
            });
        }
        // Step 2: step and gains, each finite and positive, then each product.
        let step = r.f32()?;
        positive("GQUA.step", &[g], step)?;
        let mut gains = Vec::with_capacity(usize::from(rates));
        for i in 0..u64::from(rates) {
            let v = r.f32()?;
            positive("GQUA.gains", &[g, i], v)?;
            gains.push(v);
        }
        for (i, &gain) in gains.iter().enumerate() {
            let product = step * gain;
            if !product.is_finite() {
                return Err(Error::NonFiniteValue {
                    tensor: "GQUA.gains",
                    index: vec![g, i as u64],
                });
            }
            if product == 0.0 {
                return Err(Error::ValueNotPositive {
                    tensor: "GQUA.gains",
                    index: vec![g, i as u64],
                    value: product,
                });
            }
        }
        // Step 3: the means.
        let mut mean = Vec::with_capacity(dim);
        for j in 0..dim {
            let v = r.f32()?;
            finite("GQUA.mean", &[g, j as u64], v)?;
            mean.push(v);
        }
        // Step 4: the basis factors of a scaled orthogonal lattice.
        let basis = if lattice == LATTICE_SCALED_ORTHOGONAL {
            let mut read = |count: usize, tensor: &'static str| -> Result<Vec<f16>> {
                let mut out = Vec::with_capacity(count);
                for i in 0..count {
                    let v = f16::from_bits(r.u16()?);
                    finite(tensor, &[g, i as u64], v.to_f32())?;
                    out.push(v);
                }
                Ok(out)
            };
            let u = read(dim * dim, "GQUA.basis_u")?;
            let s = read(dim, "GQUA.basis_s")?;
            if let Some(j) = s.iter().position(|v| v.to_f32() == 0.0) {
                return Err(Error::BasisSingular {
                    tensor: "GQUA.basis_s",
                    index: j as u64,
                });
            }
            Some((u, s))
        } else {
            None
        };
        // B's entries are finite: binary16 factors are at most 65504 in magnitude (§3.3).
        groups.push(Group {
            kind,
            dim,
            step,
            gains,
            mean,
            basis,
        });
    }
    r.finish()?;
    Ok(groups)
}
