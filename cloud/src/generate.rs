//! Scenario generation for the library role: sample candidates of each kind, reject the
//! infeasible ones (counted by reason), simulate and score the rest with the reference driver.
//!
//! Episodes are independent, so they run on all cores; results are gathered by candidate index,
//! which keeps the output identical whatever the number of threads.

use risktwin_common::episode::{EpisodeResult, evaluate};
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{Infeasible, MutateError, ScenarioKind, ScenarioSpec, check_feasible, mutate, sample};
use risktwin_store::library::{DEFAULT_POLICY, LibraryError, Outcome, Rejection, ScenarioLibrary, ScenarioRecord};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};

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
    pub rejected: RejectionCounts,
    pub sampled: u64,
}

/// Worker threads for episode batches: all cores.
pub fn all_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Worker threads asked for (`None`: all cores); `Err` names the range when out of it.
pub fn worker_threads(requested: Option<u64>) -> Result<usize, String> {
    match requested {
        None => Ok(all_cores()),
        Some(t @ 1..=1024) => Ok(t as usize),
        Some(t) => Err(format!("{t} is out of range [1, 1024]")),
    }
}

/// Runs `f` over `items` on `threads` workers, returning results in input order. Each worker
/// takes the next item as soon as it is free (an atomic index over `items`), so one slow item
/// does not leave the other workers idle; every result is written back at its item's index, so
/// the output is the same for every thread count.
pub fn parallel_map<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = threads.max(1).min(items.len().max(1));
    if threads == 1 {
        return items.iter().map(f).collect();
    }
    let next = AtomicUsize::new(0);
    let worker = || {
        let mut done = Vec::new();
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let Some(item) = items.get(i) else { break };
            done.push((i, f(item)));
        }
        done
    };
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads).map(|_| scope.spawn(worker)).collect();
        let mut slots: Vec<Option<R>> = std::iter::repeat_with(|| None).take(items.len()).collect();
        for h in handles {
            for (i, r) in h.join().expect("episode workers do not panic") {
                slots[i] = Some(r);
            }
        }
        slots.into_iter().map(|r| r.expect("every item is taken by exactly one worker")).collect()
    })
}

/// Samples `count` candidates of each kind under `seed`, filters and evaluates them.
pub fn generate(kinds: &[ScenarioKind], count: u64, seed: u64, threads: usize) -> Batch {
    let (mut batch, sampled) = sample_feasible(kinds, count, seed);
    batch.evaluated = evaluate_all(sampled.feasible, threads);
    batch
}

/// Scenarios evaluated and committed together by [`generate_into`]: 64, about a second of
/// evaluation on two cores, so a killed run loses at most that, while a commit (a few ms) per
/// batch costs nothing next to the evaluation.
pub const STORE_BATCH: usize = 64;

/// [`generate`] and [`store`] in batches of [`STORE_BATCH`] scenarios, each committed once
/// evaluated, so a run killed midway keeps every batch it finished: whole scenarios with their
/// outcomes, in the order (and with the sequence numbers) a whole run gives them. Each batch's
/// transaction also holds the rejection counts of the candidates sampled since the previous
/// batch (the last batch: all that are left), so a killed run's counts match its scenarios.
/// Same report as [`store`].
pub fn generate_into(
    library: &mut ScenarioLibrary,
    kinds: &[ScenarioKind],
    count: u64,
    seed: u64,
    threads: usize,
) -> Result<GenerateReport, LibraryError> {
    let (mut batch, sampled) = sample_feasible(kinds, count, seed);
    let mut rejected = rejections_by_batch(&sampled.rejected_at, sampled.feasible.len()).into_iter();
    let mut specs = sampled.feasible.chunks(STORE_BATCH);
    loop {
        let (chunk, counts) = (specs.next().unwrap_or(&[]), rejected.next().unwrap_or_default());
        let evaluated = evaluate_all(chunk.to_vec(), threads);
        let records: Vec<ScenarioRecord> =
            evaluated.iter().map(|e| ScenarioRecord::sampled(e.spec.clone(), reference_outcome(&e.result))).collect();
        library.insert_with_rejections(&records, &as_rejections(&counts))?;
        batch.evaluated.extend(evaluated);
        if specs.len() == 0 {
            break;
        }
    }
    Ok(report(kinds, &batch))
}

