//! The encoder's lattice search per attribute group (informative, spec Annex A.4 and §7: any
//! choice of lattice point gives a conformant stream, the decoder only computes `B u`).

use crate::error::{Error, Result};
use crate::lattice::{closest_dn, closest_e8_product, Lattice, SearchMethod, DEFAULT_MAX_NODES};
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::quantizer::{LatticeKind, LatticeMatrix};

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
    Closest {
        /// Most nodes visited.
        max_nodes: u64,
    },
    /// Rate-distortion optimised: the `Auto` point, then greedy moves of one coordinate by
    /// ±1 while they lower `‖B u − t‖² + λ · bits(u)`, bits from the integer entropy model
    /// (§6) at the coordinates' own scale indices, `λ = ln 2 / 6` (the slope of a lattice
    /// quantizer's D(R) at high rate, in squared steps per bit) times `lambda_milli / 1000`.
    Rdo {
        /// λ in thousandths of [`RDO_LAMBDA`].
        lambda_milli: u32,
    },
}

/// `λ` of [`Search::Rdo`] at `lambda_milli = 1000`: `−dD/dR = 2 ln 2 · D` with `D = 1/12`
/// squared steps per dimension.
pub const RDO_LAMBDA: f64 = std::f64::consts::LN_2 / 6.0;

/// Most passes of [`GroupSearch::refine_rd`] over the coordinates (each pass that moves
/// nothing ends it; every move lowers the cost, so it also ends without the bound).
const RDO_MAX_PASSES: usize = 8;

impl Search {
    /// The names `--search` takes.
    pub const NAMES: [&'static str; 5] = ["auto", "rounding", "nearest-plane", "closest", "rdo"];

    /// The search named `name` (one of [`Self::NAMES`]).
    pub fn from_name(name: &str) -> Option<Search> {
        match name {
            "auto" => Some(Search::Auto),
            "rounding" => Some(Search::Rounding),
            "nearest-plane" => Some(Search::NearestPlane),
            "closest" => Some(Search::Closest {
                max_nodes: DEFAULT_MAX_NODES,
            }),
            "rdo" => Some(Search::Rdo { lambda_milli: 1000 }),
            _ => None,
        }
    }

    /// Its name, as `--search` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Search::Auto => "auto",
            Search::Rounding => "rounding",
            Search::NearestPlane => "nearest-plane",
            Search::Closest { .. } => "closest",
            Search::Rdo { .. } => "rdo",
        }
    }
}

/// One group's quantizer as the encoder uses it: the decoder's matrix and a search.
#[derive(Debug, Clone)]
pub struct GroupSearch {
    /// The group's reconstruction matrix, as the decoder builds it (§7.3).
    pub matrix: LatticeMatrix,
    method: Search,
    /// Precomputations of the general search (not needed for Z^n, or for the exact D_n and
    /// E8 decoders).
    lattice: Option<Lattice>,
    /// B's columns as f64, one after the other (for [`Search::Rdo`] only; else empty).
    columns: Vec<f64>,
    tensor: &'static str,
}

