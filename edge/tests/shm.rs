//! Cross-process tests of the iceoryx2 shared-memory transport.
//!
//! The test binary re-executes itself as the producer process: the parent opens its subscriber,
//! starts `current_exe()` on the ignored `shm_child` test with `RISKTWIN_SHM_CHILD` naming the role,
//! and receives every sample with a blocking wait (no sleeps). The child's stdin is the control
//! line: the producer sends its first sample and waits for one byte, which the parent writes once
//! that sample arrived (so the subscriber has attached and lossless delivery holds back the
//! producer from then on; see `Delivery::Lossless`); at the end the parent closes stdin, the
//! child's cue to drop its publisher and exit (a publisher that left before its samples were read
//! could take them along). Service names carry the parent's pid and a per-test tag, so parallel
//! tests and concurrent runs never share a service.

use std::io::{Read, Write};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use risktwin_edge::shm::{
    Delivery, OBJECT_LIST_CAPACITY, ShmCanFrame, ShmError, ShmObject, ShmObjectList, ShmPayload, ShmPayloadError,
    ShmPublisher, ShmQos, ShmSubscriber, ShmVehicleState,
};

/// Counts heap allocations per thread, so that a test can check a hot path allocates nothing while
/// other tests run in parallel threads.
struct CountingAlloc;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

// SAFETY: forwards to the system allocator; the counter is a const-initialised thread local, so
// touching it never allocates (no recursion).
unsafe impl std::alloc::GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

fn allocations_on_this_thread() -> u64 {
    ALLOCATIONS.with(std::cell::Cell::get)
}

const CHILD_ENV: &str = "RISKTWIN_SHM_CHILD";
/// Longest wait for one sample; generous for a loaded CI machine, never reached when it works.
const RECEIVE_TIMEOUT: Duration = Duration::from_secs(10);
/// Lossless with a wait bound far above any scheduling stall of a loaded machine, so a slow parent
/// cannot make the producer's send fail; both sides must use the same QoS.
const QOS: ShmQos = ShmQos { subscriber_buffer: 128, delivery: Delivery::Lossless { max_wait: RECEIVE_TIMEOUT } };

fn vehicle_id(tag: &str) -> String {
    format!("t{}-{tag}", std::process::id())
}

/// The `i`-th state the producer sends: irregular bit patterns, negative zero included.
fn expected_state(i: u64) -> ShmVehicleState {
    let t = i as f64;
    ShmVehicleState {
        seq: i,
        capture_time_ns: 1_700_000_000_000_000_000 + (i as i64) * 20_000_000 - 7,
        x_m: 0.1 * t + 1e-9 * t * t,
        y_m: -(t.sqrt()),
        heading_rad: (0.37 * t).sin() * 3.0,
        speed_mps: 13.9 + (0.11 * t).cos(),
        accel_mps2: if i.is_multiple_of(7) { -0.0 } else { (0.05 * t).tan() },
        yaw_rate_radps: 1.0 / (t + 3.0),
        steer_rad: std::f64::consts::PI / (t + 11.0),
        slip_angle_rad: f64::from_bits(0x3F50_0000_0000_0001 + i),
        length_m: 4.5 + (i % 3) as f32 * 0.125,
        width_m: 1.8,
    }
}

fn expected_can(i: u64) -> ShmCanFrame {
    let bytes = i.to_le_bytes();
    let len = (i % 9) as usize;
    ShmCanFrame::new(i, i as i64 * 10_000_000, (0x100 + i as u32 * 7919) & 0x1FFF_FFFF, &bytes[..len])
        .expect("at most 8 bytes")
}

fn expected_objects(i: u64) -> ShmObjectList {
    let mut list = ShmObjectList::new(i, i as i64 * 100_000_000);
    for k in 0..(i as usize % (OBJECT_LIST_CAPACITY + 1)) {
        let f = (i * 100 + k as u64) as f64;
        list.push(ShmObject {
            id: k as u32 + 1,
            kind: (k % 3) as u32 + 1,
            x_m: f * 0.5,
            y_m: -f * 0.25 + 1e-7,
            heading_rad: (f * 0.01).sin(),
            vx_mps: (f * 0.02).cos() * 20.0,
            vy_mps: 0.3,
            visible_fraction: 1.0 / (1.0 + k as f64),
            length_m: 4.0 + k as f32 * 0.01,
            width_m: 1.9,
        })
        .expect("within capacity");
    }
    list
}

