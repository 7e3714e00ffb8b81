//! Structured round trip: a small generated scene and encoder options, read from the input's
//! first bytes, encode and decode to the encoder's prediction, or the encoder refuses cleanly
//! (`salvq_conformance::fuzzing::round_trip`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    salvq_conformance::fuzzing::round_trip(salvq_conformance::fuzzing::RoundTrip::from_bytes(data))
});
