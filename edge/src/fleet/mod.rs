//! A scene shared by several processes: one **authority** steps the physical world (the
//! scenario's road, its background IDM/MOBIL traffic, scripted adversaries, pedestrians, parked
//! cars and friction) and every connected vehicle and roadside unit is a **participant** with
//! its own onboard stack (own sensor model and noise stream; the ego's also its driver).
//!
//! This is CARLA's synchronous mode / OpenCDA's layout: per physics step the authority sends
//! the ground truth ([`wire::Truth`]) to every participant, each perceives it with its own
//! sensor, the ego's driver acts on what it perceived, and the authority advances the world
//! with the ego's controls once every participant has answered ([`wire::Reply`]). Why this and
//! not one world per process: physics must be computed once, or two processes disagree on
//! where a car is the moment they differ by one rounding; and contacts between vehicles of
//! different processes can only be detected where both are. Why the sensors run in the
//! participants and not in the authority: sensing is the onboard stack's job (its noise,
//! dropout and occlusion belong to that vehicle), and one truth message serves every
//! participant, so the authority's cost per step does not grow with the sensors.
//!
//! Roles ([`Role`]): `v0` is the scenario's ego, driven by its process; `v1…` are the
//! scenario's traffic vehicles in cast order (in a cut-in, `v1` is the cutter), whose motion
//! stays the scenario's own (IDM/MOBIL or the scripted manoeuvre: a connected cut-in adversary
//! still cuts in) while their stacks perceive and report; `rsu0…` are roadside units along the
//! route. A scene is a generated scenario or a CommonRoad recording ([`SceneSource`],
//! [`recording`]): the recording's ego is driven by its process as `resimulate` drives it, and
//! its other vehicles, connected or not, are played back. The same [`authority::run_scene`] runs embedded (every stack in one process,
//! [`authority::Embedded`]) or distributed over Zenoh ([`net`]); lockstep makes the two give
//! the same bytes.

pub mod authority;
pub mod net;
pub mod onboard;
pub mod physics;
pub mod recording;
mod reliable;
pub mod streams;
pub mod v2x;
pub mod wire;

use physics::SceneWorld;
pub use recording::Recording;
use risktwin_common::digest::fnv1a64;
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_common::world::EGO_OBJECT_ID;
use risktwin_commonroad::twin::RECORDING_SEED;
use risktwin_policy::model::DriverModel;
use risktwin_v2x::messages::MessageChannel;
use std::fmt;
use thiserror::Error;

/// Most roadside units a scene places.
pub const MAX_RSUS: u32 = 16;

/// Why a scene could not be set up or run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    #[error("--connected must be at least 1 (the ego), got 0")]
    NoEgo,
    #[error("--connected {asked} needs {needed} traffic vehicles beside the ego; this {what} has {available} {which}")]
    TooManyConnected { asked: u32, needed: u32, available: u32, what: &'static str, which: &'static str },
    #[error("--rsus {asked} is more than the {MAX_RSUS} a scene places")]
    TooManyRsus { asked: u32 },
    #[error("{reason}")]
    Recording { reason: String },
    #[error("participant {id:?} is not in this scene (it has {known})")]
    UnknownParticipant { id: String, known: String },
    #[error("participant {id} is taken out of this scene (--without {id})")]
    Withdrawn { id: String },
    #[error("--without {id}: only a connected traffic vehicle (v1, v2, …) can be taken out of the scene")]
    CannotWithdraw { id: String },
    #[error("participant {id} runs {theirs}, this process {ours}: start every role with the same scene and seed")]
    Mismatch { id: String, theirs: String, ours: String },
    #[error("participant(s) {ids} did not answer step {step} within {waited_ms} ms (stalled or dead); the scene ends")]
    Stalled { ids: String, step: u64, waited_ms: u64 },
    #[error("participant(s) {ids} did not join within {waited_s} s")]
    NotJoined { ids: String, waited_s: u64 },
    #[error("the authority was silent for {waited_ms} ms after step {step} (stalled or dead)")]
    AuthoritySilent { step: u64, waited_ms: u64 },
    #[error("no authority sent the first step within {waited_s} s")]
    NoAuthority { waited_s: u64 },
    #[error(
        "V2X: nothing heard from participant(s) {ids} within {waited_s} s (not started, or their messages do not reach this one), so this one did not join"
    )]
    V2xUnheard { ids: String, waited_s: u64 },
    #[error("the scene failed: {reason}")]
    Failed { reason: String },
    #[error("transport: {0}")]
    Transport(String),
}

