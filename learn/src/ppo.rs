//! PPO (Schulman et al. 2017): clipped surrogate, GAE(λ), value loss, entropy bonus,
//! minibatch AdamW epochs; feed-forward or through a GRU (truncated BPTT over the rollout).
//!
//! Actions are sampled from an unbounded Gaussian and clipped to [−1, 1] by the environment
//! (the log-probability is that of the unclipped sample). Truncated episodes bootstrap by
//! adding γ·V(s_final) to their last reward; rewards are scaled by the running return std.

use crate::LearnError;
use crate::envs::Environment;
use crate::gae::{ReturnScaler, gae, standardise};
use crate::host::{HostMlp, Scratch, snapshot};
use crate::lagrange::{CostConstraint, CostSide};
use crate::nn::{HALF_LN_TAU, Mlp, matrix, normals, vars};
use crate::optim::Adam;
use crate::policy::{Algo, PolicyNet, gaussian_log_prob};
use candle_core::{D, Tensor};
use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::rng::Rng;
use std::time::Instant;

/// Largest activation (rows × width) of a minibatch: candle hands elementwise ops from 64 Ki
/// elements to a spinning thread pool, which on a busy 2-core machine spent half the training
/// time waiting; minibatches are capped below it (more, smaller minibatches if needed).
const MAX_ELEMWISE: usize = 64 * 1024 - 1;

/// PPO hyper-parameters. Defaults tuned on the driving task (`examples/tune.rs`): 64 × 64-step
/// rollouts, 10 epochs of 8 minibatches (512 rows), lr 1e-3, initial σ ≈ 0.3 so exploration
/// noise does not throw the car off the road at highway speed.
#[derive(Debug, Clone, PartialEq)]
pub struct PpoConfig {
    /// Vector steps per rollout (rollout size = n_steps × n_envs).
    pub n_steps: usize,
    pub epochs: usize,
    /// Minibatches per epoch.
    pub minibatches: usize,
    pub lr: f64,
    pub gamma: f32,
    pub lambda: f32,
    pub clip: f32,
    pub vf_coef: f64,
    pub ent_coef: f64,
    pub max_grad_norm: f64,
    pub hidden: Vec<usize>,
    pub recurrent: bool,
    /// Initial log σ of the Gaussian policy.
    pub init_log_std: f32,
    /// Rollouts after a warm start ([`Ppo::imitate`]) with the PPO objective off (the critic
    /// learns, and the imitation term below if it is on): a random critic's advantages would
    /// otherwise undo the imitated policy in the first updates.
    pub critic_warmup: usize,
    /// After a warm start, the weight of an imitation term added to every update's loss: the
    /// mean squared error of the policy's mean to the demonstrated actions on a random
    /// minibatch of them (DAPG, Rajeswaran et al. 2018, "Learning complex dexterous
    /// manipulation with deep reinforcement learning and demonstrations"). It keeps PPO near
    /// the driver it imitated while its critic knows little, and fades by `imitation_decay`
    /// per rollout. 0: none.
    pub imitation_coef: f64,
    pub imitation_decay: f64,
    /// PPO-Lagrangian ([`crate::lagrange`]): a limit on the share of training episodes that end
    /// in a collision or off the road (feed-forward only). `None`: unconstrained.
    pub constraint: Option<CostConstraint>,
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            n_steps: 64,
            epochs: 10,
            minibatches: 8,
            lr: 1e-3,
            gamma: 0.99,
            lambda: 0.95,
            clip: 0.2,
            vf_coef: 0.5,
            ent_coef: 0.0,
            max_grad_norm: 0.5,
            hidden: vec![64, 64],
            recurrent: false,
            init_log_std: -1.2,
            critic_warmup: 8,
            imitation_coef: 10.0,
            imitation_decay: 0.97,
            constraint: None,
        }
    }
}

/// What one update measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PpoStats {
    pub policy_loss: f32,
    pub value_loss: f32,
    pub entropy: f32,
    pub approx_kl: f32,
}

