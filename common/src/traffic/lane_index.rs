//! Per-lane lists of vehicles sorted by arc length: the spatial index behind leader lookup,
//! MOBIL's neighbour search and the collision broad phase.
//!
//! A vehicle has an entry in its own lane's list and one in each neighbour lane's list its
//! footprint reaches into. Every step the entries' s are refreshed and the lists re-sorted by
//! insertion sort: vehicles overtake rarely, so the lists are almost sorted and this is O(n)
//! (a wrap on a closed lane moves one entry from the back to the front). Vehicles whose
//! membership changed are removed and merged back in; nothing allocates once the lists have
//! grown to their working size.

use crate::road::Road;

/// "No slot" / "no lane".
pub(crate) const NONE: u32 = u32::MAX;

/// What a step needs to know about a lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LaneInfo {
    pub closed: bool,
    pub vertices: usize,
    pub length_m: f64,
    pub width_m: f64,
    pub left: u32,
    pub right: u32,
}

impl LaneInfo {
    pub(crate) fn of_road(road: &Road, out: &mut Vec<LaneInfo>) {
        out.clear();
        out.extend(road.lanes.iter().map(|l| LaneInfo {
            closed: l.is_closed(),
            vertices: l.centre.len(),
            length_m: l.length_m(),
            width_m: l.width_m,
            left: l.left.map_or(NONE, |x| x as u32),
            right: l.right.map_or(NONE, |x| x as u32),
        }));
    }

    /// A lane needs a centreline of at least one segment of positive length to carry traffic
    /// (the road builders guarantee it; a deserialised road might not).
    pub(crate) fn usable(&self) -> bool {
        self.vertices >= 2 && self.length_m > 0.0
    }

    /// The lane a side code refers to: 0 this lane, 1 its left, 2 its right neighbour.
    #[inline]
    pub(crate) fn side_lane(&self, own: u32, side: usize) -> u32 {
        match side {
            0 => own,
            1 => self.left,
            _ => self.right,
        }
    }
}

/// One vehicle in one lane's list: its arc length in that lane's coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Entry {
    pub s_m: f64,
    pub id: u32,
    /// 0: the vehicle's own lane, 1: the list is its left neighbour, 2: its right neighbour.
    pub side: u8,
}

#[inline]
fn before(a: &Entry, b: &Entry) -> bool {
    a.s_m < b.s_m || (a.s_m == b.s_m && a.id < b.id)
}

/// Vehicle state the index reads.
pub(crate) struct Members<'a> {
    pub lane: &'a [u32],
    pub s_m: &'a [f64],
    pub intrude: &'a [u8],
    pub active: &'a [bool],
}

impl Members<'_> {
    /// s of vehicle `id` expressed in the coordinates of the lane `side` of its own lane.
    #[inline]
    fn s_in(&self, lanes: &[LaneInfo], id: u32, side: u8) -> f64 {
        let i = id as usize;
        let s = self.s_m[i];
        if side == 0 {
            return s;
        }
        let own = &lanes[self.lane[i] as usize];
        let other = own.side_lane(self.lane[i], side as usize);
        s * lanes[other as usize].length_m / own.length_m.max(1e-9)
    }
}

/// The sorted per-lane lists and, per vehicle, its entries' positions in them.
#[derive(Debug, Clone, Default)]
pub(crate) struct LaneIndex {
    pub lists: Vec<Vec<Entry>>,
    /// Per vehicle: index of its entry in the own, left and right lists (or `NONE`).
    pub slots: Vec<[u32; 3]>,
    pending: Vec<(u32, Entry)>,
    marked: Vec<bool>,
}

impl LaneIndex {
    fn push_entries(&mut self, m: &Members, lanes: &[LaneInfo], id: u32, to_pending: bool) {
        let i = id as usize;
        if !m.active[i] {
            return;
        }
        let own = m.lane[i];
        for side in 0..3u8 {
            let present = side == 0 || m.intrude[i] & (1 << (side - 1)) != 0;
            let lane = lanes[own as usize].side_lane(own, side as usize);
            if !present || lane == NONE {
                continue;
            }
            let e = Entry { s_m: m.s_in(lanes, id, side), id, side };
            if to_pending {
                self.pending.push((lane, e));
            } else {
                self.lists[lane as usize].push(e);
            }
        }
    }

    /// Builds every list from scratch.
    pub(crate) fn rebuild(&mut self, m: &Members, lanes: &[LaneInfo]) {
        self.lists.resize_with(lanes.len(), Vec::new);
        self.lists.iter_mut().for_each(Vec::clear);
        for id in 0..m.lane.len() as u32 {
            self.push_entries(m, lanes, id, false);
        }
        for list in &mut self.lists {
            list.sort_unstable_by(|a, b| a.s_m.total_cmp(&b.s_m).then(a.id.cmp(&b.id)));
        }
        self.write_slots(m.lane.len());
    }

