//! One V2X episode in virtual time: a scenario driven by the reference driver while an RSU warns
//! it of hazards ([`super::warning`]), its vehicles hear each other's CAMs ([`super::awareness`])
//! and a twin follows them through the RSU ([`super::twin`]) — all over one channel, each with
//! its own random stream under the episode's seed, none touching the physics.

use super::awareness::{Awareness, AwarenessSummary, vehicles};
use super::twin::{TwinLag, TwinSummary};
use super::warning::{WarningCounts, WarningSetup, Warnings};
use risktwin_common::episode::{EpisodeResult, run_stepped, with_reference_driver};
use risktwin_common::histogram::Histogram;
use risktwin_common::metrics::RewardWeights;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::ScenarioSpec;

/// Stream ids of the awareness and twin channels under the episode's seed.
const AWARENESS_STREAM: u64 = 0xCA_AA;
const TWIN_STREAM: u64 = 0x7_1A;

/// What one V2X episode produced.
#[derive(Debug)]
pub struct V2xEpisode {
    pub result: EpisodeResult,
    pub awareness: Option<AwarenessSummary>,
    /// Latencies of the CAM copies that arrived, µs.
    pub latency_us: Histogram,
    pub twin: TwinSummary,
    pub warnings: WarningCounts,
}

/// `spec`'s episode with the reference driver warned over `setup`'s channel, seeded by `seed`.
pub fn run_episode(spec: &ScenarioSpec, setup: WarningSetup, seed: u64) -> V2xEpisode {
    let (mut world, mut driver) = with_reference_driver(spec);
    let mut warnings = Warnings::new(&world, setup, seed);
    let receiver = warnings.mast().position();
    let mut states = Vec::new();
    vehicles(&world, &mut states);
    let n = states.len();
    let awareness_seed = Rng::derive(seed, AWARENESS_STREAM).next_u64();
    let mut awareness = Awareness::new(setup.channel, n, awareness_seed);
    let mut twin = TwinLag::new(setup.channel, receiver, n, Rng::derive(seed, TWIN_STREAM).next_u64());
    let mut stepped = false;
    let result = run_stepped(
        &mut world,
        &RewardWeights::default(),
        &mut |w, _| {
            vehicles(w, &mut states);
            awareness.step(w.time_s, &states);
            twin.step(w, &states);
            stepped = true;
        },
        &mut |w| Ok::<_, std::convert::Infallible>(warnings.step(w, &mut driver)),
    )
    .unwrap_or_else(|e| match e {});
    V2xEpisode {
        result,
        awareness: stepped.then(|| awareness.summary()),
        latency_us: awareness.into_latencies(),
        twin: twin.summary(),
        warnings: warnings.counts(),
    }
}
