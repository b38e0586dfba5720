//! The live twin: what the cloud believes each site looks like at the latest aligned tick, built
//! from the ingest's [`Snapshot`]s (transport-free, like the ingest worker).
//!
//! Per tick, every source whose `state` stream has a current value (interpolated or as-of, not
//! stale) is a vehicle of its site; every current `perception` or `rsu` object list adds its
//! objects, tagged with the source that saw them. A value the aligner holds from before the
//! tick (an object list, up to 100 ms old, or a state whose next sample came too late to
//! interpolate) is moved on to the tick at its reported velocity: without that a 20 Hz state
//! stream under 30 ms of lateness was held up to 20 ms behind (0.3 m at 25 m/s, found by the
//! fidelity measurement). Stale and missing values are left out: the twin shows only what it
//! may trust at this tick. Jerk and lateral acceleration are derived
//! from consecutive ticks of the same vehicle, since the state stream carries neither.
//!
//! [`risk`] evaluates the risk field and report of an ego on a site's twin; [`outputs`] turns
//! each tick into the scene and risk outputs the network side records and publishes;
//! [`episode`] scores one vehicle's episode as the twin saw it; [`watch`] finds a pushed
//! episode among the ticks and scores it.

pub mod episode;
pub mod fidelity;
pub mod outputs;
pub mod risk;
pub mod watch;

use crate::ingest::stream::aligner_index;
use crate::ingest::{ObservedKinematics, TwinSample};
use risktwin_align::{Snapshot, SourceIndex, ValueStatus};
use risktwin_common::geometry::{Pose, Vec2, wrap_angle};
use risktwin_common::road::Road;
use risktwin_common::scenario::{ScenarioKind, build, check_feasible, sample};
use risktwin_common::telemetry::DetectedObject;
use risktwin_transport::EdgeStream;
use std::collections::BTreeMap;
use std::sync::Arc;

/// One vehicle of the twin at the current tick.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinVehicle {
    /// The vehicle's source id.
    pub source: Arc<str>,
    /// Its kinematics at the tick (interpolated between its state samples).
    pub kinematics: ObservedKinematics,
    /// Longitudinal jerk since the previous tick, m/s³ (0 on its first tick).
    pub jerk_mps3: f64,
    /// Lateral acceleration from the heading rate, m/s² (0 on its first tick).
    pub lateral_accel_mps2: f64,
}

/// One object some source perceived, as of the tick.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinObject {
    /// Who saw it (a vehicle's perception or an RSU).
    pub observer: Arc<str>,
    pub object: DetectedObject,
}

/// The twin of one site.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SiteTwin {
    pub vehicles: Vec<TwinVehicle>,
    pub objects: Vec<TwinObject>,
}

#[derive(Debug, Clone, Copy)]
struct Previous {
    tick_ns: i64,
    accel_mps2: f64,
    heading_rad: f64,
}

/// The twin of every site, updated tick by tick.
#[derive(Debug, Default)]
pub struct Twin {
    tick_ns: Option<i64>,
    ticks: u64,
    sites: BTreeMap<Arc<str>, SiteTwin>,
    /// Per source index: its name and site once known (the ingest names them).
    names: Vec<Option<(Arc<str>, Arc<str>)>>,
    previous: Vec<Option<Previous>>,
}

impl Twin {
    /// An empty twin.
    pub fn new() -> Self {
        Twin::default()
    }

    /// Names source `index` (as the ingest numbered it) and gives its site; sources without a
    /// name are left out of the twin.
    pub fn name_source(&mut self, index: usize, source: &str, site: &str) {
        if self.names.len() <= index {
            self.names.resize(index + 1, None);
        }
        if self.names[index].as_ref().is_none_or(|(n, s)| &**n != source || &**s != site) {
            self.names[index] = Some((Arc::from(source), Arc::from(site)));
        }
    }

    /// Whether source `index` has a name yet.
    pub fn is_named(&self, index: usize) -> bool {
        self.names.get(index).is_some_and(Option::is_some)
    }

