//! `recording.mcap` of a run: the library's top scenario driven by the trained `full` policy
//! (first seed), recorded with the same topics as `simulate --record` and the pipeline, so it
//! opens in Foxglove next to a distributed recording.

use crate::error::RunError;
use risktwin_cloud::episode_recording::EpisodeRecorder;
use risktwin_cloud::trainer::drive::drive;
use risktwin_common::env::Variant;
use risktwin_common::scenario::build;
use risktwin_learn::PolicyNet;
use risktwin_store::library::{RankedScenario, ScenarioLibrary};
use std::path::Path;

/// File name of the recording in the report folder.
pub const FILE: &str = "recording.mcap";

/// Records `top[0]` driven by the `full` policy (else the first policy trained); `Ok(None)` when
/// there is no scenario or no policy to record.
pub fn record_top(
    library: &ScenarioLibrary,
    top: &[RankedScenario],
    policies: &[(Variant, PolicyNet)],
    out: &Path,
) -> Result<Option<String>, RunError> {
    let policy = policies.iter().find(|(v, _)| *v == Variant::Full).or(policies.first());
    let (Some(first), Some((variant, policy))) = (top.first(), policy) else { return Ok(None) };
    let Some(stored) = library.get(&first.id)? else { return Ok(None) };
    let path = out.join(FILE);
    let file = std::fs::File::create(&path).map_err(|source| RunError::Create { path: path.clone(), source })?;
    let mut world = build(&stored.spec);
    let mut recorder = EpisodeRecorder::new(std::io::BufWriter::new(file), &world)?;
    recorder.record(&world)?;
    let mut failed = None;
    drive(policy, &mut world, &mut |w, _| {
        if failed.is_none() {
            failed = recorder.record(w).err();
        }
    });
    if let Some(e) = failed {
        return Err(e.into());
    }
    recorder.finish()?;
    Ok(Some(format!("{FILE}: scenario {} ({}) driven by the {variant} policy", first.id, first.kind)))
}
