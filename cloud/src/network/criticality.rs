//! The `criticality` role: collects the road map and the obstacle states of a site from the live
//! stream (a `risktwin import commonroad` recording republished by `risktwin edge replay`), and
//! when the stream ends (the cloud's shutdown) rebuilds the scenario with the offline path's
//! [`ScenarioCollector`] and writes its criticality with the offline report writer — so the
//! file equals `risktwin criticality` on the same scenario.
//!
//! With a library (`--db`), every site's rebuilt scenario becomes a recorded case of it, as
//! `risktwin import commonroad --db` stores a file: the scenario as CommonRoad XML (written
//! from what travelled, [`to_xml`]), its ego, and the recorded ego replayed as its reference
//! outcome (S_risk terms, collision, completion), so a drive the fleet replayed ranks beside
//! the library's other cases and `simulate --db F --id ID` runs it.
//!
//! Every message is decoded as the ingest decodes it; one that fails is counted by reason and
//! dropped. Messages are collected per site; the report needs exactly one site with a map
//! (`--site` picks one when several are on the network).

use crate::criticality::{Pushed, RebuildError, ReportFormat, ScenarioCollector, write_report};
use risktwin_common::world::STEP_S;
use risktwin_commonroad::criticality::{CriticalityError, scenario_criticality};
use risktwin_commonroad::twin::{EgoMode, TwinScene, resimulate};
use risktwin_commonroad::{Scenario, to_xml};
use risktwin_protos::check_encoding;
use risktwin_store::library::{LibraryError, Outcome, REPLAY_POLICY, RecordedCase, ScenarioLibrary};
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::zenoh::sample::Locality;
use risktwin_transport::{EdgeStream, SiteId, TransportError, keyexpr};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use thiserror::Error;

/// Where the role writes and for which ego.
#[derive(Debug, Clone, Default)]
pub struct CriticalityConfig {
    /// The report file, `.csv` or `.json` (the formats of `risktwin criticality`).
    pub out: Option<PathBuf>,
    /// The library the rebuilt scenarios are stored in as recorded cases.
    pub library: Option<PathBuf>,
    /// The ego obstacle; `None`: the scenario's first dynamic obstacle.
    pub ego: Option<u64>,
}

impl CriticalityConfig {
    /// The report format the file name asks for (`None` without a report file).
    pub fn format(&self) -> Result<Option<ReportFormat>, CriticalityRoleError> {
        let Some(out) = &self.out else { return Ok(None) };
        let format = ReportFormat::from_path(out);
        format.map(Some).ok_or_else(|| CriticalityRoleError::Format { path: out.display().to_string() })
    }
}

/// Why the role could not produce its report.
#[derive(Debug, Error)]
pub enum CriticalityRoleError {
    #[error("--criticality-out {path}: the file must end in .csv or .json")]
    Format { path: String },
    #[error("criticality: no road map arrived from any site (nothing to compute)")]
    NoSite,
    #[error("criticality: several sites sent a road map ({sites}); give --site")]
    SeveralSites { sites: String },
    #[error("criticality of site {site}: {source}")]
    Rebuild { site: String, source: RebuildError },
    #[error("criticality of site {site}: {source}")]
    Measures { site: String, source: CriticalityError },
    #[error("writing {path}: {source}")]
    Write { path: String, source: std::io::Error },
    #[error("no replayed drive could be stored as a library case ({failed})")]
    NoCase { failed: String },
    #[error("storing site {site} as a library case: {source}")]
    StoreCase { site: String, source: LibraryError },
}

/// What the role saw and wrote, in the cloud's JSON summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct CriticalitySummary {
    /// Road maps taken, all sites.
    pub maps: u64,
    /// Obstacle states taken, all sites.
    pub states: u64,
    /// Dropped messages per reason ([`crate::criticality::Rejected::reason`]).
    pub dropped: BTreeMap<String, u64>,
    /// The site the report is about.
    pub site: Option<String>,
    /// The ego the measures are relative to.
    pub ego_id: Option<u64>,
    /// Rows of the report (time step, other) and the file written.
    pub cells: u64,
    pub out: String,
    /// The recorded cases stored in the library (with `--db`), one per site.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub cases: Vec<FleetCase>,
    /// Sites whose drive could not be stored, and why.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub failed: Vec<FailedSite>,
}

