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
use crate::library::{LibraryError, Outcome, REPLAY_POLICY, RecordedCase, ScenarioLibrary};
use risktwin_common::commonroad::criticality::{CriticalityError, scenario_criticality};
use risktwin_common::commonroad::twin::{EgoMode, TwinError, TwinScene, resimulate};
use risktwin_common::commonroad::{Scenario, to_xml};
use risktwin_common::world::STEP_S;
use risktwin_protos::check_encoding;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Subscriber;
use risktwin_transport::zenoh::sample::Locality;
use risktwin_transport::{EdgeStream, SiteId, TransportError, keyexpr};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
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
    #[error("site {site} as a library case: {source}")]
    Case { site: String, source: TwinError },
    #[error("storing site {site} as a library case: {source}")]
    Library { site: String, source: LibraryError },
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

    /// Rebuilds the scenario of every site with a map; stores each in the library (with one),
    /// and computes the criticality of the one site and writes the report (with a file).
    pub(crate) fn finish(self, config: &CriticalityConfig) -> Result<CriticalitySummary, CriticalityRoleError> {
        let format = config.format()?;
        let mut summary = self.summary;
        let mut rebuilt = Vec::new();
        for (site, collector) in self.sites.into_iter().filter(|(_, c)| c.has_map()) {
            let scenario =
                collector.finish().map_err(|source| CriticalityRoleError::Rebuild { site: site.clone(), source })?;
            rebuilt.push((site, scenario));
        }
        if rebuilt.is_empty() {
            return Err(CriticalityRoleError::NoSite);
        }
        if let Some(db) = &config.library {
            summary.cases = store_cases(db, &rebuilt, config.ego)?;
        }
        let (Some(out), Some(format)) = (&config.out, format) else { return Ok(summary) };
        if rebuilt.len() > 1 {
            let sites = rebuilt.iter().map(|(s, _)| s.as_str()).collect::<Vec<_>>().join(", ");
            return Err(CriticalityRoleError::SeveralSites { sites });
        }
        let (site, scenario) = rebuilt.remove(0);
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

/// Stores every rebuilt scenario in the library at `db` as a recorded case with its reference
/// outcome (the recorded ego replayed), as `risktwin import commonroad --db` stores a file.
fn store_cases(
    db: &Path,
    rebuilt: &[(String, Scenario)],
    ego: Option<u64>,
) -> Result<Vec<FleetCase>, CriticalityRoleError> {
    let open_error = |site: &str, source| CriticalityRoleError::Library { site: site.to_owned(), source };
    let first_site = rebuilt.first().map_or("", |(site, _)| site.as_str());
    let mut library = ScenarioLibrary::open(db).map_err(|e| open_error(first_site, e))?;
    let mut cases = Vec::new();
    for (site, scenario) in rebuilt {
        let case_error = |source| CriticalityRoleError::Case { site: site.clone(), source };
        let ego_id = TwinScene::new(scenario, ego).map_err(case_error)?.ego.id;
        let run = resimulate(scenario, Some(ego_id), EgoMode::Replay, STEP_S).map_err(case_error)?;
        let case = RecordedCase {
            source_name: format!("fleet site {site}"),
            benchmark_id: scenario.benchmark_id.clone(),
            ego_id,
            xml: to_xml(scenario),
        };
        let outcome = Outcome { policy: REPLAY_POLICY.to_owned(), metrics: run.metrics.clone(), risk: run.risk };
        let stored = library.insert_recorded(&case, &outcome).map_err(|e| open_error(site, e))?;
        tracing::info!("criticality: site {site} stored as recorded case {} ({})", stored.id, case.benchmark_id);
        cases.push(FleetCase {
            site: site.clone(),
            id: stored.id,
            inserted: stored.inserted,
            benchmark_id: case.benchmark_id,
            ego_id,
            collision: run.metrics.collision,
            risk_score: run.risk.score,
        });
    }
    Ok(cases)
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
            let mut collect = collect.lock().unwrap_or_else(PoisonError::into_inner);
            collect.handle(sample.key_expr().as_str(), &encoding, &payload);
        })
        .await
        .map_err(|e| TransportError::Declare { what: "criticality subscriber", key, reason: e.to_string() })
}
