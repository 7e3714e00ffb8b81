//! Measurement helpers (informative, spec §6.5): the synthetic symbol set of the precision
//! benchmark and the "bare coder" decode speed that full-decode timings are compared with.
//!
//! `cargo bench --bench entropy_precision` uses these; so can any later benchmark that wants
//! the ratio *full decode time / bare coder time* on the same symbols.

use std::hint::black_box;
use std::time::Instant;

use constriction::stream::model::{
    ContiguousCategoricalEntropyModel, ContiguousLookupDecoderModel,
};
use constriction::stream::stack::DefaultAnsCoder;
use constriction::stream::{Decode, Encode};
use constriction::UnwrapInfallible;

use salvq_bitstream::entropy::ans::with_precision;
use salvq_gen::rng::Stream;

/// One symbol of a measurement set: the true standard deviation in symbol units and the
/// integer u = round(σ · N(0, 1)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub sigma: f64,
    pub u: i64,
}

/// Random-stream tag of the measurement set (outside Annex B's tags).
const SAMPLE_TAG: u64 = 0x454E_5452_4F50_5931; // "ENTROPY1"

/// `n` samples with σ log-uniform in [`sigma_lo`, `sigma_hi`] and u the exact rounding of a
/// N(0, σ²) draw (so u follows the discretized Gaussian at σ). Deterministic in `seed`.
pub fn synthetic_samples(n: usize, seed: u64, sigma_lo: f64, sigma_hi: f64) -> Vec<Sample> {
    let mut rng = Stream::new(seed, SAMPLE_TAG, 0);
    let (a, b) = (sigma_lo.ln(), sigma_hi.ln());
    (0..n)
        .map(|_| {
            let sigma = (a + (b - a) * rng.uniform()).exp();
            let u = (sigma * rng.normal()).round() as i64;
            Sample { sigma, u }
        })
        .collect()
}

/// σ in Q16 as an encoder would compute it from a float σ (measurement only: the format's σ_u
/// comes from the integer hyperprior, §5).
pub fn sigma_to_q16(sigma: f64) -> u64 {
    (sigma * 65536.0).round().max(0.0) as u64
}

/// Median of `values` (sorted in place).
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => values[n / 2],
        n => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
}

/// The bare coder's decode speed: `constriction`'s `DefaultAnsCoder` decoding `symbols` with
/// ONE static categorical model (the symbols' own histogram, quantized to precision
/// `precision`; a lookup decoder model when `precision ≤ 16`), no per-symbol model choice and
/// no escapes. Returns the median over `runs` of nanoseconds per symbol. One more, untimed
/// decode checks what was timed: the coder gives back `symbols`.
///
/// # Panics
/// If `precision` is not in 12 … 24, the symbols span 2^precision values or more, or the bare
/// coder decodes other symbols than `symbols`.
pub fn bare_coder_decode_ns(symbols: &[i64], precision: u32, runs: usize) -> f64 {
    // `constriction`'s lookup model takes a u16 probability, so P ≤ 16 only (checked at
    // compile time): dispatch the two kinds of model separately.
    match precision {
        12 => bare_lookup::<12>(symbols, runs),
        13 => bare_lookup::<13>(symbols, runs),
        14 => bare_lookup::<14>(symbols, runs),
        15 => bare_lookup::<15>(symbols, runs),
        16 => bare_lookup::<16>(symbols, runs),
        p => with_precision!(p, P => bare_search::<P>(symbols, runs)),
    }
}

/// The symbols' histogram quantized to 2^P: the alphabet's smallest symbol and the
/// frequencies f = 1 + floor(count · (2^P − A) / n), the remainder to the most frequent.
fn histogram_frequencies(symbols: &[i64], precision: u32) -> (i64, Vec<u32>) {
    let lo = symbols.iter().copied().min().unwrap_or(0);
    let hi = symbols.iter().copied().max().unwrap_or(0);
    let a = (hi - lo + 1) as usize;
    assert!(
        a < (1 << precision),
        "alphabet of {a} symbols does not fit precision {precision}"
    );
    let mut counts = vec![0u64; a];
    for &u in symbols {
        counts[(u - lo) as usize] += 1;
    }
    let n = symbols.len().max(1) as u64;
    let free = (1u64 << precision) - a as u64;
    let mut freqs: Vec<u32> = counts.iter().map(|&c| (1 + c * free / n) as u32).collect();
    let rem = (1u32 << precision) - freqs.iter().sum::<u32>();
    let mode = (0..a).max_by_key(|&i| counts[i]).unwrap_or(0);
    freqs[mode] += rem;
    (lo, freqs)
}

