//! Entropy coding round trips (spec §6.2 – §6.4): random symbol streams with escapes and binary
//! events; the spec-text port (`salvq_conformance::reference_coder`) decodes and encodes them identically to
//! `constriction`; a golden word vector pins the bitstream; coded size tracks `ideal_bits`.

use constriction::stream::model::ContiguousCategoricalEntropyModel;
use constriction::stream::stack::AnsCoder;
use constriction::stream::Encode;
use constriction::UnwrapInfallible;
use salvq_bench::coder::{sigma_to_q16, synthetic_samples};
use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::{
    checked_scale_index, scale_index, GaussianTables, SymbolReader, PRECISION, SCALE_COUNT,
    SCALE_INDEX_COUNT,
};
use salvq_bitstream::error::Error;
use salvq_conformance::reference_coder as reference;
use salvq_encoder::writers::SymbolWriter;
use salvq_gen::rng::Stream;

const TAG: ChunkTag = ChunkTag::AFEA;

/// One event of a test stream.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Event {
    Symbol { u: i64, k: u8 },
    Bit { bit: bool, freq_one: u32 },
}

/// A random event sequence: mostly Gaussian-like symbols, some escapes (up to the largest
/// encodable magnitude), some binary events with random probabilities (incl. out-of-range
/// frequencies, which both sides clamp).
fn random_events(rng: &mut Stream, tables: &GaussianTables, n: usize) -> Vec<Event> {
    let p = tables.precision();
    (0..n)
        .map(|_| match rng.below(20) {
            0..=1 => Event::Bit {
                bit: rng.below(2) == 1,
                freq_one: match rng.below(4) {
                    0 => rng.below(u64::from(u32::MAX)) as u32,
                    1 => 1 << (p - 1),
                    _ => rng.below(1 << p) as u32,
                },
            },
            2 => {
                let k = rng.below(SCALE_INDEX_COUNT as u64) as u8;
                // A wide scale's high part h escapes (§6.3.6): u = h·2^b + low bits.
                let (t, b) = wide_by_the_text(k);
                let r = i64::from(tables.radius(t));
                // Escapes of every prefix length, up to w = 2^31 − 1.
                let bits = rng.below(32) as u32;
                let w = if bits == 31 {
                    (1i64 << 31) - 1
                } else {
                    (1i64 << bits) + rng.below(1 << bits) as i64
                };
                let q = if rng.below(2) == 1 { -(r + w) } else { r + w };
                let low = rng.below(1 << b) as i64;
                Event::Symbol {
                    u: (q << b) + low,
                    k,
                }
            }
            _ => {
                let k = rng.below(SCALE_INDEX_COUNT as u64) as u8;
                let sigma = 2f64.powf((f64::from(k) - 24.0) / 8.0);
                Event::Symbol {
                    u: (sigma * rng.normal()).round() as i64,
                    k,
                }
            }
        })
        .collect()
}

/// §6.3.6 from the text: a wide scale k's table scale t = k − 8b and shift
/// b = ⌊(k − 56) / 8⌋; a table's own index is (k, 0).
fn wide_by_the_text(k: u8) -> (u8, u32) {
    if k < 64 {
        (k, 0)
    } else {
        let b = (k - 56) / 8;
        (k - 8 * b, u32::from(b))
    }
}

fn encode(tables: &GaussianTables, events: &[Event]) -> Vec<u8> {
    let mut w = SymbolWriter::new(TAG, tables);
    for e in events {
        match *e {
            Event::Symbol { u, k } => w.symbol(u, k).expect("encodable"),
            Event::Bit { bit, freq_one } => w.bit(bit, freq_one),
        }
    }
    w.finish()
}

fn decode(tables: &GaussianTables, events: &[Event], body: &[u8]) -> Vec<Event> {
    let mut r = SymbolReader::new(TAG, body, tables).expect("valid body");
    let out = events
        .iter()
        .map(|e| match *e {
            Event::Symbol { k, .. } => Event::Symbol {
                u: r.symbol(k).expect("valid body"),
                k,
            },
            Event::Bit { freq_one, .. } => Event::Bit {
                bit: r.bit(freq_one).expect("valid body"),
                freq_one,
            },
        })
        .collect();
    r.finish().expect("valid body ends cleanly");
    out
}

