//! The report the `loop` role writes on shutdown (`risktwin cloud --loop-report FILE.md`): the
//! loop's state in figures, then every fleet episode of the library, the edge's outcome beside
//! the twin's.

use super::{LoopSummary, SetFigures};
use risktwin_store::library::{Outcome, StoredFleetEpisode};
use std::fmt::Write;

/// The report as Markdown.
pub fn markdown(summary: &LoopSummary, episodes: &[StoredFleetEpisode]) -> String {
    let mut md = String::new();
    let lib = &summary.library;
    let it = &summary.iteration;
    // Writing into a String cannot fail.
    let _ = writeln!(md, "# Closed loop over the fleet\n");
    let _ = writeln!(md, "| figure | value |\n|---|---|");
    for (name, value) in [
        ("scenarios in the library", lib.scenarios.to_string()),
        ("fleet episodes in the library", lib.episodes.to_string()),
        ("of which failures (collision or off road, as the edge reported)", lib.failures.to_string()),
        ("of which the twin disagrees", lib.disagreements.to_string()),
        ("pushes outstanding / given up", format!("{} / {}", lib.outstanding, lib.abandoned)),
        (
            "this run: scenarios pushed, retries, given up",
            format!("{}, {}, {}", summary.pushes, summary.retries, summary.abandoned),
        ),
        ("this run: episodes stored, failures", format!("{}, {}", summary.episodes, summary.failures)),
        ("this run: failures found per hour", format!("{:.1}", summary.failures_per_hour)),
        ("this run: children mutated around failures", summary.mutants.to_string()),
        ("this run: results for scenarios not in the library", summary.unknown_scenario.to_string()),
        (
            "loop iteration (episode handed on by the twin → scored, stored, ranked → next push out), p50 / max",
            format!("{:.1} / {:.1} ms over {}", it.p50_ms, it.max_ms, it.count),
        ),
        (
            "from the edge's result to the next push (the twin catching up with the episode's end included), p50 / max",
            format!("{:.1} / {:.1} ms", it.from_result_p50_ms, it.from_result_max_ms),
        ),
    ] {
        let _ = writeln!(md, "| {name} | {value} |");
    }
    let deployed = summary.deployed_version.map_or("the reference driver".to_owned(), |v| format!("version {v}"));
    let _ = writeln!(md, "\n## Policy versions (this run; the fleet drives {deployed})\n");
    let _ = writeln!(
        md,
        "| version | fleet failures | decision | regression set: collisions, completion (candidate / deployed) | held-out set: the same | why held back |\n|---|---|---|---|---|---|"
    );
    for g in &summary.gate {
        let set = |f: SetFigures| {
            let (c, cc) = (f.collisions, f.mean_route_completion);
            format!("{c}, {cc:.3} / {}, {:.3}", f.deployed_collisions, f.deployed_mean_route_completion)
        };
        let decision = if g.pushed { "pushed" } else { "held back" };
        let _ = writeln!(
            md,
            "| {} | {} | {decision} | {} | {} | {} |",
            g.version,
            g.failures,
            set(g.regression),
            set(g.held_out),
            g.reasons.join("; ")
        );
    }
    let _ = writeln!(md, "\n## Fleet episodes\n");
    let _ = writeln!(
        md,
        "| # | scenario | edge | driver | edge: collision, completion, S_risk | twin: collision, completion, S_risk (ticks) | disagreement |\n|---|---|---|---|---|---|---|"
    );
    for e in episodes {
        let ep = &e.episode;
        let twin = ep.twin_outcome.as_ref().map_or("—".to_owned(), |t| format!("{} ({})", verdict(t), ep.twin_ticks));
        let _ = writeln!(
            md,
            "| {} | {} | {}/{} | {} | {} | {} | {} |",
            e.seq,
            ep.scenario_id,
            ep.site,
            ep.edge,
            ep.edge_outcome.policy,
            verdict(&ep.edge_outcome),
            twin,
            ep.disagreement.as_deref().unwrap_or("")
        );
    }
    md
}

fn verdict(o: &Outcome) -> String {
    let collision = if o.metrics.collision { "yes" } else { "no" };
    format!("{collision}, {:.3}, {:.3}", o.metrics.route_completion, o.risk.score)
}
