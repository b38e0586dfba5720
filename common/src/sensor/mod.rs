//! The ego sensor model: range, field of view, occlusion by footprints, noise and dropout.
//!
//! [`Sensor::perceive`] turns the true scene ([`SceneObject`]s) into the object list the ego
//! driver actually sees ([`PerceivedObject`]s). It models a front radar/camera fusion as an
//! object-level sensor: no raw detections, one track per visible object.
//!
//! Visibility is sampled at five points of each footprint (its four corners and its centre). A
//! point is visible when it lies within `range_m` of the sensor origin, within the field of view,
//! and — with occlusion on — no other footprint cuts the line of sight to it (a `parry2d` ray
//! cast, after a bounding-circle broad phase). The visible fraction is the share of the five
//! points that are visible; an object is detected when that share is positive and at least
//! `min_visible_fraction`, and it then survives the frame's dropout draw.
//!
//! The sensor origin is the ego pose's reference point (the footprint centre) moved
//! `mount_forward_m` along the heading: with the default it sits at the front bumper of a 4.5 m
//! car. Any footprint that contains the origin (the ego itself, if the caller lists it) never
//! occludes: the sensor looks out of it.
//!
//! Determinism and cost: all randomness comes from the `Rng` passed in, drawn in input order
//! (per visible object one dropout draw, then four normals if it is kept), so a seed fixes the
//! output. The output vector and the per-frame occluder caches are cleared and refilled, never
//! reallocated once they have grown to the scene's size, so a steady simulation does not
//! allocate here.

mod occlusion;
#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};

use crate::geometry::{Obb, Pose, Vec2};
use crate::rng::Rng;
use occlusion::{Blockers, obb_is_valid};

/// Number of footprint points sampled for visibility: four corners and the centre.
const SAMPLES: usize = 5;

/// What a scene object is (its dynamics differ; the sensor treats all alike).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ObjectKind {
    /// A moving road vehicle.
    Vehicle,
    /// A pedestrian.
    Pedestrian,
    /// A parked (static) vehicle; a typical occluder.
    Parked,
}

/// The true state of one object around the ego, in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneObject {
    /// Stable identity of the object across frames.
    pub id: u32,
    /// True footprint.
    pub obb: Obb,
    /// True velocity in the world frame, m/s.
    pub velocity: Vec2,
    /// What the object is.
    pub kind: ObjectKind,
}

/// One object as the ego's sensor reports it, in the world frame (and as a V2X warning carries
/// it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PerceivedObject {
    /// Identity of the true object (perfect association).
    pub id: u32,
    /// What the object is (perfect classification).
    pub kind: ObjectKind,
    /// Footprint with a noisy centre; size and heading are the true ones.
    pub obb: Obb,
    /// Noisy velocity in the world frame, m/s.
    pub velocity: Vec2,
    /// Share of the sampled footprint points that were visible, in (0, 1].
    pub visible_fraction: f64,
}

/// Configuration of the sensor model.
///
/// Defaults describe a front radar/camera fusion: 150 m range and a 120° field of view are the
/// order of a long-range automotive radar fused with a front camera; 0.3 m / 0.3 m/s noise and
/// 2 % dropout are the order of fused-track errors at mid range.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SensorParams {
    /// Maximum detection distance from the sensor origin, m.
    pub range_m: f64,
    /// Full horizontal field of view, centred on the ego heading, rad (2π sees all around).
    pub fov_rad: f64,
    /// Standard deviation of the Gaussian noise on each coordinate of the centre, m.
    pub position_noise_std_m: f64,
    /// Standard deviation of the Gaussian noise on each velocity component, m/s.
    pub velocity_noise_std_mps: f64,
    /// Probability that a visible object is lost in a frame.
    pub dropout_rate: f64,
    /// Whether other footprints block the line of sight.
    pub occlusion: bool,
    /// Least share of visible sample points for a detection, in [0, 1].
    pub min_visible_fraction: f64,
    /// Distance from the ego reference point (footprint centre) forward to the sensor, m.
    pub mount_forward_m: f64,
}

impl Default for SensorParams {
    fn default() -> Self {
        Self {
            range_m: 150.0,
            fov_rad: 120f64.to_radians(),
            position_noise_std_m: 0.3,
            velocity_noise_std_mps: 0.3,
            dropout_rate: 0.02,
            occlusion: true,
            // One of the five sample points: "some of it" is seen.
            min_visible_fraction: 0.2,
            mount_forward_m: 2.25,
        }
    }
}

/// A sensor configuration value outside its valid range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SensorError {
    /// A parameter is non-finite or outside `[min, max]`.
    #[error("sensor parameter {name} = {value} is outside [{min}, {max}]")]
    ParamOutOfRange { name: &'static str, value: f64, min: f64, max: f64 },
}