/// What a participant is in the scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The scenario's ego: perceives and drives.
    Ego,
    /// A traffic vehicle: perceives; moved by the scenario (or the recording). `traffic_index`
    /// is its index in the scenario's traffic, or among a recording's other obstacles: its id
    /// in the truth either way.
    Agent { traffic_index: usize },
    /// Roadside unit `index` along the route.
    Rsu { index: u32 },
}

impl Role {
    /// A vehicle's object id in the truth (the ego's [`EGO_OBJECT_ID`], a traffic vehicle its
    /// index); `None` for a roadside unit.
    pub fn object_id(self) -> Option<u32> {
        match self {
            Role::Ego => Some(EGO_OBJECT_ID),
            Role::Agent { traffic_index } => Some(traffic_index as u32),
            Role::Rsu { .. } => None,
        }
    }
}

/// What a scene plays.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSource {
    /// A generated scenario (`--spec`, `--db --id`, `--kind`), built into a `World`.
    Generated(ScenarioSpec),
    /// A CommonRoad recording (`--commonroad FILE [--ego ID]`), re-simulated.
    CommonRoad(Recording),
}

/// A scene: a scenario and which of its vehicles are connected, plus roadside units.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSetup {
    pub source: SceneSource,
    /// Connected vehicles: the ego and the first `connected − 1` traffic vehicles.
    pub connected: u32,
    pub rsus: u32,
    /// Traffic indices of the connected vehicles beside the ego (`v1`, `v2`, …).
    agents: Vec<usize>,
    /// Numbers k of the connected vehicles `vk` taken out of the world, ascending.
    without: Vec<u32>,
    /// V2X between the participants over this channel ([`v2x`]); `None`: no V2X.
    v2x: Option<MessageChannel>,
    /// With V2X: the RSUs warn the vehicles of the hazards they perceive (DENM-like).
    warnings: bool,
    /// With V2X: the RSUs send CPMs of what they perceive, which the vehicles fuse.
    cpm: bool,
    /// The ego's learned driver (`None`: the scenario's reference driver).
    ego_driver: Option<EgoDriver>,
}

/// A model file driving a scene's ego, known by its content's digest (part of the scene's
/// identity, so every participant drives the same bytes wherever its copy lies).
#[derive(Debug, Clone)]
pub struct EgoDriver {
    /// How messages name it (path and digest).
    pub label: String,
    /// SHA-256 of the model file, hex.
    pub sha256: String,
    pub model: DriverModel,
}

impl PartialEq for EgoDriver {
    fn eq(&self, other: &Self) -> bool {
        self.sha256 == other.sha256
    }
}

impl SceneSetup {
    /// A generated scenario's scene: `v1…` are its moving traffic vehicles in cast order.
    /// Checks that the scenario has the vehicles asked for.
    pub fn new(spec: ScenarioSpec, connected: u32, rsus: u32) -> Result<Self, SceneError> {
        let world = build(&spec);
        let moving: Vec<usize> =
            (0..world.traffic.len()).filter(|&i| world.traffic.is_active(i) && !world.traffic.is_parked(i)).collect();
        Self::assign(SceneSource::Generated(spec), connected, rsus, moving, ("scenario", "that move"))
    }

    /// A recording's scene: `v1…` are its recorded vehicles beside the ego in file order
    /// ([`Recording::vehicles`]). Checks that the recording has the vehicles asked for.
    pub fn commonroad(recording: Recording, connected: u32, rsus: u32) -> Result<Self, SceneError> {
        let vehicles = recording.vehicles();
        let source = SceneSource::CommonRoad(recording);
        Self::assign(source, connected, rsus, vehicles, ("recording", "vehicles beside its ego"))
    }

