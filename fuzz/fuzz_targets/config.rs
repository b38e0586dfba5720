//! The JSON configuration files of the binary: `risktwin run --config` (`RunConfig::from_json`
//! then `validate`) and `risktwin v2x sweep --config` (`SweepConfig`, then the grid it spans).
//! The first byte picks the file; the rest is its text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_v2x::sweep::SweepConfig;
use risktwin_pipeline::RunConfig;

fuzz_target!(|data: &[u8]| {
    let Some((&which, text)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(text) else { return };
    if which % 2 == 0 {
        if let Ok(config) = RunConfig::from_json(text) {
            let _ = config.validate();
        }
    } else if let Ok(config) = serde_json::from_str::<SweepConfig>(text) {
        let _ = config.grid();
    }
});