/// Encodes with `constriction`'s own categorical model and the default coder (state 0 start).
fn bare_encode<const P: usize>(symbols: &[i64], lo: i64, freqs: &[u32]) -> Vec<u32> {
    let model =
        ContiguousCategoricalEntropyModel::<u32, Vec<u32>, P>::from_nonzero_fixed_point_probabilities(
            freqs, false,
        )
        .expect("frequencies are nonzero and sum to 2^P");
    let mut coder = DefaultAnsCoder::new();
    for &u in symbols.iter().rev() {
        Encode::<P>::encode_symbol(&mut coder, (u - lo) as usize, &model)
            .expect("symbol in the alphabet");
    }
    coder.into_compressed().unwrap_infallible()
}

fn bare_lookup<const P: usize>(symbols: &[i64], runs: usize) -> f64 {
    let (lo, freqs) = histogram_frequencies(symbols, P as u32);
    let words = bare_encode::<P>(symbols, lo, &freqs);
    let model =
        ContiguousLookupDecoderModel::<u16, Vec<u16>, Box<[u16]>, P>::from_nonzero_fixed_point_probabilities(
            freqs.iter().map(|&f| f as u16),
            false,
        )
        .expect("frequencies are nonzero and sum to 2^P");
    let mut times: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            time_decode(&words, symbols.len(), |c| {
                Decode::<P>::decode_symbol(c, model.as_view()).unwrap_infallible()
            })
        })
        .collect();
    check_decode(&words, symbols, lo, |c| {
        Decode::<P>::decode_symbol(c, model.as_view()).unwrap_infallible()
    });
    median(&mut times)
}

fn bare_search<const P: usize>(symbols: &[i64], runs: usize) -> f64 {
    let (lo, freqs) = histogram_frequencies(symbols, P as u32);
    let words = bare_encode::<P>(symbols, lo, &freqs);
    let model =
        ContiguousCategoricalEntropyModel::<u32, Vec<u32>, P>::from_nonzero_fixed_point_probabilities(
            &freqs, false,
        )
        .expect("frequencies are nonzero and sum to 2^P");
    let mut times: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            time_decode(&words, symbols.len(), |c| {
                Decode::<P>::decode_symbol(c, &model).unwrap_infallible()
            })
        })
        .collect();
    check_decode(&words, symbols, lo, |c| {
        Decode::<P>::decode_symbol(c, &model).unwrap_infallible()
    });
    median(&mut times)
}

/// The bare coder's decode of `words` is `symbols` (what the timings measured was a decode).
fn check_decode(
    words: &[u32],
    symbols: &[i64],
    lo: i64,
    mut decode: impl FnMut(&mut DefaultAnsCoder) -> usize,
) {
    let mut coder = DefaultAnsCoder::from_compressed(words.to_vec())
        .expect("the encoder's output is a valid stream");
    for (i, &u) in symbols.iter().enumerate() {
        let got = decode(&mut coder) as i64 + lo;
        assert_eq!(
            got, u,
            "bare coder: symbol {i} decodes as {got}, encoded {u}"
        );
    }
}

fn time_decode(
    words: &[u32],
    n: usize,
    mut decode: impl FnMut(&mut DefaultAnsCoder) -> usize,
) -> f64 {
    let start = Instant::now();
    let mut coder = DefaultAnsCoder::from_compressed(black_box(words.to_vec()))
        .expect("the encoder's output is a valid stream");
    let mut check = 0usize;
    for _ in 0..n {
        check = check.wrapping_add(decode(&mut coder));
    }
    black_box(check);
    start.elapsed().as_nanos() as f64 / n.max(1) as f64
}
