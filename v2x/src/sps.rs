//! LTE-V2X sidelink Mode 4 on a highway, simulated packet by packet: what [`super::channel`]
//! leaves out. Vehicles on a ring road broadcast periodically on resources (one sub-channel of
//! one 1 ms subframe) they pick by sensing-based semi-persistent scheduling (3GPP TS 36.213
//! §14.1.1.6, TS 36.321 §5.14.1.1); each copy at each receiver is lost to half-duplex (the
//! receiver transmits in that subframe), to a power below the sensing threshold, or to its SINR,
//! the others on the same sub-channel and subframe counted as interference. The result is the
//! packet delivery ratio against distance.
//!
//! Simplified, most of it as the analytical model of Gonzalez-Martín et al. (IEEE TVT 68(2),
//! 2019) is: the ring is one line of vehicles standing still at uniform random positions; each
//! copy draws its own shadowing; a vehicle senses a transmission (its SCI) when the copy's power
//! reaches the sensing threshold, which is also where the RSRP exclusion starts; the RSRP
//! compared is the copy's whole power; a resource keeps the power sensed in it one interval ago,
//! and its S-RSSI is averaged over the 1 s sensing window as an exponential mean; a vehicle never
//! keeps its resource at reselection (probResourceKeep 0); no retransmissions, no in-band
//! emissions, SCIs never lost to collisions.

use super::bler::BlerCurve;
use super::channel::{LinkBudget, PathLoss, normal_cdf};
use super::sps_sensing::{Resources, reselection_counter};
use risktwin_common::rng::Rng;
use serde::Serialize;

/// How a copy whose power reaches the sensing threshold is decoded.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Decoding {
    /// When its SINR reaches the link budget's `sinr_threshold_db` (as [`super::channel`]).
    SinrThreshold,
    /// With probability 1 − BLER(SINR).
    Bler(BlerCurve),
}

/// A highway of LTE-V2X Mode 4 vehicles and how long to watch it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SpsHighway {
    pub model: PathLoss,
    /// Power, antennas, and the noise over the resource blocks one packet occupies.
    pub budget: LinkBudget,
    pub decoding: Decoding,
    /// A copy weaker than this is neither decoded nor sensed; the RSRP exclusion starts here.
    pub sensing_threshold_dbm: f64,
    pub vehicles_per_km: f64,
    /// The ring's length; at least twice `range_m`, so that no pair is counted twice.
    pub road_length_m: f64,
    /// Beyond this a transmission is neither sensed nor interferes.
    pub range_m: f64,
    /// The packet interval, which is also the resource reservation interval.
    pub interval_ms: u32,
    /// Sub-channels per subframe: each packet fills one.
    pub subchannels: u32,
    /// Simulated before counting (sensing and reselections settle).
    pub warmup_ms: u32,
    /// Simulated while counting deliveries.
    pub measured_ms: u32,
}

/// A receiver counts for a requested distance when it is this close to it.
pub const DISTANCE_BIN_HALF_WIDTH_M: f64 = 5.0;

/// The largest range and number of vehicles [`SpsHighway::check`] accepts.
const MAX_RANGE_M: f64 = 20_000.0;
const MAX_VEHICLES: usize = 20_000;

/// Distances are binned by the decimetre.
const BINS_PER_M: f64 = 10.0;

/// One copy at one receiver, kept while a subframe's interference is summed.
#[derive(Debug, Clone, Copy)]
struct Reception {
    rx: u32,
    subchannel: u32,
    signal_mw: f64,
    bin: u16,
}

