//! The step: parallel compute into a scratch buffer, serial commit, index update, collisions.

use super::crossing::crossing_lanes;
use super::kernel::{ExtEntry, StepInput};
use super::lane_index::{LaneInfo, Members};
use super::state::{Kinematics, KinematicsMut};
use super::track::{lane_segments, seek};
use super::{ACTUATOR_LAG_S, ExternalAgent, Traffic};
use crate::road::Road;

/// MOBIL decisions are taken about once per second per vehicle, staggered over the vehicles
/// (highway-env likewise decides lane changes at its 1 Hz policy rate).
const MOBIL_PERIOD_S: f64 = 1.0;

/// Fewest vehicles worth a parallel task (a rayon join costs about a microsecond; 512 vehicles
/// take about 30 µs).
const MIN_VEHICLES_PER_TASK: usize = 512;

impl Traffic {
    /// Advances every vehicle from `time_s` to `time_s + dt_s` on one thread.
    pub fn step(&mut self, road: &Road, time_s: f64, dt_s: f64, external: &[ExternalAgent]) {
        self.step_threads(road, time_s, dt_s, external, 1);
    }

    /// Like [`Traffic::step`] with the per-vehicle work split over the current rayon pool when
    /// `threads > 1` (run inside `ThreadPool::install` to choose its size); the result is
    /// bit-identical for every thread count.
    pub fn step_threads(&mut self, road: &Road, time_s: f64, dt_s: f64, external: &[ExternalAgent], threads: usize) {
        // The road is expected to stay the same; a different one (checked by lane shape)
        // rebuilds the cached geometry and the lane lists.
        LaneInfo::of_road(road, &mut self.lanes_check);
        if !self.ready || self.lanes_check != self.lanes {
            self.prepare(road);
        }
        let n = self.len();
        if n == 0 || !(dt_s > 0.0 && dt_s.is_finite()) {
            self.collisions.clear();
            return;
        }
        self.index_externals(road, external);
        let inp = StepInput {
            road,
            time_s,
            dt_s,
            lag_alpha: 1.0 - (-dt_s / ACTUATOR_LAG_S).exp(),
            mobil_period: (MOBIL_PERIOD_S / dt_s).round().max(1.0) as u64,
            step_count: self.step_count,
        };
        let mut nxt = std::mem::take(&mut self.nxt);
        nxt.resize(n);
        if threads <= 1 {
            self.fill(&inp, 0, nxt.view());
        } else {
            // Halves on rayon's pool (the caller's, or the global one): a worker descheduled
            // by other load has its half stolen back instead of stalling the step.
            let grain =
                if self.min_vehicles_per_task == 0 { MIN_VEHICLES_PER_TASK } else { self.min_vehicles_per_task };
            self.fill_split(&inp, 0, nxt.view(), grain);
        }
        self.commit(nxt);
        self.detect_collisions();
        self.step_count += 1;
    }

    fn fill_split(&self, inp: &StepInput, offset: usize, out: KinematicsMut, grain: usize) {
        if out.len() <= grain {
            self.fill(inp, offset, out);
            return;
        }
        let mid = out.len() / 2;
        let (a, b) = out.split_at(mid);
        rayon::join(|| self.fill_split(inp, offset, a, grain), || self.fill_split(inp, offset + mid, b, grain));
    }

    fn fill(&self, inp: &StepInput, offset: usize, mut out: KinematicsMut) {
        // MOBIL is due for vehicle i when (step + i) % period == 0; counted, not divided.
        let mut phase = (inp.step_count + offset as u64) % inp.mobil_period;
        for k in 0..out.len() {
            out.set(k, &self.next_state(inp, offset + k, phase == 0));
            phase += 1;
            if phase == inp.mobil_period {
                phase = 0;
            }
        }
    }

    /// Makes `nxt` the current state (a swap) and updates the lane lists.
    fn commit(&mut self, nxt: Kinematics) {
        let mut changed = std::mem::take(&mut self.changed);
        changed.clear();
        for i in 0..nxt.lane.len() {
            let (c, x) = (&self.cur, &nxt);
            if x.lane[i] != c.lane[i] || x.intrude[i] != c.intrude[i] || x.active[i] != c.active[i] {
                changed.push(i as u32);
                self.lane_changes_started += u64::from(x.lane[i] != c.lane[i]);
            }
        }
        self.nxt = std::mem::replace(&mut self.cur, nxt);
        let members =
            Members { lane: &self.cur.lane, s_m: &self.cur.s_m, intrude: &self.cur.intrude, active: &self.cur.active };
        self.index.update(&members, &self.lanes, &changed);
        self.changed = changed;
    }

    /// Computes poses and lane lists from the vehicles' Frenet state without moving them
    /// (done automatically by the first step after [`Traffic::add`]).
    pub fn prepare(&mut self, road: &Road) {
        LaneInfo::of_road(road, &mut self.lanes);
        self.segments.resize_with(road.lanes.len(), Vec::new);
        for (segs, lane) in self.segments.iter_mut().zip(&road.lanes) {
            lane_segments(lane, segs);
        }
        crossing_lanes(&self.lanes, &self.segments, &mut self.crossing);
        for i in 0..self.len() {
            let lane = self.cur.lane[i] as usize;
            if lane >= self.lanes.len() || !self.lanes[lane].usable() {
                self.cur.active[i] = false;
                continue;
            }
            let info = self.lanes[lane];
            if info.closed {
                self.cur.s_m[i] = self.cur.s_m[i].rem_euclid(info.length_m);
            }
            let mut out = self.cur.get(i);
            out.seg = seek(&self.segments[lane], out.s_m, 0);
            self.place(&info, i, &mut out);
            self.cur.set(i, &out);
        }
        let members =
            Members { lane: &self.cur.lane, s_m: &self.cur.s_m, intrude: &self.cur.intrude, active: &self.cur.active };
        self.index.rebuild(&members, &self.lanes);
        self.detect_collisions();
        self.ready = true;
    }

    /// Projects every external agent on every lane whose strip its footprint overlaps.
    fn index_externals(&mut self, road: &Road, external: &[ExternalAgent]) {
        self.ext_lists.resize_with(road.lanes.len(), Vec::new);
        self.ext_lists.iter_mut().for_each(Vec::clear);
        for agent in external {
            let p = agent.pose.position();
            let hl = 0.5 * agent.footprint.length_m;
            let hw = 0.5 * agent.footprint.width_m;
            for (id, lane) in road.lanes.iter().enumerate() {
                if !self.lanes[id].usable() {
                    continue;
                }
                let f = lane.project(p);
                let info = &self.lanes[id];
                let rel = agent.pose.heading_rad - f.lane_heading_rad;
                let (c, s) = (rel.cos(), rel.sin());
                let lateral_half = hw * c.abs() + hl * s.abs();
                let along_half = hl * c.abs() + hw * s.abs();
                let inside_s = info.closed || (f.s_m > -along_half && f.s_m < info.length_m + along_half);
                if inside_s && f.e_y_m.abs() - lateral_half < 0.5 * info.width_m {
                    let dir = crate::geometry::Vec2::new(f.lane_heading_rad.cos(), f.lane_heading_rad.sin());
                    let s_m = if info.closed { f.s_m.rem_euclid(info.length_m) } else { f.s_m };
                    self.ext_lists[id].push(ExtEntry {
                        s_m,
                        half_length_m: along_half,
                        speed_mps: agent.velocity.dot(&dir),
                    });
                }
            }
        }
    }
}
