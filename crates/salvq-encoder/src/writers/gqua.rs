//! The explicit profile's `GQUA` as the encoder writes it (spec §3.3); its reader is
//! `salvq_bitstream::explicit::groups`'.

use salvq_bitstream::container::bytes::PayloadWriter;
use salvq_bitstream::container::method::METHOD_RAW;
use salvq_bitstream::explicit::groups::{Group, LATTICE_IDENTITY, LATTICE_SCALED_ORTHOGONAL};

/// Writes `GQUA` (method 0).
pub fn write_gqua(groups: &[Group]) -> Vec<u8> {
    let mut w = PayloadWriter::default();
    w.u8(METHOD_RAW);
    for g in groups {
        w.u8(if g.basis.is_some() {
            LATTICE_SCALED_ORTHOGONAL
        } else {
            LATTICE_IDENTITY
        });
        w.f32(g.step);
        w.f32s(&g.gains);
        w.f32s(&g.mean);
        if let Some((u, s)) = &g.basis {
            for v in u.iter().chain(s) {
                w.u16(v.to_bits());
            }
        }
    }
    w.buf
}
