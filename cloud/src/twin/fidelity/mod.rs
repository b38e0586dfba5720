//! Twin fidelity against a scene's ground truth. A scene's authority publishes each connected
//! vehicle's true state (`risktwin/v1/<site>/scene/gt/<source>`) and every other object's
//! (`…/scene/objects`) per physics step, stamped on the same wall clock as the edges' streams.
//! At every tick the cloud builds the truth twin of the site at the tick's time
//! ([`truth::SiteTruth::twin_at`]) and compares, for each connected vehicle:
//! - its position in the twin against its true position;
//! - with the risk role, the risk the twin sees against the risk of the truth, by the same
//!   code ([`RiskAssessor::instant`]): the S_risk score, the field at the vehicle's footprint,
//!   and the TTC to every object closing in its lane;
//! - critical events: a truth pair (this vehicle, another object) whose TTC falls below
//!   [`CRITICAL_TTC_S`] opens an event; the twin sees it at the first tick one of its objects
//!   within [`ASSOCIATION_M`] of the true one has a TTC below the threshold too. The lag is that
//!   tick's time minus the event's start (0 when the twin was there first); an event that ends
//!   (or is still open at shutdown) unseen is missed.
//!
//! What the errors contain is everything a user of the twin sees: transport, alignment
//! lateness, interpolation, the sensors' noise, occlusion and missing accelerations.

pub(crate) mod distribution;
mod truth;

pub use distribution::ErrorStats;

use super::SiteTwin;
use super::risk::RiskAssessor;
use distribution::Distribution;
use risktwin_common::geometry::Vec2;
use risktwin_common::telemetry::{ObjectList, VehicleStateSample};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write;
use std::sync::Arc;
use truth::SiteTruth;

/// A pair is critical below this TTC, s (the usual threshold for a near-conflict).
pub const CRITICAL_TTC_S: f64 = 2.0;
/// A twin object stands for a true one within this distance of its centre, m.
pub const ASSOCIATION_M: f64 = 2.5;
/// TTCs are compared for true pairs closing in below this, s (beyond it nothing is at stake).
pub const TTC_COMPARED_S: f64 = 10.0;
/// One series point per vehicle at most this often, ns (the report's plot), and at most
/// [`SERIES_POINTS`] of them (an hour).
const SERIES_PERIOD_NS: i64 = 100_000_000;
const SERIES_POINTS: usize = 36_000;

/// How well the twin mirrored one connected vehicle and its surroundings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VehicleFidelity {
    /// Ticks at which the vehicle was both in the twin and in the truth.
    pub ticks: u64,
    pub position_error_m: ErrorStats,
    /// The rest needs the risk role.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub risk: Option<RiskFidelity>,
}

/// The risk the twin sees around a vehicle against the risk of the truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RiskFidelity {
    /// |S_risk(twin) − S_risk(truth)| per tick.
    pub s_risk_abs_error: ErrorStats,
    /// |R(twin) − R(truth)| at the vehicle's footprint per tick.
    pub risk_at_ego_abs_error: ErrorStats,
    /// |TTC(twin) − TTC(truth)| per true pair closing in below [`TTC_COMPARED_S`] that the twin
    /// also sees closing in, s.
    pub ttc_abs_error_s: ErrorStats,
    /// True pairs closing in below [`TTC_COMPARED_S`] the twin did not see closing in (no
    /// object there, or not closing in).
    pub ttc_pairs_unseen: u64,
    pub critical_events: CriticalEvents,
}

/// Critical events (first TTC < [`CRITICAL_TTC_S`] of a true pair) and when the twin saw them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CriticalEvents {
    pub truth: u64,
    pub seen: u64,
    pub missed: u64,
    pub lag_s: ErrorStats,
}

/// One point of a vehicle's fidelity series (the report's plot).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesPoint {
    pub tick_ns: i64,
    pub position_error_m: f64,
    /// `(twin, truth)`; NaN without the risk role.
    pub s_risk: (f64, f64),
    pub risk_at_ego: (f64, f64),
}

