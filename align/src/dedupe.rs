//! Exactly-once by (source, sequence) with a bounded reorder window, and loss accounting.
//!
//! Each source keeps the highest sequence number it has accepted and a bitmap of the last `W`
//! sequence numbers (the technique of IPsec anti-replay, RFC 4303 §3.4.3, and of DTLS): a number
//! inside the window is accepted once and refused after; a number older than the window is
//! refused as too old, because it can no longer be told apart from a duplicate.
//!
//! Loss accounting: a jump of the highest number over a gap counts every skipped number as
//! *presumed lost*; a skipped number that arrives later inside the window is un-counted (and
//! counted as *recovered*, i.e. reordered). So at any time, per source,
//! `fresh + presumed_lost = highest − first + 1`, which is what the end-to-end check
//! "recorded + counted drops = sent" rests on.
//!
//! Sequence jumps: a number more than the window away from the highest one — ahead of it, or
//! older than the window — is not trusted on its own (a forged number far ahead would otherwise
//! make every genuine number after it too old, and a runaway one inflate the loss count). It is
//! refused (a jump ahead as `seq-jump`, one behind as `too-old`) and remembered; only when the
//! source's very next number is the one after it does the source move there (RTP's probation
//! rule, RFC 3550 Appendix A.1, with `MAX_DROPOUT` = the window and `MIN_SEQUENTIAL` = 2). A
//! confirmed jump ahead goes on counting (the skipped numbers, the refused one among them, are
//! presumed lost); a confirmed jump back starts a new incarnation at the confirming number (an
//! edge that started over unannounced). So one forged or runaway number costs nothing but its
//! own drop, and a forger must send two consecutive numbers between two genuine ones to move a
//! source, which the source's next two numbers move back (counted `too-old` once and a restart).
//! Authentication keeps forgers out altogether; this rule bounds what one can do.

use super::reason::DropReason;
use super::source::SourceIndex;

/// Messages after [`Deduper::restart`] that may still show a new incarnation.
pub const RESTART_GRACE: u32 = 64;

/// The default reorder window, in sequence numbers (20 s of a 50 Hz stream).
pub const DEFAULT_WINDOW: u64 = 1024;

/// What the deduplicator decided about one (source, sequence) pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// First time seen: take it.
    Fresh,
    /// Already accepted inside the window.
    Duplicate,
    /// Older than the window (or than the source's first expected number).
    TooOld,
    /// More than the window ahead of the highest number, not (yet) confirmed by the next one.
    Jump,
}

impl Verdict {
    /// The drop reason for a refusal; `None` for [`Verdict::Fresh`].
    pub const fn drop_reason(self) -> Option<DropReason> {
        match self {
            Verdict::Fresh => None,
            Verdict::Duplicate => Some(DropReason::Duplicate),
            Verdict::TooOld => Some(DropReason::TooOld),
            Verdict::Jump => Some(DropReason::SeqJump),
        }
    }
}

/// Per-source (or summed) counters of the deduplicator.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeqCounts {
    pub fresh: u64,
    pub duplicate: u64,
    pub too_old: u64,
    /// Numbers refused as unconfirmed jumps ahead ([`Verdict::Jump`]).
    pub jumps: u64,
    /// Numbers skipped by the highest one and not (yet) seen: presumed lost on the way.
    pub presumed_lost: u64,
    /// Numbers that arrived after a higher one, inside the window (reordered, not lost).
    pub recovered: u64,
    /// New incarnations: after [`Deduper::restart`], the times a number at or below the highest
    /// showed that the source started over, and confirmed jumps back.
    pub restarts: u64,
    /// Confirmed jumps ahead (the source went on counting from a number beyond the window).
    pub resyncs: u64,
}

impl SeqCounts {
    fn add(&mut self, o: &SeqCounts) {
        self.fresh += o.fresh;
        self.duplicate += o.duplicate;
        self.too_old += o.too_old;
        self.jumps += o.jumps;
        self.presumed_lost = self.presumed_lost.saturating_add(o.presumed_lost);
        self.recovered += o.recovered;
        self.restarts += o.restarts;
        self.resyncs += o.resyncs;
    }
}

