//! Hostile entropy-coded bodies (spec §6.2.6, §6.4): every `AnsFault`, `EscapeOverflow` from a
//! crafted stream, and thousands of random bodies decoded without panic — with the same values
//! and errors as the spec-text port (`salvq_conformance::reference_coder`).

use salvq_bitstream::container::chunk::ChunkTag;
use salvq_bitstream::entropy::{GaussianTables, SymbolReader, SCALE_COUNT, SCALE_INDEX_COUNT};
use salvq_bitstream::error::{AnsFault, Error};
use salvq_conformance::reference_coder as reference;
use salvq_encoder::writers::SymbolWriter;
use salvq_gen::rng::Stream;

const TAG: ChunkTag = ChunkTag::AOFF;

fn ans(fault: AnsFault) -> Error {
    Error::AnsStreamInvalid { tag: TAG, fault }
}

fn words(w: &[u32]) -> Vec<u8> {
    w.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn tables() -> &'static GaussianTables {
    GaussianTables::standard()
}

/// A valid body of `n` symbols at scale 30 and the symbols.
fn valid_body(n: usize) -> (Vec<u8>, Vec<i64>) {
    let mut rng = Stream::new(3, 0xFA, n as u64);
    let symbols: Vec<i64> = (0..n)
        .map(|_| (2.0 * rng.normal()).round() as i64)
        .collect();
    let mut w = SymbolWriter::new(TAG, tables());
    for &u in &symbols {
        w.symbol(u, 30).unwrap();
    }
    (w.finish(), symbols)
}

#[test]
fn framing() {
    for len in [0usize, 1, 4, 7, 9, 13] {
        let body = vec![1u8; len];
        assert_eq!(
            SymbolReader::new(TAG, &body, tables()).unwrap_err(),
            ans(AnsFault::Framing),
            "{len} bytes"
        );
        assert_eq!(
            reference::Decoder::new(&body, 16).unwrap_err(),
            AnsFault::Framing
        );
    }
}

#[test]
fn zero_top_word() {
    let body = words(&[0, 5, 7]);
    assert_eq!(
        SymbolReader::new(TAG, &body, tables()).unwrap_err(),
        ans(AnsFault::ZeroTopWord)
    );
    assert_eq!(
        reference::Decoder::new(&body, 16).unwrap_err(),
        AnsFault::ZeroTopWord
    );
}

#[test]
fn out_of_words_when_truncated() {
    let (body, symbols) = valid_body(2000);
    assert!(body.len() > 16);
    let cut = &body[..body.len() - 4];
    let mut r = SymbolReader::new(TAG, cut, tables()).unwrap();
    let mut err = None;
    for _ in &symbols {
        if let Err(e) = r.symbol(30) {
            err = Some(e);
            break;
        }
    }
    assert_eq!(err, Some(ans(AnsFault::OutOfWords)));
    // The reader stays broken: every further call repeats the error.
    assert_eq!(r.symbol(30), Err(ans(AnsFault::OutOfWords)));
    assert_eq!(r.bit(1000), Err(ans(AnsFault::OutOfWords)));
    assert_eq!(r.finish(), Err(ans(AnsFault::OutOfWords)));
}

#[test]
fn out_of_words_when_reading_past_the_end() {
    let (body, symbols) = valid_body(50);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    for &u in &symbols {
        assert_eq!(r.symbol(30).unwrap(), u);
    }
    // More symbols than were written: the state falls below 2^32 with no word left.
    let mut result = Ok(0);
    for _ in 0..100 {
        result = r.symbol(30);
        if result.is_err() {
            break;
        }
    }
    assert_eq!(result, Err(ans(AnsFault::OutOfWords)));
}

#[test]
fn words_left_over() {
    let (mut body, symbols) = valid_body(300);
    body.extend_from_slice(&[9, 9, 9, 9]);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    for &u in &symbols {
        assert_eq!(r.symbol(30).unwrap(), u);
    }
    assert_eq!(r.remaining_words(), 1);
    assert_eq!(r.finish(), Err(ans(AnsFault::WordsLeftOver)));

    // Reading fewer symbols than were written leaves words too.
    let (body, _) = valid_body(300);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    r.symbol(30).unwrap();
    assert_eq!(r.finish(), Err(ans(AnsFault::WordsLeftOver)));
}

#[test]
fn state_not_final() {
    // A body that is only a state other than 2^32, with no symbols.
    let body = words(&[1, 1]);
    let r = SymbolReader::new(TAG, &body, tables()).unwrap();
    assert_eq!(r.finish(), Err(ans(AnsFault::StateNotFinal)));
    let d = reference::Decoder::new(&body, 16).unwrap();
    assert_eq!(d.finish(), Err(AnsFault::StateNotFinal));

    // A short valid stream read with one symbol too few: all words used, wrong state.
    let mut w = SymbolWriter::new(TAG, tables());
    w.symbol(0, 30).unwrap();
    w.symbol(1, 30).unwrap();
    let body = w.finish();
    assert_eq!(body.len(), 8);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    r.symbol(30).unwrap();
    assert_eq!(r.finish(), Err(ans(AnsFault::StateNotFinal)));
}

