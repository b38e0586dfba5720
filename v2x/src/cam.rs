//! When a vehicle sends a Cooperative Awareness Message: the generation rules of ETSI EN 302
//! 637-2 (V1.4.1, §6.1.3), checked every `T_CheckCamGen` (the caller's step, at most
//! [`T_GEN_CAM_MIN_S`]); congestion control (DCC) left at its minimum interval.
//!
//! 1. Dynamics: at least [`T_GEN_CAM_MIN_S`] since the last CAM and, since then, the heading
//!    changed by more than 4°, the position by more than 4 m or the speed by more than 0.5 m/s.
//!    `T_GenCam` becomes the time since the last CAM.
//! 2. Time: `T_GenCam` since the last CAM (at first [`T_GEN_CAM_MAX_S`]). After [`N_GEN_CAM`]
//!    CAMs in a row by this rule, `T_GenCam` returns to [`T_GEN_CAM_MAX_S`].

/// The shortest interval between CAMs (10 Hz).
pub const T_GEN_CAM_MIN_S: f64 = 0.1;
/// The longest interval between CAMs (1 Hz).
pub const T_GEN_CAM_MAX_S: f64 = 1.0;
/// CAMs by the time rule after which `T_GenCam` returns to its maximum.
pub const N_GEN_CAM: u32 = 3;
/// The dynamics thresholds; a CPM's object inclusion uses the same ones (`super::cpm`).
pub(super) const HEADING_CHANGE_RAD: f64 = 4.0 * std::f64::consts::PI / 180.0;
pub(super) const POSITION_CHANGE_M: f64 = 4.0;
pub(super) const SPEED_CHANGE_MPS: f64 = 0.5;
/// Slack on time comparisons: a step of 0.05 s summed twice is not quite 0.1 s.
pub(super) const TIME_SLACK_S: f64 = 1e-9;

/// A vehicle's state as a CAM carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamState {
    pub time_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub heading_rad: f64,
    pub speed_mps: f64,
}

/// Why a CAM went out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CamCause {
    First,
    Dynamics,
    Time,
}

/// One vehicle's CAM generation.
#[derive(Debug, Clone)]
pub struct CamTrigger {
    last: Option<CamState>,
    t_gen_cam_s: f64,
    by_time_in_a_row: u32,
}

impl Default for CamTrigger {
    fn default() -> Self {
        CamTrigger { last: None, t_gen_cam_s: T_GEN_CAM_MAX_S, by_time_in_a_row: 0 }
    }
}

impl CamTrigger {
    /// Whether a CAM goes out at `now` (and why); if so, it is recorded as the last one.
    pub fn check(&mut self, now: CamState) -> Option<CamCause> {
        let cause = match self.last {
            None => CamCause::First,
            Some(last) => {
                let elapsed = now.time_s - last.time_s + TIME_SLACK_S;
                let turned = wrap_angle(now.heading_rad - last.heading_rad).abs() > HEADING_CHANGE_RAD;
                let moved = (now.x_m - last.x_m).hypot(now.y_m - last.y_m) > POSITION_CHANGE_M;
                let sped = (now.speed_mps - last.speed_mps).abs() > SPEED_CHANGE_MPS;
                if elapsed >= T_GEN_CAM_MIN_S && (turned || moved || sped) {
                    self.t_gen_cam_s = (now.time_s - last.time_s).clamp(T_GEN_CAM_MIN_S, T_GEN_CAM_MAX_S);
                    self.by_time_in_a_row = 0;
                    CamCause::Dynamics
                } else if elapsed >= self.t_gen_cam_s {
                    self.by_time_in_a_row += 1;
                    if self.by_time_in_a_row >= N_GEN_CAM {
                        self.t_gen_cam_s = T_GEN_CAM_MAX_S;
                    }
                    CamCause::Time
                } else {
                    return None;
                }
            }
        };
        self.last = Some(now);
        Some(cause)
    }
}

