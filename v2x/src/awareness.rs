//! Cooperative awareness over a V2X channel in virtual time: each vehicle sends CAMs by the
//! generation rules ([`super::cam`]), every other vehicle receives each one or not through the
//! channel ([`super::link`]), and each receiver's knowledge of each sender ages between them.
//! The age of information (AoI) of a pair at a step is the time since the newest CAM the
//! receiver holds from the sender was made; a pair that holds none has no age yet.

use super::cam::{CamState, CamTrigger};
use super::link::V2xChannel;
use super::loss::BurstState;
use risktwin_common::episode::evaluate_observed;
use risktwin_common::histogram::Histogram;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::world::World;
use serde::Serialize;

/// One sender → receiver pair.
#[derive(Debug, Clone, Default)]
struct Pair {
    burst: BurstState,
    /// CAMs on their way: (made, arrives), s.
    in_flight: Vec<(f64, f64)>,
    /// When the newest CAM that has arrived was made, s.
    newest_s: Option<f64>,
}

/// What crossed the channel and how old the receivers' knowledge was.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AwarenessSummary {
    /// CAMs made.
    pub cams: u64,
    /// CAM copies sent to a receiver (each CAM to every other vehicle present).
    pub transmissions: u64,
    /// Copies the channel passed (some may still be on their way when the run ends).
    pub passed: u64,
    /// passed / transmissions; `None` with nothing sent.
    pub pdr: Option<f64>,
    /// Latency of the copies that arrived.
    pub latency_p50_ms: Option<f64>,
    pub aoi_mean_ms: Option<f64>,
    pub aoi_p95_ms: Option<f64>,
    /// Pair-steps at which the receiver held nothing yet from the sender.
    pub never_heard: u64,
}

/// The awareness of `n` vehicles of each other.
pub struct Awareness {
    channel: V2xChannel,
    triggers: Vec<CamTrigger>,
    /// Row-major: `pairs[sender * n + receiver]`.
    pairs: Vec<Pair>,
    rng: Rng,
    cams: u64,
    transmissions: u64,
    passed: u64,
    /// Latencies of arrived copies and ages sampled, µs (quantiles within 1.6 %).
    latency_us: Histogram,
    age_us: Histogram,
    age_sum_ms: f64,
    never_heard: u64,
}

impl Awareness {
    pub fn new(channel: V2xChannel, vehicles: usize, seed: u64) -> Awareness {
        Awareness {
            channel,
            triggers: vec![CamTrigger::default(); vehicles],
            pairs: vec![Pair::default(); vehicles * vehicles],
            rng: Rng::new(seed),
            cams: 0,
            transmissions: 0,
            passed: 0,
            latency_us: Histogram::default(),
            age_us: Histogram::default(),
            age_sum_ms: 0.0,
            never_heard: 0,
        }
    }

    /// One step at `now_s`: every vehicle's state in a fixed order, `None` for one not on the
    /// road now (it neither sends, nor receives, nor is counted).
    pub fn step(&mut self, now_s: f64, states: &[Option<CamState>]) {
        let n = self.triggers.len();
        debug_assert_eq!(states.len(), n, "one slot per vehicle");
        for (sender, state) in states.iter().enumerate() {
            let Some(state) = state else { continue };
            if self.triggers[sender].check(*state).is_none() {
                continue;
            }
            self.cams += 1;
            // One transmission: the same latency for every receiver, the loss per receiver.
            let latency_ms = self.channel.latency_ms(&mut self.rng);
            for (receiver, distance_m) in receivers(states, sender) {
                let pair = &mut self.pairs[sender * n + receiver];
                self.transmissions += 1;
                if self.channel.receives(distance_m, &mut pair.burst, &mut self.rng) {
                    self.passed += 1;
                    pair.in_flight.push((now_s, now_s + latency_ms / 1e3));
                }
            }
        }
        for (k, pair) in self.pairs.iter_mut().enumerate() {
            let (sender, receiver) = (k / n, k % n);
            if sender == receiver || states[sender].is_none() || states[receiver].is_none() {
                continue;
            }
            let latency_us = &self.latency_us;
            pair.in_flight.retain(|&(made_s, arrives_s)| {
                let arrived = arrives_s <= now_s;
                if arrived {
                    latency_us.record(((arrives_s - made_s) * 1e6).round() as u64);
                    if pair.newest_s.is_none_or(|newest| made_s > newest) {
                        pair.newest_s = Some(made_s);
                    }
                }
                !arrived
            });
            match pair.newest_s {
                Some(made_s) => {
                    let age_ms = (now_s - made_s) * 1e3;
                    self.age_us.record((age_ms * 1e3).round() as u64);
                    self.age_sum_ms += age_ms;
                }
                None => self.never_heard += 1,
            }
        }
    }