/// Who the other of a true pair is.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum Other {
    Vehicle(Arc<str>),
    Object(u32),
}

#[derive(Debug, Clone, Copy)]
struct OpenEvent {
    start_ns: i64,
    seen: bool,
}

#[derive(Debug, Clone)]
struct RiskAcc {
    s_risk: Distribution,
    at_ego: Distribution,
    ttc: Distribution,
    ttc_unseen: u64,
    events: u64,
    seen: u64,
    missed_closed: u64,
    lag: Distribution,
    open: HashMap<Other, OpenEvent>,
}

impl RiskAcc {
    fn new() -> Self {
        RiskAcc {
            s_risk: Distribution::new(0.0005),
            at_ego: Distribution::new(0.001),
            ttc: Distribution::new(0.01),
            ttc_unseen: 0,
            events: 0,
            seen: 0,
            missed_closed: 0,
            lag: Distribution::new(0.01),
            open: HashMap::new(),
        }
    }

    fn summary(&self) -> RiskFidelity {
        let open_unseen = self.open.values().filter(|e| !e.seen).count() as u64;
        RiskFidelity {
            s_risk_abs_error: self.s_risk.stats(),
            risk_at_ego_abs_error: self.at_ego.stats(),
            ttc_abs_error_s: self.ttc.stats(),
            ttc_pairs_unseen: self.ttc_unseen,
            critical_events: CriticalEvents {
                truth: self.events,
                seen: self.seen,
                missed: self.missed_closed + open_unseen,
                lag_s: self.lag.stats(),
            },
        }
    }
}

#[derive(Debug, Clone)]
struct VehicleAcc {
    position: Distribution,
    risk: Option<RiskAcc>,
    series: Vec<SeriesPoint>,
}

/// The pairs of one evaluation: where the other is and the TTC to it.
#[derive(Debug, Default)]
struct Pairs {
    truth: Vec<(Other, Vec2, f64)>,
    twin: Vec<(Vec2, f64)>,
}

/// The ground truth received so far and the fidelity measured against it.
#[derive(Debug, Default)]
pub struct Fidelity {
    truth: HashMap<String, SiteTruth>,
    /// Per `site/source`.
    vehicles: BTreeMap<String, VehicleAcc>,
    truth_twin: SiteTwin,
    pairs: Pairs,
    /// Scratch for a vehicle's `site/source` key (no allocation per tick once it is known).
    key: String,
}

impl Fidelity {
    /// A connected vehicle's true state at `site`.
    pub fn observe_vehicle(&mut self, site: &str, source: &str, sample: &VehicleStateSample) {
        self.truth.entry(site.to_owned()).or_default().push_vehicle(source, sample);
    }

    /// Every other object's true state at `site`.
    pub fn observe_objects(&mut self, site: &str, list: ObjectList) {
        self.truth.entry(site.to_owned()).or_default().push_objects(list.header.capture_time_ns, list.objects);
    }

