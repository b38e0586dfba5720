//! Fixed-time traffic signals: a cycle of green, amber and red with an offset, the simplest
//! controller (and what most junction simulations start from).

use crate::telemetry::Phase;

/// A fixed-time signal; times in seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedTimeSignal {
    pub green_s: f64,
    pub amber_s: f64,
    pub red_s: f64,
    /// Time into the cycle at t = 0.
    pub offset_s: f64,
}

impl Default for FixedTimeSignal {
    /// A 60 s urban cycle: 27 s green, 3 s amber (the usual 3 s for 50 km/h), 30 s red.
    fn default() -> Self {
        Self { green_s: 27.0, amber_s: 3.0, red_s: 30.0, offset_s: 0.0 }
    }
}

impl FixedTimeSignal {
    pub fn cycle_s(&self) -> f64 {
        self.green_s + self.amber_s + self.red_s
    }

    /// The phase at `time_s` and the time until it changes.
    pub fn phase_at(&self, time_s: f64) -> (Phase, f64) {
        let cycle = self.cycle_s();
        if cycle.is_nan() || cycle <= 0.0 || !time_s.is_finite() {
            return (Phase::Red, 0.0);
        }
        let t = (time_s + self.offset_s).rem_euclid(cycle);
        if t < self.green_s {
            (Phase::Green, self.green_s - t)
        } else if t < self.green_s + self.amber_s {
            (Phase::Amber, self.green_s + self.amber_s - t)
        } else {
            (Phase::Red, cycle - t)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phases_follow_the_cycle() {
        let s = FixedTimeSignal::default();
        assert_eq!(s.phase_at(0.0), (Phase::Green, 27.0));
        assert_eq!(s.phase_at(28.0).0, Phase::Amber);
        let (p, left) = s.phase_at(40.0);
        assert_eq!(p, Phase::Red);
        assert!((left - 20.0).abs() < 1e-9);
        assert_eq!(s.phase_at(61.0).0, Phase::Green, "the cycle repeats");
        assert_eq!(FixedTimeSignal { offset_s: 28.0, ..s }.phase_at(0.0).0, Phase::Amber);
    }
}
