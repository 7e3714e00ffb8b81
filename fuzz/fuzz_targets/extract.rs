//! Rate extraction on arbitrary input (`salvq_conformance::fuzzing::extract_input`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq_conformance::fuzzing::extract_input(data));
