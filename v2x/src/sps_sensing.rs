//! What each vehicle of [`super::sps`] has sensed of every resource (a sub-channel of a subframe
//! within one reservation interval), and how it picks its next resource from that: the
//! sensing-based selection of 3GPP TS 36.213 §14.1.1.6 and the reselection counter of TS 36.321
//! §5.14.1.1.

use risktwin_common::rng::Rng;

/// A candidate resource for the next reservation.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    offset_ms: u64,
    subchannel: u32,
    rsrp_mw: f32,
    rssi_mw: f32,
}

/// Per vehicle and resource: the strongest power sensed one interval ago and the mean S-RSSI.
#[derive(Debug)]
pub(super) struct Resources {
    interval_ms: u64,
    subchannels: usize,
    /// 0 when nothing was sensed, +∞ when the vehicle was transmitting (half-duplex).
    rsrp_mw: Vec<f32>,
    rssi_mw: Vec<f32>,
    /// The exponential mean's weight: one interval of the 1 s sensing window.
    rssi_weight: f32,
    noise_mw: f32,
    candidates: Vec<Candidate>,
}

/// TS 36.213 §14.1.1.6: the RSRP threshold rises 3 dB until 20 % of the resources are left, and
/// the 20 % with the lowest S-RSSI are the candidates.
const CANDIDATE_SHARE: f64 = 0.2;
const THRESHOLD_STEP_DB: f32 = 3.0;

impl Resources {
    pub(super) fn new(vehicles: usize, interval_ms: u32, subchannels: u32, noise_mw: f64) -> Resources {
        let per_vehicle = interval_ms as usize * subchannels as usize;
        Resources {
            interval_ms: interval_ms as u64,
            subchannels: subchannels as usize,
            rsrp_mw: vec![0.0; vehicles * per_vehicle],
            rssi_mw: vec![noise_mw as f32; vehicles * per_vehicle],
            rssi_weight: interval_ms as f32 / 1000.0,
            noise_mw: noise_mw as f32,
            candidates: Vec::with_capacity(per_vehicle),
        }
    }

    fn first(&self, vehicle: usize, phase: usize) -> usize {
        (vehicle * self.interval_ms as usize + phase) * self.subchannels
    }

    /// `vehicle` transmitted in this subframe, so it heard none of it.
    pub(super) fn unmonitored(&mut self, vehicle: usize, phase: usize) {
        let k = self.first(vehicle, phase);
        self.rsrp_mw[k..k + self.subchannels].fill(f32::INFINITY);
    }

    /// What `vehicle` heard on each sub-channel of this subframe: the sum of the copies and the
    /// strongest one, which it senses when it reaches `sensing_mw`.
    pub(super) fn sensed(
        &mut self,
        vehicle: usize,
        phase: usize,
        total_mw: &[f64],
        strongest_mw: &[f64],
        sensing_mw: f64,
    ) {
        let k = self.first(vehicle, phase);
        for s in 0..self.subchannels {
            let strongest = strongest_mw[s];
            self.rsrp_mw[k + s] = if strongest >= sensing_mw { strongest as f32 } else { 0.0 };
            let rssi = &mut self.rssi_mw[k + s];
            *rssi += self.rssi_weight * ((total_mw[s] as f32 + self.noise_mw) - *rssi);
        }
    }

    /// The resource `vehicle` reserves at `now_ms`: how many ms later it first transmits (within
    /// the selection window 1 ms to one interval) and on which sub-channel.
    pub(super) fn select(&mut self, vehicle: usize, now_ms: u64, sensing_mw: f64, rng: &mut Rng) -> (u64, u32) {
        self.candidates.clear();
        for offset_ms in 1..=self.interval_ms {
            let k = self.first(vehicle, ((now_ms + offset_ms) % self.interval_ms) as usize);
            for s in 0..self.subchannels {
                let (rsrp_mw, rssi_mw) = (self.rsrp_mw[k + s], self.rssi_mw[k + s]);
                self.candidates.push(Candidate { offset_ms, subchannel: s as u32, rsrp_mw, rssi_mw });
            }
        }
        let wanted = (CANDIDATE_SHARE * self.candidates.len() as f64).ceil() as usize;
        // Exclude what was sensed above the threshold, raising it until enough are left; a
        // subframe not monitored stays excluded (+∞).
        let mut threshold_mw = sensing_mw as f32;
        let step = 10f32.powf(THRESHOLD_STEP_DB / 10.0);
        while threshold_mw.is_finite() && self.candidates.iter().filter(|c| c.rsrp_mw < threshold_mw).count() < wanted {
            threshold_mw *= step;
        }
        self.candidates.retain(|c| c.rsrp_mw < threshold_mw);
        if self.candidates.len() > wanted {
            self.candidates.select_nth_unstable_by(wanted - 1, |a, b| a.rssi_mw.total_cmp(&b.rssi_mw));
            self.candidates.truncate(wanted);
        }
        match self.candidates.len() {
            // Unreachable while at most two subframes go unmonitored; a random one then.
            0 => (1 + rng.below(self.interval_ms), rng.below(self.subchannels as u64) as u32),
            len => {
                let c = self.candidates[rng.below(len as u64) as usize];
                (c.offset_ms, c.subchannel)
            }
        }
    }
}

