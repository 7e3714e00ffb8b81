//! The `HEAD` preflight on arbitrary payloads (`salvq_conformance::fuzzing::preflight_input`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq_conformance::fuzzing::preflight_input(data));
