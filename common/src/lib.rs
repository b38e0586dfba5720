//! RiskTwin's domain core: pure, deterministic and free of I/O.
//!
//! Everything here takes its time step and its random numbers as arguments (no wall clock, no
//! global RNG, no files except through `Read`/`Write`), so an episode replays to the same bytes
//! given the same seed, whether it runs embedded or behind the edge–cloud pipeline.
//!
//! Map of the crate:
//! - [`geometry`], [`rng`], [`digest`], [`histogram`]: primitives (vectors, poses, boxes; the
//!   seeded generator; FNV-1a; a lock-free latency histogram).
//! - [`road`]: lanes, Frenet frames, road edges, crosswalks, friction, and lanelet maps.
//! - [`vehicle`]: ego dynamics (kinematic and dynamic single-track) and actuators.
//! - [`traffic`]: IDM/MOBIL traffic, scripted manoeuvres, pedestrians, parked cars (SoA).
//! - [`sensor`]: what the ego perceives (range, field of view, occlusion, noise, dropout).
//! - [`risk`]: the driving risk field, criticality measures and the scenario risk score.
//! - [`scenario`]: the five kinds, sampling, feasibility, mutation, building a world.
//! - [`world`], [`driver`], [`episode`], [`metrics`]: one episode, its reference driver, its metrics.
//! - [`planner`]: a privileged planner that tells whether a scenario has a clean drive (the achievable floor).
//! - [`env`]: the driving environment for reinforcement learning (observation, action, reward, VecEnv).
//! - [`telemetry`]: the domain types of every message (states, object lists, CAN frames, pushes).
//! - [`delivery`]: the cloud's acknowledgements of an edge's streams and the edge's ledger of them.
//!
//! Beside it, each in a crate of its own: time alignment (`risktwin-align`), V2X
//! (`risktwin-v2x`), CommonRoad (`risktwin-commonroad`) and policies on the host
//! (`risktwin-policy`).

pub mod delivery;
pub mod digest;
pub mod driver;
pub mod env;
pub mod episode;
pub mod geometry;
pub mod histogram;
pub mod metrics;
pub mod planner;
pub mod risk;
pub mod rng;
pub mod road;
pub mod scenario;
pub mod sensor;
pub mod telemetry;
pub mod traffic;
pub mod vehicle;
pub mod world;