fn state_bits(s: &ShmVehicleState) -> [u64; 12] {
    [
        s.seq,
        s.capture_time_ns as u64,
        s.x_m.to_bits(),
        s.y_m.to_bits(),
        s.heading_rad.to_bits(),
        s.speed_mps.to_bits(),
        s.accel_mps2.to_bits(),
        s.yaw_rate_radps.to_bits(),
        s.steer_rad.to_bits(),
        s.slip_angle_rad.to_bits(),
        u64::from(s.length_m.to_bits()),
        u64::from(s.width_m.to_bits()),
    ]
}

fn object_bits(o: &ShmObject) -> [u64; 10] {
    [
        u64::from(o.id),
        u64::from(o.kind),
        o.x_m.to_bits(),
        o.y_m.to_bits(),
        o.heading_rad.to_bits(),
        o.vx_mps.to_bits(),
        o.vy_mps.to_bits(),
        o.visible_fraction.to_bits(),
        u64::from(o.length_m.to_bits()),
        u64::from(o.width_m.to_bits()),
    ]
}

/// Kills the child if the parent fails before it reaped it.
struct ChildGuard(Option<Child>);

impl ChildGuard {
    fn spawn(role: &str, vehicle: &str, count: u64) -> Self {
        let exe = std::env::current_exe().expect("test binary path");
        let child = Command::new(exe)
            .args(["--exact", "shm_child", "--ignored", "--nocapture", "--test-threads=1"])
            .env(CHILD_ENV, format!("{role}:{vehicle}:{count}"))
            .stdin(Stdio::piped())
            .spawn()
            .expect("spawn the producer process");
        Self(Some(child))
    }

    /// Tells the child that its first sample arrived.
    fn go(&mut self) {
        let stdin = self.0.as_mut().and_then(|child| child.stdin.as_mut()).expect("child stdin");
        stdin.write_all(b"g").and_then(|()| stdin.flush()).expect("write to the child");
    }

