//! The twin and risk roles on the live path: the [`Twin`] follows every ingest snapshot; after
//! each tick the site's vehicles go out as `foxglove.SceneUpdate` boxes, and — with the risk role,
//! at most once per `RiskConfig::period_ns` of twin time per site (2 Hz by default) — the risk
//! field around every vehicle of the site as `foxglove.Grid` plus a `risktwin.v1.RiskReport`.
//!
//! Outputs are recorded (when recording) right here on the receive path, and handed to a
//! publisher task through a channel: publishing from inside a Zenoh callback could block it.

use crate::twin::Twin;
use crate::twin::risk::{RiskAssessment, RiskAssessor};
use risktwin_common::telemetry::{Frame, Header, RiskReport, VehicleStateSample};
use risktwin_protos::convert::foxglove::{FOXGLOVE_GRID, FOXGLOVE_SCENE_UPDATE, risk_grid, vehicle_boxes};
use risktwin_protos::recording::{Recorder, RecordingError};
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::SiteId;
use risktwin_transport::keyexpr::{CloudOutput, cloud_output};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::io::{Seek, Write};
use tokio::sync::mpsc::UnboundedSender;

/// One message for the publisher task.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Publication {
    pub(crate) key: String,
    pub(crate) payload: Vec<u8>,
}

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
}

/// The twin, the optional risk assessor and where their outputs go.
pub(crate) struct TwinOutputs {
    twin: Twin,
    risk: Option<RiskAssessor>,
    last_risk_tick: HashMap<String, i64>,
    publish: Option<UnboundedSender<Publication>>,
    summary: TwinSummary,
    boxes: Vec<VehicleStateSample>,
    assessments: Vec<(String, RiskAssessment)>,
}

impl TwinOutputs {
    /// The twin role, with the risk role when `risk` is given; outputs are published through
    /// `publish` when given.
    pub(crate) fn new(risk: Option<RiskAssessor>, publish: Option<UnboundedSender<Publication>>) -> Self {
        TwinOutputs {
            twin: Twin::new(),
            risk,
            last_risk_tick: HashMap::new(),
            publish,
            summary: TwinSummary::default(),
            boxes: Vec::new(),
            assessments: Vec::new(),
        }
    }

    pub(crate) fn twin_mut(&mut self) -> &mut Twin {
        &mut self.twin
    }

    pub(crate) fn twin(&self) -> &Twin {
        &self.twin
    }

    /// Stops publishing (the publisher task ends once the channel is empty).
    pub(crate) fn close_publisher(&mut self) {
        self.publish = None;
    }

    /// The summary so far.
    pub(crate) fn summary(&self) -> TwinSummary {
        let mut s = self.summary.clone();
        s.ticks = self.twin.ticks();
        s
    }

    /// After one or more snapshots were applied at cloud time `now_ns`: scene and (when due)
    /// risk of every site, recorded and published.
    pub(crate) fn after_tick<W: Write + Seek>(
        &mut self,
        now_ns: i64,
        mut recorder: Option<&mut Recorder<W>>,
    ) -> Result<(), RecordingError> {
        let Some(tick_ns) = self.twin.tick_ns() else { return Ok(()) };
        let log_ns = now_ns.max(0) as u64;
        self.assessments.clear();
        for (site, twin) in self.twin.sites() {
            self.summary.vehicles.insert(site.to_owned(), twin.vehicles.len());
            let Ok(site_id) = SiteId::new(site) else { continue };
            self.boxes.clear();
            self.boxes.extend(twin.vehicles.iter().map(|v| VehicleStateSample {
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
            }));
            let scene_key = cloud_output(&site_id, CloudOutput::Scene);
            if let Some(rec) = recorder.as_deref_mut() {
                rec.record_scene(&scene_key, log_ns, &self.boxes)?;
            }
            if let Some(tx) = &self.publish {
                let update = vehicle_boxes(tick_ns, &self.boxes);
                // A closed channel means shutdown: nothing left to publish to.
                let _ = tx.send(Publication { key: scene_key, payload: prost::Message::encode_to_vec(&update) });
            }
            self.summary.scenes += 1;

            let Some(risk) = self.risk.as_mut() else { continue };
            let due = self.last_risk_tick.get(site).is_none_or(|last| tick_ns - last >= risk.config().period_ns);
            if !due || twin.vehicles.is_empty() {
                continue;
            }
            self.last_risk_tick.insert(site.to_owned(), tick_ns);
            for ego in 0..twin.vehicles.len() {
                if let Some(a) = risk.assess(twin, ego, tick_ns) {
                    self.assessments.push((site.to_owned(), a));
                }
            }
        }
        for (site, a) in &self.assessments {
            let Ok(site_id) = SiteId::new(site.as_str()) else { continue };
            let field_key = cloud_output(&site_id, CloudOutput::RiskField);
            let report_key = cloud_output(&site_id, CloudOutput::RiskReport);
            let max = a.field.grid.cells.iter().copied().fold(0.0f32, f32::max);
            self.summary.max_risk = self.summary.max_risk.max(f64::from(max));
            if let Some(rec) = recorder.as_deref_mut() {
                rec.record_risk_grid(&field_key, log_ns, &a.field)?;
                let channel = rec.channel(&report_key, RiskReport::PROTO_NAME)?;
                rec.write(channel, log_ns, log_ns, &encode(&a.report))?;
            }
            if let Some(tx) = &self.publish {
                let grid = prost::Message::encode_to_vec(&risk_grid(&a.field));
                let _ = tx.send(Publication { key: field_key, payload: grid });
                let _ = tx.send(Publication { key: report_key, payload: encode(&a.report) });
            }
            self.summary.risk_assessments += 1;
        }
        Ok(())
    }
}

/// Schema names of the cloud outputs, as recorded (for readers of a recording).
pub const OUTPUT_SCHEMAS: [(CloudOutput, &str); 3] = [
    (CloudOutput::RiskField, FOXGLOVE_GRID),
    (CloudOutput::RiskReport, "risktwin.v1.RiskReport"),
    (CloudOutput::Scene, FOXGLOVE_SCENE_UPDATE),
];