/// A site whose replayed drive was not stored.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailedSite {
    pub site: String,
    pub reason: String,
}

/// A replayed drive stored as a recorded case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetCase {
    pub site: String,
    /// The case's content id in the library.
    pub id: String,
    /// False when the library held it already (the same drive replayed again).
    pub inserted: bool,
    pub benchmark_id: String,
    pub ego_id: u64,
    /// The recorded ego replayed: its collision and S_risk.
    pub collision: bool,
    pub risk_score: f64,
}

/// The collectors and counts; behind a mutex shared with the Zenoh callback.
#[derive(Default)]
pub(crate) struct CriticalityCollect {
    sites: BTreeMap<String, ScenarioCollector>,
    summary: CriticalitySummary,
    last_sample: Option<Instant>,
}

impl CriticalityCollect {
    /// Takes one message received on `key` with `encoding`; a rejected one is counted and
    /// dropped (a map or state tagged with another schema as `wrong-schema`).
    pub(crate) fn handle(&mut self, key: &str, encoding: &str, payload: &[u8]) {
        self.last_sample = Some(Instant::now());
        let message = match (keyexpr::parse_edge_map_key(key), keyexpr::parse_edge_key(key)) {
            (Some(_), _) => Some(keyexpr::EDGE_MAP_MESSAGE),
            (None, Some(parsed)) if parsed.stream == EdgeStream::State => Some(parsed.stream.message()),
            _ => None,
        };
        if let Some(Err(e)) = message.map(|m| check_encoding(encoding, m)) {
            *self.summary.dropped.entry(e.reason().to_owned()).or_default() += 1;
            return;
        }
        // The site chunk follows the root; the collector checks the rest of the key.
        let Some(site) = key.strip_prefix(keyexpr::ROOT).and_then(|r| r.strip_prefix('/')?.split('/').next()) else {
            return;
        };
        let collector = match self.sites.get_mut(site) {
            Some(c) => c,
            None => self.sites.entry(site.to_owned()).or_default(),
        };
        match collector.push(key, payload) {
            Ok(Pushed::Map) => self.summary.maps += 1,
            Ok(Pushed::State) => self.summary.states += 1,
            Ok(Pushed::Skipped) => {}
            Err(rejected) => *self.summary.dropped.entry(rejected.reason.to_owned()).or_default() += 1,
        }
    }

    /// When the last message (taken or not) arrived.
    pub(crate) fn last_sample(&self) -> Option<Instant> {
        self.last_sample
    }

