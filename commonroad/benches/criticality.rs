//! In-process cost of the criticality measures of whole CommonRoad scenarios: read the file,
//! parse it, compute every (time step, other) cell and every pair summary — what
//! `risktwin criticality` does between its start-up and its output. Used by
//! `deploy/bench/criticality-vs-crime.sh` beside the per-process time and CriMe's evaluation.
//!
//! ```sh
//! cargo bench -p risktwin-commonroad --bench criticality -- [--repeat N] [FILE.xml EGO_ID]...
//! ```
//!
//! Without scenarios it times every `data/commonroad/*.xml` whose `.yaml` names an ego
//! (`ego_id:`). Relative paths are from `commonroad/` (cargo runs benches there). Prints one line
//! per scenario: `in_process_ms best=… median=… read_parse_median=… cells=… file=…`.

use risktwin_commonroad::criticality::scenario_criticality;
use risktwin_commonroad::parse_scenario;
use std::process::ExitCode;
use std::time::Instant;

fn main() -> ExitCode {
    // `cargo bench` appends `--bench`.
    let mut args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let mut repeat = 21;
    if let Some(k) = args.iter().position(|a| a == "--repeat") {
        match args.get(k + 1).and_then(|n| n.parse().ok()) {
            Some(n) if n > 0 => repeat = n,
            _ => return usage("--repeat needs a positive count"),
        }
        args.drain(k..k + 2);
    }
    if args.is_empty() {
        args = match scenarios_with_ego() {
            Ok(a) => a,
            Err(e) => return fail(&format!("cannot list data/commonroad: {e}")),
        };
    }
    if !args.len().is_multiple_of(2) {
        return usage("give FILE.xml EGO_ID pairs");
    }
    for pair in args.chunks(2) {
        let (file, ego) = (&pair[0], &pair[1]);
        let Ok(ego) = ego.parse::<u64>() else { return usage(&format!("ego id '{ego}' is not an integer")) };
        // Whole (read + parse + measures), and the read + parse part alone, per run.
        let (mut whole_ms, mut parse_ms) = (Vec::with_capacity(repeat), Vec::with_capacity(repeat));
        let mut cells = 0;
        for _ in 0..repeat {
            let start = Instant::now();
            let text = match std::fs::read_to_string(file) {
                Ok(t) => t,
                Err(e) => return fail(&format!("cannot read {file}: {e}")),
            };
            let scenario = match parse_scenario(&text) {
                Ok(s) => s,
                Err(e) => return fail(&format!("{file}: {e}")),
            };
            parse_ms.push(start.elapsed().as_secs_f64() * 1e3);
            match scenario_criticality(&scenario, Some(ego)) {
                Ok(m) => cells = std::hint::black_box(m).cells.len(),
                Err(e) => return fail(&format!("{file}: {e}")),
            }
            whole_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let parse_median = median(&mut parse_ms);
        let whole_median = median(&mut whole_ms);
        println!(
            "in_process_ms best={:.3} median={whole_median:.3} read_parse_median={parse_median:.3} cells={cells} file={file}",
            whole_ms[0]
        );
    }
    ExitCode::SUCCESS
}

/// `FILE.xml EGO_ID` for every scenario of data/commonroad/ whose YAML names the ego.
fn scenarios_with_ego() -> std::io::Result<Vec<String>> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/commonroad");
    let mut yamls: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    yamls.sort();
    let mut args = Vec::new();
    for yaml in yamls {
        let xml = yaml.with_extension("xml");
        let text = std::fs::read_to_string(&yaml)?;
        let ego = text.lines().find_map(|l| l.trim().strip_prefix("ego_id:").map(|v| v.trim().to_string()));
        if let Some(ego) = ego.filter(|e| !e.is_empty())
            && xml.exists()
        {
            args.extend([xml.display().to_string(), ego]);
        }
    }
    Ok(args)
}

fn usage(why: &str) -> ExitCode {
    fail(&format!("{why}\nusage: criticality [--repeat N] FILE.xml EGO_ID..."))
}

fn fail(message: &str) -> ExitCode {
    eprintln!("error: {message}");
    ExitCode::from(2)
}
