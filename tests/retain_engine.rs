//! Retained memory in the engine, in virtual time: what a warm RUN start keeps (K, the
//! `[retain]` D, T and C ranges, a retained counter's state), what a cold reset clears, a
//! restored image, and a replacement engine taking the retained devices over.

use std::path::Path;

use plcd::config;
use plcd::device::{Address, BitRef, Memory};
use plcd::engine::event::{Mode, Recorder};
use plcd::engine::{Activity, Engine, ModeRequest};
use plcd::io::{Io, SwitchPosition};
use plcd::project::{self, Project};
use plcd::vm::{Clock, StepClock};

const MS: u64 = 1_000_000;

#[derive(Default)]
struct Field {
    inputs: [u16; 2],
}

impl Io for Field {
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        mem.io_image_mut()[0] = self.inputs[0];
    }
    fn refresh_outputs(&mut self, _: &Memory) {}
    fn switch(&self) -> Option<SwitchPosition> {
        None
    }
    fn is_input(&self, bit: BitRef) -> bool {
        bit.word == 0
    }
}

fn project(retain: &str, main: &str) -> Project {
    let text = format!("{retain}\n[[program]]\nfile = \"main.il\"\n");
    let config = config::parse(&text, Path::new("retain.toml")).expect("config");
    let main = main.to_string();
    project::from_config(config, move |_| Ok(main.clone())).expect("project")
}

struct Plc {
    engine: Engine,
    field: Field,
    events: Recorder,
    clock: StepClock,
}

impl Plc {
    fn new(project: &Project) -> Plc {
        let engine = Engine::new(project, &[]);
        let clock = StepClock { origin_ns: 0, origin_steps: engine.steps(), step_ns: 1000 };
        Plc { engine, field: Field::default(), events: Recorder::default(), clock }
    }

    fn now(&self) -> u64 {
        self.clock.now_ns(self.engine.steps())
    }

    fn run_for(&mut self, ns: u64) {
        let end = self.now() + ns;
        while self.now() < end {
            let now = self.now();
            self.engine.poll_time(now, &mut self.field, &mut self.events);
            if self.engine.run(&self.clock, &mut self.field, &mut self.events, 100)
                == Activity::Idle
            {
                let next = self.engine.next_wakeup(now).unwrap_or(end).clamp(now + 1, end);
                self.clock.rebase(next, self.engine.steps());
            }
        }
    }

    fn mode(&mut self, mode: Mode) {
        let now = self.now();
        self.engine.set_mode(mode, now, &mut self.field, &mut self.events);
    }

    fn read(&self, dev: &str) -> i32 {
        self.engine.vm().mem.read(&Address::parse(dev).unwrap())
    }

    fn input(&mut self, bit: u16, on: bool) {
        if on {
            self.field.inputs[0] |= 1 << bit;
        } else {
            self.field.inputs[0] &= !(1 << bit);
        }
    }
}

const RANGES: &str = "[retain]\nranges = [\"D00010-D00010\", \"C0000-C0000\", \"C0002-C0002\", \
                      \"T1500-T1500\"]\n";
const COUNT: &str = "INC K000\nINC D00010\nINC D00020\nEND\n";

#[test]
fn k_and_the_retained_ranges_survive_stop_and_run_the_rest_is_cleared() {
    let mut plc = Plc::new(&project(RANGES, COUNT));
    plc.mode(Mode::Run);
    plc.run_for(MS);
    plc.mode(Mode::Stop);
    let (k, d) = (plc.read("K000"), plc.read("D00010"));
    assert!(k > 10 && k == d && plc.read("D00020") == k, "every scan counted");
    plc.mode(Mode::Run);
    plc.run_for(MS);
    let scans = plc.read("D00020");
    assert!(scans > 0 && scans < k + 10, "D00020 is not retained: it started over");
    assert_eq!(plc.read("K000"), k + scans, "K counted on");
    assert_eq!(plc.read("D00010"), d + scans, "the retained D range counted on");
}

#[test]
fn a_cold_reset_clears_the_retained_devices_too() {
    let mut plc = Plc::new(&project(RANGES, COUNT));
    plc.mode(Mode::Run);
    plc.run_for(MS);
    let now = plc.now();
    plc.engine
        .request_mode(ModeRequest::Reset { cold: true }, now, &mut plc.field, &mut plc.events)
        .unwrap();
    assert_eq!((plc.read("K000"), plc.read("D00010")), (0, 0));
    plc.mode(Mode::Run);
    plc.run_for(MS);
    let scans = plc.read("D00020");
    assert_eq!((plc.read("K000"), plc.read("D00010")), (scans, scans));
}

