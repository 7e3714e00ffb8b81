//! Tests of §3.5's walk: context classes, rescaling and the `sh_rest` count.

use super::*;

/// A reader that answers from a script: each Gaussian's `sh_rest` count, a symbol of 1 for
/// every symbol asked, and it records which values were asked.
struct Scripted {
    counts: Vec<usize>,
    bits: u32,
    asked: Vec<(usize, usize)>,
}

impl Events for Scripted {
    fn bit(&mut self, _: u32, i: usize, what: BitEvent) -> Result<bool> {
        Ok(match what {
            BitEvent::RestCount { bit } => {
                assert!(bit < self.bits, "bit {bit} of an L = {} count", self.bits);
                self.counts[i] >> bit & 1 == 1
            }
            _ => false,
        })
    }
    fn symbol(&mut self, _: u8, i: usize, v: usize, _: i64) -> Result<i64> {
        self.asked.push((i, v));
        Ok(1)
    }
}

fn sh1_layer() -> (Layer, Vec<Group>) {
    let groups: Vec<Group> = GroupKind::present(1)
        .into_iter()
        .map(|kind| Group {
            kind,
            dim: kind.dim(1),
            step: 1.0,
            gains: vec![1.0],
            mean: vec![0.0; kind.dim(1)],
            basis: None,
        })
        .collect();
    let values: usize = groups.iter().map(|g| g.dim).sum();
    let layer = Layer {
        coord_bits: 4,
        voxel_size: 1.0,
        pred_level: 0,
        rotation_freq: [1 << 15; 3],
        size_threshold: [i32::MAX; 3],
        refine: [0; 4],
        shift: vec![[0; 4]; 4],
        scale_offset: vec![[0; 4]; 4],
        predict: vec![false; 5],
        rest_count_freq: vec![1 << 15; 15],
        scale_table: vec![[0; CONTEXT_CLASSES]; values],
    };
    (layer, groups)
}

/// §3.5: a Gaussian reads only its first n `sh_rest` symbols (SH degree 1: d = 9, L = 4);
/// the values after them are 0 without an event, and a count above d is an error.
#[test]
fn only_the_counted_sh_rest_values_read_symbols() {
    let (layer, groups) = sh1_layer();
    let voxels = [[0, 0, 0], [1, 0, 0], [2, 0, 0]];
    let mut events = Scripted {
        counts: vec![0, 4, 9],
        bits: 4,
        asked: Vec::new(),
    };
    let symbols = walk(&layer, &groups, &voxels, &mut events).unwrap();
    // Values 10 … 18 are sh_rest (after scale 3, opacity 1, rotation 3, sh_dc 3).
    for (i, n) in [(0usize, 0usize), (1, 4), (2, 9)] {
        let rest: Vec<usize> = events
            .asked
            .iter()
            .filter(|&&(g, v)| g == i && v >= 10)
            .map(|&(_, v)| v)
            .collect();
        assert_eq!(rest, (10..10 + n).collect::<Vec<_>>(), "Gaussian {i}");
        let row = &symbols.coords[i * 19..(i + 1) * 19];
        assert!(row[10..10 + n].iter().all(|&u| u == 1), "Gaussian {i}");
        assert!(row[10 + n..].iter().all(|&u| u == 0), "Gaussian {i}");
    }
    let mut events = Scripted {
        counts: vec![10],
        bits: 4,
        asked: Vec::new(),
    };
    let err = walk(&layer, &groups, &voxels[..1], &mut events).unwrap_err();
    assert!(
        matches!(
            err,
            Error::ValueInvalid {
                tensor: "GATT.rest_count",
                value: 10,
                ..
            }
        ),
        "{err:?}"
    );
}

/// The table gives §3.5's class, 1 + min(bit length of |r|, 6), around every power of two
/// and at the extremes.
#[test]
fn context_class_is_one_plus_the_capped_bit_length() {
    assert_eq!(context_class(false, 5), 0);
    let mut values = vec![0i64, i64::MIN, i64::MAX, i64::MIN + 1];
    for e in 0..63 {
        let p = 1i64 << e;
        values.extend([p - 1, p, p + 1, -(p - 1), -p, -(p + 1)]);
    }
    for r in values {
        let bits = 64 - r.unsigned_abs().leading_zeros() as usize;
        let class = 1 + bits.min(CONTEXT_CLASSES - 2);
        assert_eq!(context_class(true, r), class, "r = {r}");
    }
}

#[test]
fn rescale_clamps_the_exact_product() {
    // An escaped symbol of 2^31 + 127 shifted by 32 is far past 2^24, not wrapped.
    assert_eq!(rescale((1 << 31) + 127, 16, -16), MAX_COORDINATE);
    assert_eq!(rescale(-(1 << 31) - 127, 16, -16), -MAX_COORDINATE);
    assert_eq!(rescale(3, 1, 0), 6);
    // Every shift against the exact product, at the edges of the clamp.
    for d in 0i8..=32 {
        for u in [
            0i64,
            1,
            -1,
            2,
            7,
            -7,
            1 << 12,
            (1 << 24) - 1,
            (1 << 31) + 127,
        ] {
            for u in [u, -u] {
                let exact = (i128::from(u) << d).clamp(-(1 << 24), 1 << 24) as i64;
                assert_eq!(rescale(u, d - 16, -16), exact, "u {u}, d {d}");
            }
        }
    }
    // rshr rounds ties toward +∞.
    assert_eq!(rescale(3, 0, 1), 2);
    assert_eq!(rescale(-3, 0, 1), -1);
}