/// Transmissions before the next reselection, TS 36.321 §5.14.1.1: uniform in [5, 15] for a
/// reservation interval of 100 ms or more, [10, 30] for 50 ms, [25, 75] for 20 ms.
pub(super) fn reselection_counter(interval_ms: u32, rng: &mut Rng) -> u32 {
    let (lo, hi) = match interval_ms {
        20 => (25, 75),
        50 => (10, 30),
        _ => (5, 15),
    };
    lo + rng.below(u64::from(hi - lo + 1)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selection_avoids_sensed_and_unmonitored_resources_and_draws_from_the_quietest() {
        // One vehicle, 100 ms, 4 sub-channels: 400 resources, 80 candidates wanted.
        let mut r = Resources::new(1, 100, 4, 1e-10);
        let sensing_mw = 1e-9;
        // Phases 0–59 busy and sensed; 60–78 loud but never sensed (each copy below the
        // threshold); 79–99 quiet.
        for phase in 0..100 {
            let (total, strongest) = match phase {
                0..60 => (1e-8, 1e-8),
                60..79 => (5e-9, 5e-10),
                _ => (0.0, 0.0),
            };
            for _ in 0..50 {
                r.sensed(0, phase, &[total; 4], &[strongest; 4], sensing_mw);
            }
        }
        // Transmitting now (t = 95) in phase 95: not monitored. That leaves 156 resources
        // available, of which the 80 quiet ones (79–99 but 95) have the lowest S-RSSI.
        r.unmonitored(0, 95);
        let mut rng = Rng::new(3);
        let mut drawn = std::collections::BTreeSet::new();
        for _ in 0..2000 {
            let (offset_ms, s) = r.select(0, 95, sensing_mw, &mut rng);
            let phase = (95 + offset_ms) % 100;
            assert!((79..100).contains(&phase) && phase != 95, "phase {phase}");
            assert!(s < 4 && (1..=100).contains(&offset_ms));
            drawn.insert((phase, s));
        }
        assert_eq!(drawn.len(), 80, "every quiet resource is a candidate");
    }

    #[test]
    fn the_threshold_rises_until_a_fifth_is_left_then_the_quietest_fifth_is_drawn_from() {
        let sensing_mw = 1e-9;
        // Every resource of one sub-channel sensed: `weak` of them just over the threshold, the
        // rest 30 dB over it.
        let picks = |weak: u64| {
            let mut r = Resources::new(1, 100, 1, 1e-10);
            for phase in 0..100 {
                let p = if phase < weak { 2e-9 } else { 1e-6 };
                r.sensed(0, phase as usize, &[p], &[p], sensing_mw);
            }
            let mut rng = Rng::new(4);
            (0..400).map(|_| r.select(0, 0, sensing_mw, &mut rng).0 % 100).collect::<Vec<u64>>()
        };
        // 30 weak: +3 dB twice leaves those 30 (≥ 20), and only those are drawn.
        assert!(picks(30).iter().all(|&p| p < 30));
        // 10 weak: the threshold climbs past the strong ones; the 20 lowest S-RSSI are the ten
        // weak and ten of the strong.
        let got = picks(10);
        let mut strong: Vec<u64> = got.iter().copied().filter(|&p| p >= 10).collect();
        strong.sort_unstable();
        strong.dedup();
        assert_eq!(strong.len(), 10, "{strong:?}");
        assert!((0..10).all(|w| got.contains(&w)));
    }

    #[test]
    fn the_counter_is_in_the_standards_range() {
        let mut rng = Rng::new(5);
        for (interval_ms, lo, hi) in [(100, 5, 15), (1000, 5, 15), (50, 10, 30), (20, 25, 75)] {
            let drawn: Vec<u32> = (0..2000).map(|_| reselection_counter(interval_ms, &mut rng)).collect();
            assert_eq!(drawn.iter().min(), Some(&lo));
            assert_eq!(drawn.iter().max(), Some(&hi));
        }
    }
}
