//! What one aligned tick holds: per source and stream, the value at the tick and how it was got.

use super::source::SourceIndex;

/// A stream of a source (e.g. state, CAN signals, perception), as a small dense index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StreamIndex(pub u16);

impl StreamIndex {
    /// The index as a `usize`.
    pub const fn as_usize(self) -> usize {
        self.0 as usize
    }
}

/// How the value at a tick was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueStatus {
    /// No sample at or before the tick: nothing to show (never extrapolated backwards).
    NoData,
    /// Interpolated between the samples bracketing the tick (continuous streams).
    Interpolated,
    /// The latest sample at or before the tick, within the staleness bound (discrete streams, or
    /// a continuous stream whose next sample has not arrived: held, not extrapolated).
    AsOf,
    /// The latest sample is older than the staleness bound; the value is that sample, held, and
    /// must not be trusted as current.
    Stale,
}

/// One source and stream at one tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Aligned<T> {
    /// The value at the tick; `None` only with [`ValueStatus::NoData`].
    pub value: Option<T>,
    pub status: ValueStatus,
    /// Tick time minus the time of the latest sample at or before it (0 with `NoData`).
    pub age_ns: i64,
}

impl<T> Default for Aligned<T> {
    fn default() -> Self {
        Self { value: None, status: ValueStatus::NoData, age_ns: 0 }
    }
}

/// The aligned state of every source at one tick, reused from tick to tick (no allocation
/// unless a source was added).
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot<T> {
    /// The tick's time on the cloud clock.
    pub tick_ns: i64,
    streams: usize,
    values: Vec<Aligned<T>>,
}

impl<T> Snapshot<T> {
    /// An empty snapshot for `streams` streams per source.
    pub fn new(streams: usize) -> Self {
        Self { tick_ns: 0, streams, values: Vec::new() }
    }

    /// The value of `stream` of `source`, if the source is known.
    pub fn get(&self, source: SourceIndex, stream: StreamIndex) -> Option<&Aligned<T>> {
        if stream.as_usize() >= self.streams {
            return None;
        }
        self.values.get(source.as_usize() * self.streams + stream.as_usize())
    }

    /// How many sources the snapshot covers.
    pub fn sources(&self) -> usize {
        self.values.len().checked_div(self.streams).unwrap_or(0)
    }

    /// Streams per source.
    pub fn streams(&self) -> usize {
        self.streams
    }

    /// All values, source-major (`source * streams + stream`).
    pub fn values(&self) -> &[Aligned<T>] {
        &self.values
    }

    pub(crate) fn resize_for(&mut self, slots: usize) {
        if self.values.len() < slots {
            self.values.resize_with(slots, Aligned::default);
        }
    }

    pub(crate) fn slot_mut(&mut self, slot: usize) -> &mut Aligned<T> {
        &mut self.values[slot]
    }
}