    /// Rebuilds the scenario of every site with a map; stores each in `library` (when the role
    /// has one: a site that cannot be rebuilt or replayed is listed in `failed`, the others are
    /// stored), and computes the criticality of the one site and writes the report (with a file).
    pub(crate) fn finish(
        self,
        config: &CriticalityConfig,
        library: Option<&mut ScenarioLibrary>,
    ) -> Result<CriticalitySummary, CriticalityRoleError> {
        let format = config.format()?;
        let mut summary = self.summary;
        let mut rebuilt: Vec<(String, Result<Scenario, RebuildError>)> =
            self.sites.into_iter().filter(|(_, c)| c.has_map()).map(|(site, c)| (site, c.finish())).collect();
        if rebuilt.is_empty() {
            return Err(CriticalityRoleError::NoSite);
        }
        let report = config.out.as_ref().zip(format);
        // Refused before anything is stored: the report is about one site.
        if report.is_some() && rebuilt.len() > 1 {
            let sites = rebuilt.iter().map(|(s, _)| s.as_str()).collect::<Vec<_>>().join(", ");
            return Err(CriticalityRoleError::SeveralSites { sites });
        }
        if let Some(library) = library {
            store_cases(library, &rebuilt, config.ego, &mut summary)?;
            if report.is_none() && summary.cases.is_empty() {
                let failed = summary.failed.iter().map(|f| format!("{}: {}", f.site, f.reason)).collect::<Vec<_>>();
                return Err(CriticalityRoleError::NoCase { failed: failed.join("; ") });
            }
        }
        let Some((out, format)) = report else { return Ok(summary) };
        let (site, scenario) = rebuilt.remove(0);
        let scenario = scenario.map_err(|source| CriticalityRoleError::Rebuild { site: site.clone(), source })?;
        let measures = scenario_criticality(&scenario, config.ego)
            .map_err(|source| CriticalityRoleError::Measures { site: site.clone(), source })?;
        let path = out.display().to_string();
        let write_error = |source| CriticalityRoleError::Write { path: path.clone(), source };
        let file = std::fs::File::create(out).map_err(write_error)?;
        write_report(std::io::BufWriter::new(file), format, &scenario.benchmark_id, &measures).map_err(write_error)?;
        summary.site = Some(site);
        summary.ego_id = Some(measures.ego_id);
        summary.cells = measures.cells.len() as u64;
        summary.out = path;
        Ok(summary)
    }
}

/// Stores every rebuilt scenario in `library` as a recorded case with its reference outcome (the
/// recorded ego replayed), as `risktwin import commonroad --db` stores a file; a site that was
/// not rebuilt, or whose ego cannot be replayed, goes to the summary's `failed`.
fn store_cases(
    library: &mut ScenarioLibrary,
    rebuilt: &[(String, Result<Scenario, RebuildError>)],
    ego: Option<u64>,
    summary: &mut CriticalitySummary,
) -> Result<(), CriticalityRoleError> {
    for (site, scenario) in rebuilt {
        let failed = |reason: String| FailedSite { site: site.clone(), reason };
        let scenario = match scenario {
            Ok(scenario) => scenario,
            Err(e) => {
                summary.failed.push(failed(e.to_string()));
                continue;
            }
        };
        let replayed = TwinScene::new(scenario, ego)
            .and_then(|scene| Ok((scene.ego.id, resimulate(scenario, Some(scene.ego.id), EgoMode::Replay, STEP_S)?)));
        let (ego_id, run) = match replayed {
            Ok(replayed) => replayed,
            Err(e) => {
                summary.failed.push(failed(e.to_string()));
                continue;
            }
        };
        let case = RecordedCase {
            source_name: format!("fleet site {site}"),
            benchmark_id: scenario.benchmark_id.clone(),
            ego_id,
            xml: to_xml(scenario),
        };
        let outcome = Outcome { policy: REPLAY_POLICY.to_owned(), metrics: run.metrics.clone(), risk: run.risk };
        let stored = library
            .insert_recorded(&case, &outcome)
            .map_err(|source| CriticalityRoleError::StoreCase { site: site.clone(), source })?;
        tracing::info!("criticality: site {site} stored as recorded case {} ({})", stored.id, case.benchmark_id);
        summary.cases.push(FleetCase {
            site: site.clone(),
            id: stored.id,
            inserted: stored.inserted,
            benchmark_id: case.benchmark_id,
            ego_id,
            collision: run.metrics.collision,
            risk_score: run.risk.score,
        });
    }
    Ok(())
}

