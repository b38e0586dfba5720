//! Per-vehicle arrays precomputed once per scenario (structure of arrays, indexed by
//! `time_step − first_step`), so the pairwise loop only reads numbers: arc length and heading on
//! the reference path, along-path speed and acceleration, body for distances, and the expanded
//! lanelet set of the "same lanelet" test as a bitset.

use super::path::ReferencePath;
use crate::model::{DynamicObstacle, Shape};
use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2};
use risktwin_common::road::lanelet::LaneletNetwork;

/// What a vehicle occupies at one step, for the footprint tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body {
    Box(Obb),
    Disc { centre: Vec2, radius_m: f64 },
}

impl Body {
    /// A shape at a pose; a polygon is approximated by its bounding box in the obstacle frame.
    pub fn new(shape: &Shape, position: Vec2, heading_rad: f64) -> Self {
        let pose = Pose::new(position.x, position.y, heading_rad);
        match shape {
            Shape::Rectangle { length_m, width_m } => Body::Box(Obb::new(pose, Footprint::new(*length_m, *width_m))),
            Shape::Circle { radius_m } => Body::Disc { centre: position, radius_m: *radius_m },
            Shape::Polygon { vertices } => {
                let (lo, hi) = vertices
                    .iter()
                    .fold((Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY)), |(lo, hi), v| {
                        (lo.inf(v), hi.sup(v))
                    });
                let mut obb = Obb::new(pose, Footprint::new(hi.x - lo.x, hi.y - lo.y));
                let mid = 0.5 * (lo + hi);
                obb.centre += obb.axis * mid.x + Vec2::new(-obb.axis.y, obb.axis.x) * mid.y;
                Body::Box(obb)
            }
        }
    }

    /// Euclidean distance between the two outlines (0 when they overlap).
    pub fn distance_to(&self, other: &Body) -> f64 {
        match (self, other) {
            (Body::Box(a), Body::Box(b)) => a.distance_to(b),
            (Body::Box(a), Body::Disc { centre, radius_m }) | (Body::Disc { centre, radius_m }, Body::Box(a)) => {
                (a.distance_to_point(*centre) - radius_m).max(0.0)
            }
            (Body::Disc { centre: c1, radius_m: r1 }, Body::Disc { centre: c2, radius_m: r2 }) => {
                ((c1 - c2).norm() - r1 - r2).max(0.0)
            }
        }
    }

    /// Convex outline for the lanelet test: the box corners, or a 16-gon around the disc.
    pub fn outline(&self) -> ([Vec2; 16], usize) {
        let mut out = [Vec2::zeros(); 16];
        match self {
            Body::Box(b) => {
                out[..4].copy_from_slice(&b.corners());
                (out, 4)
            }
            Body::Disc { centre, radius_m } => {
                for (k, p) in out.iter_mut().enumerate() {
                    let a = std::f64::consts::TAU * k as f64 / 16.0;
                    *p = centre + *radius_m * Vec2::new(a.cos(), a.sin());
                }
                (out, 16)
            }
        }
    }

    /// Radius of a circle around the centre that holds the body (broad phase).
    pub fn bound_radius_m(&self) -> f64 {
        match self {
            Body::Box(b) => b.half_length_m.hypot(b.half_width_m),
            Body::Disc { radius_m, .. } => *radius_m,
        }
    }

    pub fn centre(&self) -> Vec2 {
        match self {
            Body::Box(b) => b.centre,
            Body::Disc { centre, .. } => *centre,
        }
    }
}

/// One vehicle's precomputed arrays.
#[derive(Debug, Clone)]
pub struct Track {
    pub id: u64,
    pub first_step: i64,
    /// Half of the length along the heading: ℓ/2, or r for a circle (CriMe's THW add-on).
    pub half_length_m: f64,
    /// Arc length of the centre on the reference path; NaN outside its domain.
    pub s_m: Vec<f64>,
    /// Speed along the path tangent, m/s (signed: + in the path direction).
    pub speed_along_mps: Vec<f64>,
    /// Acceleration along the path tangent, m/s².
    pub accel_along_mps2: Vec<f64>,
    /// Longitudinal acceleration (d/dt of the recorded speed), m/s².
    pub accel_mps2: Vec<f64>,
    pub body: Vec<Body>,
    /// True when the centre lies in some lanelet (CriMe needs it for TTC and a_long,req).
    pub in_lanelet: Vec<bool>,
    /// Expanded lanelet sets (§3) as bitsets, `words` u64 per step.
    pub lanelet_bits: Vec<u64>,
    pub words: usize,
}

impl Track {
    /// Number of steps with a state.
    pub fn len(&self) -> usize {
        self.s_m.len()
    }

    /// True when the track has no state.
    pub fn is_empty(&self) -> bool {
        self.s_m.is_empty()
    }

    /// Index of `time_step` in the arrays, if the vehicle has a state then.
    pub fn index(&self, time_step: i64) -> Option<usize> {
        let k = usize::try_from(time_step.checked_sub(self.first_step)?).ok()?;
        (k < self.len()).then_some(k)
    }