impl SensorParams {
    /// Checks every parameter; the first offending one is reported.
    pub fn validate(&self) -> Result<(), SensorError> {
        let checks = [
            ("range_m", self.range_m, f64::MIN_POSITIVE, f64::MAX),
            ("fov_rad", self.fov_rad, f64::MIN_POSITIVE, std::f64::consts::TAU),
            ("position_noise_std_m", self.position_noise_std_m, 0.0, f64::MAX),
            ("velocity_noise_std_mps", self.velocity_noise_std_mps, 0.0, f64::MAX),
            ("dropout_rate", self.dropout_rate, 0.0, 1.0),
            ("min_visible_fraction", self.min_visible_fraction, 0.0, 1.0),
            ("mount_forward_m", self.mount_forward_m, f64::MIN, f64::MAX),
        ];
        for (name, value, min, max) in checks {
            // `contains` is false for NaN, and ±inf lies outside the finite bounds.
            if !(min..=max).contains(&value) {
                return Err(SensorError::ParamOutOfRange { name, value, min, max });
            }
        }
        Ok(())
    }
}

/// The ego's sensor: validated parameters plus per-frame scratch space reused across calls.
#[derive(Debug, Clone)]
pub struct Sensor {
    params: SensorParams,
    /// Cosine of half the field of view: a direction is inside when its cosine to the heading
    /// is at least this (no `atan2` per point).
    cos_half_fov: f64,
    blockers: Blockers,
}

impl Sensor {
    /// A sensor with the given parameters, rejected when any is out of range.
    pub fn new(params: SensorParams) -> Result<Self, SensorError> {
        params.validate()?;
        // A full circle sees straight back too, where rounding could put the cosine below −1.
        let cos_half_fov =
            if params.fov_rad >= std::f64::consts::TAU { f64::NEG_INFINITY } else { (0.5 * params.fov_rad).cos() };
        Ok(Self { params, cos_half_fov, blockers: Blockers::default() })
    }

    /// The sensor's parameters.
    pub fn params(&self) -> &SensorParams {
        &self.params
    }

    /// Where the sensor sits for an ego at `ego`, in the world frame.
    pub fn origin(&self, ego: Pose) -> Vec2 {
        ego.position() + ego.forward() * self.params.mount_forward_m
    }

    /// Clears `out` and fills it with the objects the sensor reports this frame, in input order.
    ///
    /// A non-finite ego pose yields an empty list; objects with non-finite or negative geometry
    /// or non-finite velocity are skipped (a valid footprint with a bad velocity still occludes).
    pub fn perceive(&mut self, ego: Pose, objects: &[SceneObject], rng: &mut Rng, out: &mut Vec<PerceivedObject>) {
        out.clear();
        if !(ego.x_m.is_finite() && ego.y_m.is_finite() && ego.heading_rad.is_finite()) {
            return;
        }
        let p = self.params;
        let origin = self.origin(ego);
        let forward = ego.forward();
        if p.occlusion {
            self.blockers.rebuild(objects.iter().map(|o| &o.obb), origin, p.range_m);
        }
        for (index, object) in objects.iter().enumerate() {
            if !obb_is_valid(&object.obb) || !object.velocity.iter().all(|v| v.is_finite()) {
                continue;
            }
            let radius_m = object.obb.half_length_m.hypot(object.obb.half_width_m);
            if (object.obb.centre - origin).norm() - radius_m > p.range_m {
                continue;
            }
            // Callers build boxes with `Obb::new` (unit axis); a drifted axis must not scale them.
            let mut obb = object.obb;
            obb.axis = obb.axis.normalize();
            if p.occlusion {
                self.blockers.select(origin, obb.centre, radius_m, index);
            }
            let visible_fraction = self.visible_fraction(origin, forward, &obb);
            if visible_fraction <= 0.0 || visible_fraction < p.min_visible_fraction {
                continue;
            }
            if rng.chance(p.dropout_rate) {
                continue;
            }
            let noise_pos = Vec2::new(rng.normal(), rng.normal()) * p.position_noise_std_m;
            let noise_vel = Vec2::new(rng.normal(), rng.normal()) * p.velocity_noise_std_mps;
            obb.centre += noise_pos;
            out.push(PerceivedObject {
                id: object.id,
                kind: object.kind,
                obb,
                velocity: object.velocity + noise_vel,
                visible_fraction,
            });
        }
    }

    /// Share of the footprint's sample points inside range and field of view and, with
    /// occlusion on, in line of sight.
    fn visible_fraction(&self, origin: Vec2, forward: Vec2, obb: &Obb) -> f64 {
        let c = obb.corners();
        let samples: [Vec2; SAMPLES] = [c[0], c[1], c[2], c[3], obb.centre];
        let range_sq = self.params.range_m * self.params.range_m;
        let visible = samples
            .iter()
            .filter(|&&point| {
                let d = point - origin;
                let dist_sq = d.norm_squared();
                dist_sq <= range_sq
                    && d.dot(&forward) >= self.cos_half_fov * dist_sq.sqrt()
                    && !(self.params.occlusion && self.blockers.is_blocked(origin, point))
            })
            .count();
        visible as f64 / SAMPLES as f64
    }
}