    /// Compares `twin` (site `site`) at `tick_ns` with the truth, where the truth brackets the
    /// tick; with `risk` (the site's assessor) the risk too. Returns the truth twin it compared
    /// with, `None` where there is no truth at the tick.
    pub fn compare(
        &mut self,
        site: &str,
        tick_ns: i64,
        twin: &SiteTwin,
        mut risk: Option<&mut RiskAssessor>,
    ) -> Option<&SiteTwin> {
        let truth = self.truth.get_mut(site)?;
        if !truth.twin_at(tick_ns, &mut self.truth_twin) {
            return None;
        }
        for (ego, v) in twin.vehicles.iter().enumerate() {
            let Some(ego_truth) = self.truth_twin.vehicles.iter().position(|t| t.source == v.source) else { continue };
            let true_position = self.truth_twin.vehicles[ego_truth].kinematics.pose.position();
            self.key.clear();
            let _ = write!(self.key, "{site}/{}", v.source);
            let acc = match self.vehicles.get_mut(&self.key) {
                Some(acc) => acc,
                None => self.vehicles.entry(self.key.clone()).or_insert_with(|| VehicleAcc {
                    position: Distribution::new(0.005),
                    risk: None,
                    series: Vec::new(),
                }),
            };
            let position_error_m = (v.kinematics.pose.position() - true_position).norm();
            acc.position.add(position_error_m);
            let mut point = SeriesPoint {
                tick_ns,
                position_error_m,
                s_risk: (f64::NAN, f64::NAN),
                risk_at_ego: (f64::NAN, f64::NAN),
            };
            if let Some(risk) = risk.as_deref_mut() {
                let evaluated = evaluate(risk, twin, ego, &self.truth_twin, ego_truth, &mut self.pairs);
                if let Some((seen, true_)) = evaluated {
                    let r = acc.risk.get_or_insert_with(RiskAcc::new);
                    r.s_risk.add((seen.terms.score - true_.terms.score).abs());
                    r.at_ego.add((seen.at_ego - true_.at_ego).abs());
                    compare_pairs(r, &self.pairs, tick_ns);
                    point.s_risk = (seen.terms.score, true_.terms.score);
                    point.risk_at_ego = (seen.at_ego, true_.at_ego);
                }
            }
            let due = acc.series.last().is_none_or(|p| tick_ns - p.tick_ns >= SERIES_PERIOD_NS);
            if due && acc.series.len() < SERIES_POINTS {
                acc.series.push(point);
            }
        }
        Some(&self.truth_twin)
    }

    /// The fidelity per `site/source`.
    pub fn summary(&self) -> BTreeMap<String, VehicleFidelity> {
        let of = |a: &VehicleAcc| VehicleFidelity {
            ticks: a.position.stats().n,
            position_error_m: a.position.stats(),
            risk: a.risk.as_ref().map(RiskAcc::summary),
        };
        self.vehicles.iter().map(|(k, a)| (k.clone(), of(a))).collect()
    }

    /// The series per `site/source` (a point per [`SERIES_PERIOD_NS`] at most).
    pub fn series(&self) -> BTreeMap<String, Vec<SeriesPoint>> {
        self.vehicles.iter().map(|(k, a)| (k.clone(), a.series.clone())).collect()
    }
}

/// The instant risk of `twin.vehicles[ego]` and of `truth.vehicles[ego_truth]`, with the
/// pairs of each in `pairs`.
fn evaluate(
    risk: &mut RiskAssessor,
    twin: &SiteTwin,
    ego: usize,
    truth: &SiteTwin,
    ego_truth: usize,
    pairs: &mut Pairs,
) -> Option<(super::risk::InstantRisk, super::risk::InstantRisk)> {
    let true_ = risk.instant(truth, ego_truth)?;
    pairs.truth.clear();
    for ((state, who), &ttc) in risk.others().zip(risk.pair_ttc_s()) {
        let other = match who {
            Ok(i) => Other::Vehicle(Arc::clone(&truth.vehicles[i].source)),
            Err(j) => Other::Object(truth.objects[j].object.id),
        };
        pairs.truth.push((other, state.obb.centre, ttc));
    }
    let seen = risk.instant(twin, ego)?;
    pairs.twin.clear();
    pairs.twin.extend(risk.others().zip(risk.pair_ttc_s()).map(|((state, _), &ttc)| (state.obb.centre, ttc)));
    Some((seen, true_))
}

/// The TTC the twin has for the object it holds nearest to `centre` (within
/// [`ASSOCIATION_M`]), if any; several sources may report one object.
fn twin_ttc_near(twin: &[(Vec2, f64)], centre: Vec2) -> Option<f64> {
    twin.iter()
        .map(|&(c, ttc)| ((c - centre).norm(), ttc))
        .filter(|&(d, _)| d <= ASSOCIATION_M)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, ttc)| ttc)
}