/// Subscribes the role to every key of the shape `risktwin/v1/<site|*>/*/*` (edge streams and
/// road maps; the collector skips the rest).
pub(crate) async fn subscribe(
    session: &Session,
    site: Option<&SiteId>,
    collect: Arc<Mutex<CriticalityCollect>>,
) -> Result<Subscriber<()>, TransportError> {
    let key = keyexpr::edge_streams_all(site);
    session
        .declare_subscriber(key.clone())
        .allowed_origin(Locality::Remote)
        .callback(move |sample| {
            let payload = sample.payload().to_bytes();
            let encoding = sample.encoding().to_string();
            let mut collect = collect.locked();
            collect.handle(sample.key_expr().as_str(), &encoding, &payload);
        })
        .await
        .map_err(|e| TransportError::Declare { what: "criticality subscriber", key, reason: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::criticality::tests::{messages, two_cars};
    use risktwin_common::telemetry::VehicleStateSample;
    use risktwin_protos::WireMessage;
    use risktwin_transport::protobuf;

    /// A collector that took the two-car scenario's messages at site `two`, and at site `gap`
    /// the same but for one state of car 2 (a stream with a state lost).
    fn collected() -> CriticalityCollect {
        let mut collect = CriticalityCollect::default();
        let mut car_2_states = 0;
        for (key, payload) in messages(&two_cars()) {
            let message =
                if key.ends_with("/map") { keyexpr::EDGE_MAP_MESSAGE } else { VehicleStateSample::PROTO_NAME };
            let encoding = protobuf(message).to_string();
            collect.handle(&key, &encoding, &payload);
            if key.ends_with("/dyn-2/state") {
                car_2_states += 1;
                if car_2_states == 10 {
                    continue;
                }
            }
            collect.handle(&key.replacen("/two/", "/gap/", 1), &encoding, &payload);
        }
        collect
    }

    fn library(dir: &tempfile::TempDir) -> ScenarioLibrary {
        ScenarioLibrary::open(dir.path().join("lib.db")).expect("a library")
    }

    #[test]
    fn a_site_that_cannot_be_stored_is_listed_and_the_others_are_stored() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let mut library = library(&dir);
        let config = CriticalityConfig { library: Some(dir.path().join("lib.db")), ..CriticalityConfig::default() };
        let summary = collected().finish(&config, Some(&mut library)).expect("one site is stored");
        let stored: Vec<(&str, u64, bool)> =
            summary.cases.iter().map(|c| (c.site.as_str(), c.ego_id, c.inserted)).collect();
        assert_eq!(stored, [("two", 1, true)], "{summary:?}");
        assert_eq!(summary.failed.len(), 1, "{summary:?}");
        assert_eq!(summary.failed[0].site, "gap");
        assert!(summary.failed[0].reason.contains("obstacle id 2"), "{summary:?}");
        let case = library.recorded(&summary.cases[0].id).expect("reads").expect("the case is stored");
        assert_eq!(case.case.xml, to_xml(&two_cars_as_rebuilt(&case.case.xml)), "the XML as written");
        assert_eq!(case.outcomes.len(), 1);
        assert_eq!(case.outcomes[0].policy, REPLAY_POLICY);
    }

    /// The scenario a stored case's XML reads back as.
    fn two_cars_as_rebuilt(xml: &str) -> Scenario {
        risktwin_commonroad::parse_scenario(xml).expect("the stored XML parses")
    }

    #[test]
    fn with_no_site_stored_and_no_report_the_run_fails_naming_each_site() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let mut library = library(&dir);
        let config = CriticalityConfig { ego: Some(99), ..CriticalityConfig::default() };
        match collected().finish(&config, Some(&mut library)) {
            Err(CriticalityRoleError::NoCase { failed }) => {
                assert!(failed.contains("gap: ") && failed.contains("two: "), "{failed}");
            }
            other => panic!("expected NoCase, got {other:?}"),
        }
        // With a report file the several sites are refused before anything is stored.
        let out = Some(dir.path().join("crit.csv"));
        let config = CriticalityConfig { out, ..CriticalityConfig::default() };
        assert!(matches!(
            collected().finish(&config, Some(&mut library)),
            Err(CriticalityRoleError::SeveralSites { .. })
        ));
        assert!(library.rank_recorded(REPLAY_POLICY, None).expect("ranks").is_empty(), "nothing stored");
    }
}
