//! One V2X message to its receivers: the channel ([`super::channel`]), burst loss
//! ([`super::loss`]) and latency ([`super::latency`]) applied together, seeded, so that the same
//! seed gives the same deliveries in real time and in virtual time.

use super::channel::{LinkBudget, PathLoss};
use super::latency::Latency;
use super::loss::{BurstLoss, BurstState};
use risktwin_common::rng::Rng;

/// How messages cross one kind of V2X link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct V2xChannel {
    pub model: PathLoss,
    pub budget: LinkBudget,
    pub latency: Latency,
    /// Correlated loss on top of the channel's, if any.
    pub bursts: Option<BurstLoss>,
}

impl V2xChannel {
    pub fn check(&self) -> Result<(), String> {
        self.budget.check()?;
        self.latency.check()?;
        self.bursts.as_ref().map_or(Ok(()), BurstLoss::check)
    }

    /// Whether a message sent over `distance_m` (between the antennas, in the ground truth)
    /// reaches one receiver. `burst` is this sender–receiver pair's chain state. Each copy draws
    /// its own shadowing (no correlation between messages beyond the bursts).
    pub fn receives(&self, distance_m: f64, burst: &mut BurstState, rng: &mut Rng) -> bool {
        let survives_burst = self.bursts.as_ref().is_none_or(|chain| burst.step(chain, rng));
        let point = self.budget.at(self.model, distance_m);
        // The shadowing adds to the loss: the SNR this copy sees.
        let snr_db = point.snr_db - point.shadowing_sigma_db * rng.normal();
        survives_burst && snr_db >= self.budget.sinr_threshold_db
    }

    /// When a broadcast goes out, ms after it is made: once per message, the same for every
    /// receiver (one transmission on one resource).
    pub fn latency_ms(&self, rng: &mut Rng) -> f64 {
        self.latency.sample_ms(rng)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn urban(bursts: Option<BurstLoss>) -> V2xChannel {
        V2xChannel { model: PathLoss::UrbanNlos, budget: LinkBudget::default(), latency: Latency::SIDELINK, bursts }
    }

    /// `n` messages to one receiver: each one's latency if it arrives.
    fn delivered(channel: &V2xChannel, distance_m: f64, n: u32, seed: u64) -> Vec<Option<f64>> {
        let mut rng = Rng::new(seed);
        let mut burst = BurstState::default();
        (0..n)
            .map(|_| {
                let latency_ms = channel.latency_ms(&mut rng);
                channel.receives(distance_m, &mut burst, &mut rng).then_some(latency_ms)
            })
            .collect()
    }

    #[test]
    fn the_share_delivered_is_the_channels_pdr_and_bursts_take_their_share() {
        let n = 40_000;
        for distance_m in [100.0, 200.0, 260.0] {
            let plain = urban(None);
            let pdr = plain.budget.at(plain.model, distance_m).pdr;
            let got = delivered(&plain, distance_m, n, 11).iter().filter(|d| d.is_some()).count() as f64 / n as f64;
            // Three standard deviations of a binomial share.
            let tolerance = 3.0 * (pdr * (1.0 - pdr) / n as f64).sqrt() + 1e-3;
            assert!((got - pdr).abs() < tolerance, "{distance_m} m: {got} against {pdr}");
            let bursty = urban(Some(BurstLoss::from_share(0.2, 4.0).expect("valid")));
            let got = delivered(&bursty, distance_m, n, 12).iter().filter(|d| d.is_some()).count() as f64 / n as f64;
            assert!((got - 0.8 * pdr).abs() < 0.02, "{distance_m} m with bursts: {got} against {}", 0.8 * pdr);
        }
    }

    #[test]
    fn delivered_messages_take_the_latency_models_time_and_the_seed_decides_everything() {
        let channel = urban(Some(BurstLoss::from_share(0.1, 3.0).expect("valid")));
        let first = delivered(&channel, 200.0, 2_000, 5);
        assert!(first.iter().flatten().all(|ms| (4.0..=100.0).contains(ms)));
        let bits = |v: &[Option<f64>]| v.iter().map(|d| d.map(f64::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&first), bits(&delivered(&channel, 200.0, 2_000, 5)));
        assert_ne!(bits(&first), bits(&delivered(&channel, 200.0, 2_000, 6)));
    }
}