/// Wall time spent per phase, s (accumulated over the learner's life).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PpoTimings {
    /// Stepping the environments.
    pub env_s: f64,
    /// Acting: policy and value inference, sampling, reward bookkeeping and bootstrapping.
    pub infer_s: f64,
    /// GAE and the gradient epochs (including refreshing the acting copies).
    pub update_s: f64,
}

/// A PPO learner with its rollout buffers (allocated once for `n_envs`).
pub struct Ppo {
    cfg: PpoConfig,
    policy: PolicyNet,
    critic: Mlp,
    opt: Adam,
    rng: Rng,
    scaler: ReturnScaler,
    n_envs: usize,
    state_dim: usize,
    state: Vec<f32>,
    state0: Vec<f32>,
    obs: Vec<f32>,
    actions: Vec<f32>,
    logp: Vec<f32>,
    values: Vec<f32>,
    rewards: Vec<f32>,
    done: Vec<u8>,
    advantages: Vec<f32>,
    returns: Vec<f32>,
    noise: Vec<f32>,
    /// Per-vector-step buffers: means, values, done flags, V(s_T).
    mean: Vec<f32>,
    value: Vec<f32>,
    done_row: Vec<u8>,
    last_value: Vec<f32>,
    log_std: [f32; ACT_DIM],
    host_actor: HostMlp,
    host_critic: HostMlp,
    scratch: Scratch,
    timings: PpoTimings,
    /// Rollouts left in which only the critic learns (set by a warm start).
    frozen_rollouts: usize,
    /// A warm start's demonstrations and the imitation term's current weight.
    imitation: Option<Imitation>,
    /// The cost critic and λ of a constrained learner.
    cost: Option<CostSide>,
}

/// Demonstrations kept for the imitation term ([`PpoConfig::imitation_coef`]).
struct Imitation {
    obs: Vec<f32>,
    actions: Vec<f32>,
    weight: f64,
}

/// Below this weight the imitation term is dropped.
const MIN_IMITATION_WEIGHT: f64 = 1e-3;

impl Ppo {
    /// A learner for `n_envs` environments, initialised from `seed`.
    pub fn new(cfg: PpoConfig, n_envs: usize, seed: u64) -> Result<Self, LearnError> {
        if cfg.n_steps == 0 || cfg.epochs == 0 || cfg.minibatches == 0 || n_envs == 0 {
            return Err(LearnError::BadConfig(format!("PPO needs positive sizes, got {cfg:?} with {n_envs} envs")));
        }
        if cfg.recurrent && !n_envs.is_multiple_of(cfg.minibatches) {
            return Err(LearnError::BadConfig(format!(
                "{n_envs} envs do not split into {} minibatches",
                cfg.minibatches
            )));
        }
        let mut rng = Rng::derive(seed, 0x990);
        let algo = if cfg.recurrent { Algo::PpoGru } else { Algo::Ppo };
        let policy = PolicyNet::new(algo, &cfg.hidden, &mut rng)?;
        policy.set_log_std(cfg.init_log_std)?;
        let state_dim = policy.state_dim();
        let critic_in = if cfg.recurrent { state_dim } else { OBS_DIM };
        let mut sizes = vec![critic_in];
        sizes.extend_from_slice(if cfg.recurrent { &cfg.hidden[1..] } else { &cfg.hidden });
        sizes.push(1);
        let critic = Mlp::new("critic", &sizes, 1.0, &mut rng)?;
        let n = cfg.n_steps * n_envs;
        let cost = match cfg.constraint {
            Some(_) if cfg.recurrent => {
                return Err(LearnError::BadConfig("a cost constraint needs the feed-forward PPO policy".into()));
            }
            Some(c) => Some(CostSide::new(c, &sizes, n, n_envs, &mut rng)?),
            None => None,
        };
        let mut all = vars(policy.params());
        all.extend(vars(critic.params()));
        all.extend(cost.iter().flat_map(|c| vars(c.critic.params())));
        let opt = Adam::new(all, cfg.lr, cfg.max_grad_norm)?;
        let (host_actor, host_critic) = match policy.mean_mlp() {
            Some(mean) if !cfg.recurrent => (snapshot(mean)?, snapshot(&critic)?),
            _ => (HostMlp::default(), HostMlp::default()),
        };
        let scratch = Scratch::wide(host_actor.max_width().max(host_critic.max_width()));
        let log_std = policy.log_std()?.expect("PPO policies have a state-independent log σ");
        Ok(Self {
            mean: vec![0.0; n_envs * ACT_DIM],
            value: vec![0.0; n_envs],
            done_row: vec![0; n_envs],
            last_value: vec![0.0; n_envs],
            log_std,
            host_actor,
            host_critic,
            scratch,
            timings: PpoTimings::default(),
            frozen_rollouts: 0,
            imitation: None,
            cost,
            scaler: ReturnScaler::new(n_envs, f64::from(cfg.gamma)),
            policy,
            critic,
            opt,
            rng,
            n_envs,
            state_dim,
            state: vec![0.0; n_envs * state_dim],
            state0: vec![0.0; n_envs * state_dim],
            obs: vec![0.0; n * OBS_DIM],
            actions: vec![0.0; n * ACT_DIM],
            logp: vec![0.0; n],
            values: vec![0.0; n],
            rewards: vec![0.0; n],
            done: vec![0; n],
            advantages: vec![0.0; n],
            returns: vec![0.0; n],
            noise: Vec::with_capacity(n_envs * ACT_DIM),
            cfg,
        })
    }

