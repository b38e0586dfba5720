//! Correlated (burst) loss on top of the channel's delivery ratio: a two-state Gilbert–Elliott
//! chain per link (E. N. Gilbert, "Capacity of a burst-noise channel", Bell Syst. Tech. J. 39,
//! 1960; E. O. Elliott, ibid. 42, 1963). In the bad state every message is lost; in the good
//! state the channel's PDR decides. The chain steps once per message.

use risktwin_common::rng::Rng;
use serde::{Deserialize, Serialize};

/// The chain's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BurstLoss {
    /// P(good → bad) per message.
    pub enter: f64,
    /// P(bad → good) per message: a burst lasts 1 / `leave` messages on average.
    pub leave: f64,
}

impl BurstLoss {
    /// The chain of bursts `mean_burst` messages long on average that lose `share` of all
    /// messages in the long run.
    pub fn from_share(share: f64, mean_burst: f64) -> Result<BurstLoss, String> {
        if !((0.0..1.0).contains(&share) && mean_burst >= 1.0 && mean_burst.is_finite()) {
            return Err(format!("burst loss {share} over bursts of {mean_burst}: need 0 ≤ share < 1, bursts ≥ 1"));
        }
        // A chain can enter a burst at most once per message: share ≤ burst / (burst + 1).
        let most = mean_burst / (mean_burst + 1.0);
        if share > most {
            return Err(format!(
                "burst loss {share} over bursts of {mean_burst}: at most {most:.3} with bursts that long"
            ));
        }
        let leave = 1.0 / mean_burst;
        // Stationary P(bad) = enter / (enter + leave) = share.
        let enter = share * leave / (1.0 - share);
        let chain = BurstLoss { enter, leave };
        chain.check()?;
        Ok(chain)
    }

    pub fn check(&self) -> Result<(), String> {
        if !((0.0..=1.0).contains(&self.enter) && self.leave > 0.0 && self.leave <= 1.0) {
            return Err(format!(
                "burst chain enter {} / leave {}: need probabilities, leave > 0",
                self.enter, self.leave
            ));
        }
        Ok(())
    }

    /// The long-run share of messages in the bad state.
    pub fn stationary_loss(&self) -> f64 {
        self.enter / (self.enter + self.leave)
    }
}

/// One link's chain state.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BurstState {
    pub bad: bool,
}

impl BurstState {
    /// Steps the chain for one message; whether the message survives the burst state.
    pub fn step(&mut self, chain: &BurstLoss, rng: &mut Rng) -> bool {
        self.bad = if self.bad { !rng.chance(chain.leave) } else { rng.chance(chain.enter) };
        !self.bad
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bursts_lose_their_share_in_runs_of_their_mean_length() {
        let chain = BurstLoss::from_share(0.1, 5.0).expect("valid");
        assert!((chain.stationary_loss() - 0.1).abs() < 1e-12);
        let mut rng = Rng::new(3);
        let mut state = BurstState::default();
        let n = 200_000;
        let (mut lost, mut bursts, mut run) = (0u64, Vec::new(), 0u64);
        for _ in 0..n {
            if state.step(&chain, &mut rng) {
                if run > 0 {
                    bursts.push(run);
                }
                run = 0;
            } else {
                lost += 1;
                run += 1;
            }
        }
        let share = lost as f64 / n as f64;
        let mean_burst = bursts.iter().sum::<u64>() as f64 / bursts.len() as f64;
        assert!((share - 0.1).abs() < 0.01, "share {share}");
        assert!((mean_burst - 5.0).abs() < 0.25, "mean burst {mean_burst}");
        // Independent losses at 10 % would give bursts of 1.11 on average: these are correlated.
        assert!(mean_burst > 4.0);
    }

    #[test]
    fn impossible_chains_are_refused() {
        assert!(BurstLoss::from_share(1.0, 5.0).is_err());
        assert!(BurstLoss::from_share(0.1, 0.5).is_err());
        assert!(
            BurstLoss::from_share(0.6, 1.0).expect_err("too much for single-message bursts").contains("at most 0.500")
        );
        assert!(BurstLoss { enter: 0.1, leave: 0.0 }.check().is_err());
        assert_eq!(BurstLoss::from_share(0.0, 1.0).map(|c| c.enter), Ok(0.0));
    }
}
