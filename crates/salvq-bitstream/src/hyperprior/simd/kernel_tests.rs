//! What every whole-MLP kernel must do (spec §5.3), tested the same way for each: random
//! MLPs against §5.3 written out in scalar code and against the portable path.

use crate::hyperprior::mlp::IntMlp;

/// A whole-MLP kernel's interface ([`super::avx2::Avx2Mlp`], [`super::wasm::WasmMlp`]).
pub(super) trait MlpKernel {
    fn input_len(&self) -> usize;
    fn hidden_len(&self) -> usize;
    fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]);
    /// Hidden scratch of a batch of `a` anchors.
    fn batch_hidden_len(&self, a: usize) -> usize;
    /// [`MlpKernel::eval`] of `A` anchors, inputs and outputs one after the other.
    fn eval_batch<const A: usize>(&self, x: &[i16], h: &mut [i16], y: &mut [i32]);
}

/// A kernel's batch seen as a one-anchor kernel: the tested input goes to anchor 0 and its
/// negation (zero padding kept) to the others, whose outputs must equal the kernel's
/// one-anchor `eval` of it (their nonzero units change which pairs layer 1 skips).
struct Batch<K, const A: usize>(K, usize);

impl<K: MlpKernel, const A: usize> MlpKernel for Batch<K, A> {
    fn input_len(&self) -> usize {
        self.0.input_len()
    }
    fn hidden_len(&self) -> usize {
        self.0.batch_hidden_len(A)
    }
    fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        let (n, cout) = (self.0.input_len(), self.1);
        let neg: Vec<i16> = x[..n].iter().map(|v| v.wrapping_neg()).collect();
        let mut xs = x[..n].to_vec();
        for _ in 1..A {
            xs.extend_from_slice(&neg);
        }
        let mut ys = vec![0i32; A * cout];
        self.0.eval_batch::<A>(&xs, h, &mut ys);
        let (mut h1, mut y1) = (vec![0i16; self.0.hidden_len()], vec![0i32; cout]);
        self.0.eval(&neg, &mut h1, &mut y1);
        for a in 1..A {
            assert_eq!(&ys[a * cout..(a + 1) * cout], &y1[..], "anchor {a} of {A}");
        }
        y.copy_from_slice(&ys[..cout]);
    }
    fn batch_hidden_len(&self, _: usize) -> usize {
        unreachable!("a batch is not batched again")
    }
    fn eval_batch<const B: usize>(&self, _: &[i16], _: &mut [i16], _: &mut [i32]) {
        unreachable!("a batch is not batched again")
    }
}

/// [`matches_the_portable_mlp`] for the kernel's batches of 1 … 4 anchors.
pub(super) fn batches_match_the_portable_mlp<K: MlpKernel>(make: impl Fn(&IntMlp) -> K) {
    matches_the_portable_mlp(|m| Batch::<K, 1>(make(m), m.cout));
    matches_the_portable_mlp(|m| Batch::<K, 2>(make(m), m.cout));
    matches_the_portable_mlp(|m| Batch::<K, 3>(make(m), m.cout));
    matches_the_portable_mlp(|m| Batch::<K, 4>(make(m), m.cout));
}

/// Accumulators at which a rounding shift (§0.5 `rshr`) can go wrong: the ends of i32 and
/// around 0.
pub(super) const ROUND_SHIFT_EDGES: [i32; 11] = [
    i32::MIN,
    i32::MIN + 1,
    -3,
    -2,
    -1,
    0,
    1,
    2,
    3,
    i32::MAX - 1,
    i32::MAX,
];

struct XorShift(u64);
impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    /// Mostly small values, sometimes the extremes that exercise wrapping.
    fn i16(&mut self, extreme: bool) -> i16 {
        let r = self.next();
        match (r >> 40) % 8 {
            0 if extreme => i16::MIN,
            1 if extreme => i16::MAX,
            _ => (r as i16) >> 4,
        }
    }
    /// A weight that fits i8 (a stream's `i8` weights, §1.6.2 Table 1-7), its ends included.
    fn i8(&mut self) -> i16 {
        let r = self.next();
        match (r >> 40) % 8 {
            0 => -128,
            1 => 127,
            _ => i16::from(r as i8),
        }
    }
}

/// How [`random_mlp`] draws weights.
#[derive(Clone, Copy, Debug)]
enum Weights {
    /// Mostly small i16.
    Small,
    /// i16, sometimes its ends.
    Extreme,
    /// Within i8 (kernels may store these in a byte).
    Narrow,
}

fn random_mlp(
    rng: &mut XorShift,
    cin: usize,
    hidden: usize,
    cout: usize,
    shift0: u8,
    weights: Weights,
) -> IntMlp {
    let weight = |rng: &mut XorShift| match weights {
        Weights::Small => rng.i16(false),
        Weights::Extreme => rng.i16(true),
        Weights::Narrow => rng.i8(),
    };
    IntMlp {
        cin,
        hidden,
        cout,
        w0: (0..hidden * cin).map(|_| weight(rng)).collect(),
        b0: (0..hidden).map(|_| (rng.next() as i32) >> 8).collect(),
        w0_frac_bits: 12,
        shift0,
        w1: (0..cout * hidden).map(|_| weight(rng)).collect(),
        b1: (0..cout).map(|_| rng.next() as i32).collect(),
        w1_frac_bits: vec![12; cout],
    }
}