    /// The latencies of the copies that arrived, µs.
    pub fn into_latencies(self) -> Histogram {
        self.latency_us
    }

    pub fn summary(&self) -> AwarenessSummary {
        let ages = self.age_us.count();
        let ms = |us: Option<f64>| us.map(|us| us / 1e3);
        AwarenessSummary {
            cams: self.cams,
            transmissions: self.transmissions,
            passed: self.passed,
            pdr: (self.transmissions > 0).then(|| self.passed as f64 / self.transmissions as f64),
            latency_p50_ms: ms(self.latency_us.quantile(0.5)),
            aoi_mean_ms: (ages > 0).then(|| self.age_sum_ms / ages as f64),
            aoi_p95_ms: ms(self.age_us.quantile(0.95)),
            never_heard: self.never_heard,
        }
    }
}

/// The receivers of a broadcast of `sender` at one step, in slot order: every other slot of
/// `states` holding a state (one in the world now), with its distance from the sender's, m.
/// Shared by [`Awareness`] and [`super::messages::VirtualScene`]: one copy per such receiver.
pub(super) fn receivers(states: &[Option<CamState>], sender: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
    let from = states[sender];
    states.iter().enumerate().filter(move |&(receiver, _)| receiver != sender).filter_map(move |(receiver, other)| {
        let (from, other) = (from?, (*other)?);
        Some((receiver, (from.x_m - other.x_m).hypot(from.y_m - other.y_m)))
    })
}

/// Every vehicle of `world` as a CAM carries it: the ego, then its traffic in index order,
/// `None` for a traffic vehicle not on the road now (not yet placed, or gone off its lane's end).
/// Parked cars are on the road and send like the others (1 Hz, standing).
pub(super) fn vehicles(world: &World, out: &mut Vec<Option<CamState>>) {
    out.clear();
    let time_s = world.time_s;
    let ego = world.ego.pose();
    let speed_mps = world.ego.velocity().norm();
    out.push(Some(CamState { time_s, x_m: ego.x_m, y_m: ego.y_m, heading_rad: ego.heading_rad, speed_mps }));
    let traffic = &world.traffic;
    out.extend((0..traffic.len()).map(|i| {
        traffic.is_active(i).then(|| {
            let obb = traffic.obb(i);
            let heading_rad = obb.axis.y.atan2(obb.axis.x);
            let (x_m, y_m, speed_mps) = (obb.centre.x, obb.centre.y, traffic.velocity(i).norm());
            CamState { time_s, x_m, y_m, heading_rad, speed_mps }
        })
    }));
}

