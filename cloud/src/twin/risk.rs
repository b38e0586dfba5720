//! Risk on the live twin: for an ego vehicle of a site, the risk field on a grid around it
//! (`common::risk::GridEvaluator` over the site road's [`RoadRaster`]) and a risk report (the
//! S_risk terms of this one instant through `common::risk::RiskAccumulator`: TTC and distance to
//! the nearest objects, lane offset, jerk, contact).
//!
//! What surrounds the ego: every other vehicle of the site's twin, and every object some
//! source perceived (the ego's own perception, other vehicles', RSUs'). An object whose centre
//! lies within [`SELF_RADIUS_M`] of the ego's centre is the ego itself as another source saw it
//! and is skipped (a sensor cannot tell whom it sees; the price is that a collision so deep that
//! two centres are that close is not seen as one). Duplicates of one object seen by several sources do not add up: the field
//! takes the maximum over objects per cell.

use super::{SiteTwin, TwinVehicle};
use risktwin_common::episode::{EpisodeScorer, ScoredStep};
use risktwin_common::geometry::{Obb, Vec2};
use risktwin_common::risk::{
    EgoKinematics, FieldError, FieldObject, GridEvaluator, RiskAccumulator, RiskFieldParams, RiskGrid, RiskStep,
    RiskTerms, RiskWeights, RoadRaster, ScoreReferences, VehicleState,
};
use risktwin_common::road::Road;
use risktwin_common::telemetry::{Frame, Header, RiskField, RiskReport};

/// Objects closer than this to the ego's centre are taken for the ego itself, m: four standard
/// deviations of the sensors' position noise (0.3 m per coordinate), so that the ego seen by
/// another source is taken for an obstacle in about 3 of 10,000 sightings (at 0.5 m it was 1 in 4,
/// found by the fidelity measurement: S_risk off by the collision and distance terms).
pub const SELF_RADIUS_M: f64 = 1.2;

/// How the risk role evaluates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RiskConfig {
    /// Grid side, cells.
    pub grid_cells: usize,
    /// Cell size, m.
    pub resolution_m: f64,
    /// Field parameters (docs/method.md §4 defaults).
    pub params: RiskFieldParams,
    /// Minimum twin time between two assessments of a site, ns (2 Hz by default).
    pub period_ns: i64,
}

impl Default for RiskConfig {
    /// 160 × 160 cells of 0.5 m (80 m around the ego, as in episode recordings), at 2 Hz.
    fn default() -> Self {
        RiskConfig { grid_cells: 160, resolution_m: 0.5, params: RiskFieldParams::default(), period_ns: 500_000_000 }
    }
}

/// What the twin cannot know of an episode's step from the streams: how long it was, where the
/// ego is along its route, the speed it wants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinStep {
    pub dt_s: f64,
    /// Distance along the route from its start, m.
    pub progress_m: f64,
    pub desired_speed_mps: f64,
}

/// The risk of one ego at one tick.
#[derive(Debug, Clone, PartialEq)]
pub struct RiskAssessment {
    pub field: RiskField,
    pub report: RiskReport,
}

/// The risk of one vehicle at one instant, without the grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InstantRisk {
    pub terms: RiskTerms,
    /// Smallest finite TTC to any object in the ego's lane, s.
    pub min_ttc_s: Option<f64>,
    pub min_distance_m: f64,
    /// The risk field at the ego's footprint (its maximum over the footprint's sample points).
    pub at_ego: f64,
}

/// The field's view of a twin vehicle as the ego.
fn ego_kinematics(v: &TwinVehicle) -> EgoKinematics {
    let k = &v.kinematics;
    EgoKinematics {
        pose: k.pose,
        velocity: k.velocity,
        lateral_accel_mps2: v.lateral_accel_mps2,
        jerk_mps3: v.jerk_mps3,
        footprint: k.footprint,
    }
}

/// Evaluates risk on a site's twin; owns the road raster and the scratch buffers, so repeated
/// assessments allocate only the grid they hand out.
#[derive(Debug, Clone)]
pub struct RiskAssessor {
    road: Road,
    raster: RoadRaster,
    evaluator: GridEvaluator,
    grid: RiskGrid,
    config: RiskConfig,
    around: Surroundings,
    pair_ttc_s: Vec<f64>,
    seq: u64,
}

