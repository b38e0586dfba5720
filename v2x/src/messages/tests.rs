//! Decisions by message, the virtual scene's counts, warnings and CPMs.

use super::*;
use crate::channel::{LinkBudget, PathLoss};
use crate::latency::Latency;

fn urban(seed: u64) -> MessageChannel {
    let channel = V2xChannel {
        model: PathLoss::UrbanNlos,
        budget: LinkBudget::default(),
        latency: Latency::SIDELINK,
        bursts: None,
    };
    MessageChannel { channel, seed }
}

#[test]
fn decisions_depend_on_the_message_not_on_the_order_they_are_taken_in() {
    let channel = urban(7);
    let forward: Vec<bool> =
        (0..200).map(|seq| channel.passes("v1", "rsu0", seq, 339.0, &mut BurstState::default())).collect();
    let backward: Vec<bool> =
        (0..200).rev().map(|seq| channel.passes("v1", "rsu0", seq, 339.0, &mut BurstState::default())).collect();
    assert_eq!(forward, backward.into_iter().rev().collect::<Vec<_>>());
    // About half arrive at 339 m in urban NLOS; receivers of one broadcast differ.
    let passed = forward.iter().filter(|p| **p).count();
    assert!((70..130).contains(&passed), "{passed} of 200");
    let other: Vec<bool> =
        (0..200).map(|seq| channel.passes("v1", "v2", seq, 339.0, &mut BurstState::default())).collect();
    assert_ne!(forward, other);
    assert_eq!(channel.latency_ms("v1", 3), channel.latency_ms("v1", 3));
    assert_ne!(channel.latency_ms("v1", 3), channel.latency_ms("v1", 4));
    assert_ne!(channel.latency_ms("v1", 3), urban(8).latency_ms("v1", 3));
}

#[test]
fn the_channel_digest_changes_with_every_part_of_the_channel() {
    use crate::loss::BurstLoss;
    let base = urban(7);
    assert_eq!(base.digest(), urban(7).digest());
    let mut others = vec![urban(8)];
    let mut with = |change: &dyn Fn(&mut V2xChannel)| {
        let mut other = base;
        change(&mut other.channel);
        others.push(other);
    };
    with(&|c| c.model = PathLoss::UrbanLos);
    with(&|c| c.budget.tx_power_dbm = 20.0);
    with(&|c| c.budget.sinr_threshold_db += 1e-9);
    with(&|c| c.latency = Latency::Sidelink { t1_ms: 4.0, t2_ms: 50.0 });
    with(&|c| c.latency = Latency::Gamma { offset_ms: 4.0, shape: 100.0, scale_ms: 1.0 });
    with(&|c| c.bursts = Some(BurstLoss::from_share(0.3, 5.0).expect("valid")));
    with(&|c| c.bursts = Some(BurstLoss::from_share(0.3, 4.0).expect("valid")));
    let mut digests: Vec<u64> = others.iter().map(MessageChannel::digest).chain([base.digest()]).collect();
    digests.sort_unstable();
    digests.dedup();
    assert_eq!(digests.len(), others.len() + 1, "every change changes the digest");
    assert_eq!(base.describe(), "V2X 3gpp-urban-nlos sidelink:4:100");
    assert_eq!(others[6].describe(), "V2X 3gpp-urban-nlos sidelink:4:100 bursts 0.300:5.000");
}

#[test]
#[should_panic(expected = "one state per member")]
fn a_virtual_scene_refuses_states_that_are_not_one_per_member() {
    let mut scene = VirtualScene::new(urban(3), &[("v0".to_owned(), Some(0)), ("v1".to_owned(), Some(1))]);
    scene.step(0.0, &[None]);
}

#[test]
fn a_virtual_scene_counts_every_copy_once_and_delivers_after_the_latency() {
    let members = [("v0".to_owned(), Some(u32::MAX)), ("v1".to_owned(), Some(0)), ("rsu0".to_owned(), None)];
    let mut scene = VirtualScene::new(urban(3), &members);
    let at = |t: f64, x_m: f64| Some(CamState { time_s: t, x_m, y_m: 0.0, heading_rad: 0.0, speed_mps: 0.0 });
    for k in 0..=200 {
        let t = f64::from(k) * 0.05;
        scene.step(t, &[at(t, 0.0), at(t, 300.0), at(t, 20.0)]);
    }
    let s = scene.summaries();
    // Standing vehicles send at 1 Hz: 11 CAMs each over 10 s; the RSU sends none.
    assert_eq!((s["v0"].cams_sent, s["v1"].cams_sent, s["rsu0"].cams_sent), (11, 11, 0));
    assert_eq!((s["v0"].copies, s["v1"].copies, s["rsu0"].copies), (11, 11, 22));
    assert!(s["rsu0"].pdr.expect("copies") > s["v0"].pdr.expect("copies"), "20 m against 300 m: {s:?}");
    let p50 = s["rsu0"].latency_p50_ms.expect("delivered");
    assert!((4.0..=100.0).contains(&p50), "{p50}");
}

