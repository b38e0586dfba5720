//! A 64-bit fingerprint of the snapshots a worker emitted, so that two runs (live and replay,
//! or two machines) can be compared by one number.

use super::sample::TwinSample;
use risktwin_align::Snapshot;

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a over every snapshot's tick and, per value, its status and (for states) pose bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SnapshotDigest {
    hash: u64,
    count: u64,
}

impl Default for SnapshotDigest {
    fn default() -> Self {
        SnapshotDigest { hash: FNV_OFFSET, count: 0 }
    }
}

impl SnapshotDigest {
    /// Folds one snapshot in.
    pub fn add(&mut self, snapshot: &Snapshot<TwinSample>) {
        self.count += 1;
        self.word(snapshot.tick_ns as u64);
        for value in snapshot.values() {
            self.word(value.status as u64);
            if let Some(TwinSample::State(k)) = &value.value {
                self.word(k.pose.x_m.to_bits());
                self.word(k.pose.y_m.to_bits());
                self.word(k.pose.heading_rad.to_bits());
            }
        }
    }

    /// The hash so far.
    pub fn value(&self) -> u64 {
        self.hash
    }

    /// Snapshots folded in so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// The hash as 16 hex digits (how summaries print it: JSON numbers lose u64 precision in
    /// many readers).
    pub fn hex(&self) -> String {
        format!("{:016x}", self.hash)
    }

    fn word(&mut self, w: u64) {
        for byte in w.to_le_bytes() {
            self.hash ^= u64::from(byte);
            self.hash = self.hash.wrapping_mul(FNV_PRIME);
        }
    }
}
