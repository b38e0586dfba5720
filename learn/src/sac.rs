//! SAC (Haarnoja et al. 2018): tanh-squashed Gaussian actor, twin Q critics with Polyak-averaged
//! targets, learned temperature α towards the target entropy −|A|, uniform replay.

use crate::LearnError;
use crate::envs::Environment;
use crate::nn::{HALF_LN_TAU, Mlp, Param, const_param, matrix, normals, polyak, vars};
use crate::optim::Adam;
use crate::policy::{Algo, PolicyNet};
use candle_core::{D, Tensor};
use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::rng::Rng;

/// SAC hyper-parameters (defaults from the SAC paper, smaller networks).
#[derive(Debug, Clone, PartialEq)]
pub struct SacConfig {
    pub hidden: Vec<usize>,
    pub lr: f64,
    pub gamma: f32,
    pub tau: f64,
    pub batch: usize,
    /// Replay capacity, transitions.
    pub buffer: usize,
    /// Transitions collected with uniform random actions before learning starts.
    pub warmup: usize,
    /// Gradient steps per vector step.
    pub updates_per_step: usize,
    /// Rewards are multiplied by this before learning (the crash penalty is −200).
    pub reward_scale: f32,
}

impl Default for SacConfig {
    fn default() -> Self {
        Self {
            hidden: vec![64, 64],
            lr: 3e-4,
            gamma: 0.99,
            tau: 0.005,
            batch: 256,
            buffer: 200_000,
            warmup: 5_000,
            updates_per_step: 1,
            reward_scale: 0.1,
        }
    }
}

/// Preallocated ring buffer of transitions.
struct Replay {
    obs: Vec<f32>,
    next_obs: Vec<f32>,
    act: Vec<f32>,
    rew: Vec<f32>,
    term: Vec<f32>,
    len: usize,
    head: usize,
    cap: usize,
}

/// A SAC learner.
pub struct Sac {
    cfg: SacConfig,
    actor: PolicyNet,
    q: [Mlp; 2],
    q_target: [Mlp; 2],
    log_alpha: Param,
    opt_actor: Adam,
    opt_q: Adam,
    opt_alpha: Adam,
    rng: Rng,
    replay: Replay,
    n_envs: usize,
    collected: usize,
    actions: Vec<f32>,
    noise: Vec<f32>,
}

impl Sac {
    /// A learner for `n_envs` environments, initialised from `seed`.
    pub fn new(cfg: SacConfig, n_envs: usize, seed: u64) -> Result<Self, LearnError> {
        if cfg.batch == 0 || cfg.buffer < cfg.batch || n_envs == 0 {
            return Err(LearnError::BadConfig(format!("SAC needs 0 < batch <= buffer, got {cfg:?}")));
        }
        let mut rng = Rng::derive(seed, 0x5AC);
        let actor = PolicyNet::new(Algo::Sac, &cfg.hidden, &mut rng)?;
        let mut sizes = vec![OBS_DIM + ACT_DIM];
        sizes.extend_from_slice(&cfg.hidden);
        sizes.push(1);
        let q = [Mlp::new("q1", &sizes, 1.0, &mut rng)?, Mlp::new("q2", &sizes, 1.0, &mut rng)?];
        // Targets are separate variables (a clone would share them), copied from the critics.
        let q_target =
            [Mlp::new("q1t", &sizes, 1.0, &mut Rng::new(0))?, Mlp::new("q2t", &sizes, 1.0, &mut Rng::new(0))?];
        for k in 0..2 {
            polyak(q_target[k].params(), q[k].params(), 1.0)?;
        }
        let log_alpha = const_param("log_alpha".into(), (1, 1), 0.0)?;
        let opt_actor = Adam::new(vars(actor.params()), cfg.lr, f64::INFINITY)?;
        let opt_q = Adam::new(vars(q[0].params().chain(q[1].params())), cfg.lr, f64::INFINITY)?;
        let opt_alpha = Adam::new(vec![log_alpha.var.clone()], cfg.lr, f64::INFINITY)?;
        let cap = cfg.buffer;
        Ok(Self {
            replay: Replay {
                obs: vec![0.0; cap * OBS_DIM],
                next_obs: vec![0.0; cap * OBS_DIM],
                act: vec![0.0; cap * ACT_DIM],
                rew: vec![0.0; cap],
                term: vec![0.0; cap],
                len: 0,
                head: 0,
                cap,
            },
            cfg,
            actor,
            q,
            q_target,
            log_alpha,
            opt_actor,
            opt_q,
            opt_alpha,
            rng,
            n_envs,
            collected: 0,
            actions: vec![0.0; n_envs * ACT_DIM],
            noise: Vec::new(),
        })
    }

    /// The current policy.
    pub fn policy(&self) -> &PolicyNet {
        &self.actor
    }

    /// Reparameterised squashed sample and its log-probability for a batch of observations.
    fn sample(&mut self, obs: &Tensor, batch: usize) -> Result<(Tensor, Tensor), LearnError> {
        let (mean, log_std) = self.actor.head(obs)?;
        normals(&mut self.rng, batch * ACT_DIM, &mut self.noise);
        let eps = matrix(&self.noise, batch, ACT_DIM)?;
        let u = (&mean + (log_std.exp()? * &eps)?)?;
        let a = u.tanh()?;
        let gauss = ((eps.sqr()? * -0.5)? - &log_std)?.affine(1.0, -f64::from(HALF_LN_TAU))?;
        let squash = (a.sqr()?.affine(-1.0, 1.0 + 1e-6))?.log()?;
        let logp = (gauss - squash)?.sum_keepdim(D::Minus1)?;
        Ok((a, logp))
    }

