//! The virtual-time driver of `plcd sim`: the task engine in virtual time, deterministically, as
//! fast as the CPU allows.
//!
//! This driver only feeds the engine: stimulus changes at their times, and time itself. Every
//! executed instruction costs `step_ns` of virtual time; END processing and I/O refresh cost
//! none; while nothing runs, time jumps to the next event. The engine decides everything else,
//! exactly as it does under the real-time driver.
//!
//! Remote devices (`[[remote]]`) are not polled in virtual time: the devices their read tables
//! feed are plain devices the stimulus drives, and each status bit is held ON at every input
//! refresh, as a device that always answers, until the stimulus writes it (`5s, M0100, 0`
//! simulates a loss; `1` brings the device back).

pub mod timeline;
pub mod trace;

use crate::device::{Address, BitRef, Memory};
use crate::engine::event::{EventSink, Mode};
use crate::engine::{Activity, Engine};
use crate::io::simulated::SimulatedIo;
use crate::io::{Io, SwitchPosition};
use crate::project::{Project, Watched};
use crate::stimulus::{Stimulus, Target};
use crate::vm::{clock::CalendarClock, Clock, StepClock};

/// How long and how fine.
#[derive(Debug, Clone, Copy)]
pub struct SimOptions {
    /// Virtual time to run, from RUN start.
    pub duration_ns: u64,
    /// Virtual time one executed instruction costs.
    pub step_ns: u64,
}

/// Runs `project` from RUN at t = 0 for `options.duration_ns` of virtual time (with a `[switch]`,
/// the mode follows the simulated switch from t = 0 instead). Returns the engine as the run left
/// it, for its figures and device memory.
pub fn simulate(
    project: &Project,
    stimuli: &[Stimulus],
    watch: &[Watched],
    options: SimOptions,
    sink: &mut impl EventSink,
) -> Engine {
    let mut engine = Engine::new(project, watch);
    let mut io = SimIo {
        field: SimulatedIo::for_project(project, stimuli),
        remote_status: project
            .config
            .remotes
            .iter()
            .filter_map(|remote| remote.status)
            .map(|status| (status.device, status.bit, true))
            .collect(),
    };
    let step_ns = options.step_ns.max(1);
    let steps = StepClock { origin_ns: 0, origin_steps: engine.steps(), step_ns };
    let mut clock = CalendarClock { steps, start_utc_ns: project.config.sim.start_utc_ns };
    if project.config.switch.is_none() {
        engine.set_mode(Mode::Run, 0, &mut io, sink);
    }
    let mut next = 0;
    loop {
        let now = clock.now_ns(engine.steps());
        while let Some(s) = stimuli.get(next).filter(|s| s.t_ns <= now) {
            apply(&mut engine, &mut io, s, now, sink);
            next += 1;
        }
        engine.poll_time(now, &mut io, sink);
        if now >= options.duration_ns {
            break;
        }
        let next_stimulus = stimuli.get(next).map_or(u64::MAX, |s| s.t_ns).min(options.duration_ns);
        // The next moment something happens: a stimulus, the end, or what the engine awaits.
        let next_event = |engine: &Engine, now: u64| {
            next_stimulus.min(engine.next_wakeup(now).unwrap_or(u64::MAX)).max(now + 1)
        };
        let until = next_event(&engine, now);
        let steps = (until - now).div_ceil(step_ns).max(1);
        if engine.run(&clock, &mut io, sink, steps) == Activity::Idle {
            // Idle now, perhaps since an instant ago: skip to what the engine awaits from here.
            let after = clock.now_ns(engine.steps());
            let until = next_event(&engine, after);
            clock.steps.rebase(until, engine.steps());
        }
    }
    engine
}

/// The simulated field, and the status bits of the remote devices (see the module
/// documentation).
struct SimIo {
    field: SimulatedIo,
    /// Each status bit's device, place and simulated state.
    remote_status: Vec<(Address, BitRef, bool)>,
}

impl Io for SimIo {
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        self.field.refresh_inputs(mem);
        for (_, bit, on) in &self.remote_status {
            mem.set_bit(*bit, *on);
        }
    }

    fn refresh_outputs(&mut self, mem: &Memory) {
        self.field.refresh_outputs(mem);
    }

    fn switch(&self) -> Option<SwitchPosition> {
        self.field.switch()
    }

    fn is_input(&self, bit: BitRef) -> bool {
        self.field.is_input(bit) || self.remote_status.iter().any(|(_, b, _)| *b == bit)
    }
}

fn apply(engine: &mut Engine, io: &mut SimIo, s: &Stimulus, now: u64, sink: &mut impl EventSink) {
    match &s.target {
        Target::Mode(mode) => engine.set_mode(*mode, now, io, sink),
        Target::Switch(position) => {
            io.field.set_switch(*position);
        }
        Target::Device(address) if io.remote_status.iter().any(|(a, ..)| a == address) => {
            for (status, _, on) in &mut io.remote_status {
                if status == address {
                    *on = s.value != 0;
                }
            }
        }
        Target::Device(address) if SimulatedIo::is_io(address) => {
            let edges: Vec<_> = io.field.set_input(address, s.value).collect();
            for edge in edges {
                engine.input_edge(edge.contact, edge.rising, now, now, sink);
            }
        }
        Target::Device(address) => engine.write(address, s.value),
    }
}
