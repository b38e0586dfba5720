//! `report.md`: what the run measured, in tables a person reads, the findings computed from the
//! numbers (see `verdict`), and what the run does not cover.

use crate::metrics::RunMetrics;
use crate::push_loop::LoopOutput;
use crate::{closed_loop, verdict};
use risktwin_cloud::trainer::stats::METRIC_NAMES;
use risktwin_cloud::trainer::{EvalMetrics, EvalSpread, Spread};
use risktwin_common::env::RiskShaping;
use std::fmt::Write;

const METRIC_HEADER: &str = "| reward | success | route completion | collision | avg speed m/s | steering smoothness rad/s | \
                             longitudinal smoothness m/s³ | S_risk |";

fn pm(s: &Spread) -> String {
    format!("{:.3} ± {:.3}", s.mean, s.std)
}

fn spread_cells(e: &EvalSpread) -> String {
    e.values().iter().map(pm).collect::<Vec<_>>().join(" | ")
}

/// How the risk term is shaped, in words for the report.
fn shaping_words(shaping: RiskShaping) -> String {
    match shaping {
        RiskShaping::PerStep => "as a penalty −w_r·R̄ per second (paper eq. 7)".into(),
        RiskShaping::Potential { scale } => format!(
            "as a potential difference γ·Φ(s′) − Φ(s) with Φ = −{scale}·w_r·R̄ (Ng, Harada & Russell 1999), which \
             cannot make ending an episode early pay"
        ),
    }
}

fn plain_cells(e: &EvalMetrics) -> String {
    e.values().iter().map(|v| format!("{v:.3}")).collect::<Vec<_>>().join(" | ")
}