    fn q_min(nets: &[Mlp; 2], obs: &Tensor, act: &Tensor) -> candle_core::Result<Tensor> {
        let x = Tensor::cat(&[obs, act], 1)?;
        nets[0].forward(&x)?.minimum(&nets[1].forward(&x)?)
    }

    /// One vector step of collection, then `updates_per_step` gradient steps once warm.
    /// Returns the environment steps taken.
    pub fn learn_steps(&mut self, env: &mut dyn Environment) -> Result<u64, LearnError> {
        let n = self.n_envs;
        if self.collected < self.cfg.warmup {
            for a in self.actions.iter_mut() {
                *a = self.rng.uniform(-1.0, 1.0) as f32;
            }
        } else {
            let obs = matrix(env.obs(), n, OBS_DIM)?;
            let (a, _) = self.sample(&obs, n)?;
            self.actions.copy_from_slice(&a.flatten_all()?.to_vec1::<f32>()?);
        }
        let obs_before = env.obs().to_vec();
        env.step(&self.actions)?;
        let r = &mut self.replay;
        for i in 0..n {
            let k = r.head;
            r.obs[k * OBS_DIM..(k + 1) * OBS_DIM].copy_from_slice(&obs_before[i * OBS_DIM..(i + 1) * OBS_DIM]);
            let done = env.terminated()[i] | env.truncated()[i];
            let next = if done != 0 { env.final_obs() } else { env.obs() };
            r.next_obs[k * OBS_DIM..(k + 1) * OBS_DIM].copy_from_slice(&next[i * OBS_DIM..(i + 1) * OBS_DIM]);
            r.act[k * ACT_DIM..(k + 1) * ACT_DIM].copy_from_slice(&self.actions[i * ACT_DIM..(i + 1) * ACT_DIM]);
            r.rew[k] = env.rewards()[i] * self.cfg.reward_scale;
            r.term[k] = f32::from(env.terminated()[i]);
            r.head = (r.head + 1) % r.cap;
            r.len = (r.len + 1).min(r.cap);
        }
        self.collected += n;
        if self.collected >= self.cfg.warmup && self.replay.len >= self.cfg.batch {
            for _ in 0..self.cfg.updates_per_step {
                self.update()?;
            }
        }
        Ok(n as u64)
    }

    fn update(&mut self) -> Result<(), LearnError> {
        let b = self.cfg.batch;
        let idx: Vec<usize> = (0..b).map(|_| self.rng.below(self.replay.len as u64) as usize).collect();
        let r = &self.replay;
        let g = |src: &[f32], w: usize| -> Vec<f32> {
            idx.iter().flat_map(|&k| src[k * w..(k + 1) * w].to_vec()).collect()
        };
        let obs = matrix(&g(&r.obs, OBS_DIM), b, OBS_DIM)?;
        let next = matrix(&g(&r.next_obs, OBS_DIM), b, OBS_DIM)?;
        let act = matrix(&g(&r.act, ACT_DIM), b, ACT_DIM)?;
        let rew = matrix(&g(&r.rew, 1), b, 1)?;
        let live = matrix(&g(&r.term, 1).iter().map(|t| 1.0 - t).collect::<Vec<_>>(), b, 1)?;
        let alpha = f64::from(self.log_alpha.var.as_tensor().exp()?.flatten_all()?.to_vec1::<f32>()?[0]);

        // Critics towards r + γ(1 − term)(min Q_targ(s', a') − α log π(a'|s')).
        let (a2, logp2) = self.sample(&next, b)?;
        let q_next = (Self::q_min(&self.q_target, &next, &a2)? - (logp2 * alpha)?)?;
        let y = (rew + (live * q_next)?.affine(f64::from(self.cfg.gamma), 0.0)?)?.detach();
        let x = Tensor::cat(&[&obs, &act], 1)?;
        let q_loss =
            ((self.q[0].forward(&x)? - &y)?.sqr()?.mean_all()? + (self.q[1].forward(&x)? - &y)?.sqr()?.mean_all()?)?;
        self.opt_q.minimise(&q_loss)?;

        // Actor: minimise α log π − min Q.
        let (a_new, logp) = self.sample(&obs, b)?;
        let actor_loss = ((&logp * alpha)? - Self::q_min(&self.q, &obs, &a_new)?)?.mean_all()?;
        self.opt_actor.minimise(&actor_loss)?;

        // Temperature: −log α · (log π + target entropy), target entropy −|A|.
        let err = logp.detach().affine(1.0, -(ACT_DIM as f64))?;
        let alpha_loss = err.broadcast_mul(self.log_alpha.var.as_tensor())?.mean_all()?.neg()?;
        self.opt_alpha.minimise(&alpha_loss)?;

        for k in 0..2 {
            polyak(self.q_target[k].params(), self.q[k].params(), self.cfg.tau)?;
        }
        Ok(())
    }
}
