//! The V2X messages on a participant's key (postcard): CAMs, a sender's end, and an RSU's
//! warnings of a step.

use risktwin_common::geometry::Obb;
use risktwin_common::sensor::PerceivedObject;
use serde::{Deserialize, Serialize};

/// Version of the V2X messages; bump on any change to them.
pub(super) const V2X_SCHEMA: u32 = 3;

/// A message on a participant's V2X key (postcard): who sent it, in which scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WireV2x {
    pub schema: u32,
    /// The scene's digest (its V2X channel included): another scene's messages are dropped and
    /// counted.
    pub scene: u64,
    /// The sending participant: the last segment of the key it comes on.
    pub sender: String,
    pub body: V2xBody,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum V2xBody {
    Cam(WireCam),
    /// The sender's last message of the scene: it sent `cams` CAMs (sequence 0 to `cams` − 1).
    End {
        cams: u64,
    },
    /// Sent until the scene starts: the sender's messages reach whoever hears it.
    Hello,
    /// An RSU's warnings and CPM of one step (with `--v2x-warnings` or `--v2x-cpm`; every
    /// step, often empty).
    Rsu(RsuBatch),
}

/// What an RSU sent in one step: its warnings (one per hazard it perceived, if a repetition was
/// due) and its CPM (if an object was due).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RsuBatch {
    pub step: u64,
    pub made_s: f64,
    /// Wall clock when it was put on the wire, ns since the Unix epoch.
    pub sent_unix_ns: i64,
    /// The mast's position, m: the copies' distances are measured from it.
    pub from: [f64; 2],
    /// The first warning's sequence number; the others follow it.
    pub first_seq: u64,
    /// The hazards as the RSU perceived them, their numbers exact.
    pub objects: Vec<PerceivedObject>,
    pub cpm: Option<WireCpm>,
}

/// A Collective Perception Message: the objects its inclusion rules chose (not ETSI's ASN.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WireCpm {
    /// The RSU's CPM count before this one.
    pub seq: u64,
    pub objects: Vec<PerceivedObject>,
}

impl RsuBatch {
    /// Every number finite: a warning moves an object the driver brakes for.
    pub(super) fn is_finite(&self) -> bool {
        let numbers = |o: &PerceivedObject| {
            let Obb { centre, axis, half_length_m, half_width_m } = o.obb;
            let vectors = [centre, axis, o.velocity].into_iter().flat_map(|v| [v.x, v.y]);
            vectors.chain([half_length_m, half_width_m, o.visible_fraction])
        };
        self.from.iter().chain(&[self.made_s]).all(|v| v.is_finite())
            && self.objects.iter().chain(self.cpm.iter().flat_map(|c| &c.objects)).flat_map(numbers).all(f64::is_finite)
    }
}

/// A CAM on the wire: when it was made in the scene and on the wall clock, and the state it
/// carries (not ETSI's ASN.1 encoding).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WireCam {
    /// The sender's CAM count before this one.
    pub seq: u64,
    /// The physics step whose truth it was made from, and its scene time, s.
    pub step: u64,
    pub made_s: f64,
    /// Wall clock when it was put on the wire, ns since the Unix epoch.
    pub sent_unix_ns: i64,
    /// Position, heading and speed: m, m, rad, m/s.
    pub state: [f64; 4],
}
