//! The octree geometry decoder (§8) on arbitrary bodies (`salvq_conformance::fuzzing::geometry_input`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq_conformance::fuzzing::geometry_input(data));