    /// Closes the child's stdin (its cue to exit) and checks that it exited cleanly.
    fn finish(mut self) {
        let mut child = self.0.take().expect("not finished twice");
        drop(child.stdin.take());
        let status = child.wait().expect("wait for the producer");
        assert!(status.success(), "producer failed: {status}");
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(child) = self.0.as_mut() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Receives `count` samples and checks order, continuity and exact values; tells the child to go
/// on after the first.
fn receive_all<T: ShmPayload>(
    subscriber: &ShmSubscriber<T>,
    child: &mut ChildGuard,
    count: u64,
    check: impl Fn(u64, &T),
) {
    for i in 0..count {
        if i == 1 {
            child.go();
        }
        let sample = subscriber
            .receive_timeout(RECEIVE_TIMEOUT)
            .unwrap_or_else(|e| panic!("sample {i}: {e}"))
            .unwrap_or_else(|| panic!("sample {i} did not arrive within {RECEIVE_TIMEOUT:?}"));
        assert_eq!(sample.seq(), i, "sequence gap or reorder");
        check(i, &sample);
    }
    assert!(subscriber.try_receive().expect("receive").is_none(), "more samples than sent");
}

#[test]
fn vehicle_states_cross_processes_bit_exact_and_in_order() {
    const COUNT: u64 = 3_000;
    let vehicle = vehicle_id("state");
    let subscriber = ShmSubscriber::<ShmVehicleState>::new(&vehicle, QOS).expect("subscriber");
    let mut child = ChildGuard::spawn("state", &vehicle, COUNT);
    receive_all(&subscriber, &mut child, COUNT, |i, s| {
        assert_eq!(state_bits(s), state_bits(&expected_state(i)), "state {i}")
    });
    child.finish();
}

#[test]
fn can_frames_cross_processes_in_order() {
    const COUNT: u64 = 3_000;
    let vehicle = vehicle_id("can");
    let subscriber = ShmSubscriber::<ShmCanFrame>::new(&vehicle, QOS).expect("subscriber");
    let mut child = ChildGuard::spawn("can", &vehicle, COUNT);
    receive_all(&subscriber, &mut child, COUNT, |i, f| {
        let want = expected_can(i);
        assert_eq!(f, &want, "frame {i}");
        assert_eq!(f.payload(), &i.to_le_bytes()[..(i % 9) as usize]);
    });
    child.finish();
}

#[test]
fn object_lists_cross_processes_bit_exact_up_to_capacity() {
    const COUNT: u64 = 300;
    let vehicle = vehicle_id("objects");
    let subscriber = ShmSubscriber::<ShmObjectList>::new(&vehicle, QOS).expect("subscriber");
    let mut child = ChildGuard::spawn("objects", &vehicle, COUNT);
    receive_all(&subscriber, &mut child, COUNT, |i, list| {
        let want = expected_objects(i);
        assert_eq!((list.capture_time_ns, list.count), (want.capture_time_ns, want.count));
        let got: Vec<_> = list.objects().iter().map(object_bits).collect();
        let want: Vec<_> = want.objects().iter().map(object_bits).collect();
        assert_eq!(got, want, "list {i}");
    });
    child.finish();
}

#[test]
fn corrupted_samples_are_rejected_by_the_receiver_and_it_keeps_going() {
    let vehicle = vehicle_id("corrupt");
    let states = ShmSubscriber::<ShmVehicleState>::new(&vehicle, QOS).expect("subscriber");
    let lists = ShmSubscriber::<ShmObjectList>::new(&vehicle, QOS).expect("subscriber");
    let child = ChildGuard::spawn("corrupt", &vehicle, 0);

    let next_state = || states.receive_timeout(RECEIVE_TIMEOUT);
    assert_eq!(next_state().expect("valid").expect("arrives").seq, 0);
    match next_state() {
        Err(ShmError::InvalidSample { seq: 1, source: ShmPayloadError::NotFinite { field: "x_m", value }, .. }) => {
            assert!(value.is_nan())
        }
        other => panic!("NaN state not rejected: {other:?}"),
    }
    match next_state() {
        Err(ShmError::InvalidSample {
            seq: 2,
            source: ShmPayloadError::NotFinite { field: "speed_mps", value },
            ..
        }) => {
            assert_eq!(value, f64::INFINITY)
        }
        other => panic!("infinite state not rejected: {other:?}"),
    }
    assert_eq!(next_state().expect("valid").expect("arrives").seq, 3);

    let next_list = || lists.receive_timeout(RECEIVE_TIMEOUT);
    match next_list() {
        Err(ShmError::InvalidSample {
            seq: 10,
            source: ShmPayloadError::CountOverCapacity { count: 65, capacity: 64 },
            ..
        }) => {}
        other => panic!("over-capacity list not rejected: {other:?}"),
    }
    match next_list() {
        Err(ShmError::InvalidSample {
            seq: 11,
            source: ShmPayloadError::ObjectNotFinite { index: 1, field: "y_m", .. },
            ..
        }) => {}
        other => panic!("NaN object not rejected: {other:?}"),
    }
    assert_eq!(next_list().expect("valid").expect("arrives").seq, 12);
    child.finish();
}

#[test]
fn a_wait_with_no_producer_times_out_empty() {
    let vehicle = vehicle_id("silent");
    let subscriber = ShmSubscriber::<ShmCanFrame>::new(&vehicle, QOS).expect("subscriber");
    let start = std::time::Instant::now();
    assert!(subscriber.receive_timeout(Duration::from_millis(30)).expect("wait").is_none());
    assert!(start.elapsed() >= Duration::from_millis(30));
}

#[test]
fn a_failed_in_place_fill_sends_nothing() {
    let vehicle = vehicle_id("fill");
    let subscriber = ShmSubscriber::<ShmCanFrame>::new(&vehicle, QOS).expect("subscriber");
    let publisher = ShmPublisher::<ShmCanFrame>::new(&vehicle, QOS).expect("publisher");
    let err = publisher
        .publish_with(|frame| {
            frame.seq = 5;
            frame.set_data(&[0; 12])
        })
        .expect_err("12 data bytes do not fit");
    assert!(matches!(err, ShmError::InvalidSample { seq: 5, source: ShmPayloadError::DlcOutOfRange { dlc: 12 }, .. }));
    publisher
        .publish_with(|frame| {
            frame.seq = 6;
            frame.set_data(&[1, 2])
        })
        .expect("publish");
    let sample = subscriber.receive_timeout(RECEIVE_TIMEOUT).expect("receive").expect("arrives");
    assert_eq!((sample.seq, sample.payload()), (6, &[1u8, 2][..]));
}

/// iceoryx2 0.10 itself allocates one small `Rc` per loan (its chunk's shared state); the
/// wrapper must add nothing on top, and receiving must not allocate at all.
#[test]
fn the_wrapper_adds_no_heap_allocation_per_sample() {
    const ROUNDS: u64 = 1_000;
    const ICEORYX2_ALLOCATIONS_PER_LOAN: u64 = 1;
    let vehicle = vehicle_id("alloc");
    let subscriber = ShmSubscriber::<ShmObjectList>::new(&vehicle, QOS).expect("subscriber");
    let publisher = ShmPublisher::<ShmObjectList>::new(&vehicle, QOS).expect("publisher");
    let list = expected_objects(40);
    // The first round trip builds the connection (that allocates); the steady state is measured.
    publisher.publish(&list).expect("publish");
    assert!(subscriber.receive_timeout(RECEIVE_TIMEOUT).expect("receive").is_some());
    let (mut publishing, mut receiving) = (0, 0);
    for seq in 0..ROUNDS {
        let mut next = list;
        next.seq = seq;
        let before = allocations_on_this_thread();
        publisher.publish(&next).expect("publish");
        publisher
            .publish_with(|slot| {
                *slot = next;
                Ok(())
            })
            .expect("publish in place");
        let between = allocations_on_this_thread();
        for _ in 0..2 {
            let sample = subscriber.receive_timeout(RECEIVE_TIMEOUT).expect("receive").expect("arrives");
            assert_eq!((sample.seq, sample.count), (seq, 40));
        }
        publishing += between - before;
        receiving += allocations_on_this_thread() - between;
    }
    assert_eq!(publishing, 2 * ROUNDS * ICEORYX2_ALLOCATIONS_PER_LOAN, "allocations while publishing");
    assert_eq!(receiving, 0, "allocations while receiving");
}

/// Publishes what the named role prescribes, then waits for the parent to close stdin.
fn run_child(role: &str, vehicle: &str, count: u64) {
    let qos = QOS;
    match role {
        "state" => {
            let publisher = ShmPublisher::<ShmVehicleState>::new(vehicle, qos).expect("publisher");
            for i in 0..count {
                publisher.publish(&expected_state(i)).expect("publish");
                if i == 0 {
                    wait_for_go();
                }
            }
            wait_for_parent();
        }
        "can" => {
            let publisher = ShmPublisher::<ShmCanFrame>::new(vehicle, qos).expect("publisher");
            for i in 0..count {
                publisher.publish(&expected_can(i)).expect("publish");
                if i == 0 {
                    wait_for_go();
                }
            }
            wait_for_parent();
        }
        "objects" => {
            let publisher = ShmPublisher::<ShmObjectList>::new(vehicle, qos).expect("publisher");
            for i in 0..count {
                publisher
                    .publish_with(|list| {
                        *list = expected_objects(i);
                        Ok(())
                    })
                    .expect("publish");
                if i == 0 {
                    wait_for_go();
                }
            }
            wait_for_parent();
        }
        "corrupt" => {
            let states = ShmPublisher::<ShmVehicleState>::new(vehicle, qos).expect("publisher");
            let lists = ShmPublisher::<ShmObjectList>::new(vehicle, qos).expect("publisher");
            let mut nan = expected_state(1);
            nan.x_m = f64::NAN;
            let mut inf = expected_state(2);
            inf.speed_mps = f64::INFINITY;
            for state in [expected_state(0), nan, inf, expected_state(3)] {
                states.publish(&state).expect("publish");
            }
            // A producer bug or a hostile writer: the count field says more than the array holds.
            let mut over = expected_objects(10);
            over.count = OBJECT_LIST_CAPACITY as u32 + 1;
            let mut nan_object = expected_objects(11);
            nan_object.objects[1].y_m = f64::NAN;
            for list in [over, nan_object, expected_objects(12)] {
                lists.publish(&list).expect("publish");
            }
            wait_for_parent();
        }
        other => panic!("unknown child role {other:?}"),
    }
}

/// Blocks until the parent confirms that the first sample arrived.
fn wait_for_go() {
    let mut byte = [0u8; 1];
    std::io::stdin().read_exact(&mut byte).expect("go byte from the parent");
}

/// Blocks until the parent closes our stdin: the samples stay readable while we live.
fn wait_for_parent() {
    let mut sink = Vec::new();
    std::io::stdin().read_to_end(&mut sink).expect("read stdin");
}

/// Entry point of the producer process; the parent tests start it (ignored in normal runs).
#[test]
#[ignore = "producer role of the cross-process tests, started by them"]
fn shm_child() {
    let Ok(spec) = std::env::var(CHILD_ENV) else {
        eprintln!("shm_child: {CHILD_ENV} unset, nothing to do (the cross-process tests start this)");
        return;
    };
    let mut parts = spec.splitn(3, ':');
    let (Some(role), Some(vehicle), Some(count)) = (parts.next(), parts.next(), parts.next()) else {
        panic!("malformed {CHILD_ENV}={spec:?}");
    };
    run_child(role, vehicle, count.parse().expect("count"));
}
