//! One vehicle's next state from the current state of all: leaders, IDM, the manoeuvre,
//! MOBIL, actuator lag, the μ·g limit, integration and the new pose.
//!
//! Reads only the current state, so vehicles can be computed in any order and on any number
//! of threads with bit-identical results.

use super::idm::IdmCoeffs;
use super::lane_index::{Entry, LaneInfo, NONE, upper_bound_near};
use super::manoeuvre::{LaneChange, MOBIL_LANE_CHANGE_S};
use super::mobil::{MobilAccels, mobil_incentive, mobil_should_change};
use super::state::Next;
use super::track::{project_near, seek};
use super::{GRAVITY_MPS2, IdmParams, Manoeuvre, Traffic};
use crate::geometry::Vec2;
use crate::road::Road;

/// An external agent as seen from one lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ExtEntry {
    pub s_m: f64,
    pub half_length_m: f64,
    pub speed_mps: f64,
}

/// Per-step constants.
pub(crate) struct StepInput<'a> {
    pub road: &'a Road,
    pub time_s: f64,
    pub dt_s: f64,
    /// 1 − exp(−dt/τ): the exact discretisation of the first-order actuator lag.
    pub lag_alpha: f64,
    /// MOBIL is evaluated once per this many steps per vehicle (staggered by index).
    pub mobil_period: u64,
    pub step_count: u64,
}

/// The nearest constraint ahead: the most restrictive IDM acceleration and smallest gap.
#[derive(Debug, Clone, Copy)]
struct Lead {
    accel_mps2: f64,
    gap_m: f64,
}

/// Entry after slot `k` in `list`, with the forward offset to add to its s (wrap), if any.
#[inline]
fn next_of(list: &[Entry], k: usize, info: &LaneInfo) -> Option<(Entry, f64)> {
    if k + 1 < list.len() {
        Some((list[k + 1], 0.0))
    } else if info.closed && list.len() > 1 {
        Some((list[0], info.length_m))
    } else {
        None
    }
}

/// Entry before slot `k` in `list`, with the offset to add to its s (wrap), if any.
#[inline]
fn prev_of(list: &[Entry], k: usize, info: &LaneInfo) -> Option<(Entry, f64)> {
    if k > 0 {
        Some((list[k - 1], 0.0))
    } else if info.closed && list.len() > 1 {
        Some((list[list.len() - 1], -info.length_m))
    } else {
        None
    }
}

impl Traffic {
    #[inline]
    fn coeffs(&self, i: usize) -> &IdmCoeffs {
        &self.idm_coeffs[self.idm_idx[i] as usize]
    }

    /// Leaders of vehicle `i` in every list it belongs to, and external agents in those lanes.
    fn lead(&self, i: usize, c: &IdmCoeffs) -> Lead {
        let v = self.cur.speed_mps[i];
        let hl = self.half_length_m[i];
        let own = self.cur.lane[i];
        let mut lead = Lead { accel_mps2: c.accel(v, f64::INFINITY, 0.0), gap_m: f64::INFINITY };
        let mut consider = |gap: f64, closing: f64| {
            lead.gap_m = lead.gap_m.min(gap);
            lead.accel_mps2 = lead.accel_mps2.min(c.accel(v, gap, closing));
        };
        let slots = self.index.slots[i];
        for (side, &slot) in slots.iter().enumerate() {
            if slot == NONE {
                continue;
            }
            let lane = self.lanes[own as usize].side_lane(own, side);
            let info = &self.lanes[lane as usize];
            let list = &self.index.lists[lane as usize];
            let me = list[slot as usize];
            if let Some((e, off)) = next_of(list, slot as usize, info) {
                let j = e.id as usize;
                consider(e.s_m + off - me.s_m - hl - self.half_length_m[j], v - self.cur.speed_mps[j]);
            }
            for x in &self.ext_lists[lane as usize] {
                let mut ds = x.s_m - me.s_m;
                if info.closed {
                    ds = ds.rem_euclid(info.length_m);
                }
                if ds > 0.0 {
                    consider(ds - hl - x.half_length_m, v - x.speed_mps);
                }
            }
        }
        lead
    }

