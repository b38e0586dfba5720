//! The step: parallel compute into a scratch buffer, serial commit, index update, collisions.

use super::kernel::{ExtEntry, Next, StepInput};
use super::lane_index::{LaneInfo, Members};
use super::track::{lane_segments, seek};
use super::{ACTUATOR_LAG_S, ExternalAgent, Traffic};
use crate::road::Road;

/// MOBIL decisions are taken about once per second per vehicle, staggered over the vehicles
/// (highway-env likewise decides lane changes at its 1 Hz policy rate).
const MOBIL_PERIOD_S: f64 = 1.0;

impl Traffic {
    /// Advances every vehicle from `time_s` to `time_s + dt_s` on one thread.
    pub fn step(&mut self, road: &Road, time_s: f64, dt_s: f64, external: &[ExternalAgent]) {
        self.step_threads(road, time_s, dt_s, external, 1);
    }

    /// Like [`Traffic::step`] with the per-vehicle work split over `threads` threads; the
    /// result is bit-identical for every thread count.
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
        let mut next = std::mem::take(&mut self.next);
        next.resize(n, Next::default());
        let threads = threads.clamp(1, n);
        if threads == 1 {
            self.fill(&inp, 0, &mut next);
        } else {
            let chunk = n.div_ceil(threads);
            let this = &*self;
            let inp = &inp;
            std::thread::scope(|scope| {
                let mut chunks = next.chunks_mut(chunk).enumerate();
                let first = chunks.next();
                for (c, part) in chunks {
                    scope.spawn(move || this.fill(inp, c * chunk, part));
                }
                if let Some((_, part)) = first {
                    this.fill(inp, 0, part);
                }
            });
        }
        self.commit(&next);
        self.next = next;
        self.detect_collisions();
        self.step_count += 1;
    }

    fn fill(&self, inp: &StepInput, offset: usize, out: &mut [Next]) {
        // MOBIL is due for vehicle i when (step + i) % period == 0; counted, not divided.
        let mut phase = (inp.step_count + offset as u64) % inp.mobil_period;
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.next_state(inp, offset + k, phase == 0);
            phase += 1;
            if phase == inp.mobil_period {
                phase = 0;
            }
        }
    }

    /// Writes the step's results back and updates the lane lists.
    fn commit(&mut self, next: &[Next]) {
        let mut changed = std::mem::take(&mut self.changed);
        changed.clear();
        for (i, o) in next.iter().enumerate() {
            if o.lane != self.lane[i] || o.intrude != self.intrude[i] || o.active != self.active[i] {
                changed.push(i as u32);
            }
            self.s_m[i] = o.s_m;
            self.d_m[i] = o.d_m;
            self.d_rate_mps[i] = o.d_rate_mps;
            self.speed_mps[i] = o.speed_mps;
            self.accel_mps2[i] = o.accel_mps2;
            self.x_m[i] = o.x_m;
            self.y_m[i] = o.y_m;
            self.cos_h[i] = o.cos_h;
            self.sin_h[i] = o.sin_h;
            self.lane[i] = o.lane;
            self.seg[i] = o.seg;
            self.lane_change[i] = o.lane_change;
            self.manoeuvre_started[i] = o.manoeuvre_started;
            self.active[i] = o.active;
            self.intrude[i] = o.intrude;
        }
        let members = Members { lane: &self.lane, s_m: &self.s_m, intrude: &self.intrude, active: &self.active };
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
        for i in 0..self.len() {
            let lane = self.lane[i] as usize;
            if lane >= self.lanes.len() {
                self.active[i] = false;
                continue;
            }
            let info = self.lanes[lane];
            if info.closed {
                self.s_m[i] = self.s_m[i].rem_euclid(info.length_m);
            }
            let mut out = self.current_for_prepare(i);
            out.seg = seek(&self.segments[lane], out.s_m, 0);
            self.place(&info, i, &mut out);
            self.seg[i] = out.seg;
            self.x_m[i] = out.x_m;
            self.y_m[i] = out.y_m;
            self.cos_h[i] = out.cos_h;
            self.sin_h[i] = out.sin_h;
            self.intrude[i] = out.intrude;
        }
        let members = Members { lane: &self.lane, s_m: &self.s_m, intrude: &self.intrude, active: &self.active };
        self.index.rebuild(&members, &self.lanes);
        self.detect_collisions();
        self.ready = true;
    }

    fn current_for_prepare(&self, i: usize) -> Next {
        Next {
            s_m: self.s_m[i],
            d_m: self.d_m[i],
            d_rate_mps: self.d_rate_mps[i],
            speed_mps: self.speed_mps[i],
            lane: self.lane[i],
            ..Next::default()
        }
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
                    self.ext_lists[id].push(ExtEntry { s_m, half_length_m: along_half, speed_mps: agent.velocity.dot(&dir) });
                }
            }
        }
    }
}
