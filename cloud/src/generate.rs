//! Scenario generation for the library role: sample candidates of each kind, reject the
//! infeasible ones (counted by reason), simulate and score the rest with the reference driver.
//!
//! Episodes are independent, so they run on all cores; results are gathered by candidate index,
//! which keeps the output identical whatever the number of threads.

use risktwin_common::episode::{EpisodeResult, evaluate};
use risktwin_common::scenario::{Infeasible, ScenarioKind, ScenarioSpec, check_feasible, sample};
use std::collections::BTreeMap;

/// A candidate that passed the filter, with its episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluated {
    pub spec: ScenarioSpec,
    pub result: EpisodeResult,
}

/// Everything one generation batch produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Batch {
    pub evaluated: Vec<Evaluated>,
    /// Rejected candidates by kind and reason code.
    pub rejected: BTreeMap<(ScenarioKind, &'static str), u64>,
    pub sampled: u64,
}

/// Runs `f` over `items` on `threads` workers, returning results in input order.
pub fn parallel_map<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = threads.max(1).min(items.len().max(1));
    let chunk = items.len().div_ceil(threads).max(1);
    std::thread::scope(|scope| {
        let handles: Vec<_> = items.chunks(chunk).map(|c| scope.spawn(|| c.iter().map(&f).collect::<Vec<R>>())).collect();
        handles.into_iter().flat_map(|h| h.join().expect("episode workers do not panic")).collect()
    })
}

/// Samples `count` candidates of each kind under `seed`, filters and evaluates them.
pub fn generate(kinds: &[ScenarioKind], count: u64, seed: u64, threads: usize) -> Batch {
    let mut batch = Batch::default();
    let mut feasible = Vec::new();
    for &kind in kinds {
        for index in 0..count {
            let spec = sample(seed, kind, index);
            batch.sampled += 1;
            match check_feasible(&spec) {
                Ok(()) => feasible.push(spec),
                Err(why) => *batch.rejected.entry((kind, Infeasible::code(&why))).or_default() += 1,
            }
        }
    }
    batch.evaluated = evaluate_all(feasible, threads);
    batch
}

/// Evaluates specs with the reference driver on `threads` workers, in order.
pub fn evaluate_all(specs: Vec<ScenarioSpec>, threads: usize) -> Vec<Evaluated> {
    let results = parallel_map(&specs, threads, evaluate);
    specs.into_iter().zip(results).map(|(spec, result)| Evaluated { spec, result }).collect()
}
