//! Whole-stream decode under tight limits (`salvq_conformance::fuzzing::decode_input_metered`), with the
//! heap capped at what the preflight allows (`salvq_conformance::fuzzing::allocation_bound`): a decode
//! that allocates past it fails an allocation and aborts, and libFuzzer keeps the input.
#![no_main]

use std::alloc::System;

use cap::Cap;
use salvq_conformance::fuzzing::AllocationMeter;

#[global_allocator]
static ALLOCATOR: Cap<System> = Cap::new(System, usize::MAX);

struct CapMeter;

impl AllocationMeter for CapMeter {
    fn cap(&self, extra: Option<u64>) {
        let limit = match extra {
            Some(bytes) => ALLOCATOR
                .allocated()
                .saturating_add(usize::try_from(bytes).unwrap_or(usize::MAX)),
            None => usize::MAX,
        };
        // Fails only when the new limit is below what is allocated, which `allocated() + x`
        // never is.
        let _ = ALLOCATOR.set_limit(limit);
    }
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| salvq_conformance::fuzzing::decode_input_metered(data, &CapMeter));