    /// True when the expanded lanelet sets of `self` at `i` and `other` at `j` share a lanelet.
    pub fn shares_lanelet(&self, i: usize, other: &Track, j: usize) -> bool {
        let a = &self.lanelet_bits[i * self.words..(i + 1) * self.words];
        let b = &other.lanelet_bits[j * other.words..(j + 1) * other.words];
        a.iter().zip(b).any(|(x, y)| x & y != 0)
    }

    /// Precomputes the arrays of `obstacle` against `path` and `network`.
    pub fn new(obstacle: &DynamicObstacle, path: &ReferencePath, network: &LaneletNetwork, dt_s: f64) -> Self {
        let n = obstacle.trajectory.len() + 1;
        let words = network.len().div_ceil(64).max(1);
        let speeds: Vec<f64> = obstacle.states().map(|s| s.velocity_mps.unwrap_or(f64::NAN)).collect();
        let accel_mps2 = speed_gradient(&speeds, dt_s, obstacle.initial_state.acceleration_mps2);
        let mut t = Track {
            id: obstacle.id,
            first_step: obstacle.first_time_step(),
            half_length_m: obstacle.shape.half_length_m(),
            s_m: Vec::with_capacity(n),
            speed_along_mps: Vec::with_capacity(n),
            accel_along_mps2: Vec::with_capacity(n),
            accel_mps2,
            body: Vec::with_capacity(n),
            in_lanelet: Vec::with_capacity(n),
            lanelet_bits: vec![0; n * words],
            words,
        };
        for (k, st) in obstacle.states().enumerate() {
            let body = Body::new(&obstacle.shape, st.position, st.orientation_rad);
            let (s, psi) = path.project(st.position).map_or((f64::NAN, f64::NAN), |p| (p.s_m, p.heading_rad));
            // Speed and acceleration are along the heading; their lane components use the
            // angle between heading and path. Where the path does not reach, use the heading
            // itself (only TTC/a_long,req read these, and they are inf/0 there).
            let c = if psi.is_nan() { 1.0 } else { (st.orientation_rad - psi).cos() };
            t.s_m.push(s);
            t.speed_along_mps.push(speeds[k] * c);
            t.accel_along_mps2.push(t.accel_mps2[k] * c);
            t.in_lanelet.push(network.containing(st.position).next().is_some());
            let (outline, m) = body.outline();
            let bits = &mut t.lanelet_bits[k * words..(k + 1) * words];
            for (li, l) in network.lanelets.iter().enumerate() {
                if !l.intersects_convex(&outline[..m]) {
                    continue;
                }
                set_bit(bits, li);
                for id in l.predecessors.iter().chain(&l.successors) {
                    if let Some(j) = network.index_of(*id) {
                        set_bit(bits, j);
                    }
                }
            }
            t.body.push(body);
        }
        t
    }
}

fn set_bit(bits: &mut [u64], i: usize) {
    bits[i / 64] |= 1 << (i % 64);
}

/// d/dt of the speed samples, as numpy.gradient with uniform spacing: central differences inside,
/// one-sided at the ends (CriMe's preprocessing, criticality.md §1). A single state falls back to
/// its recorded acceleration (NaN when absent).
pub fn speed_gradient(v: &[f64], dt_s: f64, single: Option<f64>) -> Vec<f64> {
    let n = v.len();
    match n {
        0 => Vec::new(),
        1 => vec![single.unwrap_or(f64::NAN)],
        _ => (0..n)
            .map(|i| match i {
                0 => (v[1] - v[0]) / dt_s,
                i if i == n - 1 => (v[n - 1] - v[n - 2]) / dt_s,
                i => (v[i + 1] - v[i - 1]) / (2.0 * dt_s),
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_matches_numpy() {
        // numpy.gradient([0, 1, 4, 9], 0.5) = [2, 4, 8, 10].
        assert_eq!(speed_gradient(&[0.0, 1.0, 4.0, 9.0], 0.5, None), vec![2.0, 4.0, 8.0, 10.0]);
        assert_eq!(speed_gradient(&[3.0], 0.1, Some(-1.0)), vec![-1.0]);
    }

    #[test]
    fn body_distances() {
        let a = Body::new(&Shape::Rectangle { length_m: 4.0, width_m: 2.0 }, Vec2::new(0.0, 0.0), 0.0);
        let b = Body::new(&Shape::Rectangle { length_m: 4.0, width_m: 2.0 }, Vec2::new(10.0, 0.0), 0.0);
        let c = Body::new(&Shape::Circle { radius_m: 0.5 }, Vec2::new(0.0, 3.5), 0.0);
        assert!((a.distance_to(&b) - 6.0).abs() < 1e-12);
        assert!((a.distance_to(&c) - 2.0).abs() < 1e-12);
        assert!((c.distance_to(&a) - 2.0).abs() < 1e-12);
    }
}
