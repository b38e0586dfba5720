//! Frenet ↔ world conversions on a lane polyline with a segment hint, so a vehicle that moved
//! a little since the last step costs O(1) instead of a search over the whole centreline.

use crate::geometry::Vec2;
use crate::road::Lane;

/// How far a hint is walked before falling back to a binary search.
const WALK_LIMIT: usize = 8;

/// Index of the segment containing `s_m` (clamped to the valid range), starting from `hint`.
pub(crate) fn seek_segment(lane: &Lane, s_m: f64, hint: u32) -> u32 {
    let cum = &lane.cum_s;
    let n_seg = cum.len().saturating_sub(1).max(1);
    let mut k = (hint as usize).min(n_seg - 1);
    for _ in 0..WALK_LIMIT {
        if s_m < cum[k] && k > 0 {
            k -= 1;
        } else if k + 1 < n_seg && s_m >= cum[k + 1] {
            k += 1;
        } else {
            return k as u32;
        }
    }
    (cum.partition_point(|&c| c <= s_m).saturating_sub(1).min(n_seg - 1)) as u32
}

/// Unit direction of segment `seg`.
#[inline]
pub(crate) fn segment_dir(lane: &Lane, seg: u32) -> Vec2 {
    let k = seg as usize;
    let ab = lane.centre[k + 1] - lane.centre[k];
    ab / ab.norm().max(1e-12)
}

/// World point of (s, d) on segment `seg` (extended linearly beyond the segment ends), given
/// the segment's unit direction `dir`.
#[cfg(test)]
fn frenet_to_world(lane: &Lane, dir: Vec2, seg: u32, s_m: f64, d_m: f64) -> Vec2 {
    let k = seg as usize;
    let normal = Vec2::new(-dir.y, dir.x);
    lane.centre[k] + dir * (s_m - lane.cum_s[k]) + normal * d_m
}

/// One centreline segment with everything a pose update needs in one cache line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Segment {
    pub start: Vec2,
    pub dir: Vec2,
    pub s0_m: f64,
    pub s1_m: f64,
}

impl Segment {
    /// World point of (s, d), extended linearly beyond the segment's ends.
    #[inline]
    pub(crate) fn world(&self, s_m: f64, d_m: f64) -> Vec2 {
        let normal = Vec2::new(-self.dir.y, self.dir.x);
        self.start + self.dir * (s_m - self.s0_m) + normal * d_m
    }
}

/// The segments of `lane` (cached by [`super::Traffic`]).
pub(crate) fn lane_segments(lane: &Lane, out: &mut Vec<Segment>) {
    out.clear();
    out.extend((0..lane.cum_s.len().saturating_sub(1)).map(|k| Segment {
        start: lane.centre[k],
        dir: segment_dir(lane, k as u32),
        s0_m: lane.cum_s[k],
        s1_m: lane.cum_s[k + 1],
    }));
}

/// Index of the cached segment containing `s_m` (clamped), starting from `hint`.
#[inline]
pub(crate) fn seek(segs: &[Segment], s_m: f64, hint: u32) -> u32 {
    let n = segs.len().max(1);
    let mut k = (hint as usize).min(n - 1);
    for _ in 0..WALK_LIMIT {
        if k > 0 && s_m < segs[k].s0_m {
            k -= 1;
        } else if k + 1 < n && s_m >= segs[k].s1_m {
            k += 1;
        } else {
            return k as u32;
        }
    }
    (segs.partition_point(|g| g.s0_m <= s_m).saturating_sub(1).min(n - 1)) as u32
}

/// Projects `p` on `lane` searching only segments near the arc length `s_guess_m` (wrapping
/// on closed lanes): (s, d, segment). Used when a vehicle moves to a neighbouring lane.
pub(crate) fn project_near(lane: &Lane, p: Vec2, s_guess_m: f64, closed: bool) -> (f64, f64, u32) {
    let n_seg = lane.cum_s.len().saturating_sub(1).max(1);
    let centre = seek_segment(lane, s_guess_m, 0) as i64;
    let mut best = (f64::INFINITY, 0usize, 0.0f64);
    let w = (WALK_LIMIT as i64).min(n_seg as i64);
    // Nearest segments first, so a tie at a shared vertex keeps the guessed segment.
    for j in 0..=2 * w {
        let off = if j % 2 == 0 { j / 2 } else { -(j + 1) / 2 };
        let raw = centre + off;
        let k = if closed {
            raw.rem_euclid(n_seg as i64) as usize
        } else if raw < 0 || raw >= n_seg as i64 {
            continue;
        } else {
            raw as usize
        };
        let a = lane.centre[k];
        let ab = lane.centre[k + 1] - a;
        let len_sq = ab.norm_squared().max(1e-24);
        let lo = if k == 0 && !closed { f64::NEG_INFINITY } else { 0.0 };
        let hi = if k + 1 == n_seg && !closed { f64::INFINITY } else { 1.0 };
        let t = ((p - a).dot(&ab) / len_sq).clamp(lo, hi);
        let d_sq = (a + ab * t - p).norm_squared();
        if d_sq < best.0 {
            best = (d_sq, k, t);
        }
    }
    let (_, k, t) = best;
    let a = lane.centre[k];
    let ab = lane.centre[k + 1] - a;
    let len = ab.norm().max(1e-12);
    let dir = ab / len;
    let rel = p - a;
    let mut s = lane.cum_s[k] + t * len;
    if closed && s >= lane.length_m() {
        s -= lane.length_m();
    }
    (s, dir.x * rel.y - dir.y * rel.x, k as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::road::Road;

    #[test]
    fn hinted_segment_matches_search_and_projection_round_trips() {
        let road = Road::ring(2, 3.5, 500.0, 20.0);
        let lane = &road.lanes[0];
        let mut segs = Vec::new();
        lane_segments(lane, &mut segs);
        let mut hint = 0;
        for k in 0..200 {
            let s = k as f64 * 2.3;
            hint = seek_segment(lane, s, hint);
            let exact = lane.cum_s.partition_point(|&c| c <= s) - 1;
            assert_eq!(hint as usize, exact, "s {s}");
            assert_eq!(seek(&segs, s, hint.saturating_sub(3)), hint);
            assert_eq!(seek(&segs, s, 0), hint);
            let w = segs[hint as usize].world(s, -1.0);
            // Offset to the outside (right of a counter-clockwise ring): near a vertex an inside
            // point is genuinely closer to the neighbouring segment, an outside one is not.
            let p = frenet_to_world(lane, segment_dir(lane, hint), hint, s, -1.0);
            assert!((p - w).norm() < 1e-12);
            let (s2, d2, _) = project_near(lane, p, s + 0.7, true);
            assert!((s2 - s).abs() < 1e-9 && (d2 + 1.0).abs() < 1e-9, "s {s}: {s2} {d2}");
        }
        // A far jump (wrap) falls back to the binary search.
        assert_eq!(seek_segment(lane, 1.0, hint), 0);
    }
}