/// The awareness of each other of the vehicles of `spec`'s episode (its ego with the reference
/// driver, and its traffic) over `channel`, after every physics step; `None` if no step ran.
pub fn of_episode(spec: &ScenarioSpec, channel: V2xChannel, seed: u64) -> Option<AwarenessSummary> {
    let mut awareness: Option<Awareness> = None;
    let mut states = Vec::new();
    evaluate_observed(spec, &mut |world, _| {
        vehicles(world, &mut states);
        awareness.get_or_insert_with(|| Awareness::new(channel, states.len(), seed)).step(world.time_s, &states);
    });
    awareness.map(|a| a.summary())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::channel::{LinkBudget, PathLoss};
    use crate::latency::Latency;
    use crate::loss::BurstLoss;

    fn channel(latency: Latency) -> V2xChannel {
        V2xChannel { model: PathLoss::UrbanNlos, budget: LinkBudget::default(), latency, bursts: None }
    }

    /// Two vehicles standing `apart_m` apart for `seconds`, stepped every 50 ms.
    fn standing(apart_m: f64, seconds: f64, latency: Latency, seed: u64) -> AwarenessSummary {
        let mut awareness = Awareness::new(channel(latency), 2, seed);
        for k in 0..=(seconds / 0.05).round() as u32 {
            let t = k as f64 * 0.05;
            let at = |x_m| Some(CamState { time_s: t, x_m, y_m: 0.0, heading_rad: 0.0, speed_mps: 0.0 });
            awareness.step(t, &[at(0.0), at(apart_m)]);
        }
        awareness.summary()
    }

    #[test]
    fn standing_vehicles_close_by_know_each_other_at_most_a_second_and_a_latency_old() {
        // 1 Hz CAMs, 20 ms each way, all delivered at 20 m: the age runs from 20 ms to 1.0 s.
        let fixed = Latency::Sidelink { t1_ms: 20.0, t2_ms: 20.0 };
        let s = standing(20.0, 60.0, fixed, 1);
        assert_eq!(s.cams, 2 * 61, "one CAM a second each, and the first");
        assert_eq!((s.transmissions, s.passed, s.pdr), (2 * 61, 2 * 61, Some(1.0)));
        let p50 = s.latency_p50_ms.expect("latencies");
        assert!((p50 - 20.0).abs() < 20.0 / 60.0, "within the histogram's bucket: {s:?}");
        // Ages sampled every 50 ms after each arrival: 50, 100, … 1000 ms; mean 525 ms.
        let mean = s.aoi_mean_ms.expect("ages");
        assert!((mean - 525.0).abs() < 5.0, "{s:?}");
        assert!(s.aoi_p95_ms.expect("p95") <= 1000.0 * (1.0 + 1.0 / 60.0), "{s:?}");
        assert_eq!(s.never_heard, 2, "the first step, before the first CAM arrived");
    }

    #[test]
    fn the_vehicles_of_a_cut_in_hear_each_other_and_bursts_age_what_they_know() {
        let spec = risktwin_common::scenario::sample(1, risktwin_common::scenario::ScenarioKind::CutIn, 0);
        let highway = V2xChannel { model: PathLoss::HighwayLos, ..channel(Latency::SIDELINK) };
        let open = of_episode(&spec, highway, 9).expect("steps ran");
        // A few vehicles tens of metres apart: every copy arrives.
        assert!(open.cams > 0 && open.pdr == Some(1.0), "{open:?}");
        // Moving vehicles send more often than standing ones (1 Hz): with the same latency,
        // their knowledge of each other is younger than two standing vehicles' (about 550 ms).
        let still = standing(20.0, 60.0, Latency::SIDELINK, 9).aoi_mean_ms.expect("ages");
        assert!(open.aoi_mean_ms.expect("ages") < still - 100.0, "{open:?} against standing {still} ms");
        // Bursts losing 30 % of the copies, 5 in a row on average: older knowledge.
        let bursts = BurstLoss::from_share(0.3, 5.0).expect("valid");
        let lossy = of_episode(&spec, V2xChannel { bursts: Some(bursts), ..highway }, 9).expect("steps ran");
        assert!(lossy.pdr < Some(0.9) && lossy.aoi_mean_ms > open.aoi_mean_ms, "{lossy:?} against {open:?}");
        assert_eq!(Some(lossy), of_episode(&spec, V2xChannel { bursts: Some(bursts), ..highway }, 9), "seeded");
    }

    #[test]
    fn out_of_range_nothing_arrives_and_the_seed_decides() {
        let far = standing(5_000.0, 10.0, Latency::SIDELINK, 2);
        assert_eq!((far.passed, far.aoi_mean_ms), (0, None), "{far:?}");
        assert_eq!(far.never_heard, 2 * 201);
        // Around the urban NLOS 50 % distance, about half arrive, the same ones for a seed.
        let edge = standing(339.0, 120.0, Latency::SIDELINK, 3);
        let pdr = edge.pdr.expect("sent");
        assert!((0.35..0.65).contains(&pdr), "{edge:?}");
        assert_eq!(edge, standing(339.0, 120.0, Latency::SIDELINK, 3));
        assert_ne!(edge, standing(339.0, 120.0, Latency::SIDELINK, 4));
        // Losses make the knowledge older than with every CAM delivered.
        let near = standing(20.0, 120.0, Latency::SIDELINK, 3);
        assert!(edge.aoi_mean_ms > near.aoi_mean_ms, "{edge:?} against {near:?}");
    }
}
