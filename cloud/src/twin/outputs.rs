//! What the twin and risk roles produce per tick, transport-free: after each tick the site's
//! vehicles as scene boxes and — with the risk role, at most once per `RiskConfig::period_ns` of
//! twin time per site (2 Hz by default) — the risk assessment of every vehicle of the site.
//!
//! The cloud's network side ([`crate::network`]) only keys, records and publishes what
//! [`TwinOutputs::after_tick`] returns.

use super::fidelity::{Fidelity, SeriesPoint, VehicleFidelity};
use super::risk::{RiskAssessment, RiskAssessor, RiskConfig};
use super::watch::EpisodeWatch;
use super::{SiteTwin, Twin};
use risktwin_align::Snapshot;
use risktwin_common::telemetry::{Frame, Header, ObjectList, ScenarioResult, VehicleStateSample};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

/// What the twin and risk roles did, for the cloud's summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct TwinSummary {
    /// Snapshots applied to the twin.
    pub ticks: u64,
    /// Scene updates produced (one per site per tick).
    pub scenes: u64,
    /// Risk assessments produced (one field and one report each).
    pub risk_assessments: u64,
    /// Vehicles per site at the last tick.
    pub vehicles: BTreeMap<String, usize>,
    /// Highest risk-field cell of any assessment.
    pub max_risk: f64,
    /// Sites whose risk runs on the road map their scene published (lanes of the map), instead
    /// of the default road.
    pub site_roads: BTreeMap<String, usize>,
    /// Per `site/source` of a scene: the twin against the ground truth (`twin::fidelity`).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub fidelity: BTreeMap<String, VehicleFidelity>,
    /// The fidelity series per `site/source`, for a report's plot (not in the JSON summary).
    #[serde(skip)]
    pub fidelity_series: BTreeMap<String, Vec<SeriesPoint>>,
}

/// The vehicles of one site at a tick, as boxes for a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SiteScene {
    pub site: String,
    /// One sample per vehicle, stamped with the tick, in the world frame.
    pub boxes: Vec<VehicleStateSample>,
}

/// Everything one tick produced: every site's scene, then the risk assessments that were due.
#[derive(Debug, Clone, Copy)]
pub struct TickOutputs<'a> {
    /// The twin's tick, ns.
    pub tick_ns: i64,
    pub scenes: &'a [SiteScene],
    /// The ground truth at the tick of every site with a scene, its objects included (recorded
    /// beside the twin's scene).
    pub truth_scenes: &'a [SiteScene],
    /// `(site, assessment)`, in site order.
    pub assessments: &'a [(String, RiskAssessment)],
}

/// The twin's running counts, for the live metrics (`crate::network`).
#[derive(Debug, Clone, Default)]
pub struct TwinCounts {
    pub ticks: u64,
    pub scenes: u64,
    pub risk_assessments: u64,
    /// Vehicles per site at the last tick.
    pub vehicles: BTreeMap<String, usize>,
    /// Per site, the highest risk-field cell of its latest assessment.
    pub latest_max_risk: BTreeMap<String, f64>,
}

/// The twin, the optional risk assessor and the summary of what they produced.
pub struct TwinOutputs {
    twin: Twin,
    risk: Option<RiskAssessor>,
    /// Assessors on the road maps sites published; a site without one uses `risk`.
    site_risk: HashMap<String, RiskAssessor>,
    fidelity: Fidelity,
    /// The pushed episodes being watched (the loop role's).
    watch: EpisodeWatch,
    last_risk_tick: HashMap<String, i64>,
    /// Per site, the highest risk-field cell of its latest assessment.
    latest_max_risk: BTreeMap<String, f64>,
    summary: TwinSummary,
    scenes: Vec<SiteScene>,
    truth_scenes: Vec<SiteScene>,
    assessments: Vec<(String, RiskAssessment)>,
}

impl TwinOutputs {
    /// The twin role, with the risk role when `risk` is given.
    pub fn new(risk: Option<RiskAssessor>) -> Self {
        TwinOutputs {
            twin: Twin::new(),
            risk,
            site_risk: HashMap::new(),
            fidelity: Fidelity::default(),
            watch: EpisodeWatch::default(),
            last_risk_tick: HashMap::new(),
            latest_max_risk: BTreeMap::new(),
            summary: TwinSummary::default(),
            scenes: Vec::new(),
            truth_scenes: Vec::new(),
            assessments: Vec::new(),
        }
    }

    pub fn twin_mut(&mut self) -> &mut Twin {
        &mut self.twin
    }

    pub fn twin(&self) -> &Twin {
        &self.twin
    }

    /// Applies one ingest snapshot to the twin; the watched episodes see the tick.
    pub fn apply(&mut self, snapshot: &Snapshot<crate::ingest::TwinSample>) {
        self.twin.update(snapshot);
        self.watch.observe(&self.twin);
    }

    pub fn watch(&self) -> &EpisodeWatch {
        &self.watch
    }

    pub fn watch_mut(&mut self) -> &mut EpisodeWatch {
        &mut self.watch
    }

    /// An edge's result of a pushed episode, placed against the twin's latest tick.
    pub fn episode_result(&mut self, site: &str, edge: &str, result: ScenarioResult, received: Instant) {
        self.watch.result(site, edge, result, self.twin.tick_ns(), received);
    }

