//! What one twin tick produced, recorded and handed to the publisher task under the cloud's
//! output keys.

use super::Publication;
use crate::twin::outputs::TickOutputs;
use risktwin_common::telemetry::RiskReport;
use risktwin_protos::convert::foxglove::{FOXGLOVE_GRID, FOXGLOVE_SCENE_UPDATE, risk_grid, vehicle_boxes};
use risktwin_protos::recording::{Recorder, RecordingError};
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::SiteId;
use risktwin_transport::keyexpr::{CloudOutput, SceneTopic, cloud_output, scene_topic};
use std::io::{Seek, Write};
use tokio::sync::mpsc::UnboundedSender;

/// Records (when recording) and publishes (when publishing) what one tick produced, under the
/// cloud's output keys; `now_ns` is the cloud time the tick was produced at (its log time).
pub(super) fn emit<W: Write + Seek>(
    tick: TickOutputs<'_>,
    now_ns: i64,
    mut recorder: Option<&mut Recorder<W>>,
    publish: Option<&UnboundedSender<Publication>>,
) -> Result<(), RecordingError> {
    let log_ns = now_ns.max(0) as u64;
    let key = |site: &str, output| SiteId::new(site).ok().map(|id| cloud_output(&id, output));
    for scene in tick.scenes {
        let Some(scene_key) = key(&scene.site, CloudOutput::Scene) else { continue };
        if let Some(rec) = recorder.as_deref_mut() {
            rec.record_scene(&scene_key, log_ns, &scene.boxes)?;
        }
        if let Some(tx) = publish {
            let update = vehicle_boxes(tick.tick_ns, &scene.boxes);
            // A closed channel means shutdown: nothing left to publish to.
            let payload = prost::Message::encode_to_vec(&update);
            let _ = tx.send(Publication { key: scene_key, message: FOXGLOVE_SCENE_UPDATE, log_ns, payload });
        }
    }
    for truth in tick.truth_scenes {
        let (Some(rec), Ok(site)) = (recorder.as_deref_mut(), SiteId::new(&truth.site)) else { continue };
        rec.record_scene(&scene_topic(Some(&site), SceneTopic::TruthBoxes), log_ns, &truth.boxes)?;
    }
    for (site, a) in tick.assessments {
        let (Some(field_key), Some(report_key)) =
            (key(site, CloudOutput::RiskField), key(site, CloudOutput::RiskReport))
        else {
            continue;
        };
        if let Some(rec) = recorder.as_deref_mut() {
            rec.record_risk_grid(&field_key, log_ns, &a.field)?;
            let channel = rec.channel(&report_key, RiskReport::PROTO_NAME)?;
            rec.write(channel, log_ns, log_ns, &encode(&a.report))?;
        }
        if let Some(tx) = publish {
            let grid = prost::Message::encode_to_vec(&risk_grid(&a.field));
            let _ = tx.send(Publication { key: field_key, message: FOXGLOVE_GRID, log_ns, payload: grid });
            let report = encode(&a.report);
            let _ = tx.send(Publication { key: report_key, message: RiskReport::PROTO_NAME, log_ns, payload: report });
        }
    }
    Ok(())
}