fn ablation_section(s: &mut String, m: &RunMetrics) {
    let ab = &m.ablation;
    let _ = writeln!(s, "## Retraining and ablation ({})\n", ab.algo);
    let _ = writeln!(
        s,
        "Each variant was trained with {} for {} environment steps per seed, seeds {:?}. `base` has no risk term in \
         its reward; `risk-only` adds the risk-field term; `full` also trains on scenarios from the library: each \
         training episode replays, with probability {}, a scenario from its library set — the riskiest scenarios \
         the reference driver survives (risk-ranked replay) and an equal share of ordinary ones, refreshed after \
         each of {} phases with the current policy's failures and the mutations around them that the reference \
         driver survives — and otherwise drives a fresh sample of the five \
         kinds, as `base` and `risk-only` always do (prioritised level replay, Jiang et al. 2021). `ttc` is base \
         plus the literature's usual safety term instead of the risk field: ln(TTC / 4 s) per second while the \
         time to collision with the car ahead is under 4 s (Zhu et al. 2020). The risk term of `risk-only` and \
         `full` enters training {}.\n",
        ab.algo,
        ab.steps_per_run,
        m.training_seeds,
        m.config.training.replay_share,
        m.config.training.phases,
        shaping_words(m.config.training.risk_shaping)
    );
    let _ = writeln!(
        s,
        "Evaluation: {} held-out scenarios ({} per kind) from a seed stream no training or library set draws from \
         (checked by content id), driven with each policy's deterministic action; every variant is scored with the \
         same (full) reward weights. Mean ± sample standard deviation over seeds. Lower is better for collision, \
         both smoothness columns and S_risk.\n",
        ab.held_out_episodes, ab.held_out_per_kind
    );
    let _ = writeln!(s, "### All kinds\n");
    let _ = writeln!(s, "| variant {METRIC_HEADER}\n|---{}|", "|---".repeat(METRIC_NAMES.len()));
    for v in &ab.variants {
        let _ = writeln!(s, "| {} | {} |", v.variant, spread_cells(&v.overall));
    }
    let _ = writeln!(s, "| idm (reference driver) | {} |", plain_cells(&ab.reference.overall));
    let _ = writeln!(s, "\n### Per kind\n");
    let _ = writeln!(s, "| kind | variant {METRIC_HEADER}\n|---|---{}|", "|---".repeat(METRIC_NAMES.len()));
    for (kind, reference) in &ab.reference.by_kind {
        for v in &ab.variants {
            if let Some(e) = v.by_kind.get(kind) {
                let _ = writeln!(s, "| {kind} | {} | {} |", v.variant, spread_cells(e));
            }
        }
        let _ = writeln!(s, "| {kind} | idm | {} |", plain_cells(reference));
    }
    let _ = writeln!(
        s,
        "\n### How the episodes ended\n\nShares of the held-out episodes (mean ± std over seeds); out of time = \
         unharmed at the horizon but short of the route's end.\n\n| variant | success | collision | off the road | \
         out of time |\n|---|---|---|---|---|"
    );
    for v in &ab.variants {
        let e = &v.overall;
        let cells = [e.success_rate, e.collision_rate, e.offroad_rate, e.timeout_rate].map(|x| pm(&x)).join(" | ");
        let _ = writeln!(s, "| {} | {cells} |", v.variant);
    }
    let r = &ab.reference.overall;
    let _ = writeln!(
        s,
        "| idm (reference driver) | {:.3} | {:.3} | {:.3} | {:.3} |",
        r.success_rate, r.collision_rate, r.offroad_rate, r.timeout_rate
    );
    crate::floor::section(s, m);
    let _ = writeln!(s, "\n## What the numbers show\n");
    match &m.verdict {
        Some(v) => {
            for line in &v.sentences {
                let _ = writeln!(s, "- {line}");
            }
            let _ = writeln!(
                s,
                "\nRule (fixed before the run): \"lower\" compares means over seeds; \"equal or better\" allows full to \
                 trail base by at most {} in route completion and {} m/s in average speed.",
                verdict::COMPLETION_TOLERANCE,
                verdict::SPEED_TOLERANCE_MPS
            );
        }
        None => {
            let _ = writeln!(s, "Base or full was not trained, so the target cannot be checked.");
        }
    }
    let _ = writeln!(s, "\n## Training curves\n\n![training curves](training_curves.png)\n");
    let _ = writeln!(
        s,
        "Finished training episodes averaged between checkpoints; the line is the mean over seeds, the band their \
         min–max. These are training episodes: reward is each variant's own training reward (base has no risk \
         term) and full's episodes come from its library set, so the curves compare learning progress, not the \
         variants — the held-out table does that.\n"
    );
    let _ = writeln!(s, "## Ablation spectrum\n\n![ablation](ablation.png)\n");
    let _ = writeln!(
        s,
        "Bars per metric, normalised across variants so that higher is better (best = full height, worst = 0.15); \
         labels are the raw means (the seed spread is in the tables above). Steer rate and jerk are the steering and \
         longitudinal smoothness (lower is better, so the smoothest variant has the tallest bar).\n"
    );
    if let Some(full) = ab.variant(risktwin_common::env::Variant::Full) {
        let _ = writeln!(s, "### Library refreshes of `full`\n");
        let _ = writeln!(
            s,
            "| seed | phase | policy label | evaluated | failures | children | child failures | next set | policy mean S_risk |\n|---|---|---|---|---|---|---|---|---|"
        );
        for seed in &full.seeds {
            for r in &seed.refreshes {
                let _ = writeln!(
                    s,
                    "| {} | {} | `{}` | {} | {} | {} | {} | {} | {:.3} |",
                    seed.seed,
                    r.phase,
                    r.policy,
                    r.evaluated,
                    r.failures,
                    r.children,
                    r.child_failures,
                    match r.frontier {
                        Some(f) => format!("{} ({f} on the frontier)", r.training_set),
                        None => r.training_set.to_string(),
                    },
                    r.policy_mean_risk
                );
            }
        }
        let _ = writeln!(s);
    }
}

