//! RiskTwin's domain core: pure, deterministic and free of I/O.
//!
//! Everything here takes its time step and its random numbers as arguments (no wall clock, no
//! global RNG, no files except through `Read`/`Write`), so an episode replays to the same bytes
//! given the same seed, whether it runs embedded or behind the edge–cloud pipeline.
//!
//! Map of the crate:
//! - [`geometry`], [`rng`]: primitives.
//! - [`road`]: lanes, Frenet frames, road edges, crosswalks, friction.
//! - [`vehicle`]: ego dynamics (kinematic and dynamic single-track) and actuators.
//! - [`traffic`]: IDM/MOBIL traffic, scripted manoeuvres, pedestrians, parked cars (SoA).
//! - [`sensor`]: what the ego perceives (range, field of view, occlusion, noise, dropout).
//! - [`risk`]: the driving risk field, criticality measures and the scenario risk score.
//! - [`commonroad`]: CommonRoad XML import and criticality measures on recorded traffic.
//! - [`scenario`]: the five kinds, sampling, feasibility, building a world.
//! - [`world`], [`driver`], [`episode`], [`metrics`]: one episode, its reference driver, its metrics.
//! - [`planner`]: a privileged planner that tells whether a scenario has a clean drive (the achievable floor).
//! - [`env`]: the driving environment for reinforcement learning (observation, action, reward, VecEnv).
//! - [`net`]: trained policies on the host (no tensor library): policy files, MLP, driver.

pub mod align;
pub mod commonroad;
pub mod delivery;
pub mod digest;
pub mod driver;
pub mod env;
pub mod episode;
pub mod geometry;
pub mod histogram;
pub mod metrics;
pub mod net;
pub mod planner;
pub mod policy_signature;
pub mod risk;
pub mod rng;
pub mod road;
pub mod scenario;
pub mod sensor;
pub mod telemetry;
pub mod traffic;
pub mod v2x;
pub mod vehicle;
pub mod world;
