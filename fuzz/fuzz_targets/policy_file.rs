//! A policy file (safetensors with metadata), read both ways the code reads one: by the trainer
//! and `risktwin regress` (`PolicyNet::from_bytes`, what `PolicyNet::load` reads) and by a
//! vehicle loading a pushed policy's weights (`HostPolicy::from_safetensors`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_policy::HostPolicy;
use risktwin_learn::PolicyNet;

fuzz_target!(|data: &[u8]| {
    let _ = HostPolicy::from_safetensors(data);
    let _ = PolicyNet::from_bytes(data);
});
