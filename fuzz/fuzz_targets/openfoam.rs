#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tetloc_fuzz::openfoam(data));