#[test]
fn a_restored_image_is_what_the_first_run_starts_from() {
    let p = project(RANGES, COUNT);
    let mut before = Plc::new(&p);
    before.mode(Mode::Run);
    before.run_for(MS);
    let mut image = Vec::new();
    before.engine.retain_set().capture(before.engine.vm().mem.words(), &mut image);
    let k = before.read("K000");

    let mut after = Plc::new(&p);
    after.engine.restore_retained(&image);
    assert_eq!((after.read("K000"), after.read("D00010"), after.read("D00020")), (k, k, 0));
    after.mode(Mode::Run);
    after.run_for(MS);
    let scans = after.read("D00020");
    assert_eq!((after.read("K000"), after.read("D00010")), (k + scans, k + scans));
}

#[test]
fn a_replacement_engine_takes_the_retained_devices_over() {
    let p = project(RANGES, COUNT);
    let mut old = Plc::new(&p);
    old.mode(Mode::Run);
    old.run_for(MS);
    old.mode(Mode::Stop);
    let k = old.read("K000");
    let mut new = Plc::new(&p);
    new.engine.inherit_retained(&old.engine);
    assert_eq!((new.read("K000"), new.read("D00010"), new.read("D00020")), (k, k, 0));
}

#[test]
fn retained_counters_count_on_without_a_phantom_edge_and_keep_a_down_count() {
    // C0000 retained, C0001 not; C0002 a retained down counter.
    let main =
        "LOAD P0000\nCTU C0000 100\nLOAD P0000\nCTU C0001 100\nLOAD P0001\nCTD C0002 5\nEND\n";
    let mut plc = Plc::new(&project(RANGES, main));
    plc.input(0, true);
    plc.mode(Mode::Run);
    plc.run_for(MS);
    assert_eq!((plc.read("C0000"), plc.read("C0001"), plc.read("C0002")), (1, 1, 5));
    plc.input(1, true);
    plc.run_for(MS);
    assert_eq!(plc.read("C0002"), 4);

    // The inputs stay ON across STOP and RUN: no edge, nothing counted twice.
    plc.mode(Mode::Stop);
    plc.mode(Mode::Run);
    plc.run_for(MS);
    assert_eq!(plc.read("C0000"), 1, "a held input is no new part");
    assert_eq!(plc.read("C0001"), 1, "not retained: cleared, then the ON input counted");
    assert_eq!(plc.read("C0002"), 4, "a retained down counter does not load its preset again");
    plc.input(0, false);
    plc.run_for(MS);
    plc.input(0, true);
    plc.run_for(MS);
    assert_eq!(plc.read("C0000"), 2, "the next real edge counts");

    let now = plc.now();
    plc.engine
        .request_mode(ModeRequest::Reset { cold: true }, now, &mut plc.field, &mut plc.events)
        .unwrap();
    plc.mode(Mode::Run);
    plc.run_for(MS);
    // Cold: as new counters, the ON inputs are edges; the down counter loaded its preset again
    // and counted one down.
    assert_eq!((plc.read("C0000"), plc.read("C0002")), (1, 4));
}

#[test]
fn a_retained_integrating_timer_counts_on_a_retained_on_delay_timer_starts_over() {
    // T1500 and T1501 have a 1 ms base; only T1500 is retained.
    let main = "LOAD P0000\nTMR T1500 1000\nLOAD P0000\nTON T1501 1000\nEND\n";
    let p = project(RANGES, main);
    let mut plc = Plc::new(&p);
    plc.input(0, true);
    plc.mode(Mode::Run);
    plc.run_for(100 * MS);
    plc.mode(Mode::Stop);
    let (tmr, ton) = (plc.read("T1500"), plc.read("T1501"));
    assert!(tmr >= 99 && ton >= 99, "both timed: {tmr} {ton}");
    plc.mode(Mode::Run);
    plc.run_for(20 * MS);
    assert!(plc.read("T1500") >= tmr + 19, "TMR counted on from {tmr}: {}", plc.read("T1500"));
    assert!(plc.read("T1501") <= 21, "TON started over: {}", plc.read("T1501"));
}