    /// The current policy.
    pub fn policy(&self) -> &PolicyNet {
        &self.policy
    }

    /// The Lagrange multiplier λ of a constrained learner.
    pub fn lagrange_multiplier(&self) -> Option<f64> {
        self.cost.as_ref().map(|c| c.lambda)
    }

    /// Environment steps per rollout.
    pub fn rollout_steps(&self) -> usize {
        self.cfg.n_steps * self.n_envs
    }

    /// Features the heads see: the observations, or the GRU state after them (advancing `state`).
    fn features(&self, obs: &[f32], state: &mut [f32]) -> Result<Tensor, LearnError> {
        let x = matrix(obs, obs.len() / OBS_DIM, OBS_DIM)?;
        match self.policy.gru() {
            Some(cell) => {
                let h = cell.step(&x, &matrix(state, state.len() / self.state_dim, self.state_dim)?)?;
                state.copy_from_slice(&h.flatten_all()?.to_vec1::<f32>()?);
                Ok(h)
            }
            None => Ok(x),
        }
    }

    /// Value estimates of `obs` after `state` (not advanced).
    fn value_of(&self, obs: &[f32], state: &[f32]) -> Result<Vec<f32>, LearnError> {
        let mut s = state.to_vec();
        let f = self.features(obs, &mut s)?;
        Ok(self.critic.forward(&f)?.flatten_all()?.to_vec1()?)
    }

    /// Means and values of the current observations into `self.mean`/`self.value` (advancing
    /// the recurrent state): host-side for the feed-forward policy, candle for the GRU.
    fn act_batch(&mut self, obs: &[f32]) -> Result<(), LearnError> {
        if self.policy.gru().is_none() {
            let (actor, critic) = (&self.host_actor, &self.host_critic);
            let scratch = &mut self.scratch;
            for ((o, m), v) in
                obs.chunks_exact(OBS_DIM).zip(self.mean.chunks_exact_mut(ACT_DIM)).zip(self.value.iter_mut())
            {
                actor.forward(o, scratch, m);
                critic.forward(o, scratch, std::slice::from_mut(v));
            }
            return Ok(());
        }
        let mut state = std::mem::take(&mut self.state);
        let f = self.features(obs, &mut state)?;
        self.state = state;
        let (mean, _) = self.policy.head(&f)?;
        self.mean.copy_from_slice(&mean.flatten_all()?.to_vec1::<f32>()?);
        self.value.copy_from_slice(&self.critic.forward(&f)?.flatten_all()?.to_vec1::<f32>()?);
        Ok(())
    }

