//! Generalised advantage estimation (Schulman et al. 2016) over a rollout laid out as
//! `[t · n_envs + i]`, and a running return normaliser for rewards.

/// Advantages and returns of a rollout of `rewards.len() / n_envs` steps.
///
/// `done[t·n+i]` is 1 when the episode of env `i` ended at step `t` (its next value is not
/// used; a truncated episode's bootstrap value is expected to be folded into its reward).
/// `last_values[i]` is V(s_T) of the observation after the last step.
/// A_t = δ_t + γλ(1 − done_t)·A_{t+1}, δ_t = r_t + γ(1 − done_t)·V(s_{t+1}) − V(s_t); R_t = A_t + V(s_t).
#[allow(clippy::too_many_arguments)]
pub fn gae(
    rewards: &[f32],
    values: &[f32],
    done: &[u8],
    last_values: &[f32],
    n_envs: usize,
    gamma: f32,
    lambda: f32,
    advantages: &mut [f32],
    returns: &mut [f32],
) {
    let steps = rewards.len() / n_envs.max(1);
    for (i, &last) in last_values.iter().enumerate().take(n_envs) {
        let mut next_adv = 0.0f32;
        let mut next_value = last;
        for t in (0..steps).rev() {
            let k = t * n_envs + i;
            let live = 1.0 - f32::from(done[k]);
            let delta = rewards[k] + gamma * live * next_value - values[k];
            next_adv = delta + gamma * lambda * live * next_adv;
            advantages[k] = next_adv;
            returns[k] = next_adv + values[k];
            next_value = values[k];
        }
    }
}

/// Standardises advantages in place (mean 0, std 1; constant ones become 0).
pub fn standardise(x: &mut [f32]) {
    let m = x.len().max(1) as f32;
    let mu = x.iter().sum::<f32>() / m;
    let sd = (x.iter().map(|a| (a - mu) * (a - mu)).sum::<f32>() / m).sqrt();
    x.iter_mut().for_each(|a| *a = (*a - mu) / (sd + 1e-8));
}

/// Scales rewards by the running standard deviation of the discounted return (as in
/// VecNormalize), so the loss scale does not depend on the reward weights; deterministic.
#[derive(Debug, Clone)]
pub struct ReturnScaler {
    gamma: f64,
    returns: Vec<f64>,
    count: f64,
    mean: f64,
    m2: f64,
}

impl ReturnScaler {
    pub fn new(n_envs: usize, gamma: f64) -> Self {
        Self { gamma, returns: vec![0.0; n_envs], count: 0.0, mean: 0.0, m2: 0.0 }
    }

    /// Updates the running statistics with one vector step (resetting finished envs).
    pub fn observe(&mut self, rewards: &[f32], done: &[u8]) {
        for ((ret, &r), &d) in self.returns.iter_mut().zip(rewards).zip(done) {
            *ret = *ret * self.gamma + f64::from(r);
            self.count += 1.0;
            let delta = *ret - self.mean;
            self.mean += delta / self.count;
            self.m2 += delta * (*ret - self.mean);
            if d != 0 {
                *ret = 0.0;
            }
        }
    }

    /// The factor rewards are multiplied by.
    pub fn scale(&self) -> f32 {
        let var = if self.count > 1.0 { self.m2 / (self.count - 1.0) } else { 1.0 };
        (1.0 / (var.sqrt() + 1e-8)).min(1e4) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_a_hand_computed_example() {
        // One env, three steps, episode ends after step 1; γ = 0.9, λ = 0.5.
        let r = [1.0, 2.0, 3.0];
        let v = [0.5, 1.0, 1.5];
        let done = [0, 1, 0];
        let last = [2.0];
        let (mut a, mut ret) = ([0.0; 3], [0.0; 3]);
        gae(&r, &v, &done, &last, 1, 0.9, 0.5, &mut a, &mut ret);
        // t=2: δ = 3 + 0.9·2 − 1.5 = 3.3; A = 3.3.
        // t=1: done: δ = 2 − 1 = 1; A = 1.
        // t=0: δ = 1 + 0.9·1 − 0.5 = 1.4; A = 1.4 + 0.45·1 = 1.85.
        let expected = [1.85, 1.0, 3.3];
        for k in 0..3 {
            assert!((a[k] - expected[k]).abs() < 1e-6, "{k}: {} vs {}", a[k], expected[k]);
            assert!((ret[k] - (expected[k] + v[k])).abs() < 1e-6);
        }
    }

    /// Potential shaping is policy-invariant only under the learner's own discount.
    #[test]
    fn the_risk_potential_is_discounted_with_the_learners_gamma() {
        let gamma = f64::from(risktwin_common::env::SHAPING_GAMMA as f32);
        assert_eq!(f64::from(crate::ppo::PpoConfig::default().gamma), gamma);
        assert_eq!(f64::from(crate::sac::SacConfig::default().gamma), gamma);
    }

    #[test]
    fn envs_are_interleaved() {
        // Two envs, two steps: env 1 gets reward only; layout [t·n + i].
        let r = [0.0, 1.0, 0.0, 1.0];
        let v = [0.0; 4];
        let (mut a, mut ret) = ([0.0; 4], [0.0; 4]);
        gae(&r, &v, &[0; 4], &[0.0, 0.0], 2, 1.0, 1.0, &mut a, &mut ret);
        assert_eq!(a, [0.0, 2.0, 0.0, 1.0]);
    }

    #[test]
    fn scaler_normalises_return_spread() {
        let mut s = ReturnScaler::new(1, 0.0);
        for k in 0..1000 {
            s.observe(&[if k % 2 == 0 { 10.0 } else { -10.0 }], &[0]);
        }
        assert!((s.scale() - 0.1).abs() < 1e-3, "{}", s.scale());
    }
}
