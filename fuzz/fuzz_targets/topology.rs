//! A deployment topology file, as `risktwin deploy` reads it (`topology::parse`: TOML, names,
//! links, roles, events).
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_deploy::topology::parse;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = parse(text);
});