/// Rejection counts by kind and reason code.
pub type RejectionCounts = BTreeMap<(ScenarioKind, &'static str), u64>;

/// The candidates of [`generate`], sampled and filtered.
struct Sampled {
    /// The feasible specs, in sampling order.
    feasible: Vec<ScenarioSpec>,
    /// Each rejected candidate, in sampling order: how many feasible specs were sampled before
    /// it, its kind and its reason code.
    rejected_at: Vec<(usize, ScenarioKind, &'static str)>,
}

/// The rejections of each [`STORE_BATCH`] of `feasible` specs (at least one batch): batch `k`
/// takes those sampled before its last spec and after the previous batch's, the last batch
/// also those sampled after it.
fn rejections_by_batch(rejected_at: &[(usize, ScenarioKind, &'static str)], feasible: usize) -> Vec<RejectionCounts> {
    let batches = feasible.div_ceil(STORE_BATCH).max(1);
    let mut out = vec![RejectionCounts::new(); batches];
    for &(before, kind, code) in rejected_at {
        let k = (before / STORE_BATCH).min(batches - 1);
        *out[k].entry((kind, code)).or_default() += 1;
    }
    out
}

/// Samples `count` candidates of each kind under `seed` and filters them: the counts, and
/// what was kept and refused in sampling order.
fn sample_feasible(kinds: &[ScenarioKind], count: u64, seed: u64) -> (Batch, Sampled) {
    let mut batch = Batch::default();
    let mut sampled = Sampled { feasible: Vec::new(), rejected_at: Vec::new() };
    for &kind in kinds {
        for index in 0..count {
            let spec = sample(seed, kind, index);
            batch.sampled += 1;
            match check_feasible(&spec) {
                Ok(()) => sampled.feasible.push(spec),
                Err(why) => {
                    let code = Infeasible::code(&why);
                    *batch.rejected.entry((kind, code)).or_default() += 1;
                    sampled.rejected_at.push((sampled.feasible.len(), kind, code));
                }
            }
        }
    }
    (batch, sampled)
}

/// Evaluates specs with the reference driver on `threads` workers, in order.
pub fn evaluate_all(specs: Vec<ScenarioSpec>, threads: usize) -> Vec<Evaluated> {
    let results = parallel_map(&specs, threads, evaluate);
    specs.into_iter().zip(results).map(|(spec, result)| Evaluated { spec, result }).collect()
}

/// Per-kind counts of one batch (docs/cli.md `scenarios generate` → `by_kind`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct KindReport {
    pub stored: u64,
    pub infeasible: u64,
    pub collisions: u64,
}

/// The `scenarios generate` JSON document.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct GenerateReport {
    pub generated: u64,
    pub infeasible: u64,
    pub stored: u64,
    pub by_kind: BTreeMap<ScenarioKind, KindReport>,
}

/// The outcome record of an episode under the reference driver.
pub fn reference_outcome(result: &EpisodeResult) -> Outcome {
    Outcome { policy: DEFAULT_POLICY.to_string(), metrics: result.metrics.clone(), risk: result.risk }
}

/// Stores a batch (scenarios with outcomes, and rejection counts) and reports on it.
pub fn store(
    library: &mut ScenarioLibrary,
    kinds: &[ScenarioKind],
    batch: &Batch,
) -> Result<GenerateReport, LibraryError> {
    let records: Vec<ScenarioRecord> =
        batch.evaluated.iter().map(|e| ScenarioRecord::sampled(e.spec.clone(), reference_outcome(&e.result))).collect();
    library.insert_with_rejections(&records, &as_rejections(&batch.rejected))?;
    Ok(report(kinds, batch))
}

fn as_rejections(counts: &RejectionCounts) -> Vec<Rejection> {
    counts.iter().map(|(&(kind, reason), &count)| Rejection { kind, reason: reason.to_string(), count }).collect()
}

/// The report on a stored batch.
fn report(kinds: &[ScenarioKind], batch: &Batch) -> GenerateReport {
    let mut report = GenerateReport { generated: batch.sampled, ..GenerateReport::default() };
    for &kind in kinds {
        report.by_kind.insert(kind, KindReport::default());
    }
    for e in &batch.evaluated {
        let k = report.by_kind.entry(e.spec.kind).or_default();
        k.stored += 1;
        k.collisions += u64::from(e.result.metrics.collision);
    }
    for (&(kind, _), &count) in &batch.rejected {
        report.by_kind.entry(kind).or_default().infeasible += count;
    }
    report.infeasible = report.by_kind.values().map(|k| k.infeasible).sum();
    report.stored = report.by_kind.values().map(|k| k.stored).sum();
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_batch_commits_the_rejections_sampled_since_the_previous_one() {
        let (batch, sampled) = sample_feasible(&ScenarioKind::ALL, 60, 3);
        let feasible = sampled.feasible.len();
        assert!(feasible > 2 * STORE_BATCH && !sampled.rejected_at.is_empty(), "{feasible} feasible");
        let by_batch = rejections_by_batch(&sampled.rejected_at, feasible);
        assert_eq!(by_batch.len(), feasible.div_ceil(STORE_BATCH));
        // Together: exactly the run's counts.
        let mut total = RejectionCounts::new();
        for counts in &by_batch {
            for (&key, &n) in counts {
                *total.entry(key).or_default() += n;
            }
        }
        assert_eq!(total, batch.rejected);
        // A run killed after its first batch keeps the rejections sampled before that batch's
        // last scenario, no later ones.
        let first: u64 = by_batch[0].values().sum();
        let before = sampled.rejected_at.iter().filter(|&&(at, _, _)| at < STORE_BATCH).count() as u64;
        assert_eq!(first, before);
        // Nothing feasible: one commit holds every rejection.
        let only = rejections_by_batch(&sampled.rejected_at[..3], 0);
        assert_eq!(only.len(), 1);
        assert_eq!(only[0].values().sum::<u64>(), 3);
    }

    #[test]
    fn parallel_map_keeps_input_order_whatever_the_threads_and_the_cost() {
        // Uneven work: every third item takes far longer, as the floor's not-found scenarios do.
        let items: Vec<u64> = (0..23).collect();
        let slow = |&i: &u64| {
            let spins = if i % 3 == 0 { 200_000 } else { 10 };
            (0..spins).fold(i, |acc, k| std::hint::black_box(acc.wrapping_mul(31).wrapping_add(k)))
        };
        let serial: Vec<u64> = items.iter().map(slow).collect();
        for threads in [1, 2, 3, 8, 64] {
            assert_eq!(parallel_map(&items, threads, slow), serial, "{threads} threads");
        }
        assert!(parallel_map(&Vec::<u64>::new(), 4, slow).is_empty());
    }
}

/// What mutating around one stored scenario produced (`risktwin scenarios mutate`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MutationReport {
    pub parent: String,
    pub kind: ScenarioKind,
    /// Children asked for.
    pub requested: u64,
    /// Draws with no feasible child within `MAX_MUTATION_TRIES`, by reason code.
    pub infeasible: BTreeMap<&'static str, u64>,
    /// New scenarios stored.
    pub stored: usize,
    /// Children whose content the library already held (their outcomes are added).
    pub duplicates: usize,
    /// Children whose reference episode collided.
    pub collisions: usize,
    /// Every feasible child, highest S_risk first (ties by id).
    pub children: Vec<Child>,
}

/// One child as stored.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Child {
    pub id: String,
    pub seed: u64,
    pub risk: f64,
    pub collision: bool,
    pub min_ttc_s: Option<f64>,
}

