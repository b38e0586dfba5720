//! A CommonRoad scenario file, as `risktwin criticality --commonroad`, `simulate` and `import`
//! read it: parsed (`parse_scenario`), then the criticality measures of its default ego over the
//! whole scenario (`scenario_criticality`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_commonroad::criticality::scenario_criticality;
use risktwin_commonroad::parse_scenario;

fuzz_target!(|data: &[u8]| {
    // The binary reads the file as UTF-8 text (`read_xml`): anything else is refused before.
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(scenario) = parse_scenario(text) {
        let _ = scenario_criticality(&scenario, None);
    }
});