    /// IDM acceleration of vehicle `j` with its front `gap_m` behind something at `lead_mps`;
    /// parked vehicles do not care (0).
    fn follower_accel(&self, j: usize, gap_m: f64, lead_mps: f64) -> f64 {
        if self.manoeuvre[j] == Manoeuvre::Parked {
            return 0.0;
        }
        let v = self.cur.speed_mps[j];
        self.coeffs(j).accel(v, gap_m, v - lead_mps)
    }

    /// The lane MOBIL moves vehicle `i` to, if any (Kesting et al. 2007, symmetric rules).
    fn mobil_target(&self, i: usize, a_now: f64) -> Option<u32> {
        let own = self.cur.lane[i];
        let info = &self.lanes[own as usize];
        let slot = self.index.slots[i][0];
        if slot == NONE {
            return None;
        }
        let (v, hl, s) = (self.cur.speed_mps[i], self.half_length_m[i], self.cur.s_m[i]);
        let c = self.coeffs(i);
        let own_list = &self.index.lists[own as usize];
        // Old follower o: now behind i, afterwards behind i's current leader.
        let (mut ao_now, mut ao_after) = (0.0, 0.0);
        if let Some((o, off)) = prev_of(own_list, slot as usize, info) {
            let j = o.id as usize;
            let back = s - (o.s_m + off) - hl - self.half_length_m[j];
            ao_now = self.follower_accel(j, back, v);
            ao_after = match next_of(own_list, slot as usize, info) {
                Some((l, loff)) if l.id != o.id => {
                    let k = l.id as usize;
                    let gap = l.s_m + loff - (o.s_m + off) - self.half_length_m[j] - self.half_length_m[k];
                    self.follower_accel(j, gap, self.cur.speed_mps[k])
                }
                _ => self.follower_accel(j, f64::INFINITY, 0.0),
            };
        }
        let mut best: Option<(f64, u32)> = None;
        for (side, target) in [(1, info.left), (2, info.right)] {
            if target == NONE {
                continue;
            }
            let t_info = &self.lanes[target as usize];
            let s_t = s * t_info.length_m / info.length_m.max(1e-9);
            let list = &self.index.lists[target as usize];
            if self.index.slots[i][side] != NONE {
                continue; // already straddling that lane: leave it to finish first
            }
            // Lists are spread alike along the road: start from the same fraction of the list.
            let guess = (slot as usize * list.len()) / own_list.len().max(1);
            let k = upper_bound_near(list, s_t, guess);
            // New leader l (ahead of s_t) and new follower n (behind), with wrap on rings.
            let leader = if k < list.len() {
                Some((list[k], list[k].s_m - s_t))
            } else if t_info.closed && !list.is_empty() {
                Some((list[0], list[0].s_m + t_info.length_m - s_t))
            } else {
                None
            };
            let follower = if k > 0 {
                Some((list[k - 1], s_t - list[k - 1].s_m))
            } else if t_info.closed && !list.is_empty() {
                Some((list[list.len() - 1], s_t + t_info.length_m - list[list.len() - 1].s_m))
            } else {
                None
            };
            let mut acc = MobilAccels {
                own_now_mps2: a_now,
                old_follower_now_mps2: ao_now,
                old_follower_after_mps2: ao_after,
                ..Default::default()
            };
            acc.own_after_mps2 = c.accel(v, f64::INFINITY, 0.0);
            if let Some((l, ds)) = leader {
                let k = l.id as usize;
                let gap = ds - hl - self.half_length_m[k];
                if gap <= 0.0 {
                    continue;
                }
                acc.own_after_mps2 = c.accel(v, gap, v - self.cur.speed_mps[k]);
            }
            if let Some((n, ds)) = follower {
                let j = n.id as usize;
                let gap = ds - hl - self.half_length_m[j];
                if gap <= 0.0 || leader.is_some_and(|l| l.0.id == n.id) {
                    continue;
                }
                acc.new_follower_after_mps2 = self.follower_accel(j, gap, v);
                acc.new_follower_now_mps2 = match leader {
                    Some((l, lds)) => {
                        let k = l.id as usize;
                        self.follower_accel(
                            j,
                            ds + lds - self.half_length_m[j] - self.half_length_m[k],
                            self.cur.speed_mps[k],
                        )
                    }
                    None => self.follower_accel(j, f64::INFINITY, 0.0),
                };
            }
            // External agents in the target lane: leaders for i, and followers that must not
            // be forced to brake harder than b_safe (judged with default IDM parameters).
            let mut blocked = false;
            for x in &self.ext_lists[target as usize] {
                let mut ds = x.s_m - s_t;
                if t_info.closed {
                    ds = (ds + 0.5 * t_info.length_m).rem_euclid(t_info.length_m) - 0.5 * t_info.length_m;
                }
                let gap = ds.abs() - hl - x.half_length_m;
                if gap <= 0.0 {
                    blocked = true;
                } else if ds > 0.0 {
                    acc.own_after_mps2 = acc.own_after_mps2.min(c.accel(v, gap, v - x.speed_mps));
                } else {
                    let a = IdmCoeffs::new(&IdmParams::default()).accel(x.speed_mps, gap, x.speed_mps - v);
                    blocked |= a < -self.mobil.safe_decel_mps2;
                }
            }
            if blocked || !mobil_should_change(&self.mobil, &acc) {
                continue;
            }
            let gain = mobil_incentive(&self.mobil, &acc);
            if best.is_none_or(|b| gain > b.0) {
                best = Some((gain, target));
            }
        }
        best.map(|b| b.1)
    }

