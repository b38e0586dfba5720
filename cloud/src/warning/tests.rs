//! The warner on hand-made states: who is warned, about whom, how often, and what it skips.

use super::*;
use risktwin_align::SourceIndex;
use risktwin_common::telemetry::HazardKind;

const MS: i64 = 1_000_000;

/// A car on the x axis (lane-free: no road) at `x_m`, driving at `vx_mps`.
fn car(x_m: f64, y_m: f64, vx_mps: f64) -> ObservedKinematics {
    ObservedKinematics {
        pose: Pose::new(x_m, y_m, 0.0),
        velocity: Vec2::new(vx_mps, 0.0),
        speed_mps: vx_mps,
        accel_mps2: 0.0,
        footprint: Footprint::new(4.5, 1.8),
        seqs: (0, 0),
    }
}

fn msg(source: u32, seq: u64, t_ns: i64, state: ObservedKinematics) -> AcceptedMessage {
    AcceptedMessage { source: SourceIndex(source), seq, capture_ns: t_ns - 7 * MS, cloud_ns: t_ns, state: Some(state) }
}

/// Collects what a warner hands out: (key, warning).
#[derive(Default)]
struct Sent(Vec<(String, HazardWarning)>);

impl Sent {
    fn sink(&mut self) -> impl FnMut(&str, &HazardWarning) -> bool + Send + '_ {
        |key, w| {
            self.0.push((key.to_owned(), w.clone()));
            true
        }
    }
}

#[test]
fn both_cars_of_a_collision_course_are_warned_and_a_safe_pair_is_not() {
    let mut warner = HazardWarner::new(WarningConfig::default(), None);
    let mut sent = Sent::default();
    let t = 1_000 * MS;
    // Site a: a car 20 m behind a standing one at 10 m/s (gap 15.5 m, TTC 1.55 s).
    // Site b: two cars side by side at the same speed, and one far ahead.
    let feed = [
        ("a", "veh-1", 0, car(0.0, 0.0, 10.0)),
        ("b", "veh-3", 2, car(0.0, 0.0, 20.0)),
        ("b", "veh-4", 3, car(0.0, 3.5, 20.0)),
        ("b", "veh-5", 4, car(200.0, 0.0, 20.0)),
        ("a", "veh-2", 1, car(20.0, 0.0, 0.0)),
    ];
    for (i, (site, source, index, state)) in feed.into_iter().enumerate() {
        let at = t + i as i64 * 5 * MS;
        warner.on_state(site, source, &msg(index, 40, at, state), at + 2 * MS, &mut sent.sink());
    }
    let got: Vec<(&str, &str, &str)> =
        sent.0.iter().map(|(k, w)| (k.as_str(), w.warned_source.as_str(), w.hazard_source.as_str())).collect();
    assert_eq!(
        got,
        [("risktwin/v1/a/veh-2/warning", "veh-2", "veh-1"), ("risktwin/v1/a/veh-1/warning", "veh-1", "veh-2")]
    );
    // Raised by veh-2's message at t + 20 ms; veh-1 (seen at t) moved on 0.2 m by then.
    let (to_2, to_1) = (&sent.0[0].1, &sent.0[1].1);
    assert_eq!((to_2.trigger_source.as_str(), to_2.trigger_seq), ("veh-2", 40));
    assert_eq!((to_2.header.capture_time_ns, to_2.trigger_capture_time_ns), (t + 20 * MS, t + 13 * MS));
    assert_eq!((to_2.header.source.as_str(), to_2.header.seq, to_1.header.seq), ("cloud", 0, 0));
    assert!((to_2.hazard_pose.x_m - 0.2).abs() < 1e-9, "{:?}", to_2.hazard_pose);
    assert_eq!(to_1.hazard_pose.x_m, 20.0);
    assert_eq!(to_2.kind, HazardKind::PredictedContact);
    // Gap 20 − 0.2 − 4.5 = 15.3 m at 10 m/s: contact at 1.53 s, seen at the 1.55 s step.
    assert!((to_2.ttc_s - 1.55).abs() < 1e-9 && (to_2.distance_m - 15.3).abs() < 1e-9, "{to_2:?}");
    let summary = warner.summary();
    assert_eq!((summary.states, summary.sent, summary.critical, summary.failed), (5, 2, 1, 0));
    // veh-3/veh-4 are within reach of each other (3.5 m apart) but never closer; veh-5 is not.
    assert_eq!(summary.pairs_assessed, 2, "{summary:?}");
    assert_eq!(summary.sent_to, BTreeMap::from([("a/veh-1".into(), 1), ("a/veh-2".into(), 1)]));
}

