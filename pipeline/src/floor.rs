//! The achievable floor in the report: every variant's held-out collision rate per kind next
//! to what the privileged planner (`common::planner`) achieved on the same scenarios.

use crate::metrics::RunMetrics;
use std::fmt::Write;

/// The "Against the achievable floor" part of the ablation section.
pub fn section(s: &mut String, m: &RunMetrics) {
    let (floor, ab) = (&m.floor, &m.ablation);
    let _ = writeln!(
        s,
        "\n### Against the achievable floor\n\nA privileged planner — full ground truth, a beam search over the twin's \
         own dynamics and step (`risktwin scenarios floor`) — found a drive that completes the route without \
         collision or leaving the road in {} of the {} held-out scenarios. Where it found none, its best attempt \
         counts; its collision rate is therefore an upper bound of the collision floor (a search can miss a \
         drive), and its avoidable share a lower bound of the success a policy can reach. Variants: collision rate, \
         mean ± std over seeds.\n",
        floor.avoidable(None),
        floor.cases.len()
    );
    let names: Vec<&str> = ab.variants.iter().map(|v| v.variant.as_str()).collect();
    let _ = writeln!(
        s,
        "| kind | avoidable | floor collision ≤ | {} | idm |\n|---|---|---|{}---|",
        names.join(" | "),
        "---|".repeat(names.len())
    );
    let kinds = floor.planner.by_kind.iter().map(|(k, e)| (Some(*k), k.to_string(), e));
    for (kind, name, planner) in kinds.chain([(None, "all".to_string(), &floor.planner.overall)]) {
        let collision = |e: Option<f64>| e.map_or("–".to_string(), |c| format!("{c:.2}"));
        let variants: Vec<String> = ab
            .variants
            .iter()
            .map(|v| {
                let spread = match kind {
                    Some(k) => v.by_kind.get(&k).map(|e| e.collision_rate),
                    None => Some(v.overall.collision_rate),
                };
                spread.map_or("–".to_string(), |c| format!("{:.2} ± {:.2}", c.mean, c.std))
            })
            .collect();
        let reference = match kind {
            Some(k) => ab.reference.by_kind.get(&k).map(|e| e.collision_rate),
            None => Some(ab.reference.overall.collision_rate),
        };
        let _ = writeln!(
            s,
            "| {name} | {}/{} | {:.2} | {} | {} |",
            floor.avoidable(kind),
            planner.episodes,
            planner.collision_rate,
            variants.join(" | "),
            collision(reference)
        );
    }
}
