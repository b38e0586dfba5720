//! The transport's own floor under a lockstep scene (`risktwin bench fanout`): raw Zenoh, one
//! coordinator and N echo processes, each round one put out and N answers back, the shape of
//! one lockstep step with nothing else in it (no physics, no sensors, no streams, no decoding).
//!
//! The coordinator listens on TCP loopback; each echo is its own process and Zenoh peer that
//! connects to it, subscribes to the round key with a callback and answers from that callback
//! with a prebuilt reply, as a scene participant answers its truth. The coordinator tallies the
//! answers in its subscriber's callback and is woken once per round, when the last is in: the
//! same mechanism as `ZenohAuthority`. `deploy/bench/scene-lockstep.sh` runs this beside a
//! lockstep scene of as many participants, with the truth and reply sizes of that scene.

use crate::BenchError;
use risktwin_transport::sync::{CondvarExt, LockExt};
use risktwin_transport::zenoh::qos::{CongestionControl, Reliability};
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::zenoh::{Session, Wait};
use serde::Serialize;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Where the rounds go out; answers come back on `REPLIES/<echo>`.
const ROUNDS_KEY: &str = "risktwin/bench/fanout/round";
const REPLIES: &str = "risktwin/bench/fanout/reply";

/// How long one round may take before the benchmark gives up (an echo died).
const ROUND_TIMEOUT: Duration = Duration::from_secs(5);

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FanoutConfig {
    /// Echo processes.
    pub echoes: usize,
    /// Timed rounds (after as many warm-up rounds as it takes every echo to answer, plus 50).
    pub rounds: u64,
    /// Size of what goes out each round, bytes (a scene's truth).
    pub out_bytes: usize,
    /// Size of each answer, bytes (a participant's reply).
    pub reply_bytes: usize,
}

impl FanoutConfig {
    /// Refuses a configuration that measures nothing.
    pub fn check(&self) -> Result<(), BenchError> {
        if self.echoes == 0 || self.rounds == 0 || self.out_bytes < 8 || self.reply_bytes < 16 {
            return Err(BenchError::Input(
                "--echoes and --rounds must be positive, --out-bytes at least 8, --reply-bytes at least 16".into(),
            ));
        }
        Ok(())
    }
}

/// The figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FanoutReport {
    pub echoes: usize,
    pub rounds: u64,
    pub out_bytes: usize,
    pub reply_bytes: usize,
    /// Wall time per round, ms: the raw Zenoh cost of one lockstep step of `echoes` participants.
    pub ms_per_round: f64,
}

/// The answers to the current round, tallied by the replies' callback: each echo counts once.
struct Tally {
    state: Mutex<Round>,
    all_in: Condvar,
}

struct Round {
    round: u64,
    answered: Vec<bool>,
    missing: usize,
}

impl Tally {
    /// A reply carries the round, then the echo's index (8 bytes each, little-endian).
    fn on_reply(&self, payload: &[u8]) {
        let word = |at: usize| payload.get(at..at + 8).and_then(|b| b.try_into().ok()).map(u64::from_le_bytes);
        let (Some(round), Some(echo)) = (word(0), word(8)) else { return };
        let mut state = self.state.locked();
        if state.round != round {
            return;
        }
        if let Some(seen) = state.answered.get_mut(echo as usize)
            && !std::mem::replace(seen, true)
        {
            state.missing -= 1;
            if state.missing == 0 {
                self.all_in.notify_one();
            }
        }
    }

    /// Waits until every echo answered the current round; false on the timeout.
    fn wait(&self, timeout: Duration) -> bool {
        let state = self.state.locked();
        let (state, _) = self.all_in.waited_while(state, timeout, |s| s.missing > 0);
        state.missing == 0
    }

    fn start(&self, round: u64) {
        let mut state = self.state.locked();
        state.round = round;
        state.answered.fill(false);
        state.missing = state.answered.len();
    }
}