    /// Refreshes s, re-sorts, and moves the vehicles in `changed` (membership changed this
    /// step) to their new lists.
    pub(crate) fn update(&mut self, m: &Members, lanes: &[LaneInfo], changed: &[u32]) {
        let n = m.lane.len();
        if !changed.is_empty() {
            self.marked.clear();
            self.marked.resize(n, false);
            for &id in changed {
                self.marked[id as usize] = true;
            }
            let marked = &self.marked;
            for list in &mut self.lists {
                list.retain(|e| !marked[e.id as usize]);
            }
        }
        for list in &mut self.lists {
            for e in list.iter_mut() {
                e.s_m = m.s_in(lanes, e.id, e.side);
            }
            insertion_sort(list);
        }
        if !changed.is_empty() {
            self.pending.clear();
            for &id in changed {
                self.push_entries(m, lanes, id, true);
            }
            self.pending
                .sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.s_m.total_cmp(&b.1.s_m)).then(a.1.id.cmp(&b.1.id)));
            let mut start = 0;
            while start < self.pending.len() {
                let lane = self.pending[start].0;
                let end = start + self.pending[start..].iter().take_while(|p| p.0 == lane).count();
                merge_into(&mut self.lists[lane as usize], &self.pending[start..end]);
                start = end;
            }
        }
        self.write_slots(n);
    }

    fn write_slots(&mut self, n: usize) {
        self.slots.clear();
        self.slots.resize(n, [NONE; 3]);
        for list in &self.lists {
            for (k, e) in list.iter().enumerate() {
                self.slots[e.id as usize][e.side as usize] = k as u32;
            }
        }
    }
}

/// Index of the first entry with s > `s_m` (like `partition_point(|e| e.s_m <= s_m)`),
/// galloping out from `guess`: O(log distance) instead of O(log n) cache-missing probes.
pub(crate) fn upper_bound_near(list: &[Entry], s_m: f64, guess: usize) -> usize {
    let n = list.len();
    let g = guess.min(n);
    let (lo, hi) = if g < n && list[g].s_m <= s_m {
        let (mut lo, mut step) = (g + 1, 1);
        loop {
            let hi = g + step;
            if hi >= n {
                break (lo, n);
            }
            if list[hi].s_m > s_m {
                break (lo, hi);
            }
            lo = hi + 1;
            step *= 2;
        }
    } else {
        let (mut hi, mut step) = (g, 1);
        loop {
            if step > g {
                break (0, hi);
            }
            let lo = g - step;
            if list[lo].s_m <= s_m {
                break (lo + 1, hi);
            }
            hi = lo;
            step *= 2;
        }
    };
    lo + list[lo..hi].partition_point(|e| e.s_m <= s_m)
}

/// Insertion sort: O(n + number of inversions), i.e. O(n) on an almost sorted list.
fn insertion_sort(v: &mut [Entry]) {
    for i in 1..v.len() {
        if before(&v[i], &v[i - 1]) {
            let x = v[i];
            let mut j = i;
            while j > 0 && before(&x, &v[j - 1]) {
                v[j] = v[j - 1];
                j -= 1;
            }
            v[j] = x;
        }
    }
}

/// Merges the sorted `extra` (lane, entry) pairs into the sorted `list`, back to front.
fn merge_into(list: &mut Vec<Entry>, extra: &[(u32, Entry)]) {
    let old = list.len();
    list.extend(extra.iter().map(|p| p.1));
    let (mut i, mut j, mut w) = (old, extra.len(), list.len());
    while j > 0 {
        w -= 1;
        if i > 0 && before(&extra[j - 1].1, &list[i - 1]) {
            list[w] = list[i - 1];
            i -= 1;
        } else {
            list[w] = extra[j - 1].1;
            j -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(s: f64, id: u32) -> Entry {
        Entry { s_m: s, id, side: 0 }
    }

    #[test]
    fn galloping_search_matches_binary_search() {
        let list: Vec<Entry> = (0..300).map(|k| e((k / 2) as f64 * 1.5, k)).collect();
        for q in 0..500 {
            let s = q as f64 * 0.47 - 3.0;
            let exact = list.partition_point(|x| x.s_m <= s);
            for guess in [0, 1, 37, 150, 299, 300, 1000] {
                assert_eq!(upper_bound_near(&list, s, guess), exact, "s {s} guess {guess}");
            }
        }
        assert_eq!(upper_bound_near(&[], 1.0, 5), 0);
    }

    #[test]
    fn sorts_and_merges() {
        let mut v = vec![e(1.0, 0), e(5.0, 1), e(3.0, 2), e(0.5, 3)];
        insertion_sort(&mut v);
        assert_eq!(v.iter().map(|x| x.id).collect::<Vec<_>>(), vec![3, 0, 2, 1]);
        merge_into(&mut v, &[(0, e(0.1, 7)), (0, e(4.0, 8)), (0, e(9.0, 9))]);
        assert_eq!(v.iter().map(|x| x.id).collect::<Vec<_>>(), vec![7, 3, 0, 2, 8, 1, 9]);
    }
}
