//! A driver model file, read every way the code reads one: a policy file (safetensors with
//! metadata) by the trainer (`PolicyNet::from_bytes`, what `PolicyNet::load` reads) and by every
//! `--driver PATH.safetensors` and a vehicle loading a pushed policy's weights
//! (`HostPolicy::from_safetensors`), and an ONNX model (`OnnxPolicy::from_bytes`, every
//! `--driver PATH.onnx`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_learn::PolicyNet;
use risktwin_policy::HostPolicy;
use risktwin_policy::onnx::OnnxPolicy;

fuzz_target!(|data: &[u8]| {
    let _ = HostPolicy::from_safetensors(data);
    let _ = PolicyNet::from_bytes(data);
    let _ = OnnxPolicy::from_bytes(data);
});