#[test]
fn a_virtual_scene_warns_vehicles_of_hazards_from_the_first_step_after_the_latency() {
    use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2};
    use risktwin_common::sensor::ObjectKind;
    let members = [("v0".to_owned(), Some(u32::MAX)), ("rsu0".to_owned(), None)];
    let pedestrian = PerceivedObject {
        id: 7,
        kind: ObjectKind::Pedestrian,
        obb: Obb::new(Pose::new(30.0, 0.0, 0.0), Footprint::new(0.5, 0.5)),
        velocity: Vec2::new(0.0, 1.0),
        visible_fraction: 1.0,
    };
    let at = |t: f64, x_m: f64| Some(CamState { time_s: t, x_m, y_m: 0.0, heading_rad: 0.0, speed_mps: 0.0 });
    let channel = urban(3);
    let mut off = VirtualScene::new(channel, &members);
    off.warn(0.0, &[at(0.0, 0.0), at(0.0, 20.0)], &[&[], &[pedestrian]]);
    assert_eq!(off.summaries()["rsu0"].warnings_made, 0, "no warnings unless asked");
    let mut scene = VirtualScene::new(channel, &members).warning(true);
    let latency_ms = channel.warning_latency_ms("rsu0", 0);
    let mut first_heard = None;
    for k in 0..40 {
        let t = f64::from(k) * 0.05;
        if !scene.warned(0, t, &[]).is_empty() {
            first_heard.get_or_insert(t);
        }
        // The RSU sees the pedestrian in the first step only.
        let seen: &[PerceivedObject] = if k == 0 { &[pedestrian] } else { &[] };
        scene.warn(t, &[at(t, 0.0), at(t, 20.0)], &[&[], seen]);
    }
    let s = scene.summaries();
    assert_eq!((s["rsu0"].warnings_made, s["v0"].warning_copies, s["v0"].warnings_passed), (1, 1, 1));
    assert_eq!(s["v0"].warnings_heard, 1);
    let first = first_heard.expect("heard");
    assert!(warning_due(0.0, latency_ms, first) && !warning_due(0.0, latency_ms, first - 0.05), "{first}");
    // Kept 1 s after it was heard, then forgotten.
    let steps = s["v0"].warned_steps;
    assert!((20..=21).contains(&steps), "{steps}");
}

#[test]
fn a_virtual_scene_cpm_reaches_vehicles_after_its_latency_and_a_vehicle_is_not_told_of_itself() {
    use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2};
    use risktwin_common::sensor::ObjectKind;
    let object = |id, kind, x_m| PerceivedObject {
        id,
        kind,
        obb: Obb::new(Pose::new(x_m, 0.0, 0.0), Footprint::new(4.5, 1.8)),
        velocity: Vec2::new(0.0, 0.0),
        visible_fraction: 1.0,
    };
    // v0 is object 5 in the truth; the RSU sees it and a parked car, 7.
    let seen = [object(5, ObjectKind::Vehicle, 0.0), object(7, ObjectKind::Parked, 40.0)];
    let members = [("v0".to_owned(), Some(5)), ("rsu0".to_owned(), None)];
    let at = |t: f64, x_m: f64| Some(CamState { time_s: t, x_m, y_m: 0.0, heading_rad: 0.0, speed_mps: 0.0 });
    let channel = urban(3);
    let mut scene = VirtualScene::new(channel, &members).cpm(true);
    let mut warned = Vec::new();
    for k in 0..10 {
        let t = f64::from(k) * 0.05;
        warned.push(scene.warned(0, t, &[]).iter().map(|o| o.id).collect::<Vec<_>>());
        scene.warn(t, &[at(t, 0.0), at(t, 20.0)], &[&[], &seen]);
    }
    let s = scene.summaries();
    // New at 0 s, then nothing due before 1 s (standing): one CPM of both objects.
    assert_eq!((s["rsu0"].cpms_made, s["rsu0"].cpm_objects_sent, s["rsu0"].warnings_made), (1, 2, 0));
    assert_eq!((s["v0"].cpm_copies, s["v0"].cpms_passed, s["v0"].cpm_objects_heard), (1, 1, 1), "not itself");
    let latency_ms = channel.cpm_latency_ms("rsu0", 0);
    let first = warned.iter().position(|w| !w.is_empty()).expect("heard");
    let step = |k: usize| 0.05 * k as f64;
    assert!(warning_due(0.0, latency_ms, step(first)) && !warning_due(0.0, latency_ms, step(first - 1)), "{first}");
    assert!(warned[first..].iter().all(|w| w == &[7]), "the parked car, never v0 itself: {warned:?}");
}
