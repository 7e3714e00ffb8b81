//! The octree geometry decoder (§8) on arbitrary bodies (`salvq::fuzzing::geometry_input`).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq::fuzzing::geometry_input(data));