    /// V(final observation) of environment `i` after `state` (not advanced).
    fn bootstrap_value(&mut self, final_obs: &[f32], i: usize) -> Result<f32, LearnError> {
        if self.policy.gru().is_none() {
            let mut v = 0.0f32;
            self.host_critic.forward(final_obs, &mut self.scratch, std::slice::from_mut(&mut v));
            return Ok(v);
        }
        let sd = self.state_dim;
        Ok(self.value_of(final_obs, &self.state[i * sd..(i + 1) * sd])?[0])
    }

    /// Copies the current weights into the host-side networks used for acting.
    fn refresh_host(&mut self) -> Result<(), LearnError> {
        if self.policy.gru().is_none() {
            self.host_actor = snapshot(self.policy.mean_mlp().expect("feed-forward PPO has a mean MLP"))?;
            self.host_critic = snapshot(&self.critic)?;
        }
        self.log_std = self.policy.log_std()?.expect("PPO policies have a state-independent log σ");
        if let Some(cost) = &mut self.cost {
            cost.refresh_host()?;
        }
        Ok(())
    }

    /// Warm start (feed-forward policy only): fits the policy's mean to demonstrated actions
    /// by least squares (`obs` n × OBS_DIM, `actions` n × ACT_DIM), `epochs` passes of shuffled
    /// minibatches with its own optimiser, and sets the exploration noise σ to `noise_std`
    /// (the demonstrations' own: the imitation knows the states that noise leads to, and
    /// PPO's initial σ ≈ 0.3 would wreck it before it learns anything). The next
    /// `critic_warmup` rollouts then run with the PPO objective off. Returns the mean squared
    /// error of the last epoch.
    pub fn imitate(&mut self, obs: &[f32], actions: &[f32], epochs: usize, noise_std: f32) -> Result<f32, LearnError> {
        let Some(mean) = self.policy.mean_mlp() else {
            return Err(LearnError::BadConfig("a warm start needs the feed-forward PPO policy".into()));
        };
        let n = actions.len() / ACT_DIM;
        if n == 0 || obs.len() != n * OBS_DIM {
            return Err(LearnError::BadConfig(format!(
                "{} observations for {n} demonstrated actions",
                obs.len() / OBS_DIM
            )));
        }
        let mean = mean.clone();
        let mut opt = Adam::new(vars(mean.params()), self.cfg.lr, self.cfg.max_grad_norm)?;
        let widest = self.cfg.hidden.iter().copied().max().unwrap_or(1).max(1);
        let mb = 512.min(MAX_ELEMWISE / widest).max(1);
        let mut last = 0.0f32;
        for _ in 0..epochs {
            let perm = self.permutation(n);
            let (mut sum, mut batches) = (0.0f32, 0usize);
            for rows in perm.chunks(mb) {
                let loss = imitation_mse(&mean, obs, actions, rows)?;
                opt.minimise(&loss)?;
                sum += loss.to_scalar::<f32>()?;
                batches += 1;
            }
            last = sum / batches.max(1) as f32;
        }
        self.policy.set_log_std(noise_std.max(1e-3).ln())?;
        self.frozen_rollouts = self.cfg.critic_warmup;
        self.imitation = (self.cfg.imitation_coef > 0.0).then(|| Imitation {
            obs: obs.to_vec(),
            actions: actions.to_vec(),
            weight: self.cfg.imitation_coef,
        });
        self.refresh_host()?;
        Ok(last)
    }

    /// Where the time of the learner went so far.
    pub fn timings(&self) -> PpoTimings {
        self.timings
    }