    /// Moves vehicle `i` into `target` (its Frenet coordinates re-expressed there) and starts
    /// the lateral profile.
    fn begin_lane_change(&self, road: &Road, i: usize, target: u32, t0_s: f64, duration_s: f64, out: &mut Next) {
        let from = &self.lanes[self.cur.lane[i] as usize];
        let to = &self.lanes[target as usize];
        let p = Vec2::new(self.cur.x_m[i], self.cur.y_m[i]);
        let s_guess = self.cur.s_m[i] * to.length_m / from.length_m.max(1e-9);
        let (s, d, seg) = project_near(&road.lanes[target as usize], p, s_guess, to.closed);
        out.lane = target;
        out.s_m = s;
        out.d_m = d;
        out.seg = seg;
        out.lane_change = LaneChange { active: true, t0_s, duration_s: duration_s.max(1e-3), d0_m: d };
    }

    /// The next state of vehicle `i`.
    /// `mobil_due`: MOBIL is evaluated for this vehicle in this step.
    pub(crate) fn next_state(&self, inp: &StepInput, i: usize, mobil_due: bool) -> Next {
        let mut out = self.cur.get(i);
        if !out.active || self.manoeuvre[i] == Manoeuvre::Parked {
            return out;
        }
        let (road, t, dt) = (inp.road, inp.time_s, inp.dt_s);
        let c = self.coeffs(i);
        let v = self.cur.speed_mps[i];
        let lead = self.lead(i, c);
        let mu = if road.friction_patches.is_empty() {
            road.friction_default
        } else {
            road.friction_at(Vec2::new(self.cur.x_m[i], self.cur.y_m[i]))
        };
        let mu_g = mu.max(0.0) * GRAVITY_MPS2;
        let mut a_cmd = lead.accel_mps2;
        let mut change: Option<(u32, f64, f64)> = None;
        let started = self.cur.manoeuvre_started[i];
        match self.manoeuvre[i] {
            Manoeuvre::None | Manoeuvre::Parked => {
                if mobil_due && self.lane_changes[i] && !self.cur.lane_change[i].active {
                    change = self.mobil_target(i, lead.accel_mps2).map(|l| (l, t, MOBIL_LANE_CHANGE_S));
                }
            }
            Manoeuvre::Brake { start_time_s, decel_mps2 } => {
                if t >= start_time_s {
                    a_cmd = a_cmd.min(-decel_mps2.abs().min(mu_g));
                }
            }
            Manoeuvre::CutIn { start_time_s, duration_s, target_lane } => {
                if !started && t >= start_time_s {
                    change = Some((target_lane as u32, start_time_s, duration_s));
                }
            }
            Manoeuvre::Swerve { trigger_gap_m, duration_s, target_lane } => {
                if !started {
                    // It means to pass what stands ahead: it holds its speed until it swerves
                    // (the late reveal of the sensor-occlusion kind).
                    a_cmd = c.accel(v, f64::INFINITY, 0.0);
                    if lead.gap_m < trigger_gap_m {
                        change = Some((target_lane as u32, t, duration_s));
                    }
                }
            }
        }
        if let Some((target, t0, dur)) = change {
            out.manoeuvre_started = true;
            let usable = self.lanes.get(target as usize).is_some_and(LaneInfo::usable);
            if usable && target != self.cur.lane[i] {
                self.begin_lane_change(road, i, target, t0, dur, &mut out);
            }
        }
        // First-order actuator lag, then the friction limit |a| ≤ μ·g.
        let a_prev = self.cur.accel_mps2[i];
        let a = (a_prev + (a_cmd - a_prev) * inp.lag_alpha).clamp(-mu_g, mu_g);
        // Ballistic update that stops exactly at v = 0 instead of reversing (Treiber &
        // Kanagaraj 2015, "Comparing numerical integration schemes for time-continuous
        // car-following models", Eq. (8)).
        if v + a * dt < 0.0 {
            out.s_m += if a < 0.0 { -v * v / (2.0 * a) } else { 0.0 };
            out.speed_mps = 0.0;
            out.accel_mps2 = 0.0;
        } else {
            out.s_m += v * dt + 0.5 * a * dt * dt;
            out.speed_mps = v + a * dt;
            out.accel_mps2 = a;
        }
        if out.lane_change.active {
            match out.lane_change.lateral_at(t + dt) {
                Some((d, rate)) => (out.d_m, out.d_rate_mps) = (d, rate),
                None => {
                    (out.d_m, out.d_rate_mps) = (0.0, 0.0);
                    out.lane_change.active = false;
                }
            }
        } else {
            out.d_rate_mps = 0.0;
        }
        let info = self.lanes[out.lane as usize];
        if info.closed {
            // A step moves far less than a lap: one subtraction instead of fmod.
            if out.s_m >= info.length_m {
                out.s_m -= info.length_m;
            } else if out.s_m < 0.0 {
                out.s_m += info.length_m;
            }
            if !(out.s_m >= 0.0 && out.s_m < info.length_m) {
                out.s_m = out.s_m.rem_euclid(info.length_m) % info.length_m;
            }
        } else if out.s_m > info.length_m {
            out.active = false;
            return out;
        }
        self.place(&info, i, &mut out);
        out
    }

