//! Risk terms, the risk report and the risk-field grid.

use super::geometry::{header, vec_from, vec_to};
use super::{ConvertError, distance_or_inf, in_range, invalid, non_empty, non_negative, positive, required};
use crate::v1;
use risktwin_common::risk::raster::MAX_CELLS;
use risktwin_common::risk::{RiskGrid, RiskTerms};
use risktwin_common::telemetry::{RiskField, RiskReport};

impl From<&RiskTerms> for v1::RiskTerms {
    fn from(t: &RiskTerms) -> Self {
        Self { score: t.score, ttc: t.ttc, dist: t.dist, lane: t.lane, jerk: t.jerk, collision: t.collision }
    }
}

impl TryFrom<v1::RiskTerms> for RiskTerms {
    type Error = ConvertError;
    fn try_from(t: v1::RiskTerms) -> Result<Self, ConvertError> {
        const M: &str = "RiskTerms";
        let unit = |field, v| in_range(M, field, v, 0.0, 1.0);
        Ok(Self {
            score: unit("score", t.score)?,
            ttc: unit("ttc", t.ttc)?,
            dist: unit("dist", t.dist)?,
            lane: unit("lane", t.lane)?,
            jerk: unit("jerk", t.jerk)?,
            collision: unit("collision", t.collision)?,
        })
    }
}

/// The required risk terms `field` of `message`.
pub(crate) fn terms(
    message: &'static str,
    field: &'static str,
    t: Option<v1::RiskTerms>,
) -> Result<RiskTerms, ConvertError> {
    required(message, field, t)?.try_into()
}

impl From<&RiskReport> for v1::RiskReport {
    fn from(r: &RiskReport) -> Self {
        Self {
            header: Some((&r.header).into()),
            ego_source: r.ego_source.clone(),
            terms: Some((&r.terms).into()),
            min_ttc_s: r.min_ttc_s,
            min_distance_m: r.min_distance_m,
        }
    }
}

impl TryFrom<v1::RiskReport> for RiskReport {
    type Error = ConvertError;
    fn try_from(r: v1::RiskReport) -> Result<Self, ConvertError> {
        const M: &str = "RiskReport";
        Ok(Self {
            header: header(M, r.header)?,
            ego_source: non_empty(M, "ego_source", r.ego_source)?,
            terms: terms(M, "terms", r.terms)?,
            min_ttc_s: r.min_ttc_s.map(|t| non_negative(M, "min_ttc_s", t)).transpose()?,
            min_distance_m: distance_or_inf(M, "min_distance_m", r.min_distance_m)?,
        })
    }
}

impl From<&RiskField> for v1::RiskGrid {
    fn from(f: &RiskField) -> Self {
        let g = &f.grid;
        Self {
            header: Some((&f.header).into()),
            origin_m: Some(vec_to(&g.origin_m)),
            resolution_m: g.resolution_m,
            cols: g.cols as u32,
            rows: g.rows as u32,
            cells: g.cells.clone(),
        }
    }
}

impl TryFrom<v1::RiskGrid> for RiskField {
    type Error = ConvertError;
    fn try_from(g: v1::RiskGrid) -> Result<Self, ConvertError> {
        const M: &str = "RiskGrid";
        let (cols, rows) = (g.cols as usize, g.rows as usize);
        if cols == 0 || rows == 0 {
            return Err(invalid(M, "cols", format!("{cols}×{rows} cells, need at least 1×1")));
        }
        let cells = cols.saturating_mul(rows);
        if cells > MAX_CELLS {
            return Err(invalid(M, "cols", format!("{cols}×{rows} cells exceed the limit of {MAX_CELLS}")));
        }
        if g.cells.len() != cells {
            return Err(invalid(M, "cells", format!("{} values for {cols}×{rows} cells", g.cells.len())));
        }
        if let Some(i) = g.cells.iter().position(|v| !v.is_finite()) {
            return Err(invalid(M, "cells", format!("cell {i} is {}", g.cells[i])));
        }
        Ok(Self {
            header: header(M, g.header)?,
            grid: RiskGrid {
                origin_m: vec_from(M, "origin_m", g.origin_m)?,
                resolution_m: positive(M, "resolution_m", g.resolution_m)?,
                cols,
                rows,
                cells: g.cells,
            },
        })
    }
}