#[test]
fn a_pair_is_warned_about_once_per_repeat_interval_and_a_failed_put_is_tried_again() {
    // The standing lead publishes once; a long enough age bound keeps it.
    let config = WarningConfig { max_age_ns: 2_000 * MS, ..WarningConfig::default() };
    let mut warner = HazardWarner::new(config, None);
    let mut sent = Sent::default();
    let t0 = 1_000 * MS;
    let mut failing = |_: &str, _: &HazardWarning| false;
    warner.on_state("s", "lead", &msg(0, 0, t0, car(30.0, 0.0, 0.0)), t0, &mut failing);
    // The first critical message's puts fail: counted, and the pair is not marked as warned.
    warner.on_state("s", "follow", &msg(1, 0, t0, car(15.0, 0.0, 15.0)), t0, &mut failing);
    assert_eq!((warner.summary().failed, warner.summary().sent), (2, 0));
    // Then the same follower state every 20 ms for 1 s: critical each time.
    for k in 1..=50u64 {
        let t = t0 + k as i64 * 20 * MS;
        warner.on_state("s", "follow", &msg(1, k, t, car(15.0, 0.0, 15.0)), t + MS, &mut sent.sink());
    }
    // 50 critical messages, two directions: sent at 20 ms and 520 ms, the rest held back.
    let summary = warner.summary();
    assert_eq!((summary.sent, summary.rate_limited), (4, 96), "{summary:?}");
    let seqs: Vec<(u64, &str)> = sent.0.iter().map(|(_, w)| (w.trigger_seq, w.warned_source.as_str())).collect();
    assert_eq!(seqs, [(1, "follow"), (1, "lead"), (26, "follow"), (26, "lead")]);
    assert_eq!(sent.0[2].1.header.seq, 1, "the second warning to a vehicle is its number 1");
}

#[test]
fn stale_others_late_triggers_and_other_sites_raise_nothing() {
    let config = WarningConfig::default();
    let mut warner = HazardWarner::new(config, None);
    let mut sent = Sent::default();
    let t = 5_000 * MS;
    warner.on_state("s", "old", &msg(0, 0, t, car(10.0, 0.0, 0.0)), t, &mut sent.sink());
    // 201 ms later the standing car's state is too old to move on: no pair.
    let later = t + config.max_age_ns + MS;
    warner.on_state("s", "new", &msg(1, 0, later, car(0.0, 0.0, 10.0)), later, &mut sent.sink());
    assert_eq!(warner.summary().pairs_assessed, 0);
    // A message received 250 ms after its time (recovered, late): kept as the latest, no one warned.
    let fresh = later + 10 * MS;
    warner.on_state("s", "old", &msg(0, 1, t + 5 * MS, car(10.0, 0.0, 0.0)), t + 255 * MS, &mut sent.sink());
    // An older message than the source's latest: no one warned, the latest stays.
    warner.on_state("s", "new", &msg(1, 1, later - 10 * MS, car(0.0, 0.0, 10.0)), fresh, &mut sent.sink());
    // The same geometry at another site: never paired.
    warner.on_state("other", "x", &msg(2, 0, fresh, car(11.0, 0.0, 0.0)), fresh, &mut sent.sink());
    let summary = warner.summary();
    assert_eq!((summary.states, summary.late_states, summary.pairs_assessed), (5, 2, 0), "{summary:?}");
    assert!(sent.0.is_empty());
}

#[test]
fn a_source_whose_id_makes_no_key_is_counted_not_warned() {
    let mut warner = HazardWarner::new(WarningConfig::default(), None);
    let mut sent = Sent::default();
    let t = 1_000 * MS;
    // `+` passes Zenoh's key chunks but not the key scheme's ids.
    warner.on_state("s", "odd+id", &msg(0, 0, t, car(10.0, 0.0, 0.0)), t, &mut sent.sink());
    warner.on_state("s", "ok", &msg(1, 0, t, car(0.0, 0.0, 10.0)), t, &mut sent.sink());
    let summary = warner.summary();
    assert_eq!((summary.sent, summary.failed), (1, 1));
    assert_eq!(sent.0[0].1.warned_source, "ok");
    // A message without a state (another stream) is not taken in.
    warner.on_state(
        "s",
        "ok",
        &AcceptedMessage { state: None, ..msg(1, 1, t, car(0.0, 0.0, 0.0)) },
        t,
        &mut sent.sink(),
    );
    assert_eq!(warner.summary().states, 2);
}

