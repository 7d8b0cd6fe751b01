//! The scan: its start (input refresh, the key switch looked at, the scan program or the init
//! task begun), END processing once every pending task has run (DUTY, scan time, output
//! refresh, the next scan on the grid of the scan period), the refresh points of the I/O image
//! with the forces written over it, and the watched devices compared at each of them.

use crate::io::Io;
use crate::stats::Histogram;

use super::event::{Event, EventSink, INIT, SCAN};
use super::mode::{KeySwitch, ModeState};
use super::schedule::Init;
use super::task::{read_sample, Sample};
use super::Engine;
use crate::project::{Through, Watched};
use crate::value::{Elem, Pointer, ValueType};
use crate::vm::Vm;

/// How far the current scan is; only RUN and DEBUG have one. `paused` says the scan stopped at
/// a DEBUG breakpoint, so that its duration is the engineer's, not a scan time: it lives in the
/// scan it describes, set when the scan starts and gone between scans, and it survives a
/// change from DEBUG to RUN in the middle of the scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Phase {
    /// Between two scans of a fixed scan period (tasks still run).
    Idle,
    /// The scan program (or the init task) is executing or preempted.
    Scan { paused: bool },
    /// After END: device tasks and every pending task run before the next scan.
    AfterEnd { paused: bool },
}

impl Phase {
    #[inline]
    fn paused(self) -> bool {
        match self {
            Phase::Idle => false,
            Phase::Scan { paused } | Phase::AfterEnd { paused } => paused,
        }
    }

    /// A breakpoint paused execution: the scan under way, if one is, is no longer timed.
    #[inline]
    pub(super) fn pause(&mut self) {
        if let Phase::Scan { paused } | Phase::AfterEnd { paused } = self {
            *paused = true;
        }
    }
}

/// A watched device, resolved once: comparing it at every output refresh and task end is a
/// load and a compare, not an address lookup.
/// Where a watch reads.
#[derive(Debug, Clone, Copy)]
pub(super) enum WatchAt {
    /// A device, as conditions read it.
    Device(Sample),
    /// A Structured Text variable of an elementary type.
    Value { at: Pointer, elem: Elem },
    /// A `STRING` variable.
    Text { at: Pointer },
    /// A `WSTRING` variable: `text` holds its code units' bytes after a count of units.
    WideText { at: Pointer },
}

/// A watched device or variable and the value last reported (for a `STRING`, its bytes).
#[derive(Debug, Clone)]
pub(super) struct Watch {
    pub(super) at: WatchAt,
    pub(super) last: u64,
    pub(super) text: Box<[u8]>,
    /// A name through a reference (`main.r^`): `at` is then found where the reference points
    /// at each look, and reads 0 (an empty `STRING`) while it points nowhere.
    pub(super) through: Option<Box<Through>>,
}

impl Watch {
    pub(super) fn new(watched: &Watched) -> Watch {
        let (at, text) = match watched {
            // As `Memory::read` resolves it: a word if the address is one, else a bit.
            Watched::Device(address) => (
                WatchAt::Device(match address.as_word() {
                    Ok(word) => Sample::Word(word),
                    Err(_) => Sample::Bit(address.as_bit().expect("an address is a bit or a word")),
                }),
                Box::default(),
            ),
            Watched::Variable(symbol) | Watched::Through(Through { target: symbol, .. }) => {
                match symbol.ty {
                    ValueType::String { cap } => (
                        WatchAt::Text { at: symbol.at },
                        vec![0; cap as usize + 1].into_boxed_slice(),
                    ),
                    ValueType::WString { cap } => {
                        let room = 2 * cap.min(255) as usize + 1;
                        (WatchAt::WideText { at: symbol.at }, vec![0; room].into_boxed_slice())
                    }
                    ref ty => (WatchAt::Value { at: symbol.at, elem: ty.elem() }, Box::default()),
                }
            }
        };
        let through = match watched {
            Watched::Through(through) => Some(Box::new(through.clone())),
            _ => None,
        };
        Watch { at, last: 0, text, through }
    }

