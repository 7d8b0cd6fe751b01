//! The kernel's gpio-sim and the GPIO character device, as plcd's gpiocdev backend uses them:
//! edge events on inputs, levels of outputs, and a line held by one request only.
//!
//! These need gpio-sim (root, configfs, the gpio-sim module); elsewhere each test says
//! `skipped: <reason>` and passes. `tests/qemu/run-gpiosim` runs them in a VM with a kernel that
//! has it.
#[macro_use]
mod harness;

use std::time::Duration;

use gpiocdev::line::{EdgeDetection, EdgeEvent, EdgeKind, EventClock, Value};
use gpiocdev::request::Request;
use gpiosim::{Bank, Level, Sim};

const LINES: u32 = 8;

/// A live simulator of one chip with [`LINES`] lines, all pulled down.
fn sim(label: &str) -> Sim {
    gpiosim::builder()
        .with_bank(&Bank::new(LINES, label))
        .live()
        .unwrap_or_else(|e| panic!("gpio-sim chip {label:?} does not go live: {e}"))
}

/// CLOCK_MONOTONIC now, in nanoseconds, as edge events with [`EventClock::Monotonic`] stamp.
fn monotonic_ns() -> u64 {
    let t = nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC).unwrap();
    t.tv_sec() as u64 * 1_000_000_000 + t.tv_nsec() as u64
}

/// The one event that is already waiting; panics if there is none, or more than one.
fn only_event(req: &Request, what: &str) -> EdgeEvent {
    assert!(
        req.wait_edge_event(Duration::from_secs(2)).unwrap(),
        "{what}: no edge event within 2 s"
    );
    let event = req.read_edge_event().unwrap();
    assert!(!req.has_edge_event().unwrap(), "{what}: more than one edge event ({event:?} first)");
    event
}

#[test]
fn every_pull_toggle_gives_one_edge_event() {
    require_gpiosim!();
    let sim = sim("plcd-smoke-edges");
    let chip = &sim.chips()[0];
    let offsets: Vec<u32> = (0..LINES).collect();
    let req = Request::builder()
        .on_chip(chip.dev_path())
        .with_consumer("plcd-smoke")
        .with_lines(&offsets)
        .as_input()
        .with_edge_detection(EdgeDetection::BothEdges)
        .with_event_clock(EventClock::Monotonic)
        .request()
        .unwrap();
    assert!(!req.has_edge_event().unwrap(), "an event before any toggle");
    for &offset in &offsets {
        assert_eq!(req.value(offset).unwrap(), Value::Inactive, "line {offset} starts pulled down");
    }

    // Each line up and down again, then the lines in a scattered order, several times over.
    let mut toggles: Vec<u32> = offsets.iter().flat_map(|&o| [o, o]).collect();
    toggles.extend([3, 0, 7, 3, 5, 1, 0, 6, 2, 7, 4, 5, 1, 6, 2, 4]);
    toggles.extend(toggles.clone());
    let mut line_seqnos = vec![0u32; LINES as usize];
    let mut last_ns = 0u64;
    for (i, &offset) in toggles.iter().enumerate() {
        let before_ns = monotonic_ns();
        let level = chip.toggle(offset).unwrap();
        let what = format!("toggle {i} (line {offset} to {level:?})");
        let event = only_event(&req, &what);
        let kind = match level {
            Level::High => EdgeKind::Rising,
            Level::Low => EdgeKind::Falling,
        };
        line_seqnos[offset as usize] += 1;
        assert_eq!(event.kind, kind, "{what}: {event:?}");
        assert_eq!(event.offset, offset, "{what}: {event:?}");
        assert_eq!(event.seqno, i as u32 + 1, "{what}: request seqno: {event:?}");
        assert_eq!(event.line_seqno, line_seqnos[offset as usize], "{what}: line seqno: {event:?}");
        assert!(event.timestamp_ns >= before_ns, "{what}: stamped before the toggle: {event:?}");
        assert!(event.timestamp_ns <= monotonic_ns(), "{what}: stamped in the future: {event:?}");
        assert!(event.timestamp_ns > last_ns, "{what}: time went back: {event:?}");
        last_ns = event.timestamp_ns;
        let value = if level == Level::High { Value::Active } else { Value::Inactive };
        assert_eq!(req.value(offset).unwrap(), value, "{what}: the line's value");
    }

    // Pulling a line the way it is already pulled is no edge.
    chip.pulldown(0).unwrap();
    chip.pullup(1).unwrap();
    assert_eq!(only_event(&req, "line 1 up").kind, EdgeKind::Rising);
    chip.pullup(1).unwrap();
    assert!(
        !req.wait_edge_event(Duration::from_millis(200)).unwrap(),
        "an event with no change: {:?}",
        req.read_edge_event()
    );
}