/// Why mutating around a stored scenario failed.
#[derive(Debug, thiserror::Error)]
pub enum MutationError {
    #[error("no generated scenario '{0}' in the library (a recorded CommonRoad case cannot be mutated)")]
    UnknownParent(String),
    #[error("{0}")]
    Mutate(MutateError),
    #[error(transparent)]
    Library(#[from] LibraryError),
}

/// Draws `count` feasibility-checked children of stored scenario `parent_id` within `radius`
/// (a share of each parameter's range), evaluates them with the reference driver on `threads`
/// workers and stores them as its mutations. The same library, parent, seed, count and radius
/// give the same children.
pub fn mutate_stored(
    library: &mut ScenarioLibrary,
    parent_id: &str,
    count: u64,
    radius: f64,
    seed: u64,
    threads: usize,
) -> Result<MutationReport, MutationError> {
    let parent = library.get(parent_id)?.ok_or_else(|| MutationError::UnknownParent(parent_id.to_owned()))?;
    let mut rng = Rng::new(seed);
    let (mut specs, mut infeasible) = (Vec::new(), BTreeMap::new());
    for _ in 0..count {
        match mutate(&parent.spec, radius, &mut rng) {
            Ok(child) => specs.push(child),
            Err(e) => match e.infeasible() {
                Some(why) => *infeasible.entry(Infeasible::code(why)).or_default() += 1,
                None => return Err(MutationError::Mutate(e)),
            },
        }
    }
    let evaluated = evaluate_all(specs, threads);
    let records: Vec<ScenarioRecord> = evaluated
        .iter()
        .map(|e| ScenarioRecord::mutated(e.spec.clone(), parent_id, reference_outcome(&e.result)))
        .collect();
    let summary = library.insert_batch(&records)?;
    let mut children: Vec<Child> = evaluated
        .iter()
        .map(|e| Child {
            id: risktwin_store::library::content_id(&e.spec),
            seed: e.spec.seed,
            risk: e.result.risk.score,
            collision: e.result.metrics.collision,
            min_ttc_s: e.result.metrics.min_ttc_s,
        })
        .collect();
    children.sort_by(|a, b| b.risk.total_cmp(&a.risk).then_with(|| a.id.cmp(&b.id)));
    Ok(MutationReport {
        parent: parent_id.to_owned(),
        kind: parent.spec.kind,
        requested: count,
        infeasible,
        stored: summary.inserted,
        duplicates: summary.duplicates,
        collisions: children.iter().filter(|c| c.collision).count(),
        children,
    })
}