    /// Replaces the twin's content by `snapshot`'s.
    pub fn update(&mut self, snapshot: &Snapshot<TwinSample>) {
        for site in self.sites.values_mut() {
            site.vehicles.clear();
            site.objects.clear();
        }
        if self.previous.len() < snapshot.sources() {
            self.previous.resize(snapshot.sources(), None);
        }
        for index in 0..snapshot.sources() {
            let Some(Some((source, site))) = self.names.get(index) else { continue };
            let src = SourceIndex(index as u32);
            let twin = match self.sites.get_mut(site) {
                Some(t) => t,
                None => self.sites.entry(Arc::clone(site)).or_default(),
            };
            if let Some((TwinSample::State(k), behind_ns)) = current(snapshot, src, EdgeStream::State) {
                let k = ObservedKinematics { pose: moved_on(k.pose, k.velocity, behind_ns), ..*k };
                let (jerk_mps3, lateral_accel_mps2) = match self.previous[index] {
                    Some(p) if snapshot.tick_ns > p.tick_ns => {
                        let dt_s = (snapshot.tick_ns - p.tick_ns) as f64 * 1e-9;
                        let yaw_rate = wrap_angle(k.pose.heading_rad - p.heading_rad) / dt_s;
                        ((k.accel_mps2 - p.accel_mps2) / dt_s, yaw_rate * k.speed_mps)
                    }
                    _ => (0.0, 0.0),
                };
                self.previous[index] = Some(Previous {
                    tick_ns: snapshot.tick_ns,
                    accel_mps2: k.accel_mps2,
                    heading_rad: k.pose.heading_rad,
                });
                twin.vehicles.push(TwinVehicle {
                    source: Arc::clone(source),
                    kinematics: k,
                    jerk_mps3,
                    lateral_accel_mps2,
                });
            } else {
                self.previous[index] = None;
            }
            for stream in [EdgeStream::Perception, EdgeStream::Rsu] {
                if let Some((TwinSample::Objects(list), behind_ns)) = current(snapshot, src, stream) {
                    twin.objects.extend(list.iter().map(|o| TwinObject {
                        observer: Arc::clone(source),
                        object: DetectedObject { pose: moved_on(o.pose, o.velocity, behind_ns), ..*o },
                    }));
                }
            }
        }
        self.tick_ns = Some(snapshot.tick_ns);
        self.ticks += 1;
    }

    /// The tick the twin shows, on the cloud clock (`None` before the first snapshot).
    pub fn tick_ns(&self) -> Option<i64> {
        self.tick_ns
    }

    /// Snapshots applied so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Every site seen so far, with its twin at the current tick.
    pub fn sites(&self) -> impl Iterator<Item = (&str, &SiteTwin)> {
        self.sites.iter().map(|(k, v)| (&**k, v))
    }

    /// The twin of one site.
    pub fn site(&self, site: &str) -> Option<&SiteTwin> {
        self.sites.get(site)
    }
}

/// The road of the first feasible scenario of `kind` (run seed 0): the road an edge running
/// `kind` with the default seed drives on (every candidate of a kind shares its road layout).
pub fn scenario_road(kind: ScenarioKind) -> Road {
    (0..1000)
        .map(|index| sample(0, kind, index))
        .find(|spec| check_feasible(spec).is_ok())
        .map_or_else(|| Road::straight(3, 3.5, 1200.0, 36.0), |spec| build(&spec).road)
}

/// The value of `stream` of `src` when it is current (interpolated or as-of, not stale), with
/// how far behind the tick it is, ns (0 when interpolated at the tick).
fn current(snapshot: &Snapshot<TwinSample>, src: SourceIndex, stream: EdgeStream) -> Option<(&TwinSample, i64)> {
    let aligned = snapshot.get(src, aligner_index(stream))?;
    let behind_ns = match aligned.status {
        ValueStatus::Interpolated => 0,
        ValueStatus::AsOf => aligned.age_ns,
        ValueStatus::NoData | ValueStatus::Stale => return None,
    };
    aligned.value.as_ref().map(|v| (v, behind_ns))
}

/// `pose` moved on at `velocity` for `behind_ns` (a held value predicted to the tick).
pub(crate) fn moved_on(pose: Pose, velocity: Vec2, behind_ns: i64) -> Pose {
    let p = pose.position() + velocity * (behind_ns as f64 * 1e-9);
    Pose::new(p.x, p.y, pose.heading_rad)
}

#[cfg(test)]
mod tests;
