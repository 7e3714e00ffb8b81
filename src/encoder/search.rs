//! The encoder's lattice search per attribute group (informative, spec Annex A.4; DESIGN P8:
//! any choice of lattice point gives a conformant stream, the decoder only computes `B u`).

use crate::error::{Error, Result};
use crate::lattice::{closest_dn, closest_e8_product, Lattice, SearchMethod, DEFAULT_MAX_NODES};
use crate::quantizer::{LatticeKind, LatticeMatrix};

/// Which lattice point the encoder picks for a target (`salvq encode --search`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Search {
    /// Exact for Z^n, D_n and E8 products (Conway & Sloane); Babai nearest plane on the
    /// LLL-reduced basis for a general basis (`cargo bench --bench search_methods`: 14 % less
    /// feature MSE than rounding at F = 50 for +0.2 % bits and ~10 % encode time; the exact
    /// search costs 7x the encode time for 4 % more).
    #[default]
    Auto,
    /// Babai rounding `u = round(B^-1 t)`.
    Rounding,
    /// Babai nearest plane on the LLL-reduced basis.
    NearestPlane,
    /// Schnorr–Euchner closest point on the LLL-reduced basis, at most `max_nodes` nodes
    /// (then the best point found; never worse than nearest plane).
    Closest { max_nodes: u64 },
}

impl Search {
    /// The names `--search` takes.
    pub const NAMES: [&'static str; 4] = ["auto", "rounding", "nearest-plane", "closest"];

    pub fn from_name(name: &str) -> Option<Search> {
        match name {
            "auto" => Some(Search::Auto),
            "rounding" => Some(Search::Rounding),
            "nearest-plane" => Some(Search::NearestPlane),
            "closest" => Some(Search::Closest {
                max_nodes: DEFAULT_MAX_NODES,
            }),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Search::Auto => "auto",
            Search::Rounding => "rounding",
            Search::NearestPlane => "nearest-plane",
            Search::Closest { .. } => "closest",
        }
    }
}

/// One group's quantizer as the encoder uses it: the decoder's matrix and a search.
#[derive(Debug, Clone)]
pub struct GroupSearch {
    pub matrix: LatticeMatrix,
    method: Search,
    /// Precomputations of the general search (not needed for Z^n, or for the exact D_n and
    /// E8 decoders).
    lattice: Option<Lattice>,
    tensor: &'static str,
}

impl GroupSearch {
    /// `tensor` names the group in errors (its `quant.<group>.step`).
    pub fn new(matrix: LatticeMatrix, method: Search, tensor: &'static str) -> Result<GroupSearch> {
        let needs_lattice = match matrix.kind {
            LatticeKind::Identity => false,
            LatticeKind::Dn | LatticeKind::E8Product => {
                !matches!(method, Search::Auto | Search::Closest { .. })
            }
            LatticeKind::General => true,
        };
        let lattice = if needs_lattice {
            let n = matrix.dim;
            Some(
                Lattice::new(n, &matrix.to_f64()).map_err(|e| Error::LatticeSearchFailed {
                    tensor,
                    anchor: None,
                    reason: e.to_string(),
                })?,
            )
        } else {
            None
        };
        Ok(GroupSearch {
            matrix,
            method,
            lattice,
            tensor,
        })
    }

    /// Integer coordinates `u` for the target `t = (x − μ) / Δ` of anchor `anchor`.
    pub fn quantize(&self, t: &[f64], anchor: u64) -> Result<Vec<i64>> {
        let fail = |e: crate::lattice::LatticeError| Error::LatticeSearchFailed {
            tensor: self.tensor,
            anchor: Some(anchor),
            reason: e.to_string(),
        };
        let Some(lattice) = &self.lattice else {
            return match self.matrix.kind {
                LatticeKind::Dn => closest_dn(t).map(|p| p.u).map_err(fail),
                LatticeKind::E8Product => closest_e8_product(t).map(|p| p.u).map_err(fail),
                // Z^n: rounding is the exact search.
                _ => Ok(t
                    .iter()
                    .map(|v| v.round().clamp(-9.0e18, 9.0e18) as i64)
                    .collect()),
            };
        };
        let method = match self.method {
            Search::Rounding => SearchMethod::Rounding,
            Search::Auto | Search::NearestPlane => SearchMethod::NearestPlane,
            Search::Closest { max_nodes } => SearchMethod::ClosestPoint { max_nodes },
        };
        lattice.quantize(t, method).map(|q| q.u).map_err(fail)
    }
}