    /// The summary so far.
    pub fn summary(&self) -> TwinSummary {
        let mut s = self.summary.clone();
        s.ticks = self.twin.ticks();
        s.fidelity = self.fidelity.summary();
        s.fidelity_series = self.fidelity.series();
        s
    }

    /// The running counts (a map per site; the fidelity series are not copied).
    pub fn counts(&self) -> TwinCounts {
        TwinCounts {
            ticks: self.twin.ticks(),
            scenes: self.summary.scenes,
            risk_assessments: self.summary.risk_assessments,
            vehicles: self.summary.vehicles.clone(),
            latest_max_risk: self.latest_max_risk.clone(),
        }
    }

    /// A scene's true state of connected vehicle `source` at `site` (its authority's clock).
    pub fn observe_truth_vehicle(&mut self, site: &str, source: &str, sample: &VehicleStateSample) {
        self.fidelity.observe_vehicle(site, source, sample);
    }

    /// A scene's true state of every other object at `site`.
    pub fn observe_truth_objects(&mut self, site: &str, list: ObjectList) {
        self.fidelity.observe_objects(site, list);
    }

    /// How the risk role evaluates; `None` without it.
    pub fn risk_config(&self) -> Option<RiskConfig> {
        self.risk.as_ref().map(|r| *r.config())
    }

    /// Assesses `site`'s risk with `assessor` from now on (built on the road map its scene
    /// published, with [`Self::risk_config`]).
    pub fn set_site_risk(&mut self, site: &str, assessor: RiskAssessor) {
        let lanes = assessor.road().lanes.len();
        self.site_risk.insert(site.to_owned(), assessor);
        self.summary.site_roads.insert(site.to_owned(), lanes);
        tracing::info!("risk: site {site} on its scene's road map ({lanes} lanes)");
    }

    /// After one or more snapshots were applied: the scene of every site that `publishable`
    /// accepts (the network side can only key valid site ids) and, when due, its risk.
    /// `None` before the first tick.
    pub fn after_tick(&mut self, publishable: impl Fn(&str) -> bool) -> Option<TickOutputs<'_>> {
        let tick_ns = self.twin.tick_ns()?;
        self.scenes.clear();
        self.truth_scenes.clear();
        self.assessments.clear();
        for (site, twin) in self.twin.sites() {
            self.summary.vehicles.insert(site.to_owned(), twin.vehicles.len());
            let assessor = self.site_risk.get_mut(site).or(self.risk.as_mut());
            let truth = self.fidelity.compare(site, tick_ns, twin, assessor);
            if !publishable(site) {
                continue;
            }
            if let Some(truth) = truth {
                self.truth_scenes.push(SiteScene { site: site.to_owned(), boxes: boxes(tick_ns, truth, true) });
            }
            self.scenes.push(SiteScene { site: site.to_owned(), boxes: boxes(tick_ns, twin, false) });
            self.summary.scenes += 1;

            let Some(risk) = self.site_risk.get_mut(site).or(self.risk.as_mut()) else { continue };
            let due = self.last_risk_tick.get(site).is_none_or(|last| tick_ns - last >= risk.config().period_ns);
            if !due || twin.vehicles.is_empty() {
                continue;
            }
            self.last_risk_tick.insert(site.to_owned(), tick_ns);
            let mut site_max = None::<f64>;
            for ego in 0..twin.vehicles.len() {
                if let Some(a) = risk.assess(twin, ego, tick_ns) {
                    let max = a.field.grid.cells.iter().copied().fold(0.0f32, f32::max);
                    site_max = Some(site_max.unwrap_or(0.0).max(f64::from(max)));
                    self.summary.risk_assessments += 1;
                    self.assessments.push((site.to_owned(), a));
                }
            }
            let Some(site_max) = site_max else { continue };
            self.summary.max_risk = self.summary.max_risk.max(site_max);
            match self.latest_max_risk.get_mut(site) {
                Some(latest) => *latest = site_max,
                None => {
                    self.latest_max_risk.insert(site.to_owned(), site_max);
                }
            }
        }
        Some(TickOutputs {
            tick_ns,
            scenes: &self.scenes,
            truth_scenes: &self.truth_scenes,
            assessments: &self.assessments,
        })
    }
}

/// The vehicles of `twin` (and its objects when `with_objects`) as boxes stamped `tick_ns`.
fn boxes(tick_ns: i64, twin: &SiteTwin, with_objects: bool) -> Vec<VehicleStateSample> {
    let header = |source: &str| Header {
        source: source.to_owned(),
        seq: 0,
        capture_time_ns: tick_ns,
        publish_time_ns: tick_ns,
        frame: Frame::World,
    };
    let vehicles = twin.vehicles.iter().map(|v| VehicleStateSample {
        header: header(&v.source),
        pose: v.kinematics.pose,
        velocity: v.kinematics.velocity,
        speed_mps: v.kinematics.speed_mps,
        accel_mps2: v.kinematics.accel_mps2,
        yaw_rate_radps: 0.0,
        steer_rad: 0.0,
        footprint: v.kinematics.footprint,
    });
    let objects = twin.objects.iter().filter(|_| with_objects).map(|o| {
        let object = &o.object;
        VehicleStateSample {
            header: header(&format!("#{}", object.id)),
            pose: object.pose,
            velocity: object.velocity,
            speed_mps: object.velocity.norm(),
            accel_mps2: object.accel_mps2,
            yaw_rate_radps: 0.0,
            steer_rad: 0.0,
            footprint: object.footprint,
        }
    });
    vehicles.chain(objects).collect()
}
