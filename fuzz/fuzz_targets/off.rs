#![no_main]
//! Fuzz target `off`: see fuzz/src/lib.rs and docs/fuzzing.md.
use libfuzzer_sys::fuzz_target;
use raysift_fuzz::{run, Target};

fuzz_target!(|data: &[u8]| run(Target::Off, data));