    /// Where a variable's watch reads now: its place, or where its reference points.
    #[inline(always)]
    fn place(&self, vm: &Vm, at: Pointer) -> Pointer {
        match &self.through {
            None => at,
            Some(through) => through_place(through, vm),
        }
    }

    pub(super) fn watches_device(&self) -> bool {
        matches!(self.at, WatchAt::Device(_))
    }

    /// Takes the current value as the last one reported, without reporting it.
    pub(super) fn sample_quietly(&mut self, vm: &Vm) {
        match self.at {
            WatchAt::Device(sample) => self.last = read_sample(&vm.mem, sample) as u64,
            WatchAt::Value { at, elem } => self.last = vm.read_value(self.place(vm, at), elem),
            WatchAt::Text { at } => {
                let now = vm.string_bytes(self.place(vm, at));
                let len = now.len().min(self.text.len() - 1);
                self.text[0] = len as u8;
                self.text[1..=len].copy_from_slice(&now[..len]);
            }
            WatchAt::WideText { at } => {
                let now = vm.wstring_bytes(self.place(vm, at));
                let len = now.len().min(self.text.len() - 1) & !1;
                self.text[0] = (len / 2) as u8;
                self.text[1..=len].copy_from_slice(&now[..len]);
            }
        }
    }
}

/// Scan time figures in ns (a scan: from its start to the end of END processing, tasks that
/// ran meanwhile included).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ScanStats {
    pub count: u64,
    pub last_ns: u64,
    pub min_ns: u64,
    pub max_ns: u64,
    pub time: Histogram,
}

impl Engine {
    /// END of the scan program (or of the init task's scan): the tasks after END come next.
    #[inline]
    pub(super) fn scan_program_ended(&mut self) {
        if let Some(running) = self.running_mut() {
            running.phase = Phase::AfterEnd { paused: running.phase.paused() };
        }
    }

    /// A scan starts: input refresh, a key switch move acted on (which may stop the PLC before
    /// the scan begins), then the scan program, or the init task until it is done.
    pub(super) fn start_scan(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.scan.count += 1;
        self.scan_start_ns = now;
        self.watchdog_start_ns = now;
        self.vm.begin_scan(self.scan.count == 1, now - self.run_start_ns);
        self.refresh_inputs(io);
        if self.switch.as_ref().is_some_and(KeySwitch::has_moved) {
            self.apply_switch(now, io, sink);
            if !self.executing() {
                return;
            }
        }
        sink.event(now, Event::ScanStart { n: self.scan.count });
        let Some(running) = self.running_mut() else { return };
        running.phase = Phase::Scan { paused: false };
        let task = if running.init == Init::Done { SCAN } else { INIT };
        self.begin(task, now, sink);
    }

    /// The rest of END processing once no task is left to run: DUTY, scan time, outputs.
    pub(super) fn finish_scan(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.vm.end_scan();
        let took = now - self.scan_start_ns;
        let paused = self.phase().paused();
        let scan = &mut self.scan;
        // A scan that paused at a breakpoint took the engineer's time, not the program's.
        if !paused {
            scan.last_ns = took;
            scan.min_ns = if scan.time.count() == 0 { took } else { scan.min_ns.min(took) };
            scan.max_ns = scan.max_ns.max(took);
            scan.time.record(took);
        }
        let tenth_ms = |ns: u64| (ns / 100_000).min(u64::from(u16::MAX)) as u16;
        self.vm.mem.set_scan_times(tenth_ms(took), tenth_ms(scan.min_ns), tenth_ms(scan.max_ns));
        self.refresh_outputs(io);
        match &mut self.mode {
            ModeState::Run(running) => running.phase = Phase::Idle,
            ModeState::Debug(running, session) => {
                running.phase = Phase::Idle;
                session.scan_ended();
            }
            ModeState::Stop | ModeState::Error(_) => {}
        }
        self.check_watches(now, sink);
        let period = self.settings.scan_period_ns;
        // On the grid of the schedule, not counted from the (possibly late) start: a scan that
        // started late — a driver's wake-up latency, a task that ran first — does not push
        // every later one back. Grid points already passed are skipped, not caught up.
        self.next_scan_ns = if period == 0 {
            now
        } else {
            let next = self.next_scan_ns + period;
            next + now.saturating_sub(next).div_ceil(period) * period
        };
    }