/// How the deduplicator is set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DedupConfig {
    /// Reorder window in sequence numbers; rounded up to a power of two, at least 64.
    pub window: u64,
    /// The number every source starts counting from (`Some(0)` by default), so numbers lost
    /// before the first arrival are counted too. `None`: the first number seen from a source
    /// starts its count, and anything below it is refused as too old.
    pub first_seq: Option<u64>,
}

impl Default for DedupConfig {
    fn default() -> Self {
        Self { window: DEFAULT_WINDOW, first_seq: Some(0) }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct SeqState {
    started: bool,
    /// No number at or above `floor` accepted yet.
    empty: bool,
    floor: u64,
    highest: u64,
    /// The source may have started over ([`Deduper::restart`]): the next numbers decide, for up
    /// to this many more messages.
    may_restart: u32,
    /// The last number refused for lying more than the window away: the next one confirms it.
    probation: Option<u64>,
    counts: SeqCounts,
    /// `counts.fresh` and `counts.presumed_lost` when the current incarnation started, so that
    /// [`Deduper::progress`] tells of this incarnation alone.
    base_fresh: u64,
    base_lost: u64,
}

/// How far the current incarnation of a source has been accounted for: what a delivery
/// acknowledgement tells the edge.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeqProgress {
    /// Every number below this one was accepted or is counted presumed lost.
    pub next_seq: u64,
    /// Numbers accepted.
    pub received: u64,
    /// Numbers skipped and not (yet) seen (those before the first accepted one included).
    pub lost: u64,
}

/// The per-source sequence windows; memory is `W/8` bytes per source, allocated once per source.
#[derive(Debug, Clone)]
pub struct Deduper {
    window: u64,
    words: usize,
    first_seq: Option<u64>,
    states: Vec<SeqState>,
    bits: Vec<u64>,
}

impl Deduper {
    /// A deduplicator with no sources yet.
    pub fn new(config: DedupConfig) -> Self {
        let window = config.window.max(64).next_power_of_two();
        Self {
            window,
            words: (window / 64) as usize,
            first_seq: config.first_seq,
            states: Vec::new(),
            bits: Vec::new(),
        }
    }

    /// The reorder window actually used (a power of two).
    pub fn window(&self) -> u64 {
        self.window
    }

    /// Decides on `(source, seq)` and records it; allocates only the first time `source` appears.
    pub fn accept(&mut self, source: SourceIndex, seq: u64) -> Verdict {
        let s = source.as_usize();
        if s >= self.states.len() {
            self.states.resize(s + 1, SeqState::default());
            self.bits.resize((s + 1) * self.words, 0);
        }
        let window = self.window;
        let st = &mut self.states[s];
        let bits = &mut self.bits[s * self.words..(s + 1) * self.words];
        if st.may_restart > 0 {
            st.may_restart -= 1;
            if seq <= st.highest {
                st.may_restart = 0;
                st.started = false;
                st.counts.restarts += 1;
                bits.fill(0);
            }
        }
        if !st.started {
            st.base_fresh = st.counts.fresh;
            st.base_lost = st.counts.presumed_lost;
            st.started = true;
            st.empty = true;
            st.floor = self.first_seq.unwrap_or(seq);
        }
        let confirmed = st.probation.take().is_some_and(|p| p.checked_add(1) == Some(seq));
        let verdict = if !st.empty && seq < st.highest && st.highest - seq >= window && confirmed {
            // A confirmed jump back: the source started over from an earlier number.
            st.counts.restarts += 1;
            st.base_fresh = st.counts.fresh;
            st.base_lost = st.counts.presumed_lost;
            st.floor = seq;
            st.highest = seq;
            bits.fill(0);
            set_bit(bits, window, seq);
            Verdict::Fresh
        } else if seq < st.floor {
            Verdict::TooOld
        } else if !st.empty && seq > st.highest && seq - st.highest > window && !confirmed {
            st.probation = Some(seq);
            Verdict::Jump
        } else if st.empty {
            st.empty = false;
            st.highest = seq;
            st.counts.presumed_lost = st.counts.presumed_lost.saturating_add(seq - st.floor);
            set_bit(bits, window, seq);
            Verdict::Fresh
        } else if seq > st.highest {
            let gap = seq - st.highest - 1;
            // The slots of the skipped numbers still hold numbers that now leave the window.
            if gap >= window - 1 {
                bits.fill(0);
            } else {
                for n in st.highest + 1..seq {
                    clear_bit(bits, window, n);
                }
            }
            set_bit(bits, window, seq);
            st.highest = seq;
            st.counts.presumed_lost = st.counts.presumed_lost.saturating_add(gap);
            if gap >= window {
                st.counts.resyncs += 1;
            }
            Verdict::Fresh
        } else if st.highest - seq >= window {
            st.probation = Some(seq);
            Verdict::TooOld
        } else if get_bit(bits, window, seq) {
            Verdict::Duplicate
        } else {
            set_bit(bits, window, seq);
            st.counts.presumed_lost -= 1;
            st.counts.recovered += 1;
            Verdict::Fresh
        };
        match verdict {
            Verdict::Fresh => st.counts.fresh += 1,
            Verdict::Duplicate => st.counts.duplicate += 1,
            Verdict::TooOld => st.counts.too_old += 1,
            Verdict::Jump => st.counts.jumps += 1,
        }
        verdict
    }

