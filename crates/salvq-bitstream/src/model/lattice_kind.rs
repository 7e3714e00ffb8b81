//! The lattice kinds a group may use (spec §7.1, Table 7-1): part of a scene's dimensions;
//! their matrices and reconstruction are [`crate::quantizer`]'s.

/// The lattice of an attribute group (spec §7.1, Table 7-1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub enum LatticeKind {
    /// Z^d: uniform scalar quantization (USQ), B = I.
    #[cfg_attr(feature = "serde", serde(rename = "identity"))]
    Identity,
    /// D_d = {x in Z^d : sum even}, d >= 2, with the generator of §7.2.
    #[cfg_attr(feature = "serde", serde(rename = "dn"))]
    Dn,
    /// E8^(d/8), d a multiple of 8, with the generator of §7.2 on each block.
    #[cfg_attr(feature = "serde", serde(rename = "e8"))]
    E8Product,
    /// A learned basis B = U diag(s) V^T stored as its factors (SALVQ).
    #[cfg_attr(feature = "serde", serde(rename = "basis"))]
    General,
}

impl LatticeKind {
    /// Every kind, in code order.
    pub const ALL: [LatticeKind; 4] = [
        LatticeKind::Identity,
        LatticeKind::Dn,
        LatticeKind::E8Product,
        LatticeKind::General,
    ];

    /// The code stored in `HEAD` (Table 7-1).
    pub fn code(self) -> u8 {
        match self {
            LatticeKind::Identity => 0,
            LatticeKind::Dn => 1,
            LatticeKind::E8Product => 2,
            LatticeKind::General => 3,
        }
    }

    /// The kind of a `HEAD` code (Table 7-1), `None` for an unassigned code.
    pub fn from_code(code: u8) -> Option<LatticeKind> {
        LatticeKind::ALL.into_iter().find(|k| k.code() == code)
    }

    /// The name used by the interchange metadata (Annex A) and the tools.
    pub fn name(self) -> &'static str {
        match self {
            LatticeKind::Identity => "identity",
            LatticeKind::Dn => "dn",
            LatticeKind::E8Product => "e8",
            LatticeKind::General => "basis",
        }
    }

    /// The kind of a [`Self::name`].
    pub fn from_name(name: &str) -> Option<LatticeKind> {
        LatticeKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// §7.1: whether a group of dimension `d` can use this lattice; `Err` gives the rule.
    pub fn check_dim(self, d: u64) -> Result<(), &'static str> {
        match self {
            LatticeKind::Dn if d < 2 => Err("D_n needs a dimension of at least 2"),
            LatticeKind::E8Product if d % 8 != 0 => {
                Err("an E8 product needs a dimension that is a multiple of 8")
            }
            _ => Ok(()),
        }
    }

    /// Whether the group stores basis factors (`QUAN`, Table 2-1).
    pub fn has_factors(self) -> bool {
        self == LatticeKind::General
    }
}
