//! A vehicle's side of the RSUs' batches (warnings and CPMs), in real time: kept as they come,
//! waited for by the step that needs them, decided as virtual time decides them.

use super::{AHEAD_STEPS, Inbox, Receiving, RsuBatch, WARNING_WAIT};
use risktwin_transport::sync::CondvarExt;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_v2x::warning::Warning;
use std::sync::MutexGuard;
use std::time::Instant;

/// One RSU's warning batches, as a vehicle receives them.
#[derive(Debug)]
pub(super) struct RsuBatches {
    pub(super) id: String,
    /// Whether its hello came: its messages reach this participant.
    pub(super) hello: bool,
    /// The newest step a batch came for.
    pub(super) through: Option<u64>,
    /// Steps through which missing batches were counted late.
    pub(super) counted: Option<u64>,
    /// Batches not decided yet, with their arrival, ns since the Unix epoch.
    pub(super) batches: Vec<(RsuBatch, i64)>,
}

/// A step number with `None` before step 0, for comparisons.
pub(super) fn after(step: Option<u64>) -> u64 {
    step.map_or(0, |s| s.saturating_add(1))
}

impl Inbox {
    /// RSU `sender`'s warnings of one step: kept until a step of this vehicle needs them.
    /// Another RSU ignores them; a batch of no RSU of the scene, repeated or out of order, or
    /// not finite is counted malformed.
    pub(super) fn take_warnings(&self, state: &mut Receiving, sender: &str, batch: RsuBatch) {
        if !self.warners.iter().any(|w| w == sender) {
            state.malformed += 1;
            return;
        }
        let horizon = state.latest_step.unwrap_or(0).saturating_add(AHEAD_STEPS);
        let Some(rsu) = state.rsus.iter_mut().find(|r| r.id == sender) else { return };
        let seqs_fit = batch.first_seq.checked_add(batch.objects.len() as u64).is_some();
        if batch.step < after(rsu.through) || !batch.is_finite() || !seqs_fit {
            state.malformed += 1;
            return;
        }
        // A step far ahead (a wrong or hostile sender) must not move `through` past the genuine
        // batches to come.
        if batch.step > horizon {
            state.ahead += 1;
            return;
        }
        // One publisher's samples come in order: a step skipped is a batch lost.
        let lost = batch.step - after(rsu.through);
        if lost > 0 {
            tracing::warn!(
                "V2X {}: {sender}'s warning batches of steps {} to {} lost",
                self.id,
                after(rsu.through),
                batch.step - 1
            );
            state.warning_batches_lost += lost;
        }
        rsu.through = Some(batch.step);
        rsu.batches.push((batch, unix_ns()));
    }

    /// Waits (at most [`WARNING_WAIT`]) for every RSU's warnings through `step`, counting the
    /// batches that did not come, then decides every copy of the batches held through `step`:
    /// in step order, RSUs in participant order, as virtual time decides them.
    pub(super) fn decide_warnings_through<'a>(
        &'a self,
        mut state: MutexGuard<'a, Receiving>,
        step: u64,
    ) -> MutexGuard<'a, Receiving> {
        let deadline = Instant::now() + WARNING_WAIT;
        while !state.has_warnings_through(Some(step)) {
            let now = Instant::now();
            if now >= deadline {
                let receiving = &mut *state;
                for rsu in &mut receiving.rsus {
                    let have = after(rsu.through).max(after(rsu.counted));
                    receiving.warning_batches_late += (step + 1).saturating_sub(have);
                    rsu.counted = Some(step.max(rsu.counted.unwrap_or(0)));
                }
                tracing::warn!("V2X {}: RSU warnings of step {step} not here after {WARNING_WAIT:?}", self.id);
                break;
            }
            state = self.taken.waited_for(state, deadline - now);
        }
        let receiving = &mut *state;
        let mut ready: Vec<(u64, usize, RsuBatch, i64)> = Vec::new();
        for (index, rsu) in receiving.rsus.iter_mut().enumerate() {
            let (now, later): (Vec<_>, Vec<_>) = rsu.batches.drain(..).partition(|(b, _)| b.step <= step);
            rsu.batches = later;
            ready.extend(now.into_iter().map(|(b, arrived)| (b.step, index, b, arrived)));
        }
        ready.sort_by_key(|&(step, index, ..)| (step, index));
        for (_, index, batch, arrived_unix_ns) in ready {
            let own = match receiving.own.get(&batch.step) {
                Some(&Some(own)) => own,
                // Not in the world when the warnings were made: no copy (as in virtual time).
                Some(None) => continue,
                None => {
                    receiving.stale += 1;
                    continue;
                }
            };
            let sender = receiving.rsus[index].id.as_str();
            let distance_m = (batch.from[0] - own.0).hypot(batch.from[1] - own.1);
            let ids = (sender, self.id.as_str());
            let late = |latency_ms: f64| {
                u64::from(arrived_unix_ns > batch.sent_unix_ns.saturating_add((latency_ms * 1e6).round() as i64))
            };
            for (seq, object) in (batch.first_seq..).zip(&batch.objects) {
                let latency_ms = self.channel.warning_latency_ms(sender, seq);
                let warning = Warning { made_s: batch.made_s, object: *object };
                let tally = &mut receiving.tally;
                if receiving.warnings.decide(&self.channel, ids, seq, distance_m, latency_ms, warning, tally) {
                    receiving.warnings_late += late(latency_ms);
                }
            }
            // After the step's warnings, as virtual time decides them.
            if let Some(cpm) = &batch.cpm {
                let latency_ms = self.channel.cpm_latency_ms(sender, cpm.seq);
                let (inbox, tally) = (&mut receiving.warnings, &mut receiving.tally);
                let made = (batch.made_s, latency_ms);
                if inbox.decide_cpm(&self.channel, ids, cpm.seq, distance_m, made, &cpm.objects, tally) {
                    receiving.cpms_late += late(latency_ms);
                }
            }
        }
        state
    }
}
