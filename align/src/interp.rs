//! Interpolation of continuous signals between two samples.
//!
//! Positions, speeds and other real-valued signals interpolate linearly. Angles do not: a
//! heading going from 179° to −179° crossed 2°, not 358°, so headings, yaws and steering angles
//! must use [`lerp_angle`], which takes the shorter way round and returns a value in (−π, π]
//! (wrapped by [`risktwin_common::geometry::wrap_angle`], the one angle wrap of the crate).
//! A pose type implements [`Interpolate`] with `lerp` for x and y and `lerp_angle` for the
//! heading (the `TestPose` of this module's tests shows the pattern).

use risktwin_common::geometry::wrap_angle;

/// A value that can be interpolated between two samples of a continuous signal.
pub trait Interpolate: Sized {
    /// The value a fraction `frac` ∈ [0, 1] of the way from `a` to `b`.
    fn lerp(a: &Self, b: &Self, frac: f64) -> Self;
}

impl Interpolate for f64 {
    fn lerp(a: &f64, b: &f64, frac: f64) -> f64 {
        a + (b - a) * frac
    }
}

impl Interpolate for f32 {
    fn lerp(a: &f32, b: &f32, frac: f64) -> f32 {
        a + (b - a) * frac as f32
    }
}

/// Interpolates between two angles the shorter way round; the result lies in (−π, π].
pub fn lerp_angle(a_rad: f64, b_rad: f64, frac: f64) -> f64 {
    let diff = wrap_angle(b_rad - a_rad);
    wrap_angle(a_rad + diff * frac)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// A planar pose: the pattern for any state with a heading.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct TestPose {
        pub x_m: f64,
        pub y_m: f64,
        pub heading_rad: f64,
    }

    impl Interpolate for TestPose {
        fn lerp(a: &Self, b: &Self, frac: f64) -> Self {
            Self {
                x_m: f64::lerp(&a.x_m, &b.x_m, frac),
                y_m: f64::lerp(&a.y_m, &b.y_m, frac),
                heading_rad: lerp_angle(a.heading_rad, b.heading_rad, frac),
            }
        }
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn linear_values() {
        assert_eq!(f64::lerp(&2.0, &4.0, 0.25), 2.5);
        assert_eq!(f64::lerp(&2.0, &4.0, 0.0), 2.0);
        assert_eq!(f64::lerp(&2.0, &4.0, 1.0), 4.0);
        assert_eq!(f32::lerp(&-1.0, &1.0, 0.5), 0.0);
    }

    #[test]
    fn angles_take_the_short_way_across_pi() {
        let a = 179f64.to_radians();
        let b = (-179f64).to_radians();
        let mid = lerp_angle(a, b, 0.5);
        assert!(close(mid.abs(), PI), "midpoint {mid} should be ±π, not 0");
        assert!(close(lerp_angle(a, b, 0.25), 179.5f64.to_radians()));
        assert!(close(lerp_angle(a, b, 0.75), (-179.5f64).to_radians()));
        assert!(close(lerp_angle(0.1, 0.3, 0.5), 0.2));
        assert!(close(lerp_angle(-0.1, 0.1, 0.5), 0.0));
    }

    #[test]
    fn pose_interpolates_position_linearly_and_heading_on_the_circle() {
        let a = TestPose { x_m: 0.0, y_m: 10.0, heading_rad: 3.0 };
        let b = TestPose { x_m: 4.0, y_m: 6.0, heading_rad: -3.0 };
        let p = TestPose::lerp(&a, &b, 0.25);
        assert_eq!((p.x_m, p.y_m), (1.0, 9.0));
        // 3.0 → −3.0 the short way is +0.283 rad across π.
        let step = TAU - 6.0;
        assert!(close(p.heading_rad, 3.0 + 0.25 * step));
    }
}