/// The spec-text port decodes the same events.
fn decode_reference(tables: &GaussianTables, events: &[Event], body: &[u8]) -> Vec<Event> {
    let mut d = reference::Decoder::new(body, tables.precision()).expect("valid body");
    let out = events
        .iter()
        .map(|e| match *e {
            Event::Symbol { k, .. } => {
                let (t, b) = wide_by_the_text(k);
                let t = tables.scale(t);
                let q = d
                    .decode_symbol(t.frequencies(), t.radius())
                    .expect("valid body")
                    .expect("no overflow");
                let low = if b > 0 {
                    let uniform = vec![1u32 << (tables.precision() - b); 1 << b];
                    d.decode(&uniform).expect("valid body") as i64
                } else {
                    0
                };
                Event::Symbol {
                    u: (q << b) + low,
                    k,
                }
            }
            Event::Bit { freq_one, .. } => Event::Bit {
                bit: d.decode_bit(freq_one).expect("valid body"),
                freq_one,
            },
        })
        .collect();
    d.finish().expect("valid body ends cleanly");
    out
}

/// The spec-text port's encoder, fed the intervals §6.2.1 and §6.4 define.
fn encode_reference(tables: &GaussianTables, events: &[Event]) -> Vec<u8> {
    let p = tables.precision();
    let total = 1u32 << p;
    let mut e = reference::Encoder::new(p);
    let bit = |e: &mut reference::Encoder, b: bool, f1: u32| {
        let f1 = f1.clamp(1, total - 1);
        if b {
            e.push(total - f1, f1)
        } else {
            e.push(0, total - f1)
        }
    };
    for ev in events {
        match *ev {
            Event::Bit { bit: b, freq_one } => bit(&mut e, b, freq_one),
            Event::Symbol { u: full, k } => {
                let (t, b) = wide_by_the_text(k);
                let u = full.div_euclid(1 << b);
                let t = tables.scale(t);
                let r = i64::from(t.radius());
                let c = t.cumulative();
                let i = if u.abs() <= r {
                    (u + r) as usize
                } else {
                    t.escape_index()
                };
                e.push(c[i], c[i + 1] - c[i]);
                if u.abs() > r {
                    let w = (u.abs() - r) as u64;
                    let l = 63 - w.leading_zeros();
                    for _ in 0..l {
                        bit(&mut e, false, total / 2);
                    }
                    for j in (0..=l).rev() {
                        bit(&mut e, (w >> j) & 1 == 1, total / 2);
                    }
                    bit(&mut e, u < 0, total / 2);
                }
                if b > 0 {
                    let low = (full - (u << b)) as u32;
                    e.push(low << (p - b), 1 << (p - b));
                }
            }
        }
    }
    e.finish()
}

#[test]
fn random_streams_round_trip_and_match_the_spec_port() {
    let mut rng = Stream::new(7, 0xE7, 0);
    for precision in [PRECISION, 12, 20, 24] {
        let tables = GaussianTables::new(precision);
        for len in [0usize, 1, 2, 3, 10, 100, 1000, 5000] {
            for _ in 0..4 {
                let events = random_events(&mut rng, &tables, len);
                let body = encode(&tables, &events);
                assert_eq!(body.len() % 4, 0);
                assert!(body.len() >= 8);
                assert_eq!(decode(&tables, &events, &body), events);
                assert_eq!(decode_reference(&tables, &events, &body), events);
                assert_eq!(
                    encode_reference(&tables, &events),
                    body,
                    "P = {precision}, {len} events"
                );
            }
        }
    }
}

#[test]
fn empty_stream_is_the_initial_state() {
    let body = SymbolWriter::new(TAG, GaussianTables::standard()).finish();
    assert_eq!(body, [1, 0, 0, 0, 0, 0, 0, 0]);
    SymbolReader::new(TAG, &body, GaussianTables::standard())
        .unwrap()
        .finish()
        .unwrap();
}