    /// Collects one rollout from `env` and updates the networks on it.
    pub fn learn_rollout(&mut self, env: &mut dyn Environment) -> Result<PpoStats, LearnError> {
        let (n, sd) = (self.n_envs, self.state_dim);
        self.state0.copy_from_slice(&self.state);
        let std: [f32; ACT_DIM] = self.log_std.map(f32::exp);
        for t in 0..self.cfg.n_steps {
            let t0 = Instant::now();
            let rows = t * n..(t + 1) * n;
            self.obs[rows.start * OBS_DIM..rows.end * OBS_DIM].copy_from_slice(env.obs());
            self.act_batch(env.obs())?;
            if let Some(cost) = &mut self.cost {
                for (i, o) in env.obs().chunks_exact(OBS_DIM).enumerate() {
                    cost.values[t * n + i] = cost.value(o, &mut self.scratch);
                }
            }
            normals(&mut self.rng, n * ACT_DIM, &mut self.noise);
            for i in 0..n {
                let k = t * n + i;
                let m = &self.mean[i * ACT_DIM..(i + 1) * ACT_DIM];
                let a = &mut self.actions[k * ACT_DIM..(k + 1) * ACT_DIM];
                for j in 0..ACT_DIM {
                    a[j] = m[j] + std[j] * self.noise[i * ACT_DIM + j];
                }
                self.logp[k] = gaussian_log_prob(a, m, &self.log_std);
                self.values[k] = self.value[i];
            }
            let t1 = Instant::now();
            env.step(&self.actions[rows.start * ACT_DIM..rows.end * ACT_DIM])?;
            let t2 = Instant::now();
            for i in 0..n {
                self.done_row[i] = env.terminated()[i] | env.truncated()[i];
            }
            self.scaler.observe(env.rewards(), &self.done_row);
            let scale = self.scaler.scale();
            for i in 0..n {
                let k = t * n + i;
                self.rewards[k] = env.rewards()[i] * scale;
                self.done[k] = self.done_row[i];
                if env.truncated()[i] != 0 {
                    // The cut episode still has a future: fold γ·V(s_final) into its reward.
                    let v = self.bootstrap_value(&env.final_obs()[i * OBS_DIM..(i + 1) * OBS_DIM], i)?;
                    self.rewards[k] += self.cfg.gamma * v;
                }
                if let Some(cost) = &mut self.cost {
                    let final_obs = &env.final_obs()[i * OBS_DIM..(i + 1) * OBS_DIM];
                    let cut =
                        (env.truncated()[i] != 0).then(|| self.cfg.gamma * cost.value(final_obs, &mut self.scratch));
                    cost.record(k, env.terminated()[i] != 0, self.done_row[i] != 0, cut);
                }
                if self.done_row[i] != 0 {
                    self.state[i * sd..(i + 1) * sd].fill(0.0);
                }
            }
            self.timings.infer_s += (t1 - t0 + t2.elapsed()).as_secs_f64();
            self.timings.env_s += (t2 - t1).as_secs_f64();
        }
        let t0 = Instant::now();
        self.act_batch_values_only(env.obs())?;
        gae(
            &self.rewards,
            &self.values,
            &self.done,
            &self.last_value,
            n,
            self.cfg.gamma,
            self.cfg.lambda,
            &mut self.advantages,
            &mut self.returns,
        );
        if let Some(cost) = &mut self.cost {
            gae(
                &cost.costs,
                &cost.values,
                &self.done,
                &cost.last_value,
                n,
                self.cfg.gamma,
                self.cfg.lambda,
                &mut cost.advantages,
                &mut cost.returns,
            );
            cost.update_lambda();
        }
        let stats = if self.cfg.recurrent { self.update_recurrent() } else { self.update_flat() }?;
        self.frozen_rollouts = self.frozen_rollouts.saturating_sub(1);
        if let Some(im) = &mut self.imitation {
            im.weight *= self.cfg.imitation_decay;
        }
        self.refresh_host()?;
        self.timings.update_s += t0.elapsed().as_secs_f64();
        Ok(stats)
    }

    /// V(s_T) of the observations after the rollout into `self.last_value` (state not advanced).
    fn act_batch_values_only(&mut self, obs: &[f32]) -> Result<(), LearnError> {
        if self.policy.gru().is_none() {
            for (i, (o, v)) in obs.chunks_exact(OBS_DIM).zip(self.last_value.iter_mut()).enumerate() {
                self.host_critic.forward(o, &mut self.scratch, std::slice::from_mut(v));
                if let Some(cost) = &mut self.cost {
                    cost.last_value[i] = cost.value(o, &mut self.scratch);
                }
            }
            return Ok(());
        }
        let v = self.value_of(obs, &self.state.clone())?;
        self.last_value.copy_from_slice(&v);
        Ok(())
    }