    /// The safe state: every output OFF, forces or not.
    pub(super) fn clear_outputs(&mut self, io: &mut impl Io) {
        self.vm.mem.io_image_mut().fill(0);
        io.refresh_outputs(&self.vm.mem);
        io.refresh_inputs(&mut self.vm.mem);
        self.note_switch(io);
    }

    /// Input refresh: the backend's inputs, then the forces over them, then a look at the key
    /// switch.
    pub(super) fn refresh_inputs(&mut self, io: &mut impl Io) {
        io.refresh_inputs(&mut self.vm.mem);
        self.forces.refresh(&mut self.vm.mem);
        self.note_switch(io);
    }

    /// Output refresh: the forces over what the program wrote, then the backend.
    pub(super) fn refresh_outputs(&mut self, io: &mut impl Io) {
        self.forces.refresh(&mut self.vm.mem);
        io.refresh_outputs(&self.vm.mem);
    }

    pub(super) fn check_watches(&mut self, now: u64, sink: &mut impl EventSink) {
        let vm = &self.vm;
        for (index, watch) in self.watches.iter_mut().enumerate() {
            let index = index as u16;
            match watch.at {
                WatchAt::Device(sample) => {
                    let value = read_sample(&vm.mem, sample);
                    if value as u64 != watch.last {
                        watch.last = value as u64;
                        sink.event(now, Event::Set { watch: index, value });
                    }
                }
                WatchAt::Value { at, elem } => {
                    let slot = vm.read_value(watch.place(vm, at), elem);
                    if slot != watch.last {
                        watch.last = slot;
                        sink.event(now, Event::SetVariable { watch: index, slot });
                    }
                }
                WatchAt::Text { at } => {
                    let now_text = vm.string_bytes(watch.place(vm, at));
                    let len = now_text.len().min(watch.text.len() - 1);
                    if watch.text[1..=usize::from(watch.text[0])] != now_text[..len] {
                        watch.text[0] = len as u8;
                        watch.text[1..=len].copy_from_slice(&now_text[..len]);
                        sink.text(now, index, &now_text[..len]);
                    }
                }
                WatchAt::WideText { at } => {
                    let now_text = vm.wstring_bytes(watch.place(vm, at));
                    let len = now_text.len().min(watch.text.len() - 1) & !1;
                    if watch.text[1..=2 * usize::from(watch.text[0])] != now_text[..len] {
                        watch.text[0] = (len / 2) as u8;
                        watch.text[1..=len].copy_from_slice(&now_text[..len]);
                        sink.wide_text(now, index, &now_text[..len]);
                    }
                }
            }
        }
    }

    /// RUN start, online change: the watches take the values they see as reported, so that
    /// a variable's initial value is never an event.
    pub(super) fn sample_watches_quietly(&mut self) {
        for watch in &mut self.watches {
            watch.sample_quietly(&self.vm);
        }
    }
}

/// Where the reference of a watch through it (`main.r^`, `main.p^.next^.value`) points now.
/// Out of the watches' loop and cold: the loop checks every watch once a scan, and a
/// free-running scan of a long program (`benches/layout`) measured the loop's own code growing
/// with it inline.
#[cold]
#[inline(never)]
fn through_place(through: &Through, vm: &Vm) -> Pointer {
    let slot = vm.read_value(through.reference.at, Elem::U64);
    through
        .follow(slot, vm.vars().len(), |at| vm.read_value(at, Elem::U64))
        .unwrap_or(Pointer::DISCARD)
}