/// The events of the golden vector (spec §6.2.8).
fn golden_events() -> Vec<Event> {
    vec![
        Event::Symbol { u: 0, k: 24 },
        Event::Symbol { u: -3, k: 24 },
        Event::Symbol { u: 5, k: 40 },
        Event::Bit {
            bit: true,
            freq_one: 1 << 14,
        },
        Event::Symbol { u: 0, k: 0 },
        Event::Symbol { u: 1, k: 0 },
        Event::Symbol { u: -100, k: 10 },
        Event::Bit {
            bit: false,
            freq_one: 60000,
        },
        Event::Symbol { u: 17, k: 63 },
        Event::Symbol {
            u: -1_000_000,
            k: 63,
        },
    ]
}

/// `constriction`'s output for a fixed input: catches an upgrade that changes the bitstream.
#[test]
fn golden_vector() {
    let body = encode(GaussianTables::standard(), &golden_events());
    let words: Vec<u32> = body
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let expected: [u32; 5] = [
        0x3220_f91d,
        0xf52c_9853,
        0x9460_0dfe,
        0xc9df_b75b,
        0x5e00_0000,
    ];
    assert_eq!(words, expected, "golden words: {words:#010x?}");
    assert_eq!(
        encode_reference(GaussianTables::standard(), &golden_events()),
        body
    );
    assert_eq!(
        decode(GaussianTables::standard(), &golden_events(), &body),
        golden_events()
    );
}

/// `constriction`'s stock categorical model, fed the table frequencies, writes the same words
/// as the crate's interval models.
#[test]
fn stock_constriction_model_gives_the_same_words() {
    let tables = GaussianTables::standard();
    let samples = synthetic_samples(3000, 5, 0.1, 30.0);
    let events: Vec<(i64, u8)> = samples
        .iter()
        .map(|s| {
            let k = scale_index(sigma_to_q16(s.sigma));
            let r = i64::from(tables.radius(k));
            (s.u.clamp(-r, r), k)
        })
        .collect();
    let models: Vec<_> = (0..SCALE_COUNT as u8)
        .map(|k| {
            ContiguousCategoricalEntropyModel::<u32, Vec<u32>, 16>::from_nonzero_fixed_point_probabilities(
                tables.scale(k).frequencies(),
                false,
            )
            .unwrap()
        })
        .collect();
    let mut coder: AnsCoder<u32, u64> = AnsCoder::from_raw_parts(Vec::new(), 1 << 32);
    for &(u, k) in events.iter().rev() {
        let r = i64::from(tables.radius(k));
        Encode::<16>::encode_symbol(&mut coder, (u + r) as usize, &models[usize::from(k)]).unwrap();
    }
    let mut words = coder.into_compressed().unwrap_infallible();
    words.reverse();
    let stock: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();

    let mut w = SymbolWriter::new(TAG, tables);
    for &(u, k) in &events {
        w.symbol(u, k).unwrap();
    }
    assert_eq!(w.finish(), stock);
}

#[test]
fn coded_size_tracks_ideal_bits() {
    let tables = GaussianTables::standard();
    for (lo, hi) in [(0.2, 8.0), (0.05, 40.0)] {
        let samples = synthetic_samples(200_000, 11, lo, hi);
        let mut w = SymbolWriter::new(TAG, tables);
        let mut ideal = 0.0;
        for s in &samples {
            let k = scale_index(sigma_to_q16(s.sigma));
            ideal += tables.ideal_bits(k, s.u);
            w.symbol(s.u, k).unwrap();
        }
        let coded = (w.finish().len() * 8) as f64;
        assert!(
            coded <= 1.001 * ideal + 64.0,
            "σ in [{lo}, {hi}]: coded {coded} bits, ideal {ideal:.1}"
        );
        assert!(coded >= ideal - 64.0);
    }
}

#[test]
fn ideal_bits_of_escapes() {
    let tables = GaussianTables::standard();
    let t = tables.scale(24);
    let r = i64::from(t.radius());
    let f_esc = f64::from(t.frequencies()[t.escape_index()]);
    let esc = f64::from(PRECISION) - f_esc.log2();
    // w = 1: prefix 0, one value bit, one sign bit.
    assert_eq!(tables.ideal_bits(24, r + 1), esc + 2.0);
    // w = 5 = 0b101: 2 zeros, 3 value bits, sign.
    assert_eq!(tables.ideal_bits(24, -(r + 5)), esc + 6.0);
    assert_eq!(tables.ideal_bits(24, r + (1 << 31)), f64::INFINITY);
    assert_eq!(tables.ideal_bits(24, i64::MIN), f64::INFINITY);
}