    /// The clipped PPO loss on one minibatch given the features of its rows.
    fn loss(&self, features: &Tensor, rows: &[usize]) -> Result<(Tensor, PpoStats), LearnError> {
        let m = rows.len();
        let gather = |src: &[f32], w: usize| -> Vec<f32> {
            rows.iter().flat_map(|&k| src[k * w..(k + 1) * w].to_vec()).collect()
        };
        let actions = matrix(&gather(&self.actions, ACT_DIM), m, ACT_DIM)?;
        let logp_old = matrix(&gather(&self.logp, 1), m, 1)?;
        let mut adv = gather(&self.advantages, 1);
        standardise(&mut adv);
        if let Some(cost) = &self.cost {
            // (Â_r − λ·Â_c)/(1 + λ): both standardised, so λ = 1 weighs them equally.
            let mut cost_adv = gather(&cost.advantages, 1);
            standardise(&mut cost_adv);
            let lambda = cost.lambda as f32;
            adv.iter_mut().zip(&cost_adv).for_each(|(a, c)| *a = (*a - lambda * c) / (1.0 + lambda));
        }
        let adv = matrix(&adv, m, 1)?;
        let ret = matrix(&gather(&self.returns, 1), m, 1)?;
        let (mean, log_std) = self.policy.head(features)?;
        let z = actions.sub(&mean)?.broadcast_mul(&log_std.neg()?.exp()?)?;
        let logp = ((z.sqr()? * -0.5)?.broadcast_sub(&log_std)? - f64::from(HALF_LN_TAU))?.sum_keepdim(D::Minus1)?;
        let log_ratio = (&logp - &logp_old)?;
        let ratio = log_ratio.exp()?;
        let clipped = ratio.clamp(1.0 - self.cfg.clip, 1.0 + self.cfg.clip)?;
        let surr = (&ratio * &adv)?.minimum(&(clipped * &adv)?)?;
        let policy_loss = (surr.mean_all()?.neg()? * if self.frozen_rollouts > 0 { 0.0 } else { 1.0 })?;
        let value = self.critic.forward(features)?;
        let mut value_loss = (value - ret)?.sqr()?.mean_all()?;
        if let Some(cost) = &self.cost {
            let cost_ret = matrix(&gather(&cost.returns, 1), m, 1)?;
            value_loss = (value_loss + (cost.critic.forward(features)? - cost_ret)?.sqr()?.mean_all()?)?;
        }
        let entropy = (log_std + (0.5 + f64::from(HALF_LN_TAU)))?.sum_keepdim(D::Minus1)?.mean_all()?;
        let loss = ((&policy_loss + (&value_loss * self.cfg.vf_coef)?)? - (&entropy * self.cfg.ent_coef)?)?;
        let approx_kl = ((ratio - 1.0)? - log_ratio)?.mean_all()?.to_scalar::<f32>()?;
        let stats = PpoStats {
            policy_loss: policy_loss.to_scalar()?,
            value_loss: value_loss.to_scalar()?,
            entropy: entropy.to_scalar()?,
            approx_kl,
        };
        Ok((loss, stats))
    }

