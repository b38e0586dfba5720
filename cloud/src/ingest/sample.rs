//! What the aligner holds per source and stream: the decoded content the twin needs.

use risktwin_align::{Interpolate, lerp_angle};
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::telemetry::{DetectedObject, Phase, VehicleStateSample};
use std::sync::Arc;

/// A vehicle's kinematics as observed on its `state` stream (and interpolated between its
/// samples by the aligner): what the twin knows of a remote vehicle, as opposed to the
/// simulator's own state arrays or the risk field's `EgoKinematics` input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObservedKinematics {
    pub pose: Pose,
    pub velocity: Vec2,
    pub speed_mps: f64,
    pub accel_mps2: f64,
    pub footprint: Footprint,
    /// The header seqs of the state samples it comes from: `(n, n)` for one sample, `(a, b)`
    /// when interpolated between samples `a` and `b` (how the cloud finds an edge's episode
    /// among its ticks).
    pub seqs: (u64, u64),
}

impl From<&VehicleStateSample> for ObservedKinematics {
    fn from(s: &VehicleStateSample) -> Self {
        ObservedKinematics {
            pose: s.pose,
            velocity: s.velocity,
            speed_mps: s.speed_mps,
            accel_mps2: s.accel_mps2,
            footprint: s.footprint,
            seqs: (s.header.seq, s.header.seq),
        }
    }
}

impl Interpolate for ObservedKinematics {
    /// Linear, heading the short way round; the later sample's footprint.
    fn lerp(x: &Self, y: &Self, t: f64) -> Self {
        ObservedKinematics {
            pose: Pose::new(
                lerp(x.pose.x_m, y.pose.x_m, t),
                lerp(x.pose.y_m, y.pose.y_m, t),
                lerp_angle(x.pose.heading_rad, y.pose.heading_rad, t),
            ),
            velocity: x.velocity + (y.velocity - x.velocity) * t,
            speed_mps: lerp(x.speed_mps, y.speed_mps, t),
            accel_mps2: lerp(x.accel_mps2, y.accel_mps2, t),
            footprint: y.footprint,
            seqs: (x.seqs.0, y.seqs.1),
        }
    }
}

/// One aligned value.
#[derive(Debug, Clone, PartialEq)]
pub enum TwinSample {
    State(ObservedKinematics),
    /// Decoded CAN signals by frame id: (can_id, raw payload).
    Can {
        can_id: u32,
        data: [u8; 8],
    },
    /// Objects seen by a vehicle or an RSU (shared: snapshots copy them often).
    Objects(Arc<[DetectedObject]>),
    Signal {
        signal_id: u32,
        phase: Phase,
    },
}

pub(crate) fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

impl Interpolate for TwinSample {
    /// States interpolate (heading the short way round); every other stream is as-of and never
    /// interpolated — the nearer sample is kept should the aligner ask.
    fn lerp(a: &Self, b: &Self, t: f64) -> Self {
        match (a, b) {
            (TwinSample::State(x), TwinSample::State(y)) => TwinSample::State(Interpolate::lerp(x, y, t)),
            _ => {
                if t < 0.5 {
                    a.clone()
                } else {
                    b.clone()
                }
            }
        }
    }
}
