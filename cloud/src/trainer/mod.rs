//! The trainer role: retrains driving policies against the scenario library and evaluates them
//! (docs/method.md §7–9, the ablation of base / risk-only / full).
//!
//! - [`session`]: one training run (PPO or SAC from `risktwin-learn`) of a variant and a seed, in
//!   phases, with training curves.
//! - [`curriculum`]: how `full` draws its training scenarios from the library (risk-ranked
//!   replay, mutation around the policy's failures, refreshed after every phase; or the
//!   frontier of what the policy sometimes completes); `base`, `ttc` and
//!   `risk-only` sample the five kinds uniformly.
//! - [`held_out`]: the evaluation set, disjoint from everything trained on.
//! - [`ablation`]: variants × seeds → per-variant, per-kind metrics with their spread over seeds.
//! - [`floor`]: the achievable floor of the held-out set, from the privileged planner.
//! - [`gate`]: the regression gate a policy version passes before it is pushed.
//! - [`stats`]: the metrics of paper table 1 (plus S_risk) and their spread.
//! - [`outcomes`]: a driver's outcome shares and means with 95 % intervals.
//! - [`evaluation`]: one driver's evaluation document beside the reference driver.

pub mod ablation;
pub mod curriculum;
pub mod drive;
pub mod evaluation;
pub mod floor;
pub mod gate;
pub mod held_out;
pub mod outcomes;
mod plan;
pub mod session;
pub mod stats;

#[cfg(test)]
mod tests;

pub use ablation::{
    AblationReport, PolicyEvaluation, VariantResult, evaluate_policy, reference_episodes, run_ablation,
};
pub use floor::{FloorCase, FloorEvaluation, evaluate_floor};
pub use held_out::HeldOut;
pub use plan::{ReplayRule, TrainerError, TrainingPlan};
pub use session::{CurvePoint, TrainedPolicy, train_variant};
pub use stats::{EvalMetrics, EvalSpread, Spread};