#[test]
fn lane_ttc_uses_the_sites_road_and_braking() {
    // A lead braking at 6 m/s² 30 m ahead, both at 20 m/s: constant velocity sees no contact,
    // the lane TTC (constant acceleration) does: 25.5 − 3τ² = 0 → τ = 2.92 s; at 8 m/s² 2.52 s;
    // at 14 m/s² 1.91 s, critical.
    let road = Road::straight(2, 3.5, 1000.0, 30.0);
    let y = -road.lane(0).project(Vec2::new(100.0, 0.0)).e_y_m;
    let mut warner = HazardWarner::new(WarningConfig::default(), None);
    warner.set_site_road("s", road);
    let mut sent = Sent::default();
    let t = 1_000 * MS;
    let lead = ObservedKinematics { accel_mps2: -14.0, ..car(130.0, y, 20.0) };
    warner.on_state("s", "lead", &msg(0, 0, t, lead), t, &mut sent.sink());
    warner.on_state("s", "follow", &msg(1, 0, t, car(100.0, y, 20.0)), t, &mut sent.sink());
    assert_eq!(sent.0.len(), 2);
    let w = &sent.0[0].1;
    assert_eq!(w.kind, HazardKind::LaneTtc);
    assert!((w.ttc_s - (25.5f64 / 7.0).sqrt()).abs() < 1e-9, "{w:?}");
    // A site without a road has no lane TTC: the braking lead goes unseen.
    let mut plain = HazardWarner::new(WarningConfig::default(), None);
    plain.on_state("s", "lead", &msg(0, 0, t, lead), t, &mut sent.sink());
    plain.on_state("s", "follow", &msg(1, 0, t, car(100.0, y, 20.0)), t, &mut sent.sink());
    assert_eq!(plain.summary().critical, 0);
}

/// A sink that logs joins, leaves and puts (keys).
#[derive(Default)]
struct Log {
    joined: Vec<String>,
    left: Vec<String>,
    puts: Vec<(String, HazardWarning)>,
}

impl WarningSink for Log {
    fn joined(&mut self, key: &str) {
        self.joined.push(key.to_owned());
    }
    fn left(&mut self, key: &str) {
        self.left.push(key.to_owned());
    }
    fn put(&mut self, key: &str, warning: &HazardWarning) -> bool {
        self.puts.push((key.to_owned(), warning.clone()));
        true
    }
}