/// §6.3.6: a wide scale costs its high part ⌊u / 2^b⌋ and b bits; the floor makes −1 a
/// high part −1 with all low bits set.
#[test]
fn ideal_bits_of_wide_scales() {
    let tables = GaussianTables::standard();
    for (k, t, b) in [
        (64u8, 56u8, 1u32),
        (71, 63, 1),
        (72, 56, 2),
        (100, 60, 5),
        (127, 63, 8),
    ] {
        for u in [0i64, 1, -1, 255, -256, 1 << 20, -(1 << 20) - 7] {
            let q = u.div_euclid(1 << b);
            assert_eq!(
                tables.ideal_bits(k, u),
                tables.ideal_bits(t, q) + f64::from(b),
                "k {k}, u {u}"
            );
        }
    }
    // u = −1 at k = 64: q = −1, low bit 1; at k = 127: q = −1, low bits 255.
    let mut w = SymbolWriter::new(TAG, tables);
    w.symbol(-1, 64).unwrap();
    w.symbol(-1, 127).unwrap();
    assert_eq!(w.interval_count(), 4);
    let body = w.finish();
    let mut d = reference::Decoder::new(&body, PRECISION).unwrap();
    for (t, b, low) in [(56u8, 1u32, 1usize), (63, 8, 255)] {
        let s = tables.scale(t);
        assert_eq!(d.decode_symbol(s.frequencies(), s.radius()), Ok(Ok(-1)));
        assert_eq!(d.decode(&vec![1 << (PRECISION - b); 1 << b]), Ok(low));
    }
    d.finish().unwrap();
}

#[test]
fn writer_rejects_unencodable_symbols_without_writing() {
    let tables = GaussianTables::standard();
    let r = i64::from(tables.radius(5));
    let mut w = SymbolWriter::new(TAG, tables);
    w.symbol(1, 5).unwrap();
    for u in [r + (1 << 31), -(r + (1 << 31)), i64::MAX, i64::MIN] {
        match w.symbol(u, 5) {
            Err(Error::EscapeOverflow {
                tag,
                symbol,
                prefix_bits,
            }) => {
                assert_eq!((tag, symbol), (TAG, 1));
                assert!(prefix_bits > 30);
            }
            other => panic!("{u}: {other:?}"),
        }
    }
    assert_eq!(
        w.symbol(0, 128),
        Err(Error::ScaleIndexOutOfRange {
            tag: TAG,
            symbol: 1,
            scale_index: 128,
            max: 127
        })
    );
    // A wide scale's high part h = ⌊u / 2^8⌋ at k = 127 has the same bound (§6.3.6).
    let r63 = i64::from(tables.radius(63));
    assert!(matches!(
        w.symbol((r63 + (1 << 31)) << 8, 127),
        Err(Error::EscapeOverflow { symbol: 1, .. })
    ));
    // The largest magnitudes still round-trip.
    w.symbol(r + (1 << 31) - 1, 5).unwrap();
    w.symbol(-(r + (1 << 31) - 1), 5).unwrap();
    let body = w.finish();
    let mut rd = SymbolReader::new(TAG, &body, tables).unwrap();
    assert_eq!(rd.symbol(5).unwrap(), 1);
    assert_eq!(rd.symbol(5).unwrap(), r + (1 << 31) - 1);
    assert_eq!(rd.symbol(5).unwrap(), -(r + (1 << 31) - 1));
    rd.finish().unwrap();
}

#[test]
fn scale_index_check_helper() {
    assert_eq!(checked_scale_index(TAG, 3, 0), Ok(0));
    assert_eq!(checked_scale_index(TAG, 3, 63), Ok(63));
    assert_eq!(checked_scale_index(TAG, 3, 64), Ok(64));
    assert_eq!(checked_scale_index(TAG, 3, 127), Ok(127));
    for bad in [-1, 128, i64::MIN, i64::MAX] {
        let e = checked_scale_index(TAG, 3, bad).unwrap_err();
        assert_eq!(
            e,
            Error::ScaleIndexOutOfRange {
                tag: TAG,
                symbol: 3,
                scale_index: bad,
                max: 127
            }
        );
        assert_eq!(e.spec_section(), "§6.3");
    }
}
