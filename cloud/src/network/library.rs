//! The `library` role: a Zenoh queryable on `risktwin/v1/<site>/cloud/library/**` answering
//! `…/library/ranked?top=K;kind=KIND` with the K riskiest scenarios of the SQLite library
//! (latest outcome of the reference driver, highest risk first) as one encoded
//! `risktwin.v1.LibraryRanking`.
//!
//! Parameters: `top` (1–[`MAX_TOP`], default [`DEFAULT_TOP`]) and `kind` (a scenario kind or
//! `all`, the default). Any other parameter, a bad value or another path under `library/` is
//! answered with an error reply whose payload is the reason as UTF-8 text; the queryable keeps
//! serving.

use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};
use risktwin_protos::v1;
use risktwin_store::library::{RankedScenario, ScenarioLibrary};
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::handlers::FifoChannelHandler;
use risktwin_transport::zenoh::query::{Query, Queryable};
use risktwin_transport::{Shutdown, SiteId, TransportError, protobuf};
use serde::Serialize;
use thiserror::Error;

/// Scenarios in a reply unless `top` says otherwise.
pub const DEFAULT_TOP: usize = 10;
/// Most scenarios one reply may carry.
pub const MAX_TOP: usize = 1000;

/// Why a library query was refused (sent back as the error reply's text).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum LibraryQueryError {
    #[error("unknown query path {path:?}; the library answers .../library/ranked")]
    UnknownPath { path: String },
    #[error("unknown parameter {name:?}; known are top and kind")]
    UnknownParameter { name: String },
    #[error("top = {value:?} is not an integer in 1..={MAX_TOP}")]
    BadTop { value: String },
    #[error("kind = {value:?}: {reason}")]
    BadKind { value: String, reason: String },
    #[error("library: {reason}")]
    Library { reason: String },
}

/// A validated ranked-scenarios query.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RankedQuery {
    pub top: usize,
    pub kind: Option<ScenarioKind>,
}

impl RankedQuery {
    /// Parses the parameters of a query (name/value pairs as Zenoh split them).
    pub fn parse<'a>(params: impl IntoIterator<Item = (&'a str, &'a str)>) -> Result<Self, LibraryQueryError> {
        let mut query = RankedQuery { top: DEFAULT_TOP, kind: None };
        for (name, value) in params {
            match name {
                "top" => {
                    query.top = value
                        .parse::<usize>()
                        .ok()
                        .filter(|k| (1..=MAX_TOP).contains(k))
                        .ok_or_else(|| LibraryQueryError::BadTop { value: value.to_owned() })?;
                }
                "kind" if value == "all" => query.kind = None,
                "kind" => {
                    let kind = value
                        .parse::<ScenarioKind>()
                        .map_err(|e| LibraryQueryError::BadKind { value: value.to_owned(), reason: e.to_string() })?;
                    query.kind = Some(kind);
                }
                other => return Err(LibraryQueryError::UnknownParameter { name: other.to_owned() }),
            }
        }
        Ok(query)
    }
}

/// What the library role did, for the cloud's summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct LibrarySummary {
    /// Queries answered with a ranking.
    pub answered: u64,
    /// Queries refused, by reason.
    pub refused: u64,
}

/// The full name of the reply's message (its encoding's schema).
const LIBRARY_RANKING: &str = "risktwin.v1.LibraryRanking";

/// The ranking as its wire message.
pub fn ranking_message(ranked: &[RankedScenario]) -> Result<v1::LibraryRanking, LibraryQueryError> {
    let mut scenarios = Vec::with_capacity(ranked.len());
    for (i, r) in ranked.iter().enumerate() {
        let spec = ScenarioSpec::new(r.kind, r.seed, r.params.clone())
            .map_err(|e| LibraryQueryError::Library { reason: format!("stored scenario {}: {e}", r.id) })?;
        scenarios.push(v1::RankedScenario {
            rank: u32::try_from(i + 1).unwrap_or(u32::MAX),
            id: r.id.clone(),
            spec: Some((&spec).into()),
            risk: Some((&r.risk).into()),
            collision: r.outcome.collision,
            min_ttc_s: r.outcome.min_ttc_s,
            min_distance_m: r.outcome.min_distance_m,
        });
    }
    Ok(v1::LibraryRanking { scenarios })
}

/// Answers one query on `key` from `library`: the encoded ranking, or the reason for refusing
/// it. (One library serves every site it is asked for; the site only scopes the key.)
pub fn answer(library: &ScenarioLibrary, key: &str, params: &[(&str, &str)]) -> Result<Vec<u8>, LibraryQueryError> {
    if risktwin_transport::keyexpr::parse_library_ranked(key).is_none() {
        return Err(LibraryQueryError::UnknownPath { path: key.to_owned() });
    }
    let query = RankedQuery::parse(params.iter().copied())?;
    let ranked =
        library.rank(Some(query.top), query.kind).map_err(|e| LibraryQueryError::Library { reason: e.to_string() })?;
    Ok(prost::Message::encode_to_vec(&ranking_message(&ranked)?))
}