fn library_section(s: &mut String, m: &RunMetrics) {
    let _ = writeln!(s, "## Scenario generation\n");
    let _ = writeln!(
        s,
        "Scenarios of five kinds were sampled ({} per kind), filtered for physical feasibility, driven by the \
         reference driver (IDM/MOBIL on perceived objects) in the twin, scored with S_risk and stored in \
         `library.db`; {} mutation rounds then searched around the failures.\n",
        m.config.count_per_kind, m.config.iterations
    );
    let _ = writeln!(s, "| kind | stored | infeasible | collisions |\n|---|---|---|---|");
    for (k, r) in &m.generation.by_kind {
        let _ = writeln!(s, "| {k} | {} | {} | {} |", r.stored, r.infeasible, r.collisions);
    }
    if !m.rounds.is_empty() {
        let _ = writeln!(s, "\n### Mutation rounds (reference driver)\n");
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
    }
    let _ = writeln!(s, "\n### Library by kind (after mutation and training)\n");
    let _ = writeln!(
        s,
        "| kind | scenarios | collisions (idm) | collision rate | mean S_risk | max S_risk |\n|---|---|---|---|---|---|"
    );
    for (k, r) in &m.by_kind {
        let _ = writeln!(
            s,
            "| {k} | {} | {} | {:.2} | {:.3} | {:.3} |",
            r.scenarios, r.collisions, r.collision_rate, r.mean_risk, r.max_risk
        );
    }
    let _ = writeln!(s, "\n## Top scenarios, re-scored\n");
    let mut header = String::from("| rank | id | kind | collision (idm) | min TTC s |");
    let mut rule = String::from("|---|---|---|---|---|");
    for r in &m.rescore {
        let _ = write!(header, " S_risk {} |", r.policy);
        rule.push_str("---|");
    }
    let _ = writeln!(s, "{header}\n{rule}");
    for (i, r) in m.top.iter().enumerate() {
        let ttc = r.outcome.min_ttc_s.map_or("∞".to_string(), |t| format!("{t:.2}"));
        let _ = write!(s, "| {} | `{}` | {} | {} | {ttc} |", i + 1, r.id, r.kind, r.outcome.collision);
        for p in &m.rescore {
            let _ = write!(s, " {} |", p.risk.get(i).map_or("–".to_string(), |v| format!("{v:.3}")));
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "\n| policy | collisions on the top {} | mean S_risk |\n|---|---|---|", m.top.len());
    for p in &m.rescore {
        let _ = writeln!(s, "| {} | {} | {:.3} |", p.policy, p.collisions, p.mean_risk);
    }
    let _ = writeln!(
        s,
        "\nThe top scenarios come from the library that `full` trains on, so its column here is in-distribution; \
         the held-out table above is the fair comparison."
    );
    if !m.heatmaps.is_empty() {
        let _ = writeln!(s, "\n## Risk fields of the top scenarios\n");
        for h in &m.heatmaps {
            let _ = writeln!(s, "![{h}]({h})\n");
        }
    }
}

/// The report; `timings` (what, seconds) are measurements and appear only here, never in
/// metrics.json.
pub fn markdown(m: &RunMetrics, traffic: Option<&LoopOutput>, timings: &[(String, f64)]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# RiskTwin run (seed {})\n", m.seed);
    ablation_section(&mut s, m);
    library_section(&mut s, m);
    if let Some(closed) = &m.closed_loop {
        closed_loop::section(&mut s, closed, traffic);
    }
    let _ = writeln!(s, "\n## Wall time (this machine; not in metrics.json)\n\n| phase | s |\n|---|---|");
    for (what, secs) in timings {
        let _ = writeln!(s, "| {what} | {secs:.1} |");
    }
    let _ = writeln!(s, "\n| run | s |\n|---|---|");
    for (v, seed, secs) in &m.ablation.train_wall_s {
        let _ = writeln!(s, "| train {v} seed {seed} | {secs:.1} |");
    }
    if let Some(what) = &m.recording {
        let _ = writeln!(s, "\n## Recording\n\n{what}: open it in Foxglove (states, scene boxes, risk grid at 2 Hz).");
    }
    let loop_line = if m.closed_loop.is_some() {
        "The closed loop above runs every role in this one process on loopback, with one edge vehicle; roles as \
         separate processes or machines (`risktwin router`, `cloud`, `edge vehicle`, `push scenario|policy`), a \
         fleet of vehicles and the twin and risk roles on the pushed streams are shown by the pipeline tests."
    } else {
        "Pushing scenarios and policies to an edge vehicle over Zenoh (`push_scenarios` is 0, or nothing was \
         trained to push): shown by the pipeline tests with separate processes."
    };
    let _ = writeln!(s, "\n## Not in this run\n\n- {loop_line}\n- Files: {}.", m.files.join(", "));
    s
}
