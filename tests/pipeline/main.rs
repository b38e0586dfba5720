//! The edge–cloud pipeline as separate processes: a real router on a free port, vehicles and a
//! roadside unit, and a cloud ingest worker, all `risktwin` processes. Every message sent must
//! be accounted for at the cloud (reliable mode: received = sent, no drops).
//!
//! Readiness is waited on, never slept for: the router's `listening on` line, the cloud's
//! `ready` line, edges waiting for a matching subscriber before publishing, the cloud's
//! `edge left` lines (liveliness) before it is sent SIGTERM.

mod cloudloop;
mod crash;
mod criticality;
mod delivery;
mod faults;
mod fleet;
mod fleetloop;
mod overload;
#[path = "../interop/peer_cache.rs"]
mod peer_cache;
#[path = "../interop/peer_node.rs"]
mod peer_node;
#[path = "../interop/peer_python.rs"]
mod peer_python;
mod policyloop;
mod prometheus;
mod pushrace;
mod python_zenoh;
mod rotation;
mod scene;
mod scene_v2x;
mod shard;
mod shm_gateway;
mod signed_policy;
mod support;
mod tls;
mod v2x_agreement;
mod viz;
