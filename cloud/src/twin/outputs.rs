//! What the twin and risk roles produce per tick, transport-free: after each tick the site's
//! vehicles as scene boxes and — with the risk role, at most once per `RiskConfig::period_ns` of
//! twin time per site (2 Hz by default) — the risk assessment of every vehicle of the site.
//!
//! The cloud's network side ([`crate::network`]) only keys, records and publishes what
//! [`TwinOutputs::after_tick`] returns.

use super::Twin;
use super::fidelity::{Fidelity, PositionError};
use super::risk::{RiskAssessment, RiskAssessor};
use risktwin_common::geometry::Vec2;
use risktwin_common::risk::FieldError;
use risktwin_common::road::Road;
use risktwin_common::telemetry::{Frame, Header, VehicleStateSample};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

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
    /// Per `site/source` of a scene: the twin's position error against the ground truth.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub fidelity: BTreeMap<String, PositionError>,
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
    /// `(site, assessment)`, in site order.
    pub assessments: &'a [(String, RiskAssessment)],
}

/// The twin, the optional risk assessor and the summary of what they produced.
pub struct TwinOutputs {
    twin: Twin,
    risk: Option<RiskAssessor>,
    /// Assessors on the road maps sites published; a site without one uses `risk`.
    site_risk: HashMap<String, RiskAssessor>,
    fidelity: Fidelity,
    last_risk_tick: HashMap<String, i64>,
    summary: TwinSummary,
    scenes: Vec<SiteScene>,
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
            last_risk_tick: HashMap::new(),
            summary: TwinSummary::default(),
            scenes: Vec::new(),
            assessments: Vec::new(),
        }
    }

    pub fn twin_mut(&mut self) -> &mut Twin {
        &mut self.twin
    }

    pub fn twin(&self) -> &Twin {
        &self.twin
    }

    /// The summary so far.
    pub fn summary(&self) -> TwinSummary {
        let mut s = self.summary.clone();
        s.ticks = self.twin.ticks();
        s.fidelity = self.fidelity.summary();
        s
    }

    /// A scene's true position of `source` at `site` at `time_ns` (its authority's clock).
    pub fn observe_truth(&mut self, site: &str, source: &str, time_ns: i64, position: Vec2) {
        self.fidelity.observe_truth(site, source, time_ns, position);
    }

    /// Assesses `site`'s risk on `road` from now on (the road map its scene published).
    /// Without the risk role there is nothing to do.
    pub fn set_site_road(&mut self, site: &str, road: Road) -> Result<(), FieldError> {
        let Some(default) = self.risk.as_ref() else { return Ok(()) };
        let lanes = road.lanes.len();
        self.site_risk.insert(site.to_owned(), RiskAssessor::new(road, *default.config())?);
        self.summary.site_roads.insert(site.to_owned(), lanes);
        tracing::info!("risk: site {site} on its scene's road map ({lanes} lanes)");
        Ok(())
    }

    /// After one or more snapshots were applied: the scene of every site that `publishable`
    /// accepts (the network side can only key valid site ids) and, when due, its risk.
    /// `None` before the first tick.
    pub fn after_tick(&mut self, publishable: impl Fn(&str) -> bool) -> Option<TickOutputs<'_>> {
        let tick_ns = self.twin.tick_ns()?;
        self.scenes.clear();
        self.assessments.clear();
        for (site, twin) in self.twin.sites() {
            self.summary.vehicles.insert(site.to_owned(), twin.vehicles.len());
            self.fidelity.compare(site, tick_ns, twin);
            if !publishable(site) {
                continue;
            }
            let boxes = twin.vehicles.iter().map(|v| VehicleStateSample {
                header: Header {
                    source: v.source.to_string(),
                    seq: 0,
                    capture_time_ns: tick_ns,
                    publish_time_ns: tick_ns,
                    frame: Frame::World,
                },
                pose: v.kinematics.pose,
                velocity: v.kinematics.velocity,
                speed_mps: v.kinematics.speed_mps,
                accel_mps2: v.kinematics.accel_mps2,
                yaw_rate_radps: 0.0,
                steer_rad: 0.0,
                footprint: v.kinematics.footprint,
            });
            self.scenes.push(SiteScene { site: site.to_owned(), boxes: boxes.collect() });
            self.summary.scenes += 1;

            let Some(risk) = self.site_risk.get_mut(site).or(self.risk.as_mut()) else { continue };
            let due = self.last_risk_tick.get(site).is_none_or(|last| tick_ns - last >= risk.config().period_ns);
            if !due || twin.vehicles.is_empty() {
                continue;
            }
            self.last_risk_tick.insert(site.to_owned(), tick_ns);
            for ego in 0..twin.vehicles.len() {
                if let Some(a) = risk.assess(twin, ego, tick_ns) {
                    let max = a.field.grid.cells.iter().copied().fold(0.0f32, f32::max);
                    self.summary.max_risk = self.summary.max_risk.max(f64::from(max));
                    self.summary.risk_assessments += 1;
                    self.assessments.push((site.to_owned(), a));
                }
            }
        }
        Some(TickOutputs { tick_ns, scenes: &self.scenes, assessments: &self.assessments })
    }
}