#[test]
fn silent_members_are_forgotten_with_their_publishers_and_old_repeat_entries_go() {
    let config = WarningConfig::default();
    let mut warner = HazardWarner::new(config, None);
    let mut log = Log::default();
    let t0 = 1_000 * MS;
    // A follower 15 m behind a standing lead at 15 m/s: critical, both warned.
    warner.on_state("s", "lead", &msg(0, 0, t0, car(30.0, 0.0, 0.0)), t0, &mut log);
    warner.on_state("s", "follow", &msg(1, 0, t0, car(15.0, 0.0, 15.0)), t0, &mut log);
    warner.on_state("s", "third", &msg(2, 0, t0, car(500.0, 0.0, 0.0)), t0, &mut log);
    assert_eq!(
        log.joined,
        ["risktwin/v1/s/lead/warning", "risktwin/v1/s/follow/warning", "risktwin/v1/s/third/warning"]
    );
    assert_eq!(log.puts.len(), 2);
    assert_eq!(warner.sites[0].last_warned.len(), 2);
    // Then only the follower and the third car publish, far apart from each other, every 100 ms.
    for k in 1..=25u64 {
        let t = t0 + k as i64 * 100 * MS;
        warner.on_state("s", "follow", &msg(1, k, t, car(-1000.0, 0.0, 0.0)), t, &mut log);
        warner.on_state("s", "third", &msg(2, k, t, car(500.0, 0.0, 0.0)), t, &mut log);
        if k == 6 {
            // 600 ms on: the repeat entries (500 ms) are swept.
            assert!(warner.sites[0].last_warned.is_empty(), "{:?}", warner.sites[0].last_warned);
        }
    }
    // The lead, not heard for over 2 s, is forgotten: its publisher goes, its count stays.
    assert_eq!(log.left, ["risktwin/v1/s/lead/warning"]);
    assert_eq!(warner.members(), 2);
    let summary = warner.summary();
    assert_eq!(summary.forgotten, 1);
    assert_eq!(summary.sent_to, BTreeMap::from([("s/follow".into(), 1), ("s/lead".into(), 1)]));
    // The swap-remove moved a member: both remaining ones still map to their own slots.
    for (index, name) in [(1, "follow"), (2, "third")] {
        let (s, m) = warner.members[index].expect("a member");
        assert_eq!(warner.sites[s as usize].names[m as usize], name);
    }
    assert_eq!(warner.members[0], None);
    // Heard again: a new member, declared again, its warnings numbered from 0.
    let t = t0 + 2_600 * MS;
    warner.on_state("s", "lead", &msg(0, 30, t, car(30.0, 0.0, 0.0)), t, &mut log);
    warner.on_state("s", "follow", &msg(1, 30, t, car(15.0, 0.0, 15.0)), t, &mut log);
    assert_eq!(log.joined.last().map(String::as_str), Some("risktwin/v1/s/lead/warning"));
    let to_lead = log.puts.iter().rfind(|(_, w)| w.warned_source == "lead").expect("warned again");
    assert_eq!((to_lead.1.trigger_seq, to_lead.1.header.seq), (30, 0));
    assert_eq!(warner.summary().sent_to["s/lead"], 2);
}

#[test]
fn a_pair_coming_to_contact_is_warned_at_once_despite_the_repeat_limit() {
    let mut warner = HazardWarner::new(WarningConfig::default(), None);
    let mut log = Log::default();
    let t0 = 1_000 * MS;
    warner.on_state("s", "lead", &msg(0, 0, t0, car(30.0, 0.0, 0.0)), t0, &mut log);
    warner.on_state("s", "follow", &msg(1, 0, t0, car(15.0, 0.0, 15.0)), t0, &mut log);
    // 100 ms later: still predicted, held back; then touching: contact, sent; again: held back.
    let cases = [(100, 16.5, 0), (200, 26.0, 2), (300, 26.0, 0)];
    for (k, (after_ms, x, new_puts)) in cases.into_iter().enumerate() {
        let before = log.puts.len();
        let t = t0 + after_ms * MS;
        warner.on_state("s", "lead", &msg(0, k as u64 + 1, t, car(30.0, 0.0, 0.0)), t, &mut log);
        warner.on_state("s", "follow", &msg(1, k as u64 + 1, t, car(x, 0.0, 15.0)), t, &mut log);
        assert_eq!(log.puts.len() - before, new_puts, "at {after_ms} ms: {:?}", &log.puts[before..]);
    }
    let kinds: Vec<HazardKind> = log.puts.iter().map(|(_, w)| w.kind).collect();
    use HazardKind::{Contact, PredictedContact};
    assert_eq!(kinds, [PredictedContact, PredictedContact, Contact, Contact]);
}

#[test]
fn an_edge_that_left_is_forgotten_and_its_next_process_taken_in() {
    let mut warner = HazardWarner::new(WarningConfig::default(), None);
    let mut log = Log::default();
    let t = 10_000 * MS;
    warner.on_state("s", "veh", &msg(0, 50, t, car(0.0, 0.0, 0.0)), t, &mut log);
    warner.source_left("s", "veh", &mut log);
    warner.source_left("s", "unknown", &mut log);
    warner.source_left("nowhere", "veh", &mut log);
    assert_eq!((log.left.len(), warner.members(), warner.summary().forgotten), (1, 0, 1));
    // The new process's clock estimate starts over: its first state maps 300 ms earlier than
    // the old one's last, and still counts as its latest.
    let earlier = t - 300 * MS;
    warner.on_state("s", "veh", &msg(0, 0, earlier, car(0.0, 0.0, 0.0)), earlier, &mut log);
    assert_eq!((warner.summary().late_states, log.joined.len()), (0, 2));
}