    /// The first `connected − 1` of `candidates` become `v1…`; `(what, which)` name them in
    /// the error when there are too few.
    fn assign(
        source: SceneSource,
        connected: u32,
        rsus: u32,
        candidates: Vec<usize>,
        (what, which): (&'static str, &'static str),
    ) -> Result<Self, SceneError> {
        if connected == 0 {
            return Err(SceneError::NoEgo);
        }
        if rsus > MAX_RSUS {
            return Err(SceneError::TooManyRsus { asked: rsus });
        }
        let needed = connected - 1;
        if candidates.len() < needed as usize {
            let available = candidates.len() as u32;
            return Err(SceneError::TooManyConnected { asked: connected, needed, available, what, which });
        }
        let agents = candidates[..needed as usize].to_vec();
        Ok(SceneSetup {
            source,
            connected,
            rsus,
            agents,
            without: Vec::new(),
            v2x: None,
            warnings: false,
            cpm: false,
            ego_driver: None,
        })
    }

    /// The same scene with connected traffic vehicles `ids` (`v1`, …) taken out of the world: a
    /// counterfactual (what the ego does when that vehicle is not there). Every other vehicle
    /// keeps its place, id and behaviour.
    pub fn without(mut self, ids: &[String]) -> Result<Self, SceneError> {
        for id in ids {
            match self.role_of(id) {
                // `role_of` accepted it, so it is `v<k>`.
                Ok(Role::Agent { .. }) => self.without.extend(id[1..].parse::<u32>().ok()),
                Ok(_) => return Err(SceneError::CannotWithdraw { id: id.clone() }),
                Err(SceneError::Withdrawn { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        self.without.sort_unstable();
        Ok(self)
    }

    /// The same scene with V2X between its participants over `channel` (`None`: none). The
    /// channel is part of the scene's identity ([`SceneSetup::digest`]): participants started
    /// with other V2X flags are refused at the join, by name.
    pub fn with_v2x(mut self, channel: Option<MessageChannel>) -> Self {
        self.v2x = channel;
        self
    }

    /// The scene's V2X channel, if it has V2X.
    pub fn v2x(&self) -> Option<&MessageChannel> {
        self.v2x.as_ref()
    }

    /// The same scene with its RSUs warning the vehicles over the V2X channel (with `on`, and
    /// V2X): part of the scene's identity, as the channel is.
    pub fn with_warnings(mut self, on: bool) -> Self {
        self.warnings = on;
        self
    }

    /// Whether the scene's RSUs warn its vehicles over V2X.
    pub fn warnings(&self) -> bool {
        self.warnings && self.v2x.is_some()
    }

    /// The same scene with its RSUs sending CPMs over the V2X channel (with `on`, and V2X): part
    /// of the scene's identity, as the channel is.
    pub fn with_cpm(mut self, on: bool) -> Self {
        self.cpm = on;
        self
    }

    /// The same scene with the ego driven by `driver` (`None`: the reference driver).
    pub fn with_ego_driver(mut self, driver: Option<EgoDriver>) -> Self {
        self.ego_driver = driver;
        self
    }

    /// The ego's learned driver, if it has one.
    pub fn ego_driver(&self) -> Option<&EgoDriver> {
        self.ego_driver.as_ref()
    }

    /// Whether the scene's RSUs send CPMs over V2X.
    pub fn cpm(&self) -> bool {
        self.cpm && self.v2x.is_some()
    }

    /// Whether the scene's RSUs send anything over V2X (warnings or CPMs).
    pub fn rsus_send(&self) -> bool {
        self.warnings() || self.cpm()
    }

    /// The generated scenario whose episode the ego reports to the cloud when the scene ends:
    /// `None` for a recording (not a library scenario) and for a counterfactual (its episode is
    /// not the scenario's).
    pub fn reported_spec(&self) -> Option<&ScenarioSpec> {
        match &self.source {
            SceneSource::Generated(spec) if self.without.is_empty() => Some(spec),
            _ => None,
        }
    }

    /// The scene's world at t = 0: the scenario's (or the recording at the ego's first state),
    /// less the vehicles taken out.
    pub fn world(&self) -> Result<SceneWorld<'_>, SceneError> {
        let taken_out = self.without.iter().map(|&k| self.agents[k as usize - 1]);
        match &self.source {
            SceneSource::Generated(spec) => {
                let mut world = build(spec);
                for i in taken_out {
                    world.withdraw_traffic(i);
                }
                Ok(SceneWorld::Generated(world))
            }
            SceneSource::CommonRoad(recording) => Ok(SceneWorld::Recorded(recording.stepper(taken_out)?)),
        }
    }

    /// The scene's identity: every participant must run the same one. Covers the wire schema,
    /// the role assignment and the scenario: a spec's kind, seed and exact parameters, or a
    /// recording's file bytes (their FNV-1a) and ego; and with V2X its channel
    /// ([`MessageChannel::digest`]; a scene without V2X keeps the digest it had before V2X).
    pub fn digest(&self) -> u64 {
        let head = [wire::SCHEMA_VERSION.to_le_bytes(), self.connected.to_le_bytes(), self.rsus.to_le_bytes()];
        let without = self.without.iter().flat_map(|k| k.to_le_bytes());
        let scenario: Vec<u8> = match &self.source {
            SceneSource::Generated(spec) => serde_json::to_vec(spec).expect("a spec serialises"),
            // A spec's JSON starts with `{`: the two never collide.
            SceneSource::CommonRoad(r) => {
                let ids = [r.file_digest.to_le_bytes(), r.ego_id.to_le_bytes()];
                b"commonroad\0".iter().copied().chain(ids.into_iter().flatten()).collect()
            }
        };
        // After the scenario's bytes: a spec's JSON ends with `}`, a recording's ids are fixed
        // length, so the tag cannot be read as part of either.
        let v2x = self.v2x.iter().flat_map(|c| b"\0v2x\0".iter().copied().chain(c.digest().to_le_bytes()));
        let warnings = if self.warnings() { &b"\0warn"[..] } else { &[][..] };
        let cpm = if self.cpm() { &b"\0cpm"[..] } else { &[][..] };
        let rsus = warnings.iter().chain(cpm).copied();
        // Last, so that a scene with the reference driver keeps the digest it always had.
        let driver = self.ego_driver.iter().flat_map(|d| b"\0driver\0".iter().chain(d.sha256.as_bytes()).copied());
        fnv1a64(head.iter().flatten().copied().chain(without).chain(scenario).chain(v2x).chain(rsus).chain(driver))
    }

    /// The physics step, s: the world's own, as in the library and `risktwin run`.
    pub fn step_s(&self) -> f64 {
        risktwin_common::world::STEP_S
    }

    /// The scenario's kind as the outcome names it (`cut_in`, or `commonroad`).
    pub fn kind_name(&self) -> &'static str {
        match &self.source {
            SceneSource::Generated(spec) => spec.kind.name(),
            SceneSource::CommonRoad(_) => "commonroad",
        }
    }

    /// The seed the onboard stacks' noise streams derive from: the scenario's, or
    /// [`RECORDING_SEED`] for a recording.
    pub fn seed(&self) -> u64 {
        match &self.source {
            SceneSource::Generated(spec) => spec.seed,
            SceneSource::CommonRoad(_) => RECORDING_SEED,
        }
    }

    /// What this scene is, for messages: `cut_in seed 3, 3 connected, 1 RSU, scene 9f…` or
    /// `CommonRoad USA_Lanker-1_3_T-1 (file 5c…) ego 30, 3 connected, …`.
    pub fn describe(&self) -> String {
        let scenario = match &self.source {
            SceneSource::Generated(spec) => format!("{} seed {}", spec.kind.name(), spec.seed),
            SceneSource::CommonRoad(r) => {
                format!("CommonRoad {} (file {:016x}) ego {}", r.benchmark_id(), r.file_digest, r.ego_id)
            }
        };
        let without: String = self.without.iter().map(|k| format!(" without v{k},")).collect();
        let rsus_send = [(self.warnings(), " + warnings"), (self.cpm(), " + CPM")];
        let rsus_send: String = rsus_send.iter().filter(|(on, _)| *on).map(|(_, what)| *what).collect();
        let v2x = self.v2x.map_or(String::new(), |c| format!(" {}{rsus_send},", c.describe()));
        let (connected, rsus, digest) = (self.connected, self.rsus, self.digest());
        format!("{scenario}, {connected} connected,{without} {rsus} RSU(s),{v2x} scene {digest:016x}")
    }

    /// Every participant id, vehicles first.
    pub fn participants(&self) -> Vec<String> {
        let vehicles = (0..self.connected).filter(|k| !self.without.contains(k)).map(|k| format!("v{k}"));
        vehicles.chain((0..self.rsus).map(|k| format!("rsu{k}"))).collect()
    }

    /// The role of participant `id`.
    pub fn role_of(&self, id: &str) -> Result<Role, SceneError> {
        let unknown = || SceneError::UnknownParticipant { id: id.to_owned(), known: self.participants().join(", ") };
        let number =
            |prefix: &str| id.strip_prefix(prefix).filter(|n| !n.starts_with('+')).and_then(|n| n.parse::<u32>().ok());
        if let Some(k) = number("rsu") {
            return if k < self.rsus && id == format!("rsu{k}") { Ok(Role::Rsu { index: k }) } else { Err(unknown()) };
        }
        match number("v") {
            Some(k) if id != format!("v{k}") => Err(unknown()),
            Some(0) => Ok(Role::Ego),
            Some(k) if self.without.contains(&k) => Err(SceneError::Withdrawn { id: id.to_owned() }),
            Some(k) if k < self.connected => Ok(Role::Agent { traffic_index: self.agents[k as usize - 1] }),
            _ => Err(unknown()),
        }
    }
}

impl fmt::Display for SceneSetup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::scenario::ScenarioKind;

    fn cut_in(connected: u32, rsus: u32) -> Result<SceneSetup, SceneError> {
        let spec = crate::scene::feasible_spec(3, ScenarioKind::CutIn).expect("a feasible cut-in");
        SceneSetup::new(spec, connected, rsus)
    }

    #[test]
    fn participants_and_roles_follow_the_scenario_cast() {
        let setup = cut_in(3, 1).expect("a cut-in has two moving cars");
        assert_eq!(setup.participants(), ["v0", "v1", "v2", "rsu0"]);
        assert_eq!(setup.role_of("v0"), Ok(Role::Ego));
        assert_eq!(setup.role_of("v1"), Ok(Role::Agent { traffic_index: 0 }), "the cutter");
        assert_eq!(setup.role_of("rsu0"), Ok(Role::Rsu { index: 0 }));
        for bad in ["v3", "rsu1", "v01", "v+1", "x", "", "rsu"] {
            assert!(matches!(setup.role_of(bad), Err(SceneError::UnknownParticipant { .. })), "{bad}");
        }
    }

    #[test]
    fn a_scene_is_refused_when_the_scenario_lacks_the_vehicles() {
        assert_eq!(cut_in(0, 0), Err(SceneError::NoEgo));
        assert!(matches!(cut_in(40, 0), Err(SceneError::TooManyConnected { asked: 40, .. })));
        assert!(matches!(cut_in(1, MAX_RSUS + 1), Err(SceneError::TooManyRsus { .. })));
    }

    #[test]
    fn the_digest_changes_with_the_seed_and_the_roles() {
        let a = cut_in(3, 1).expect("scene");
        assert_eq!(a.digest(), cut_in(3, 1).expect("scene").digest());
        assert_ne!(a.digest(), cut_in(2, 1).expect("scene").digest());
        assert_ne!(a.digest(), cut_in(3, 0).expect("scene").digest());
        let SceneSource::Generated(mut spec) = a.source.clone() else { unreachable!("a generated scene") };
        spec.seed += 1;
        assert_ne!(a.digest(), SceneSetup::new(spec, 3, 1).expect("scene").digest());
    }

    #[test]
    fn the_v2x_channel_is_part_of_the_scene_and_named_in_it() {
        use risktwin_v2x::channel::{LinkBudget, PathLoss};
        use risktwin_v2x::latency::Latency;
        use risktwin_v2x::link::V2xChannel;
        let plain = cut_in(3, 1).expect("scene");
        let channel = |latency| {
            let channel =
                V2xChannel { model: PathLoss::UrbanNlos, budget: LinkBudget::default(), latency, bursts: None };
            MessageChannel { channel, seed: plain.seed() }
        };
        let v2x = plain.clone().with_v2x(Some(channel(Latency::SIDELINK)));
        assert_eq!(plain.clone().with_v2x(None).digest(), plain.digest(), "no V2X, the digest of before");
        assert_ne!(v2x.digest(), plain.digest());
        let slower = plain.clone().with_v2x(Some(channel(Latency::Sidelink { t1_ms: 4.0, t2_ms: 50.0 })));
        assert_ne!(v2x.digest(), slower.digest(), "another latency, another scene");
        assert!(v2x.describe().contains(", V2X 3gpp-urban-nlos sidelink:4:100, scene "), "{v2x}");
        assert!(!plain.describe().contains("V2X"), "{plain}");
    }
}