/// Declares the queryable of `site`'s library (every site's if `None`).
pub(crate) async fn declare(
    session: &Session,
    site: Option<&SiteId>,
) -> Result<Queryable<FifoChannelHandler<Query>>, TransportError> {
    let key = risktwin_transport::keyexpr::library_queryable_all(site);
    session.declare_queryable(key.clone()).await.map_err(|e| TransportError::Declare {
        what: "queryable",
        key,
        reason: e.to_string(),
    })
}

/// Answers the queries of `queryable` from `library` until `shutdown` fires.
pub(crate) async fn serve(
    queryable: Queryable<FifoChannelHandler<Query>>,
    library: ScenarioLibrary,
    mut shutdown: Shutdown,
) -> Result<LibrarySummary, TransportError> {
    let key = queryable.key_expr().to_string();
    let mut summary = LibrarySummary::default();
    loop {
        let query: Query = tokio::select! {
            q = queryable.recv_async() => match q { Ok(q) => q, Err(_) => break },
            () = shutdown.wait() => break,
        };
        let params: Vec<(&str, &str)> = query.parameters().iter().collect();
        let reply_key = query.key_expr().clone();
        let sent = match answer(&library, reply_key.as_str(), &params) {
            Ok(bytes) => {
                summary.answered += 1;
                query.reply(reply_key, bytes).encoding(protobuf(LIBRARY_RANKING)).await
            }
            Err(e) => {
                summary.refused += 1;
                tracing::warn!("cloud library: refused a query: {e}");
                query.reply_err(e.to_string()).await
            }
        };
        if let Err(e) = sent {
            // The querier may be gone; the next query deserves an answer all the same.
            tracing::warn!("cloud library: reply failed: {e}");
        }
    }
    queryable.undeclare().await.map_err(|e| TransportError::Declare {
        what: "undeclare",
        key,
        reason: e.to_string(),
    })?;
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_are_validated() {
        assert_eq!(RankedQuery::parse([]), Ok(RankedQuery { top: DEFAULT_TOP, kind: None }));
        assert_eq!(
            RankedQuery::parse([("top", "3"), ("kind", "cut-in")]),
            Ok(RankedQuery { top: 3, kind: Some(ScenarioKind::CutIn) })
        );
        assert_eq!(RankedQuery::parse([("kind", "all")]).map(|q| q.kind), Ok(None));
        for bad in ["0", "-1", "x", "1001", ""] {
            assert_eq!(RankedQuery::parse([("top", bad)]), Err(LibraryQueryError::BadTop { value: bad.into() }));
        }
        assert!(matches!(RankedQuery::parse([("kind", "warp")]), Err(LibraryQueryError::BadKind { .. })));
        assert_eq!(
            RankedQuery::parse([("limit", "3")]),
            Err(LibraryQueryError::UnknownParameter { name: "limit".into() })
        );
    }

    /// Stores `n` feasible cut-ins with their reference-driver outcomes; returns how many.
    pub(crate) fn store_evaluated(library: &mut ScenarioLibrary, n: usize) -> usize {
        use risktwin_common::scenario::{check_feasible, sample};
        use risktwin_store::library::{DEFAULT_POLICY, Outcome, ScenarioRecord};
        let records: Vec<ScenarioRecord> = (0..100)
            .map(|i| sample(7, ScenarioKind::CutIn, i))
            .filter(|s| check_feasible(s).is_ok())
            .take(n)
            .map(|spec| {
                let r = risktwin_common::episode::evaluate(&spec);
                ScenarioRecord::sampled(
                    spec,
                    Outcome { policy: DEFAULT_POLICY.to_owned(), metrics: r.metrics, risk: r.risk },
                )
            })
            .collect();
        library.insert_batch(&records).expect("stored");
        records.len()
    }

    #[test]
    fn answers_the_ranking_of_a_real_library() {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut library = ScenarioLibrary::open(dir.path().join("lib.db")).expect("library");
        let records = store_evaluated(&mut library, 3);
        let site = SiteId::new("s").expect("valid");
        let key = risktwin_transport::keyexpr::library_ranked(&site);
        let bytes = answer(&library, &key, &[("top", "2")]).expect("answered");
        let ranking = <v1::LibraryRanking as prost::Message>::decode(&*bytes).expect("decodes");
        assert_eq!(ranking.scenarios.len(), 2.min(records));
        let scores: Vec<f64> = ranking.scenarios.iter().map(|s| s.risk.as_ref().map_or(-1.0, |r| r.score)).collect();
        assert!(scores.windows(2).all(|w| w[0] >= w[1]), "highest risk first: {scores:?}");
        assert_eq!(ranking.scenarios[0].rank, 1);
        let expected = library.rank(Some(2), None).expect("rank");
        assert_eq!(ranking.scenarios[0].id, expected[0].id);
        assert!(matches!(
            answer(&library, "risktwin/v1/s/cloud/library/other", &[]),
            Err(LibraryQueryError::UnknownPath { .. })
        ));
    }
}