#[test]
fn sim_reads_the_level_an_output_is_set_to() {
    require_gpiosim!();
    let sim = sim("plcd-smoke-outputs");
    let chip = &sim.chips()[0];
    let req = Request::builder()
        .on_chip(chip.dev_path())
        .with_consumer("plcd-smoke")
        .with_line(2)
        .as_output(Value::Active)
        .with_line(5)
        .as_output(Value::Inactive)
        .request()
        .unwrap();
    assert_eq!(chip.get_level(2).unwrap(), Level::High, "line 2 requested active");
    assert_eq!(chip.get_level(5).unwrap(), Level::Low, "line 5 requested inactive");
    for round in 0..4 {
        let (v2, v5) = if round % 2 == 0 {
            (Value::Inactive, Value::Active)
        } else {
            (Value::Active, Value::Inactive)
        };
        req.set_value(2, v2).unwrap();
        req.set_value(5, v5).unwrap();
        let level = |v| if v == Value::Active { Level::High } else { Level::Low };
        assert_eq!(chip.get_level(2).unwrap(), level(v2), "round {round}: line 2 set {v2:?}");
        assert_eq!(chip.get_level(5).unwrap(), level(v5), "round {round}: line 5 set {v5:?}");
    }
    // An active-low output drives the line low when active.
    drop(req);
    let req = Request::builder()
        .on_chip(chip.dev_path())
        .with_line(7)
        .as_active_low()
        .as_output(Value::Active)
        .request()
        .unwrap();
    assert_eq!(chip.get_level(7).unwrap(), Level::Low, "active-low line 7 set active");
    req.set_value(7, Value::Inactive).unwrap();
    assert_eq!(chip.get_level(7).unwrap(), Level::High, "active-low line 7 set inactive");
}

#[test]
fn a_requested_line_is_busy_for_a_second_request() {
    require_gpiosim!();
    let sim = sim("plcd-smoke-busy");
    let chip = &sim.chips()[0];
    let request = |offsets: &[u32]| {
        Request::builder()
            .on_chip(chip.dev_path())
            .with_consumer("plcd-smoke")
            .with_lines(offsets)
            .as_input()
            .request()
    };
    let first = request(&[4]).unwrap();
    let info = gpiocdev::Chip::from_path(chip.dev_path()).unwrap().line_info(4).unwrap();
    assert!(info.used, "line 4 is requested: {info:?}");
    assert_eq!(info.consumer, "plcd-smoke");

    // Alone or among free lines, line 4 cannot be had twice.
    let ebusy = std::io::Error::from_raw_os_error(libc::EBUSY).to_string();
    for offsets in [&[4][..], &[3, 4, 5]] {
        match request(offsets) {
            Ok(_) => panic!("a second request of line 4 (lines {offsets:?}) succeeded"),
            Err(gpiocdev::Error::Uapi(call, e)) => {
                assert_eq!(call, gpiocdev::UapiCall::GetLine, "lines {offsets:?}: {e}");
                assert_eq!(e.to_string(), ebusy, "lines {offsets:?}: not EBUSY: {e:?}");
            }
            Err(e) => panic!("lines {offsets:?}: not EBUSY from the kernel: {e:?}"),
        }
    }
    // The failed requests took nothing; the lines beside line 4 are free.
    drop(request(&[3, 5]).unwrap());
    drop(first);
    drop(request(&[4]).expect("line 4 once released"));
}