    /// `source` may have started over (its process left; a new one under the same name numbers
    /// from its first number again). The next [`RESTART_GRACE`] numbers decide: one above the
    /// highest accepted continues the count (a message of the old process still in flight, or
    /// the process did not restart after all); the first at or below it starts a new
    /// incarnation, whose window is empty and whose count starts as a new source's. The
    /// counters go on summing, so the accounting identity holds summed over incarnations.
    pub fn restart(&mut self, source: SourceIndex) {
        if let Some(st) = self.states.get_mut(source.as_usize()) {
            st.may_restart = if st.started && !st.empty { RESTART_GRACE } else { 0 };
        }
    }

    /// The counters of one source (zeros for a source never seen).
    pub fn counts(&self, source: SourceIndex) -> SeqCounts {
        self.states.get(source.as_usize()).map(|s| s.counts).unwrap_or_default()
    }

    /// The highest sequence number accepted from `source`, if any.
    pub fn highest(&self, source: SourceIndex) -> Option<u64> {
        self.states.get(source.as_usize()).filter(|s| s.started && !s.empty).map(|s| s.highest)
    }

    /// How far `source`'s current incarnation is accounted for; `None` before its first
    /// accepted number.
    pub fn progress(&self, source: SourceIndex) -> Option<SeqProgress> {
        let st = self.states.get(source.as_usize()).filter(|s| s.started && !s.empty)?;
        Some(SeqProgress {
            next_seq: st.highest.saturating_add(1),
            received: st.counts.fresh - st.base_fresh,
            lost: st.counts.presumed_lost.saturating_sub(st.base_lost),
        })
    }

