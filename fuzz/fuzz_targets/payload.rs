//! One payload of a valid stream replaced by the input (`salvq_conformance::fuzzing::payload_input`):
//! the payload decoders behind a valid signature, `HEAD`, chunk order and CRCs.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq_conformance::fuzzing::payload_input(data));