    /// Fisher–Yates shuffle of 0..n from the learner's Rng.
    fn permutation(&mut self, n: usize) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            idx.swap(i, self.rng.below(i as u64 + 1) as usize);
        }
        idx
    }

    fn update_flat(&mut self) -> Result<PpoStats, LearnError> {
        let total = self.rollout_steps();
        let widest = self.cfg.hidden.iter().copied().max().unwrap_or(1).max(1);
        let mb = total.div_ceil(self.cfg.minibatches).min(MAX_ELEMWISE / widest).max(1);
        let mut stats = PpoStats::default();
        for _ in 0..self.cfg.epochs {
            let perm = self.permutation(total);
            for rows in perm.chunks(mb) {
                let obs: Vec<f32> =
                    rows.iter().flat_map(|&k| self.obs[k * OBS_DIM..(k + 1) * OBS_DIM].to_vec()).collect();
                let features = matrix(&obs, rows.len(), OBS_DIM)?;
                let (loss, s) = self.loss(&features, rows)?;
                let loss = match self.imitation_loss(rows.len())? {
                    Some(imitation) => (loss + imitation)?,
                    None => loss,
                };
                self.opt.minimise(&loss)?;
                stats = s;
            }
        }
        Ok(stats)
    }

    /// The weighted imitation term on `m` demonstrations drawn at random, if it is still on.
    fn imitation_loss(&mut self, m: usize) -> Result<Option<Tensor>, LearnError> {
        let (Some(im), Some(mean)) = (&self.imitation, self.policy.mean_mlp()) else { return Ok(None) };
        if im.weight < MIN_IMITATION_WEIGHT {
            return Ok(None);
        }
        let n = (im.actions.len() / ACT_DIM) as u64;
        let rows: Vec<usize> = (0..m).map(|_| self.rng.below(n) as usize).collect();
        Ok(Some((imitation_mse(mean, &im.obs, &im.actions, &rows)? * im.weight)?))
    }

    /// Minibatches are groups of environments; the GRU is unrolled over the whole rollout from
    /// the state it had at the rollout's start, reset where episodes ended.
    fn update_recurrent(&mut self) -> Result<PpoStats, LearnError> {
        let cell = self.policy.gru().expect("recurrent PPO has a GRU policy").clone();
        let (n, t_len, sd) = (self.n_envs, self.cfg.n_steps, self.state_dim);
        let group = n / self.cfg.minibatches;
        let mut stats = PpoStats::default();
        for _ in 0..self.cfg.epochs {
            let perm = self.permutation(n);
            for envs in perm.chunks(group) {
                let h0: Vec<f32> = envs.iter().flat_map(|&i| self.state0[i * sd..(i + 1) * sd].to_vec()).collect();
                let mut h = matrix(&h0, envs.len(), sd)?;
                let mut outs = Vec::with_capacity(t_len);
                let mut rows = Vec::with_capacity(t_len * envs.len());
                for t in 0..t_len {
                    let ks: Vec<usize> = envs.iter().map(|&i| t * n + i).collect();
                    let x: Vec<f32> =
                        ks.iter().flat_map(|&k| self.obs[k * OBS_DIM..(k + 1) * OBS_DIM].to_vec()).collect();
                    h = cell.step(&matrix(&x, envs.len(), OBS_DIM)?, &h)?;
                    outs.push(h.clone());
                    let live: Vec<f32> = ks.iter().map(|&k| 1.0 - f32::from(self.done[k])).collect();
                    h = h.broadcast_mul(&matrix(&live, envs.len(), 1)?)?;
                    rows.extend(ks);
                }
                let features = Tensor::cat(&outs, 0)?;
                let (loss, s) = self.loss(&features, &rows)?;
                self.opt.minimise(&loss)?;
                stats = s;
            }
        }
        Ok(stats)
    }
}

/// Mean squared error of `mean`'s output to the demonstrated actions on `rows` of the
/// demonstrations (`obs` n × OBS_DIM, `actions` n × ACT_DIM): the warm start's fit and the
/// imitation term of the updates after it.
fn imitation_mse(mean: &Mlp, obs: &[f32], actions: &[f32], rows: &[usize]) -> candle_core::Result<Tensor> {
    let x: Vec<f32> = rows.iter().flat_map(|&k| obs[k * OBS_DIM..(k + 1) * OBS_DIM].iter().copied()).collect();
    let y: Vec<f32> = rows.iter().flat_map(|&k| actions[k * ACT_DIM..(k + 1) * ACT_DIM].iter().copied()).collect();
    let pred = mean.forward(&matrix(&x, rows.len(), OBS_DIM)?)?;
    (pred - matrix(&y, rows.len(), ACT_DIM)?)?.sqr()?.mean_all()
}