impl SpsHighway {
    pub fn check(&self) -> Result<(), String> {
        self.budget.check()?;
        if let Decoding::Bler(curve) = &self.decoding {
            curve.check()?;
        }
        let positive = [
            ("vehicles_per_km", self.vehicles_per_km),
            ("road_length_m", self.road_length_m),
            ("range_m", self.range_m),
        ];
        if let Some((name, v)) = positive.into_iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Err(format!("{name} {v} must be a positive number"));
        }
        // Bounds that keep the tables (a decimetre of range each; interval × sub-channels
        // resources per vehicle) to tens of megabytes.
        if self.range_m > MAX_RANGE_M {
            return Err(format!("range {} m: at most {MAX_RANGE_M} m", self.range_m));
        }
        if self.vehicle_count() > MAX_VEHICLES {
            return Err(format!("{} vehicles on the ring: at most {MAX_VEHICLES}", self.vehicle_count()));
        }
        if self.road_length_m < 2.0 * self.range_m {
            return Err(format!("road {} m shorter than twice the range {} m", self.road_length_m, self.range_m));
        }
        if self.vehicle_count() < 2 {
            return Err(format!(
                "{} vehicles/km on {} m is fewer than two vehicles",
                self.vehicles_per_km, self.road_length_m
            ));
        }
        // TS 36.331 SL-ReservationPeriod: 20, 50 or 100 ms, or 100 ms multiples up to 1 s.
        let i = self.interval_ms;
        if !(i == 20 || i == 50 || (i.is_multiple_of(100) && (100..=1000).contains(&i))) {
            return Err(format!("interval {i} ms: LTE-V2X reserves every 20, 50 or 100–1000 ms (100 ms steps)"));
        }
        if !(1..=20).contains(&self.subchannels) {
            return Err(format!("{} sub-channels: need 1–20", self.subchannels));
        }
        if self.sensing_threshold_dbm.is_nan() {
            return Err("sensing threshold is not a number".into());
        }
        Ok(())
    }

    fn vehicle_count(&self) -> usize {
        (self.vehicles_per_km * self.road_length_m / 1000.0).round() as usize
    }

    /// The share of copies delivered to receivers within [`DISTANCE_BIN_HALF_WIDTH_M`] of each
    /// of `distances_m` (each ≤ `range_m`), NaN where none stood there. The same seed gives the
    /// same curve.
    pub fn pdr_at(&self, distances_m: &[f64], seed: u64) -> Result<Vec<f64>, String> {
        self.check()?;
        let max_m = self.range_m - DISTANCE_BIN_HALF_WIDTH_M;
        if let Some(d) = distances_m.iter().find(|d| !(0.0..=max_m).contains(*d)) {
            return Err(format!("distance {d} m: need 0 to {max_m} m (the range less a bin)"));
        }
        if distances_m.len() >= u16::MAX as usize {
            return Err(format!("{} distances: at most {}", distances_m.len(), u16::MAX - 1));
        }
        let (delivered, sent) = self.run(&distance_bins(distances_m), distances_m.len(), seed);
        Ok(delivered.iter().zip(&sent).map(|(&ok, &n)| if n == 0 { f64::NAN } else { ok as f64 / n as f64 }).collect())
    }

    /// Copies delivered and sent per bin.
    fn run(&self, bin_of: &[u16], bins: usize, seed: u64) -> (Vec<u64>, Vec<u64>) {
        let mut rng = Rng::new(seed);
        let n = self.vehicle_count();
        let subchannels = self.subchannels as usize;
        let interval = self.interval_ms as u64;
        let length_m = self.road_length_m;
        let mut position_m: Vec<f64> = (0..n).map(|_| rng.uniform(0.0, length_m)).collect();
        position_m.sort_by(f64::total_cmp);

        // Median received power (SNR plus noise) by the decimetre; each copy's shadowing scales it.
        // Indexed by the distance rounded to the decimetre, so sized by the range rounded too.
        let median_mw: Vec<f64> = (0..=(self.range_m * BINS_PER_M + 0.5) as usize)
            .map(|dm| dbm_to_mw(self.budget.at(self.model, dm as f64 / BINS_PER_M).snr_db + self.budget.noise_dbm()))
            .collect();
        let shadowing = shadowing_factors(self.model.shadowing_sigma_db());
        let noise_mw = dbm_to_mw(self.budget.noise_dbm());
        let sensing_mw = dbm_to_mw(self.sensing_threshold_dbm);
        let threshold_sinr = 10f64.powf(self.budget.sinr_threshold_db / 10.0);

        let mut resources = Resources::new(n, self.interval_ms, self.subchannels, noise_mw);
        let mut next_tx_ms: Vec<u64> = Vec::with_capacity(n);
        let mut subchannel: Vec<u32> = Vec::with_capacity(n);
        let mut counter: Vec<u32> = Vec::with_capacity(n);
        for _ in 0..n {
            // Before sensing has heard anything: a resource at random.
            next_tx_ms.push(1 + rng.below(interval));
            subchannel.push(rng.below(subchannels as u64) as u32);
            counter.push(reselection_counter(self.interval_ms, &mut rng));
        }

        // Per-subframe scratch, sized once.
        let mut transmitters: Vec<u32> = Vec::with_capacity(n);
        let mut heard_total_mw = vec![0.0f64; n * subchannels];
        let mut heard_strongest_mw = vec![0.0f64; n * subchannels];
        let measured_span_m = bin_of.len() as f64 / BINS_PER_M;
        let copies_per_tx = (2.0 * measured_span_m * self.vehicles_per_km / 1000.0).ceil() as usize + 16;
        let mut copies: Vec<Reception> = Vec::with_capacity(8 * copies_per_tx * n.div_ceil(interval as usize).max(1));
        let (mut delivered, mut sent) = (vec![0u64; bins], vec![0u64; bins]);

        let end_ms = u64::from(self.warmup_ms) + u64::from(self.measured_ms);
        for t in 1..=end_ms {
            let measuring = t > u64::from(self.warmup_ms);
            transmitters.clear();
            transmitters.extend((0..n as u32).filter(|&v| next_tx_ms[v as usize] == t));

            // Every copy of this subframe at every vehicle in range.
            copies.clear();
            for &tx in &transmitters {
                let s = subchannel[tx as usize];
                for_each_in_range(&position_m, tx as usize, self.range_m, length_m, |rx, distance_m| {
                    let dm = (distance_m * BINS_PER_M + 0.5) as usize;
                    let p = median_mw[dm] * shadowing[(rng.next_u64() >> (64 - SHADOWING_BITS)) as usize];
                    let k = rx * subchannels + s as usize;
                    heard_total_mw[k] += p;
                    heard_strongest_mw[k] = heard_strongest_mw[k].max(p);
                    if measuring && dm < bin_of.len() && bin_of[dm] != NO_BIN {
                        copies.push(Reception { rx: rx as u32, subchannel: s, signal_mw: p, bin: bin_of[dm] });
                    }
                });
            }

            for c in &copies {
                let rx = c.rx as usize;
                sent[c.bin as usize] += 1;
                let half_duplex = next_tx_ms[rx] == t;
                if half_duplex || c.signal_mw < sensing_mw {
                    continue;
                }
                let others_mw = (heard_total_mw[rx * subchannels + c.subchannel as usize] - c.signal_mw).max(0.0);
                let sinr = c.signal_mw / (noise_mw + others_mw);
                let decoded = match &self.decoding {
                    Decoding::SinrThreshold => sinr >= threshold_sinr,
                    Decoding::Bler(curve) => rng.unit() >= curve.at(10.0 * sinr.log10()),
                };
                delivered[c.bin as usize] += u64::from(decoded);
            }

            let phase = (t % interval) as usize;
            let heard =
                heard_total_mw.chunks_exact_mut(subchannels).zip(heard_strongest_mw.chunks_exact_mut(subchannels));
            for (v, ((total, strongest), &next)) in heard.zip(&next_tx_ms).enumerate() {
                if next == t {
                    resources.unmonitored(v, phase);
                } else {
                    resources.sensed(v, phase, total, strongest, sensing_mw);
                }
                total.fill(0.0);
                strongest.fill(0.0);
            }

            for &tx in &transmitters {
                let v = tx as usize;
                counter[v] -= 1;
                if counter[v] > 0 {
                    next_tx_ms[v] = t + interval;
                    continue;
                }
                let (offset_ms, s) = resources.select(v, t, sensing_mw, &mut rng);
                next_tx_ms[v] = t + offset_ms;
                subchannel[v] = s;
                counter[v] = reselection_counter(self.interval_ms, &mut rng);
            }
        }
        (delivered, sent)
    }
}