    /// The counters summed over all sources.
    pub fn totals(&self) -> SeqCounts {
        let mut t = SeqCounts::default();
        for s in &self.states {
            t.add(&s.counts);
        }
        t
    }
}

fn slot(window: u64, n: u64) -> (usize, u64) {
    let i = n & (window - 1);
    ((i / 64) as usize, 1u64 << (i % 64))
}

fn set_bit(bits: &mut [u64], window: u64, n: u64) {
    let (w, m) = slot(window, n);
    bits[w] |= m;
}

fn clear_bit(bits: &mut [u64], window: u64, n: u64) {
    let (w, m) = slot(window, n);
    bits[w] &= !m;
}

fn get_bit(bits: &[u64], window: u64, n: u64) -> bool {
    let (w, m) = slot(window, n);
    bits[w] & m != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: SourceIndex = SourceIndex(0);
    const B: SourceIndex = SourceIndex(1);

    fn dedup(window: u64) -> Deduper {
        Deduper::new(DedupConfig { window, first_seq: Some(0) })
    }

    #[test]
    fn duplicates_are_refused_and_sources_are_independent() {
        let mut d = dedup(64);
        assert_eq!(d.accept(A, 0), Verdict::Fresh);
        assert_eq!(d.accept(A, 1), Verdict::Fresh);
        assert_eq!(d.accept(A, 1), Verdict::Duplicate);
        assert_eq!(d.accept(A, 0), Verdict::Duplicate);
        assert_eq!(d.accept(B, 1), Verdict::Fresh, "B's numbers are its own");
        assert_eq!(d.counts(A), SeqCounts { fresh: 2, duplicate: 2, ..Default::default() });
        assert_eq!(d.counts(B).presumed_lost, 1, "B's 0 was skipped");
        assert_eq!(d.totals().fresh, 3);
        assert_eq!(Verdict::Duplicate.drop_reason(), Some(DropReason::Duplicate));
        assert_eq!(Verdict::Fresh.drop_reason(), None);
    }

    #[test]
    fn reorders_inside_the_window_are_taken_once_and_uncount_the_loss() {
        let mut d = dedup(64);
        for n in [0, 1, 5] {
            assert_eq!(d.accept(A, n), Verdict::Fresh);
        }
        assert_eq!(d.counts(A).presumed_lost, 3, "2, 3, 4 skipped");
        assert_eq!(d.accept(A, 3), Verdict::Fresh);
        assert_eq!(d.accept(A, 3), Verdict::Duplicate);
        assert_eq!(d.accept(A, 2), Verdict::Fresh);
        let c = d.counts(A);
        assert_eq!((c.fresh, c.presumed_lost, c.recovered, c.duplicate), (5, 1, 2, 1));
        assert_eq!(d.highest(A), Some(5));
    }

    #[test]
    fn numbers_older_than_the_window_are_too_old() {
        let mut d = dedup(64);
        assert_eq!(d.window(), 64);
        assert_eq!(d.accept(A, 100), Verdict::Fresh);
        assert_eq!(d.accept(A, 37), Verdict::Fresh, "100 − 37 = 63 < 64: inside");
        assert_eq!(d.accept(A, 36), Verdict::TooOld, "100 − 36 = 64: outside");
        assert_eq!(d.accept(A, 0), Verdict::TooOld);
        assert_eq!(d.counts(A).too_old, 2);
        // 36 stays counted as lost: it arrived too late to be told from a duplicate.
        assert_eq!(d.counts(A).presumed_lost, 99);
    }

    #[test]
    fn one_forged_number_far_ahead_costs_only_itself() {
        // The probe that cut a vehicle off: one forged number far ahead made every genuine one
        // after it too old. Now it is refused and the genuine stream goes on untouched.
        for forged in [5_000, 1_000_000_000_000, u64::MAX] {
            let mut d = dedup(1024);
            for n in 0..100 {
                assert_eq!(d.accept(A, n), Verdict::Fresh);
            }
            assert_eq!(d.accept(A, forged), Verdict::Jump);
            for n in 100..1_500 {
                assert_eq!(d.accept(A, n), Verdict::Fresh, "genuine {n} after forged {forged}");
            }
            let c = d.counts(A);
            assert_eq!((c.fresh, c.jumps, c.presumed_lost, c.too_old), (1_500, 1, 0, 0));
            assert_eq!(Verdict::Jump.drop_reason(), Some(DropReason::SeqJump));
        }
    }

    #[test]
    fn a_confirmed_jump_ahead_goes_on_counting_and_a_confirmed_jump_back_starts_over() {
        let mut d = dedup(64);
        for n in 0..10 {
            d.accept(A, n);
        }
        // A real outage longer than the window: the first number after it waits for the next.
        assert_eq!(d.accept(A, 500), Verdict::Jump);
        assert_eq!(d.accept(A, 501), Verdict::Fresh, "501 confirms 500");
        let c = d.counts(A);
        assert_eq!((c.fresh, c.presumed_lost, c.resyncs), (11, 491, 1), "10..=500 presumed lost");
        assert_eq!(c.fresh + c.presumed_lost, d.highest(A).unwrap() + 1, "the span identity holds");
        // The numbers in between do not confirm anything: 502 after a refused 900 is in range.
        assert_eq!(d.accept(A, 900), Verdict::Jump);
        assert_eq!(d.accept(A, 502), Verdict::Fresh);
        assert_eq!(d.accept(A, 901), Verdict::Jump, "900 was not confirmed by its successor");
        // Two numbers far below, one after the other: an unannounced new incarnation.
        assert_eq!(d.accept(A, 3), Verdict::TooOld);
        assert_eq!(d.accept(A, 4), Verdict::Fresh, "4 confirms 3: the source started over");
        assert_eq!(d.accept(A, 5), Verdict::Fresh);
        assert_eq!(d.accept(A, 4), Verdict::Duplicate);
        assert_eq!(d.counts(A).restarts, 1);
        assert_eq!(d.highest(A), Some(5));
    }

    #[test]
    fn a_forger_with_consecutive_numbers_moves_a_source_only_until_its_next_two_numbers() {
        let mut d = dedup(1024);
        for n in 0..100 {
            d.accept(A, n);
        }
        assert_eq!(d.accept(A, 50_000), Verdict::Jump);
        assert_eq!(d.accept(A, 50_001), Verdict::Fresh, "the forger's pair moves the source");
        assert_eq!(d.accept(A, 100), Verdict::TooOld, "the genuine next number is refused once");
        for n in 101..200 {
            assert_eq!(d.accept(A, n), Verdict::Fresh, "and the source is back at {n}");
        }
        let c = d.counts(A);
        assert_eq!((c.too_old, c.jumps, c.restarts, c.resyncs), (1, 1, 1, 1));
    }

    #[test]
    fn the_window_slides_without_stale_bits() {
        // Number n and n + W share a slot: after the window moved past n, n + W is fresh.
        let mut d = dedup(64);
        assert_eq!(d.accept(A, 3), Verdict::Fresh);
        assert_eq!(d.accept(A, 3 + 64), Verdict::Fresh);
        assert_eq!(d.accept(A, 3 + 64), Verdict::Duplicate);
        // A jump of several windows clears everything; numbers just below it are fresh even
        // where their slot was set before the jump (41 and 937 share slot 41).
        assert_eq!(d.accept(A, 41), Verdict::Fresh);
        assert_eq!(d.accept(A, 999), Verdict::Jump, "beyond the window: on probation");
        assert_eq!(d.accept(A, 1000), Verdict::Fresh, "confirmed");
        assert_eq!(d.accept(A, 1000 - 64), Verdict::TooOld);
        assert_eq!(d.accept(A, 1000 - 63), Verdict::Fresh, "slot of 937 was cleared by the jump");
        assert_eq!(d.accept(A, 1000 - 1), Verdict::Fresh, "the refused number is still welcome");
    }

    #[test]
    fn fresh_plus_lost_equals_the_span_under_random_loss_reorder_and_duplication() {
        let mut rng = risktwin_common::rng::Rng::new(7);
        let mut d = dedup(1024);
        let sent = 20_000u64;
        let mut inflight: Vec<u64> = Vec::new();
        let mut delivered_unique = std::collections::HashSet::new();
        for n in 0..sent {
            if rng.chance(0.05) {
                continue; // lost
            }
            inflight.push(n);
            if rng.chance(0.1) {
                inflight.push(n); // duplicated
            }
            // Deliver in a shuffled order within a small reorder buffer.
            while inflight.len() > 8 {
                let i = rng.below(inflight.len() as u64) as usize;
                let m = inflight.swap_remove(i);
                if d.accept(A, m) == Verdict::Fresh {
                    assert!(delivered_unique.insert(m), "{m} taken twice");
                }
            }
        }
        for m in inflight {
            if d.accept(A, m) == Verdict::Fresh {
                assert!(delivered_unique.insert(m));
            }
        }
        let c = d.counts(A);
        let span = d.highest(A).unwrap() + 1;
        assert_eq!(c.fresh + c.presumed_lost, span);
        assert_eq!(c.fresh, delivered_unique.len() as u64);
        assert!(c.duplicate > 1000 && c.recovered > 1000, "{c:?}");
        assert_eq!(c.too_old, 0, "reorder depth 8 is far inside the window");
    }

    #[test]
    fn first_seq_none_starts_at_the_first_number_seen() {
        let mut d = Deduper::new(DedupConfig { window: 64, first_seq: None });
        assert_eq!(d.accept(A, 500), Verdict::Fresh);
        assert_eq!(d.counts(A).presumed_lost, 0);
        assert_eq!(d.accept(A, 499), Verdict::TooOld);
        assert_eq!(d.accept(A, u64::MAX - 1), Verdict::Jump);
        assert_eq!(d.accept(A, u64::MAX), Verdict::Fresh, "confirmed");
        assert_eq!(d.accept(A, u64::MAX), Verdict::Duplicate, "no overflow at the top");
        assert_eq!(d.accept(A, u64::MAX - 1), Verdict::Fresh, "inside the window now");
    }

    #[test]
    fn a_restarted_source_counts_from_its_first_number_again_and_keeps_its_counters() {
        let mut d = Deduper::new(DedupConfig::default());
        for seq in 0..10 {
            assert_eq!(d.accept(A, seq), Verdict::Fresh);
        }
        assert_eq!(d.accept(A, 3), Verdict::Duplicate, "the same incarnation");
        d.restart(A);
        assert_eq!(d.accept(A, 1), Verdict::Fresh, "a new process numbers from its start again");
        assert_eq!(d.accept(A, 0), Verdict::Fresh);
        assert_eq!(d.accept(A, 1), Verdict::Duplicate);
        let c = d.counts(A);
        assert_eq!((c.fresh, c.duplicate, c.presumed_lost, c.recovered), (12, 2, 0, 1));
        d.restart(B);
        assert_eq!(d.counts(B), SeqCounts::default(), "restarting a source never seen changes nothing");
        // The old process's last message still in flight after it left, then the new process.
        d.restart(A);
        assert_eq!(d.accept(A, 2), Verdict::Fresh, "the old incarnation's, late");
        assert_eq!(d.accept(A, 0), Verdict::Fresh, "the new incarnation's first");
        assert_eq!(d.accept(A, 0), Verdict::Duplicate);
        assert_eq!(d.counts(A).presumed_lost, 0, "nothing counted twice");
        assert_eq!(d.counts(A).restarts, 2, "two new incarnations");
        // A source that left and came back without restarting goes on counting past the grace.
        d.restart(A);
        for seq in 1..=u64::from(RESTART_GRACE) {
            assert_eq!(d.accept(A, seq), Verdict::Fresh);
        }
        assert_eq!(d.accept(A, 3), Verdict::Duplicate, "the same incarnation after the grace");
        assert_eq!(d.counts(A).presumed_lost, 0);
        assert_eq!(d.counts(A).restarts, 2, "coming back is not starting over");
    }

    #[test]
    fn progress_tells_of_the_current_incarnation_only() {
        let mut d = dedup(64);
        assert_eq!(d.progress(A), None, "nothing accepted yet");
        for seq in [2, 3, 5, 4, 7] {
            assert_eq!(d.accept(A, seq), Verdict::Fresh);
        }
        assert_eq!(d.progress(A), Some(SeqProgress { next_seq: 8, received: 5, lost: 3 }), "0, 1 and 6 missing");
        d.restart(A);
        assert_eq!(d.accept(A, 0), Verdict::Fresh, "a new process");
        assert_eq!(d.accept(A, 2), Verdict::Fresh);
        assert_eq!(d.progress(A), Some(SeqProgress { next_seq: 3, received: 2, lost: 1 }));
        assert_eq!(d.counts(A).fresh, 7, "the counters go on summing");
    }
}