impl GroupSearch {
    /// `tensor` names the group in errors (its `quant.<group>.step`).
    pub fn new(matrix: LatticeMatrix, method: Search, tensor: &'static str) -> Result<GroupSearch> {
        let needs_lattice = match matrix.kind {
            LatticeKind::Identity => false,
            LatticeKind::Dn | LatticeKind::E8Product => !matches!(
                method,
                Search::Auto | Search::Closest { .. } | Search::Rdo { .. }
            ),
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
        let columns = if matches!(method, Search::Rdo { .. }) {
            let (d, b) = (matrix.dim, matrix.to_f64());
            (0..d * d).map(|c| b[(c % d) * d + c / d]).collect()
        } else {
            Vec::new()
        };
        Ok(GroupSearch {
            matrix,
            method,
            lattice,
            columns,
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
            Search::Auto | Search::NearestPlane | Search::Rdo { .. } => SearchMethod::NearestPlane,
            Search::Closest { max_nodes } => SearchMethod::ClosestPoint { max_nodes },
        };
        lattice.quantize(t, method).map(|q| q.u).map_err(fail)
    }

    /// The `λ` of an RDO search, if this is one.
    pub fn rdo_lambda(&self) -> Option<f64> {
        match self.method {
            Search::Rdo { lambda_milli } => Some(RDO_LAMBDA * f64::from(lambda_milli) / 1000.0),
            _ => None,
        }
    }

    /// [`Search::Rdo`]'s refinement of `u` for target `t` (step units) with scale indices
    /// `k` (one per coordinate): passes over the coordinates in order, each trying the move
    /// toward 0 first, then away, and taking the first that lowers the cost.
    pub fn refine_rd(
        &self,
        t: &[f64],
        u: &mut [i64],
        k: &[u8],
        tables: &GaussianTables,
        lambda: f64,
    ) {
        let d = t.len();
        if self.columns.len() != d * d || u.len() != d || k.len() != d {
            return;
        }
        let col = |j: usize| &self.columns[j * d..(j + 1) * d];
        let norm2: Vec<f64> = (0..d).map(|j| col(j).iter().map(|v| v * v).sum()).collect();
        // Residual r = B u − t.
        let mut r: Vec<f64> = t.iter().map(|v| -v).collect();
        for (j, &uj) in u.iter().enumerate() {
            if uj != 0 {
                for (ri, bij) in r.iter_mut().zip(col(j)) {
                    *ri += bij * uj as f64;
                }
            }
        }
        for _ in 0..RDO_MAX_PASSES {
            let mut moved = false;
            for j in 0..d {
                let br: f64 = col(j).iter().zip(&r).map(|(bij, ri)| bij * ri).sum();
                let bits_now = tables.ideal_bits(k[j], u[j]);
                let toward = if u[j] > 0 { -1 } else { 1 };
                for step in [toward, -toward] {
                    let Some(cand) = u[j].checked_add(step) else {
                        continue;
                    };
                    let s = step as f64;
                    let dd = 2.0 * s * br + norm2[j];
                    let dr = tables.ideal_bits(k[j], cand) - bits_now;
                    if dd + lambda * dr < -1e-12 {
                        u[j] = cand;
                        for (ri, bij) in r.iter_mut().zip(col(j)) {
                            *ri += s * bij;
                        }
                        moved = true;
                        break;
                    }
                }
            }
            if !moved {
                break;
            }
        }
    }
}

/// A group's searches, one per spatial region (§7.6).
#[derive(Debug, Clone)]
pub struct GroupSearches {
    starts: Vec<u32>,
    searches: Vec<GroupSearch>,
}

impl GroupSearches {
    /// A search per region of `lattices`.
    pub fn new(
        lattices: &salvq_bitstream::quantizer::GroupLattices,
        method: Search,
        tensor: &'static str,
    ) -> Result<GroupSearches> {
        Ok(GroupSearches {
            starts: lattices.starts().to_vec(),
            searches: lattices
                .matrices()
                .iter()
                .map(|m| GroupSearch::new(m.clone(), method, tensor))
                .collect::<Result<_>>()?,
        })
    }

    /// The search of the region holding canonical anchor `anchor`.
    pub fn for_anchor(&self, anchor: u32) -> &GroupSearch {
        let k = self.starts.partition_point(|&s| s <= anchor).max(1);
        &self.searches[k - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use salvq_bitstream::model::Basis;
    use salvq_gen::rng::Stream;

    /// `‖B u − t‖² + λ · bits(u)` computed from scratch.
    fn cost(b: &[f64], t: &[f64], u: &[i64], k: &[u8], tables: &GaussianTables, l: f64) -> f64 {
        let d = t.len();
        let dist: f64 = (0..d)
            .map(|i| {
                let z: f64 = (0..d).map(|j| b[i * d + j] * u[j] as f64).sum();
                (z - t[i]).powi(2)
            })
            .sum();
        dist + l * (0..d).map(|j| tables.ideal_bits(k[j], u[j])).sum::<f64>()
    }

    /// The refinement never raises the cost, and stops at a point no single ±1 move improves,
    /// for the identity, E8² and a learned basis, at several λ.
    #[test]
    fn rdo_refinement_lowers_the_cost_to_a_local_minimum() {
        let tables = GaussianTables::standard();
        let mut s = Stream::new(5, 77, 0);
        let d = 16;
        let basis = Basis {
            u: salvq_gen::linalg::orthogonal(&mut s, d)
                .iter()
                .map(|&v| v as f32)
                .collect(),
            s: (0..d).map(|i| 0.5 + i as f32 / 10.0).collect(),
            v: salvq_gen::linalg::orthogonal(&mut s, d)
                .iter()
                .map(|&v| v as f32)
                .collect(),
        };
        for (kind, b) in [
            (LatticeKind::Identity, None),
            (LatticeKind::E8Product, None),
            (LatticeKind::General, Some(&basis)),
        ] {
            for milli in [250, 1000, 4000] {
                let gs = GroupSearch::new(
                    LatticeMatrix::new(kind, d, b),
                    Search::Rdo {
                        lambda_milli: milli,
                    },
                    "x",
                )
                .unwrap();
                let l = gs.rdo_lambda().unwrap();
                let bm = gs.matrix.to_f64();
                for trial in 0..50 {
                    let k: Vec<u8> = (0..d).map(|_| s.below(40) as u8).collect();
                    let t: Vec<f64> = (0..d).map(|_| 3.0 * s.normal()).collect();
                    let mut u = gs.quantize(&t, trial).unwrap();
                    let before = cost(&bm, &t, &u, &k, tables, l);
                    gs.refine_rd(&t, &mut u, &k, tables, l);
                    let after = cost(&bm, &t, &u, &k, tables, l);
                    assert!(
                        after <= before + 1e-9,
                        "{kind:?} λ×{milli}: {before} -> {after}"
                    );
                    for j in 0..d {
                        for step in [-1, 1] {
                            let mut v = u.clone();
                            v[j] += step;
                            let c = cost(&bm, &t, &v, &k, tables, l);
                            assert!(c >= after - 1e-9, "{kind:?}: move {j} {step:+} lowers it");
                        }
                    }
                }
            }
        }
    }
}