/// `angle` in (−π, π].
fn wrap_angle(angle: f64) -> f64 {
    let a = angle.rem_euclid(std::f64::consts::TAU);
    if a > std::f64::consts::PI { a - std::f64::consts::TAU } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The times CAMs went out over `seconds`, checked every 50 ms, for a vehicle whose state at
    /// time t is `state(t)`.
    fn cams(seconds: f64, state: impl Fn(f64) -> (f64, f64, f64, f64)) -> Vec<(f64, CamCause)> {
        let mut trigger = CamTrigger::default();
        (0..=(seconds / 0.05).round() as u32)
            .filter_map(|k| {
                let t = k as f64 * 0.05;
                let (x_m, y_m, heading_rad, speed_mps) = state(t);
                trigger.check(CamState { time_s: t, x_m, y_m, heading_rad, speed_mps }).map(|c| (t, c))
            })
            .collect()
    }

    fn intervals(sent: &[(f64, CamCause)]) -> Vec<f64> {
        sent.windows(2).map(|w| ((w[1].0 - w[0].0) * 1000.0).round() / 1000.0).collect()
    }

    #[test]
    fn a_standing_vehicle_sends_once_a_second() {
        let sent = cams(5.0, |_| (0.0, 0.0, 0.0, 0.0));
        assert_eq!(sent[0].1, CamCause::First);
        assert!(intervals(&sent).iter().all(|&i| i == 1.0), "{sent:?}");
        assert!(sent[1..].iter().all(|s| s.1 == CamCause::Time));
    }

    #[test]
    fn a_moving_vehicle_sends_each_time_it_has_moved_over_4_m() {
        // 30 m/s: 4 m in 0.133 s, so a CAM at each check past it, every 0.15 s.
        let sent = cams(3.0, |t| (30.0 * t, 0.0, 0.0, 30.0));
        assert!(intervals(&sent).iter().all(|&i| i == 0.15), "{sent:?}");
        // 80 m/s would move 4 m in 50 ms, but CAMs stay at most 10 per second.
        let fast = cams(2.0, |t| (80.0 * t, 0.0, 0.0, 80.0));
        assert!(intervals(&fast).iter().all(|&i| i == 0.1), "{fast:?}");
    }

    #[test]
    fn turning_or_braking_sends_and_the_interval_keeps_for_three_cams_then_relaxes() {
        // Standing, turning on the spot by 9°/s: 4° exceeded after 0.45 s (4.05°).
        let turning = cams(2.0, |t| (0.0, 0.0, (9.0 * t).to_radians(), 0.0));
        assert!(intervals(&turning).iter().all(|&i| i == 0.45), "{turning:?}");
        // Braking at 2 m/s² from 20 m/s for 1 s, then standing: speed changes of 0.5 m/s in
        // 0.25 s, 4 m moved sooner; then, standing, T_GenCam stays the last dynamic interval for
        // three CAMs by time, and returns to 1 s.
        let braking = cams(6.0, |t| {
            let tb = t.min(1.0);
            let speed = 20.0 - 2.0 * tb;
            (20.0 * tb - tb * tb, 0.0, 0.0, if t < 1.0 { speed } else { 18.0 })
        });
        // While braking: 4 m moved or 0.5 m/s lost every 0.25 s.
        let times: Vec<f64> = braking.iter().map(|s| (s.0 * 100.0).round() / 100.0).collect();
        assert_eq!(times[..5], [0.0, 0.25, 0.5, 0.75, 1.0], "{braking:?}");
        assert!(braking[1..5].iter().all(|s| s.1 == CamCause::Dynamics), "{braking:?}");
        // Then T_GenCam = 0.25 s for three CAMs by time, then 1 s.
        assert_eq!(times[5..], [1.25, 1.5, 1.75, 2.75, 3.75, 4.75, 5.75], "{braking:?}");
        assert!(braking[5..].iter().all(|s| s.1 == CamCause::Time), "{braking:?}");
    }

    #[test]
    fn headings_wrap() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.1) + 0.1).abs() < 1e-12);
        // 359° to 1° is a 2° turn: no CAM for it.
        let mut trigger = CamTrigger::default();
        let at = |t: f64, deg: f64| CamState {
            time_s: t,
            x_m: 0.0,
            y_m: 0.0,
            heading_rad: deg.to_radians(),
            speed_mps: 0.0,
        };
        assert_eq!(trigger.check(at(0.0, 359.0)), Some(CamCause::First));
        assert_eq!(trigger.check(at(0.5, 1.0)), None);
    }
}