    /// World pose and lane-boundary intrusion of the state in `out`.
    pub(crate) fn place(&self, info: &LaneInfo, i: usize, out: &mut Next) {
        let segs = &self.segments[out.lane as usize];
        out.seg = seek(segs, out.s_m, out.seg);
        let seg = &segs[out.seg as usize];
        let p = seg.world(out.s_m, out.d_m);
        let dir = seg.dir;
        // Heading relative to the lane: atan2(ḋ, v), with v floored so a slow lane change
        // does not turn the car sideways.
        let (c, s) = if out.d_rate_mps == 0.0 {
            (1.0, 0.0)
        } else {
            let (fwd, lat) = (out.speed_mps.max(1.0), out.d_rate_mps);
            let inv = 1.0 / (fwd * fwd + lat * lat).sqrt();
            (fwd * inv, lat * inv)
        };
        out.x_m = p.x;
        out.y_m = p.y;
        out.cos_h = dir.x * c - dir.y * s;
        out.sin_h = dir.y * c + dir.x * s;
        let lateral_half = self.half_width_m[i] * c + self.half_length_m[i] * s.abs();
        let half_lane = 0.5 * info.width_m;
        let mut intrude = 0;
        if info.left != NONE && out.d_m + lateral_half > half_lane {
            intrude |= 1;
        }
        if info.right != NONE && out.d_m - lateral_half < -half_lane {
            intrude |= 2;
        }
        out.intrude = intrude;
    }
}