/// §5.3 written out in scalar code, independent of the crate's `dot` (SSE2 on x86-64):
/// products in i32, every addition modulo 2^32. Also returns, per output, whether its sum
/// left the i32 range (so wrapped), and per hidden unit the exact sum before the shift.
fn scalar_mlp(m: &IntMlp, x: &[i16]) -> (Vec<i16>, Vec<i32>, Vec<bool>) {
    let h: Vec<i16> = (0..m.hidden)
        .map(|r| {
            let row = &m.w0[r * m.cin..(r + 1) * m.cin];
            let acc = row.iter().zip(x).fold(m.b0[r], |a, (&w, &v)| {
                a.wrapping_add(i32::from(w) * i32::from(v))
            });
            let q = crate::hyperprior::mlp::round_shift(acc, m.shift0);
            q.clamp(0, crate::hyperprior::mlp::HIDDEN_MAX) as i16
        })
        .collect();
    let mut wrapped = Vec::new();
    let y = (0..m.cout)
        .map(|o| {
            let row = &m.w1[o * m.hidden..(o + 1) * m.hidden];
            let exact = row.iter().zip(&h).fold(i64::from(m.b1[o]), |a, (&w, &v)| {
                a + i64::from(w) * i64::from(v)
            });
            wrapped.push(i32::try_from(exact).is_err());
            exact as i32
        })
        .collect();
    (h, y, wrapped)
}

/// The kernel against the scalar definition and the portable path, on random MLPs of
/// shapes that need every kind of padding (inputs not a multiple of 16 or 8, hidden units not a
/// multiple of 16 or 8, outputs not a multiple of 8 or 4), every shift, extreme weights and
/// weights that fit i8 (which a kernel may store in a byte). The
/// inputs must reach every branch a wrong kernel could get wrong: hidden units clamped to
/// 0, saturated at 32767 and in between, and outputs whose sums wrap modulo 2^32; the test
/// counts them and fails if any kind never occurred. Layer 1 skips pairs of zero units, so
/// runs with every unit 0 and with none 0, and pairs with one unit 0, must occur too.
pub(super) fn matches_the_portable_mlp<K: MlpKernel>(make: impl Fn(&IntMlp) -> K) {
    let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
    let shapes = [
        (96, 100, 175),
        (1, 1, 1),
        (16, 16, 8),
        (17, 9, 9),
        (24, 8, 19),
        (48, 33, 7),
    ];
    // Hidden units at 0, at 32767, in between; outputs that wrapped; vectors compared.
    // All units 0, pairs with one unit 0, no unit 0.
    let mut seen = [0usize; 8];
    for (cin, hidden, cout) in shapes {
        for shift0 in [0u8, 1, 5, 12, 20, 31] {
            for weights in [Weights::Small, Weights::Extreme, Weights::Narrow] {
                let m = random_mlp(&mut rng, cin, hidden, cout, shift0, weights);
                let k = make(&m);
                let extreme = !matches!(weights, Weights::Small);
                let mut x = vec![0i16; k.input_len()];
                let mut hk = vec![0i16; k.hidden_len()];
                let (mut h, mut y, mut yk) =
                    (vec![0i16; hidden], vec![0i32; cout], vec![0i32; cout]);
                for _ in 0..20 {
                    for v in &mut x[..cin] {
                        *v = rng.i16(extreme);
                    }
                    let (hs, ys, wrapped) = scalar_mlp(&m, &x[..cin]);
                    m.eval(&x[..cin], &mut h, &mut y);
                    k.eval(&x, &mut hk, &mut yk);
                    let at = format!("shape {cin}/{hidden}/{cout} shift {shift0}");
                    assert_eq!(yk, ys, "{at}: kernel vs scalar definition");
                    assert_eq!(&hk[..hidden], &hs[..], "{at}: hidden units");
                    assert_eq!(y, ys, "{at}: portable path vs scalar definition");
                    assert_eq!(h, hs, "{at}: portable hidden units");
                    seen[0] += hs.iter().filter(|&&v| v == 0).count();
                    seen[1] += hs.iter().filter(|&&v| v == i16::MAX).count();
                    seen[2] += hs.iter().filter(|&&v| v > 0 && v < i16::MAX).count();
                    seen[3] += wrapped.iter().filter(|&&w| w).count();
                    seen[4] += 1;
                    let nonzero = hs.iter().filter(|&&v| v != 0).count();
                    seen[5] += usize::from(nonzero == 0);
                    seen[6] += hs
                        .chunks_exact(2)
                        .filter(|p| (p[0] == 0) != (p[1] == 0))
                        .count();
                    seen[7] += usize::from(nonzero == hidden);
                }
            }
        }
    }
    assert!(
        seen.iter().all(|&c| c > 0),
        "inputs too tame: hidden 0 / 32767 / between, wrapped outputs, runs, all units 0, \
         pairs with one unit 0, no unit 0: {seen:?}"
    );
}

#[cfg(all(feature = "simd", target_arch = "x86_64"))]
impl MlpKernel for super::avx2::Avx2Mlp {
    fn input_len(&self) -> usize {
        self.input_len()
    }
    fn hidden_len(&self) -> usize {
        self.hidden_len()
    }
    fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        self.eval(x, h, y)
    }
    fn batch_hidden_len(&self, a: usize) -> usize {
        self.batch_hidden_len(a)
    }
    fn eval_batch<const A: usize>(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        self.eval_batch::<A>(x, h, y)
    }
}

impl MlpKernel for super::wasm::WasmMlp {
    fn input_len(&self) -> usize {
        self.input_len()
    }
    fn hidden_len(&self) -> usize {
        self.hidden_len()
    }
    fn eval(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        self.eval(x, h, y)
    }
    fn batch_hidden_len(&self, a: usize) -> usize {
        self.batch_hidden_len(a)
    }
    fn eval_batch<const A: usize>(&self, x: &[i16], h: &mut [i16], y: &mut [i32]) {
        self.eval_batch::<A>(x, h, y)
    }
}
