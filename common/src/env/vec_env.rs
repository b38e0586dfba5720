//! Many driving environments stepped together into flat, preallocated buffers (row-major,
//! one row per environment), in parallel with rayon. Each environment depends only on its own
//! actions and its (seed, index, episode) scenario stream, so the buffers are identical whatever
//! the thread count. Finished episodes reset automatically; the observation that ended them is
//! kept in `final_obs` for bootstrapping truncated episodes.

use super::driving::{DrivingEnv, EpisodeSummary, StepOutcome};
use super::observe::{ACT_DIM, OBS_DIM};
use super::reward::TrainingReward;
use super::source::{ScenarioSource, SourceError};
use rayon::prelude::*;

/// Environments per rayon task: enough work to amortise scheduling.
const MIN_ENVS_PER_TASK: usize = 4;

/// One environment with its episode counter and the outcome of its last step.
#[derive(Debug, Clone)]
struct Slot {
    env: DrivingEnv,
    episode: u64,
    outcome: StepOutcome,
    /// Set when the last step ended an episode (taken by [`VecEnv::drain_finished`]).
    finished: Option<EpisodeSummary>,
    final_obs: [f32; OBS_DIM],
    error: Option<SourceError>,
}

/// `n` environments stepped together.
#[derive(Debug, Clone)]
pub struct VecEnv {
    slots: Vec<Slot>,
    source: ScenarioSource,
    /// Current observations, `n × OBS_DIM`.
    obs: Vec<f32>,
    /// Rewards of the last step, `n`.
    rewards: Vec<f32>,
    /// 1 where the last step terminated the episode (collision, off-road), `n`.
    terminated: Vec<u8>,
    /// 1 where the last step truncated the episode (horizon, route end), `n`.
    truncated: Vec<u8>,
    /// Observation at the end of the episode where one ended, `n × OBS_DIM`.
    final_obs: Vec<f32>,
}

impl VecEnv {
    /// `n` environments drawing scenarios from `source`, rewarded with `reward`.
    pub fn new(n: usize, source: ScenarioSource, reward: TrainingReward) -> Result<Self, SourceError> {
        source.validate()?;
        let mut obs = vec![0.0f32; n * OBS_DIM];
        let slots = obs
            .par_chunks_mut(OBS_DIM)
            .enumerate()
            .map(|(i, o)| {
                let spec = source.spec(i, 0)?;
                let o: &mut [f32; OBS_DIM] = o.try_into().expect("chunks are OBS_DIM long");
                Ok(Slot {
                    env: DrivingEnv::new(&spec, reward, o),
                    episode: 0,
                    outcome: StepOutcome::default(),
                    finished: None,
                    final_obs: [0.0; OBS_DIM],
                    error: None,
                })
            })
            .collect::<Result<Vec<_>, SourceError>>()?;
        Ok(Self {
            slots,
            source,
            obs,
            rewards: vec![0.0; n],
            terminated: vec![0; n],
            truncated: vec![0; n],
            final_obs: vec![0.0; n * OBS_DIM],
        })
    }

    /// Number of environments.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// True when there are no environments.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Current observations, `len() × OBS_DIM`.
    pub fn obs(&self) -> &[f32] {
        &self.obs
    }

    /// Rewards of the last step.
    pub fn rewards(&self) -> &[f32] {
        &self.rewards
    }

    /// 1 where the last step terminated an episode.
    pub fn terminated(&self) -> &[u8] {
        &self.terminated
    }

    /// 1 where the last step truncated an episode.
    pub fn truncated(&self) -> &[u8] {
        &self.truncated
    }

    /// The observation that ended each episode finished by the last step (rows of other
    /// environments hold stale values).
    pub fn final_obs(&self) -> &[f32] {
        &self.final_obs
    }

    /// Replaces the scenario source (e.g. a refreshed library selection); takes effect at each
    /// environment's next reset.
    pub fn set_source(&mut self, source: ScenarioSource) -> Result<(), SourceError> {
        source.validate()?;
        self.source = source;
        Ok(())
    }

    /// Steps every environment with its row of `actions` (`len() × ACT_DIM`, each in [−1, 1]),
    /// resetting finished ones. Errors only when the source cannot produce a spec.
    pub fn step(&mut self, actions: &[f32]) -> Result<(), SourceError> {
        assert_eq!(actions.len(), self.slots.len() * ACT_DIM, "one action row per environment");
        let source = &self.source;
        self.slots
            .par_iter_mut()
            .with_min_len(MIN_ENVS_PER_TASK)
            .zip(self.obs.par_chunks_mut(OBS_DIM))
            .zip(actions.par_chunks(ACT_DIM))
            .enumerate()
            .for_each(|(i, ((slot, obs), action))| {
                let obs: &mut [f32; OBS_DIM] = obs.try_into().expect("chunks are OBS_DIM long");
                let action: &[f32; ACT_DIM] = action.try_into().expect("chunks are ACT_DIM long");
                let outcome = slot.env.step(action, obs);
                slot.outcome = outcome;
                if outcome.done() {
                    slot.final_obs = *obs;
                    slot.finished = Some(slot.env.summary());
                    slot.episode += 1;
                    match source.spec(i, slot.episode) {
                        Ok(spec) => slot.env.reset(&spec, obs),
                        Err(e) => slot.error = Some(e),
                    }
                }
            });
        for (i, slot) in self.slots.iter_mut().enumerate() {
            if let Some(e) = slot.error.take() {
                return Err(e);
            }
            self.rewards[i] = slot.outcome.reward as f32;
            self.terminated[i] = u8::from(slot.outcome.terminated);
            self.truncated[i] = u8::from(slot.outcome.truncated);
            if slot.outcome.done() {
                self.final_obs[i * OBS_DIM..(i + 1) * OBS_DIM].copy_from_slice(&slot.final_obs);
            }
        }
        Ok(())
    }

    /// Abandons every environment's episode and starts its next one from the source (an
    /// abandoned episode is not reported by [`Self::drain_finished`]).
    pub fn restart(&mut self) -> Result<(), SourceError> {
        let source = &self.source;
        let results: Vec<Result<(), SourceError>> = self
            .slots
            .par_iter_mut()
            .zip(self.obs.par_chunks_mut(OBS_DIM))
            .enumerate()
            .map(|(i, (slot, obs))| {
                let obs: &mut [f32; OBS_DIM] = obs.try_into().expect("chunks are OBS_DIM long");
                slot.episode += 1;
                (slot.finished, slot.outcome) = (None, StepOutcome::default());
                slot.env.reset(&source.spec(i, slot.episode)?, obs);
                Ok(())
            })
            .collect();
        self.rewards.fill(0.0);
        self.terminated.fill(0);
        self.truncated.fill(0);
        results.into_iter().collect()
    }

    /// Hands the episodes finished by the last step, in environment order, to `f`.
    pub fn drain_finished(&mut self, mut f: impl FnMut(usize, EpisodeSummary)) {
        for (i, slot) in self.slots.iter_mut().enumerate() {
            if let Some(s) = slot.finished.take() {
                f(i, s);
            }
        }
    }
}