/// Per-pair TTC errors and the critical events of one tick.
fn compare_pairs(r: &mut RiskAcc, pairs: &Pairs, tick_ns: i64) {
    for (other, centre, ttc) in &pairs.truth {
        let twin_ttc = twin_ttc_near(&pairs.twin, *centre).filter(|t| t.is_finite());
        if *ttc < TTC_COMPARED_S {
            match twin_ttc {
                Some(t) => r.ttc.add((t - ttc).abs()),
                None => r.ttc_unseen += 1,
            }
        }
        if *ttc < CRITICAL_TTC_S {
            let event = r.open.entry(other.clone()).or_insert_with(|| {
                r.events += 1;
                OpenEvent { start_ns: tick_ns, seen: false }
            });
            if !event.seen && twin_ttc.is_some_and(|t| t < CRITICAL_TTC_S) {
                event.seen = true;
                r.seen += 1;
                r.lag.add((tick_ns - event.start_ns) as f64 * 1e-9);
            }
        }
    }
    // Events whose pair is no longer critical (or gone) close; unseen, they were missed.
    let open = std::mem::take(&mut r.open);
    for (other, event) in open {
        let still = pairs.truth.iter().any(|(o, _, ttc)| *o == other && *ttc < CRITICAL_TTC_S);
        if still {
            r.open.insert(other, event);
        } else if !event.seen {
            r.missed_closed += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(truth: &[(u32, f64, f64)], twin: &[(f64, f64)]) -> Pairs {
        Pairs {
            truth: truth.iter().map(|&(id, x, ttc)| (Other::Object(id), Vec2::new(x, 0.0), ttc)).collect(),
            twin: twin.iter().map(|&(x, ttc)| (Vec2::new(x, 0.0), ttc)).collect(),
        }
    }

    #[test]
    fn a_critical_event_is_seen_with_its_lag_or_missed() {
        let mut r = RiskAcc::new();
        // Truth critical from 0 ns; the twin sees the object close in from 200 ms.
        compare_pairs(&mut r, &pairs(&[(1, 20.0, 1.8)], &[(20.5, 3.0)]), 0);
        compare_pairs(&mut r, &pairs(&[(1, 19.0, 1.6)], &[(19.2, 2.2)]), 100_000_000);
        compare_pairs(&mut r, &pairs(&[(1, 18.0, 1.4)], &[(18.1, 1.9)]), 200_000_000);
        // Object 2: critical, the twin has nothing there (the nearest is 5 m off), then it ends.
        compare_pairs(&mut r, &pairs(&[(1, 17.0, 1.2), (2, 40.0, 1.5)], &[(17.0, 1.3), (45.0, 1.5)]), 300_000_000);
        compare_pairs(&mut r, &pairs(&[(1, 16.0, 1.0), (2, 40.0, 5.0)], &[(16.0, 1.1)]), 400_000_000);
        let s = r.summary();
        assert_eq!((s.critical_events.truth, s.critical_events.seen, s.critical_events.missed), (2, 1, 1));
        assert!((s.critical_events.lag_s.max - 0.2).abs() < 1e-12);
        // Compared TTCs: ticks 0–300 ms for object 1 (|Δ| 1.2, 0.6, 0.5, 0.1) and tick 400 (0.1);
        // object 2 unseen at 300 ms and at 400 ms (TTC 5 s < 10 s, no twin object near).
        assert_eq!(s.ttc_abs_error_s.n, 5);
        assert_eq!(s.ttc_pairs_unseen, 2);
        assert!((s.ttc_abs_error_s.max - 1.2).abs() < 1e-9);
    }

    #[test]
    fn a_twin_already_critical_sees_the_event_at_once_and_an_open_unseen_one_counts_missed() {
        let mut r = RiskAcc::new();
        compare_pairs(&mut r, &pairs(&[(1, 20.0, 1.9), (2, 60.0, 1.0)], &[(20.0, 1.5)]), 0);
        let s = r.summary();
        assert_eq!((s.critical_events.truth, s.critical_events.seen, s.critical_events.missed), (2, 1, 1));
        assert_eq!(s.critical_events.lag_s.max, 0.0);
    }
}