impl RiskAssessor {
    /// An assessor for vehicles on `road`.
    pub fn new(road: Road, config: RiskConfig) -> Result<Self, FieldError> {
        config.params.validate()?;
        let half_m = 0.5 * config.resolution_m * config.grid_cells as f64;
        let raster = RoadRaster::new(&road, &config.params, config.resolution_m, half_m + 10.0)?;
        let grid = RiskGrid::new(raster.grid().origin_m, config.resolution_m, config.grid_cells, config.grid_cells)?;
        Ok(RiskAssessor {
            road,
            raster,
            evaluator: GridEvaluator::new(config.params),
            grid,
            config,
            around: Surroundings::default(),
            pair_ttc_s: Vec::new(),
            seq: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &RiskConfig {
        &self.config
    }

    /// The road it evaluates on.
    pub fn road(&self) -> &Road {
        &self.road
    }

    /// The risk field around `site.vehicles[ego]` and its report, stamped `tick_ns` (cloud
    /// clock); `None` if there is no such vehicle.
    pub fn assess(&mut self, site: &SiteTwin, ego: usize, tick_ns: i64) -> Option<RiskAssessment> {
        let ego_vehicle = site.vehicles.get(ego)?;
        let ego_kin = ego_kinematics(ego_vehicle);
        let instant = self.instant(site, ego)?;
        let half_m = 0.5 * self.config.resolution_m * self.config.grid_cells as f64;
        self.grid.origin_m = self.raster.snap_origin(ego_kin.pose.position() - Vec2::new(half_m, half_m));
        self.evaluator.fill(&mut self.grid, &self.raster, &self.road, &self.around.objects, &ego_kin);
        let header = self.header(ego_vehicle, tick_ns);
        self.seq += 1;
        Some(RiskAssessment {
            field: RiskField { header: header.clone(), grid: self.grid.clone() },
            report: RiskReport {
                header,
                ego_source: ego_vehicle.source.to_string(),
                terms: instant.terms,
                min_ttc_s: instant.min_ttc_s,
                min_distance_m: instant.min_distance_m,
            },
        })
    }

    /// The risk of `site.vehicles[ego]` at this instant without the grid: the S_risk terms, the
    /// field at its footprint, and the TTC to each object around it (in [`Self::others`]'
    /// order). `None` if there is no such vehicle.
    pub fn instant(&mut self, site: &SiteTwin, ego: usize) -> Option<InstantRisk> {
        let ego_vehicle = site.vehicles.get(ego)?;
        let k = &ego_vehicle.kinematics;
        let ego_kin = ego_kinematics(ego_vehicle);
        self.around.fill(site, ego);
        let ego_obb = Obb::new(k.pose, k.footprint);
        let ego_state = VehicleState { obb: ego_obb, velocity: k.velocity, accel: ego_obb.axis * k.accel_mps2 };
        let at = self.road.locate_heading(k.pose.position(), k.pose.heading_rad);
        let collision = self.around.others.iter().any(|o| o.obb.overlaps(&ego_obb));
        let offroad = !self.road.contains_footprint(&ego_obb);
        let mut accumulator = RiskAccumulator::new(RiskWeights::default(), ScoreReferences::default());
        accumulator.push(
            &self.road,
            &RiskStep {
                ego: ego_state,
                lane_offset_m: at.frenet.e_y_m,
                lane_width_m: self.road.lane(at.lane).width_m,
                jerk_mps3: ego_vehicle.jerk_mps3,
                others: &self.around.others,
                collision,
                offroad,
            },
        );
        self.pair_ttc_s.clear();
        self.pair_ttc_s.extend(accumulator.pairs().iter().map(|p| p.min_ttc_s));
        let (terms, summary) = accumulator.finish();
        let at_ego = self.raster.evaluate_footprint(&self.road, &self.around.objects, &ego_kin);
        Some(InstantRisk { terms, min_ttc_s: summary.min_ttc_s, min_distance_m: summary.min_distance_m, at_ego })
    }

    /// The objects around the ego of the last evaluation, and who each is: `Ok(i)` vehicle `i`
    /// of the site, `Err(j)` object `j`.
    pub fn others(&self) -> impl Iterator<Item = (&VehicleState, Result<usize, usize>)> {
        self.around.others.iter().zip(self.around.who.iter().copied())
    }

    /// The TTC to each of [`Self::others`] at the last [`Self::instant`], s (∞: not closing in
    /// the ego's lane).
    pub fn pair_ttc_s(&self) -> &[f64] {
        &self.pair_ttc_s
    }

    fn header(&self, ego: &TwinVehicle, tick_ns: i64) -> Header {
        Header {
            source: ego.source.to_string(),
            seq: self.seq,
            capture_time_ns: tick_ns,
            publish_time_ns: tick_ns,
            frame: Frame::World,
        }
    }
}

/// What surrounds an ego at a tick (see the module doc): the objects of the risk field, their
/// states for the criticality measures, and who each is. Scoring an episode needs only these
/// and the road, not the raster of the field, which takes 60–100 ms (seconds on a long curved
/// road) to build.
#[derive(Debug, Clone, Default)]
pub struct Surroundings {
    objects: Vec<FieldObject>,
    others: Vec<VehicleState>,
    /// Who each of `others` is (see [`RiskAssessor::others`]).
    who: Vec<Result<usize, usize>>,
}

impl Surroundings {
    /// Feeds `site.vehicles[ego]` at this tick to an episode's `scorer`, as `simulate` feeds its
    /// world's step: the same field, reward and criticality code on what the twin shows (its
    /// surroundings as [`RiskAssessor::instant`] sees them; contact is an overlap with any of them,
    /// leaving the road is the footprint leaving it). The twin has no steering angle (the state
    /// stream does not carry it), so the episode's steering smoothness is 0. False if there is
    /// no such vehicle.
    pub fn score(
        &mut self,
        road: &Road,
        site: &SiteTwin,
        ego: usize,
        step: TwinStep,
        scorer: &mut EpisodeScorer,
    ) -> bool {
        let Some(ego_vehicle) = site.vehicles.get(ego) else { return false };
        let k = ego_vehicle.kinematics;
        let mut ego_kin = ego_kinematics(ego_vehicle);
        ego_kin.jerk_mps3 = scorer.jerk_of(k.accel_mps2, step.dt_s);
        self.fill(site, ego);
        let ego_obb = ego_kin.obb();
        let scored = ScoredStep {
            dt_s: step.dt_s,
            ego: ego_kin,
            speed_mps: k.speed_mps,
            steer_rad: 0.0,
            accel_mps2: k.accel_mps2,
            progress_m: step.progress_m,
            desired_speed_mps: step.desired_speed_mps,
            objects: &self.objects,
            others: &self.others,
            collision: self.others.iter().any(|o| o.obb.overlaps(&ego_obb)),
            offroad: !road.contains_footprint(&ego_obb),
        };
        scorer.push(road, &scored);
        true
    }

    /// Fills the field objects and the criticality states of everything around `ego`.
    fn fill(&mut self, site: &SiteTwin, ego: usize) {
        self.objects.clear();
        self.others.clear();
        self.who.clear();
        let centre = site.vehicles[ego].kinematics.pose.position();
        for (i, v) in site.vehicles.iter().enumerate() {
            if i == ego {
                continue;
            }
            let obb = Obb::new(v.kinematics.pose, v.kinematics.footprint);
            self.objects.push(FieldObject { obb, velocity: v.kinematics.velocity });
            self.others.push(VehicleState {
                obb,
                velocity: v.kinematics.velocity,
                accel: obb.axis * v.kinematics.accel_mps2,
            });
            self.who.push(Ok(i));
        }
        for (j, o) in site.objects.iter().enumerate() {
            let obj = &o.object;
            if (obj.pose.position() - centre).norm() < SELF_RADIUS_M {
                continue;
            }
            let obb = Obb::new(obj.pose, obj.footprint);
            self.objects.push(FieldObject { obb, velocity: obj.velocity });
            self.others.push(VehicleState { obb, velocity: obj.velocity, accel: obb.axis * obj.accel_mps2 });
            self.who.push(Err(j));
        }
    }
}