/// The shadowing is drawn from 2^14 equally likely quantiles of the normal distribution: the
/// hot loop's cost is one random number and one look-up instead of a logarithm, a cosine and an
/// exponential, and only the tails beyond ±4 σ (6·10⁻⁵ of the copies) are left out.
const SHADOWING_BITS: u32 = 14;

/// For each quantile z of the shadowing (mid-points of 2^[`SHADOWING_BITS`] equal steps of
/// probability), the factor 10^(−σ z / 10) on the median power: shadowing adds to the loss.
fn shadowing_factors(sigma_db: f64) -> Vec<f64> {
    let steps = 1usize << SHADOWING_BITS;
    (0..steps)
        .map(|i| {
            let z = normal_quantile((i as f64 + 0.5) / steps as f64);
            10f64.powf(-sigma_db * z / 10.0)
        })
        .collect()
}

/// Φ⁻¹(p) for p in (0, 1), by bisection on [`normal_cdf`] to 1e-12.
fn normal_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (-10.0, 10.0);
    while hi - lo > 1e-12 {
        let mid = 0.5 * (lo + hi);
        if normal_cdf(mid) < p { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// No requested distance near this one.
const NO_BIN: u16 = u16::MAX;

/// For each decimetre from 0 to the farthest requested distance plus a bin, the nearest
/// requested distance within [`DISTANCE_BIN_HALF_WIDTH_M`], if any.
fn distance_bins(distances_m: &[f64]) -> Vec<u16> {
    let farthest_m = distances_m.iter().copied().fold(0.0, f64::max) + DISTANCE_BIN_HALF_WIDTH_M;
    (0..=(farthest_m * BINS_PER_M) as usize)
        .map(|dm| {
            let d = dm as f64 / BINS_PER_M;
            distances_m
                .iter()
                .enumerate()
                .map(|(i, &want)| (i, (want - d).abs()))
                .filter(|&(_, gap)| gap <= DISTANCE_BIN_HALF_WIDTH_M)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or(NO_BIN, |(i, _)| i as u16)
        })
        .collect()
}

/// Calls `f(vehicle, distance_m)` for every other vehicle within `range_m` of `from` along the
/// ring, `position_m` sorted; each once, as the ring is at least twice the range.
fn for_each_in_range(position_m: &[f64], from: usize, range_m: f64, length_m: f64, mut f: impl FnMut(usize, f64)) {
    let n = position_m.len();
    let here = position_m[from];
    for step in 1..n {
        let j = (from + step) % n;
        let d = wrap(position_m[j] - here, length_m);
        if d > range_m {
            break;
        }
        f(j, d);
    }
    for step in 1..n {
        let j = (from + n - step) % n;
        let d = wrap(here - position_m[j], length_m);
        // Stop before a vehicle the forward walk already reached.
        if d > range_m || length_m - d <= range_m {
            break;
        }
        f(j, d);
    }
}

/// A gap along the ring of `length_m` in [0, length_m), from one in (−length_m, length_m).
fn wrap(gap_m: f64, length_m: f64) -> f64 {
    if gap_m < 0.0 { gap_m + length_m } else { gap_m }
}

fn dbm_to_mw(dbm: f64) -> f64 {
    10f64.powf(dbm / 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sps_reference::published_configuration;

    /// The published configuration's ring (4 km, 1.5 km range, 4 sub-channels every 100 ms)
    /// on the default link budget, decoded by its SINR threshold as [`super::super::channel`]
    /// does; the sensing threshold under anything decodable.
    fn highway(vehicles_per_km: f64) -> SpsHighway {
        SpsHighway {
            model: PathLoss::HighwayLos,
            budget: LinkBudget::default(),
            decoding: Decoding::SinrThreshold,
            sensing_threshold_dbm: -110.0,
            vehicles_per_km,
            ..published_configuration()
        }
    }

    #[test]
    fn without_interferers_the_pdr_is_the_channels_less_half_duplex() {
        // 20 vehicles/km in urban NLOS: 80 vehicles for 400 resources, and those sharing one
        // are kilometres apart; what is left is the channel and ~1 % half-duplex.
        let sparse = SpsHighway { model: PathLoss::UrbanNlos, measured_ms: 20_000, ..highway(20.0) };
        let distances_m = [100.0, 200.0, 300.0, 400.0];
        let ours = sparse.pdr_at(&distances_m, 7).expect("valid");
        for (d, got) in distances_m.iter().zip(&ours) {
            let channel = sparse.budget.at(sparse.model, *d).pdr;
            assert!((got - 0.99 * channel).abs() < 0.03, "{d} m: {got} against the channel's {channel}");
        }
    }

    #[test]
    fn interference_and_half_duplex_lower_the_pdr_at_range() {
        let loaded = highway(200.0);
        let distances_m = [5.0, 100.0, 300.0, 500.0];
        let ours = loaded.pdr_at(&distances_m, 8).expect("valid");
        let channel: Vec<f64> = distances_m.iter().map(|&d| loaded.budget.at(loaded.model, d).pdr).collect();
        // Alone the channel delivers everything to 500 m (half at 9.4 km).
        assert!(channel.iter().all(|&p| p > 0.999_99), "{channel:?}");
        // Close by, only half-duplex and the odd collision: about 1 %.
        assert!((0.97..0.998).contains(&ours[0]), "{ours:?}");
        // Farther, the interferers near the receiver weigh more against the signal.
        assert!(ours.windows(2).all(|w| w[1] < w[0]), "{ours:?}");
        assert!(ours[2] < 0.9 && ours[3] < 0.75, "{ours:?}");
    }

    #[test]
    fn the_seed_decides_the_curve() {
        let quick = SpsHighway { warmup_ms: 1000, measured_ms: 1000, ..highway(100.0) };
        let distances_m = [0.0, 150.0, 400.0];
        let a = quick.pdr_at(&distances_m, 3).expect("valid");
        assert_eq!(a, quick.pdr_at(&distances_m, 3).expect("valid"));
        assert_ne!(a, quick.pdr_at(&distances_m, 4).expect("valid"));
    }

    #[test]
    fn a_range_between_decimetres_reaches_its_last_receivers() {
        // 2,000 static vehicles: tens of pairs stand between 150.05 and 150.07 m apart, whose
        // distance rounds past the range's decimetre.
        let h = SpsHighway { range_m: 150.07, warmup_ms: 100, measured_ms: 100, ..highway(500.0) };
        let pdr = h.pdr_at(&[100.0], 5).expect("valid");
        assert!(pdr[0] > 0.5, "{pdr:?}");
    }

    #[test]
    fn impossible_highways_are_refused_by_name() {
        let h = highway(200.0);
        let bad = [
            SpsHighway { vehicles_per_km: 0.0, ..h },
            SpsHighway { road_length_m: 2000.0, ..h },
            SpsHighway { interval_ms: 30, ..h },
            SpsHighway { subchannels: 0, ..h },
            SpsHighway { vehicles_per_km: 0.1, ..h },
        ];
        for (highway, word) in
            bad.iter().zip(["vehicles_per_km", "twice the range", "interval", "sub-channels", "two vehicles"])
        {
            let e = highway.check().expect_err("refused");
            assert!(e.contains(word), "{e}");
        }
        assert!(h.pdr_at(&[1496.0], 1).expect_err("beyond the range").contains("distance"));
        assert!(h.pdr_at(&[-1.0], 1).is_err());
    }
}