/// ESCAPE followed by `zeros` escape bits of value 0, then a 1 and the rest of a valid escape.
fn crafted_escape(zeros: u32) -> Vec<u8> {
    let t = tables().scale(20);
    let c = t.cumulative();
    let e = t.escape_index();
    let mut enc = reference::Encoder::new(16);
    enc.push(c[e], c[e + 1] - c[e]);
    for _ in 0..zeros {
        enc.push(0, 1 << 15);
    }
    enc.push(1 << 15, 1 << 15); // the terminating 1
    for _ in 0..zeros.min(30) {
        enc.push(1 << 15, 1 << 15);
    }
    enc.push(0, 1 << 15); // sign: positive
    enc.finish()
}

#[test]
fn escape_overflow_on_a_crafted_stream() {
    // 30 zeros is the longest prefix: w = 2^31 − 1.
    let body = crafted_escape(30);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    let r20 = i64::from(tables().radius(20));
    assert_eq!(r.symbol(20).unwrap(), r20 + (1 << 31) - 1);
    r.finish().unwrap();

    let body = crafted_escape(31);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    let err = Error::EscapeOverflow {
        tag: TAG,
        symbol: 0,
        prefix_bits: 31,
    };
    assert_eq!(r.symbol(20), Err(err.clone()));
    assert_eq!(err.spec_section(), "§6.4");
    assert_eq!(r.symbol(20), Err(err.clone()));
    assert_eq!(r.finish(), Err(err));
    let mut d = reference::Decoder::new(&body, 16).unwrap();
    let t = tables().scale(20);
    assert_eq!(d.decode_symbol(t.frequencies(), t.radius()), Ok(Err(31)));
}

#[test]
fn out_of_range_scale_index_reads_nothing() {
    let (body, symbols) = valid_body(5);
    let mut r = SymbolReader::new(TAG, &body, tables()).unwrap();
    assert_eq!(r.symbol(30).unwrap(), symbols[0]);
    assert_eq!(
        r.symbol(SCALE_INDEX_COUNT as u8),
        Err(Error::ScaleIndexOutOfRange {
            tag: TAG,
            symbol: 1,
            scale_index: 128,
            max: 127
        })
    );
    for &u in &symbols[1..] {
        assert_eq!(r.symbol(30).unwrap(), u);
    }
    r.finish().unwrap();
}

/// What one decoder made of one call.
#[derive(Debug, PartialEq)]
enum Outcome {
    Value(i64),
    Ans(AnsFault),
    Overflow,
}

#[test]
fn random_bodies_never_panic_and_agree_with_the_spec_port() {
    let mut rng = Stream::new(99, 0xBAD, 0);
    let (valid, _) = valid_body(400);
    let tables = tables();
    for case in 0..4000u64 {
        // Random bytes, or a valid body with a few bytes flipped.
        let body: Vec<u8> = if case % 2 == 0 {
            let len = rng.below(120) as usize;
            let mut b: Vec<u8> = (0..len).map(|_| rng.below(256) as u8).collect();
            if case % 8 == 0 && b.len() > 3 {
                // Small top words make long escape runs and early ends likelier.
                b[0] = rng.below(3) as u8;
                b[1..4].fill(0);
            }
            b
        } else {
            let mut b = valid.clone();
            for _ in 0..1 + rng.below(3) {
                let i = rng.below(b.len() as u64) as usize;
                b[i] ^= 1 << rng.below(8);
            }
            b
        };
        let mine = SymbolReader::new(TAG, &body, tables);
        let theirs = reference::Decoder::new(&body, 16);
        let (mut mine, mut theirs) = match (mine, theirs) {
            (Ok(m), Ok(t)) => (m, t),
            (Err(Error::AnsStreamInvalid { fault, .. }), Err(t)) => {
                assert_eq!(fault, t);
                continue;
            }
            (m, t) => panic!("case {case}: {m:?} vs {t:?}"),
        };
        for _ in 0..rng.below(600) {
            let (a, b) = if rng.below(8) == 0 {
                let f = rng.below(1 << 17) as u32;
                let a = match mine.bit(f) {
                    Ok(v) => Outcome::Value(i64::from(v)),
                    Err(Error::AnsStreamInvalid { fault, .. }) => Outcome::Ans(fault),
                    Err(e) => panic!("{e:?}"),
                };
                let b = match theirs.decode_bit(f) {
                    Ok(v) => Outcome::Value(i64::from(v)),
                    Err(f) => Outcome::Ans(f),
                };
                (a, b)
            } else {
                let k = rng.below(SCALE_COUNT as u64) as u8;
                let a = match mine.symbol(k) {
                    Ok(v) => Outcome::Value(v),
                    Err(Error::AnsStreamInvalid { fault, .. }) => Outcome::Ans(fault),
                    Err(Error::EscapeOverflow { .. }) => Outcome::Overflow,
                    Err(e) => panic!("{e:?}"),
                };
                let t = tables.scale(k);
                let b = match theirs.decode_symbol(t.frequencies(), t.radius()) {
                    Ok(Ok(v)) => Outcome::Value(v),
                    Ok(Err(_)) => Outcome::Overflow,
                    Err(f) => Outcome::Ans(f),
                };
                (a, b)
            };
            assert_eq!(a, b, "case {case}");
            if !matches!(a, Outcome::Value(_)) {
                break;
            }
        }
        let _ = mine.finish();
    }
}
