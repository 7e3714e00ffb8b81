//! Whole-stream decode under tight limits (`salvq::fuzzing::decode_input`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq::fuzzing::decode_input(data));