fn zenoh_error(what: &str) -> impl Fn(Box<dyn std::error::Error + Send + Sync>) -> BenchError + '_ {
    move |e| BenchError::Runtime(format!("{what}: {e}"))
}

/// The coordinator's side: `session` listens, and `config.echoes` echo processes connect to it.
pub fn coordinate(session: &Session, config: FanoutConfig) -> Result<FanoutReport, BenchError> {
    config.check()?;
    let round = Round { round: 0, answered: vec![false; config.echoes], missing: config.echoes };
    let tally = Arc::new(Tally { state: Mutex::new(round), all_in: Condvar::new() });
    let _replies = session
        .declare_subscriber(format!("{REPLIES}/*"))
        .callback({
            let tally = Arc::clone(&tally);
            move |sample: Sample| tally.on_reply(&sample.payload().to_bytes())
        })
        .wait()
        .map_err(zenoh_error("replies"))?;
    let out = session
        .declare_publisher(ROUNDS_KEY)
        .congestion_control(CongestionControl::Block)
        .reliability(Reliability::Reliable)
        .wait()
        .map_err(zenoh_error("rounds"))?;
    let mut payload = vec![0u8; config.out_bytes];
    let mut round = 0u64;
    let mut put_round = |round: u64| {
        tally.start(round);
        payload[..8].copy_from_slice(&round.to_le_bytes());
        out.put(payload.as_slice()).wait().map_err(zenoh_error("round"))
    };
    // Warm-up: repeat until a round is answered by every echo (all have joined), then 50 more.
    let joined_by = Instant::now() + Duration::from_secs(30);
    loop {
        round += 1;
        put_round(round)?;
        if tally.wait(Duration::from_millis(200)) {
            break;
        }
        if Instant::now() >= joined_by {
            return Err(BenchError::Runtime(format!("not every one of {} echoes joined within 30 s", config.echoes)));
        }
    }
    let mut timed = |rounds: u64| -> Result<Duration, BenchError> {
        let start = Instant::now();
        for _ in 0..rounds {
            round += 1;
            put_round(round)?;
            if !tally.wait(ROUND_TIMEOUT) {
                return Err(BenchError::Runtime(format!("round {round} was not answered by every echo")));
            }
        }
        Ok(start.elapsed())
    };
    timed(50)?;
    let wall = timed(config.rounds)?;
    Ok(FanoutReport {
        echoes: config.echoes,
        rounds: config.rounds,
        out_bytes: config.out_bytes,
        reply_bytes: config.reply_bytes,
        ms_per_round: 1e3 * wall.as_secs_f64() / config.rounds as f64,
    })
}

/// One echo: answers every round with `reply_bytes` bytes (the round number, then `id`) from the
/// subscriber's callback, until its standard input ends (the coordinator exited or closed it).
pub fn echo(session: &Session, id: usize, reply_bytes: usize) -> Result<(), BenchError> {
    let reply_key = format!("{REPLIES}/{id}");
    let publisher = session
        .declare_publisher(reply_key)
        .congestion_control(CongestionControl::Block)
        .reliability(Reliability::Reliable)
        .wait()
        .map_err(zenoh_error("reply"))?;
    let mut reply = vec![0u8; reply_bytes.max(16)];
    reply[8..16].copy_from_slice(&(id as u64).to_le_bytes());
    let reply = Mutex::new(reply);
    let _rounds = session
        .declare_subscriber(ROUNDS_KEY)
        .callback(move |sample: Sample| {
            let round = sample.payload().to_bytes();
            let mut reply = reply.locked();
            if let Some(stamp) = round.get(..8) {
                reply[..8].copy_from_slice(stamp);
                // A failed put shows as an unanswered round at the coordinator.
                let _ = publisher.put(reply.as_slice()).wait();
            }
        })
        .wait()
        .map_err(zenoh_error("rounds"))?;
    // Returns at end of input, or on a read error: either way the coordinator is gone.
    let _ = std::io::copy(&mut std::io::stdin(), &mut std::io::sink());
    Ok(())
}
