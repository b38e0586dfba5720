//! `report.md`: what the run measured, in tables a person reads, and what it does not cover yet.

use super::RunMetrics;
use std::fmt::Write;

pub fn markdown(m: &RunMetrics) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# RiskTwin run (seed {})\n", m.seed);
    let _ = writeln!(
        s,
        "Scenarios of five kinds were sampled ({} per kind), filtered for physical feasibility, driven by the \
         reference driver (IDM/MOBIL on perceived objects) in the twin, scored with S_risk and stored in \
         `library.db`; {} mutation rounds then searched around the failures.\n",
        m.config.count_per_kind, m.config.iterations
    );
    let _ = writeln!(s, "## Generation\n");
    let _ = writeln!(s, "| kind | stored | infeasible | collisions |\n|---|---|---|---|");
    for (k, r) in &m.generation.by_kind {
        let _ = writeln!(s, "| {k} | {} | {} | {} |", r.stored, r.infeasible, r.collisions);
    }
    let _ = writeln!(s, "\n## Library by kind (after mutation)\n");
    let _ = writeln!(
        s,
        "| kind | scenarios | collisions | collision rate | mean S_risk | max S_risk |\n|---|---|---|---|---|---|"
    );
    for (k, r) in &m.by_kind {
        let _ = writeln!(
            s,
            "| {k} | {} | {} | {:.2} | {:.3} | {:.3} |",
            r.scenarios, r.collisions, r.collision_rate, r.mean_risk, r.max_risk
        );
    }
    if !m.rounds.is_empty() {
        let _ = writeln!(s, "\n## Mutation rounds\n");
        let _ = writeln!(
            s,
            "| round | parents | children | infeasible | parent mean S_risk | child mean S_risk | child collisions |\n|---|---|---|---|---|---|---|"
        );
        for r in &m.rounds {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.3} | {:.3} | {} |",
                r.round,
                r.parents,
                r.children,
                r.infeasible_children,
                r.parent_mean_risk,
                r.child_mean_risk,
                r.child_collisions
            );
        }
        let _ = writeln!(
            s,
            "\nChildren are neighbours of the riskiest parents (failures first); a child mean near the parent mean \
             says the failure region is wide, a much lower one that the failures sit on a thin edge."
        );
    }
    let _ = writeln!(s, "\n## Top scenarios\n");
    let _ = writeln!(
        s,
        "| rank | id | kind | S_risk | TTC | dist | lane | jerk | collision | min TTC s | min dist m |\n|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (i, r) in m.top.iter().enumerate() {
        let ttc = r.outcome.min_ttc_s.map_or("∞".to_string(), |t| format!("{t:.2}"));
        let _ = writeln!(
            s,
            "| {} | `{}` | {} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {ttc} | {:.2} |",
            i + 1,
            r.id,
            r.kind,
            r.risk.score,
            r.risk.ttc,
            r.risk.dist,
            r.risk.lane,
            r.risk.jerk,
            r.outcome.collision,
            r.outcome.min_distance_m
        );
    }
    if !m.heatmaps.is_empty() {
        let _ = writeln!(s, "\n## Risk fields of the top scenarios\n");
        for h in &m.heatmaps {
            let _ = writeln!(s, "![{h}]({h})\n");
        }
    }
    let _ = writeln!(
        s,
        "\n## Not in this run yet\n\nPolicy retraining (PPO/SAC) with training curves and the base / risk-only / full \
         ablation, and the MCAP recording, arrive with the learning and pipeline work; this report covers the \
         scenario-generation and risk-scoring half of the loop only."
    );
    s
}
