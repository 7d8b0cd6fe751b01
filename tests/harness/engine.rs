//! The engine in virtual time, for the tests of what it decides: a project from literal texts,
//! a field the test holds in its hands, and the engine driven the way the simulator drives it.

use std::path::Path;

use plcd::config::{self, Config};
use plcd::device::{Address, BitRef, Memory};
use plcd::drivers::virtual_time::{simulate, SimOptions};
use plcd::engine::event::{Event, Mode, Recorder};
use plcd::engine::{Activity, Engine, ModeRequest, Refusal};
use plcd::io::{Io, SwitchPosition};
use plcd::project::{self, Project, Watched};
use plcd::stimulus::Stimulus;
use plcd::vm::{Clock, StepClock};

pub const MS: u64 = 1_000_000;

/// What an executed instruction costs in these tests' virtual time: 1 µs.
pub const STEP_NS: u64 = 1000;

/// A config from its text; panics with the diagnostics.
pub fn config(text: &str) -> Config {
    config::parse(text, Path::new("test.toml")).unwrap_or_else(|d| panic!("config:\n{d}"))
}

/// A project of `config`; `program` gives the text of each program by its file name. Panics
/// with the diagnostics.
pub fn project_from(config: Config, program: impl Fn(&str) -> String) -> Project {
    project::from_config(config, |path| Ok(program(path.file_name().unwrap().to_str().unwrap())))
        .unwrap_or_else(|d| panic!("project:\n{d}"))
}

/// A project of `config` with its programs' texts by file name.
pub fn project_of(config: Config, programs: &[(&str, &str)]) -> Project {
    project_from(config, |name| {
        let found = programs.iter().find(|(file, _)| *file == name);
        found.unwrap_or_else(|| panic!("no program text for {name}")).1.to_string()
    })
}

/// `project` with native code attached to its programs (plcd-native), or as it is (also
/// when plcd is built without its `native` feature).
pub fn with_native(project: Project, native: bool) -> Project {
    #[cfg(feature = "native")]
    if native {
        let mut project = project;
        let errors = plcd_native::attach(&mut project);
        assert!(errors.is_empty(), "native code: {errors:?}");
        return project;
    }
    let _ = native;
    project
}

/// A project from a config text and its programs' texts by file name.
pub fn project(config_text: &str, programs: &[(&str, &str)]) -> Project {
    project_of(config(config_text), programs)
}

/// `plcd sim` of `project` for `duration_ns`, at [`STEP_NS`] an instruction: the engine as it
/// ends and every event.
pub fn sim(
    project: &Project,
    stimuli: &[Stimulus],
    watch: &[Address],
    duration_ns: u64,
) -> (Engine, Recorder) {
    let watch: Vec<Watched> = watch.iter().map(Watched::from).collect();
    sim_watching(project, stimuli, &watch, duration_ns)
}

/// [`sim`] watching devices and Structured Text variables.
pub fn sim_watching(
    project: &Project,
    stimuli: &[Stimulus],
    watch: &[Watched],
    duration_ns: u64,
) -> (Engine, Recorder) {
    let mut events = Recorder::default();
    let options = SimOptions { duration_ns, step_ns: STEP_NS };
    let engine = simulate(project, stimuli, watch, options, &mut events);
    (engine, events)
}

pub fn bit(dev: &str) -> BitRef {
    Address::parse(dev).unwrap().as_bit().unwrap()
}

/// A field the test holds in its hands: input words, the outputs as last refreshed, a switch.
/// A P bit is an input once [`Field::input`] set it; every other bit is an output.
pub struct Field {
    pub inputs: [u16; 128],
    pub input_mask: [u16; 128],
    pub outputs: [u16; 128],
    pub switch: Option<SwitchPosition>,
}

impl Default for Field {
    fn default() -> Self {
        Field { inputs: [0; 128], input_mask: [0; 128], outputs: [0; 128], switch: None }
    }
}

impl Io for Field {
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        for (w, word) in mem.io_image_mut().iter_mut().enumerate() {
            let m = self.input_mask[w];
            *word = (*word & !m) | (self.inputs[w] & m);
        }
    }
    fn refresh_outputs(&mut self, mem: &Memory) {
        for (w, word) in mem.io_image().iter().enumerate() {
            self.outputs[w] = word & !self.input_mask[w];
        }
    }
    fn switch(&self) -> Option<SwitchPosition> {
        self.switch
    }
    fn is_input(&self, bit: BitRef) -> bool {
        self.input_mask[bit.word as usize] & bit.mask != 0
    }
}

impl Field {
    /// Makes `dev` an input and sets its level.
    pub fn input(&mut self, dev: &str, on: bool) {
        let b = bit(dev);
        self.input_mask[b.word as usize] |= b.mask;
        if on {
            self.inputs[b.word as usize] |= b.mask;
        } else {
            self.inputs[b.word as usize] &= !b.mask;
        }
    }

    /// An output as the last output refresh left it.
    pub fn output(&self, dev: &str) -> bool {
        let b = bit(dev);
        self.outputs[b.word as usize] & b.mask != 0
    }
}

/// The engine on a [`STEP_NS`]-per-instruction clock, driven the way the simulator drives it,
/// with its field and every event it reported.
pub struct Plc {
    pub engine: Engine,
    pub field: Field,
    pub events: Recorder,
    pub clock: StepClock,
}

impl Plc {
    pub fn new(project: &Project) -> Plc {
        let engine = Engine::new::<Address>(project, &[]);
        let clock = StepClock { origin_ns: 0, origin_steps: engine.steps(), step_ns: STEP_NS };
        Plc { engine, field: Field::default(), events: Recorder::default(), clock }
    }

    /// Virtual time now.
    pub fn now(&self) -> u64 {
        self.clock.now_ns(self.engine.steps())
    }

    /// Runs `ns` of virtual time: instructions cost their step, idle stretches are jumped to
    /// the engine's next wake-up.
    pub fn run_for(&mut self, ns: u64) {
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

    /// A mode change as the control socket asks for one.
    pub fn request(&mut self, request: ModeRequest) -> Result<(), Refusal> {
        let now = self.now();
        self.engine.request_mode(request, now, &mut self.field, &mut self.events)
    }

    /// A mode change as the daemon makes one (startup, a signal).
    pub fn set_mode(&mut self, mode: Mode) {
        let now = self.now();
        self.engine.set_mode(mode, now, &mut self.field, &mut self.events);
    }

    pub fn read(&self, dev: &str) -> i32 {
        self.engine.vm().mem.read(&Address::parse(dev).unwrap())
    }

    pub fn write(&mut self, dev: &str, value: i32) {
        self.engine.write(&Address::parse(dev).unwrap(), value);
    }

    /// The mode changes reported so far.
    pub fn modes(&self) -> Vec<Mode> {
        self.events
            .0
            .iter()
            .filter_map(|(_, e)| match e {
                Event::Mode(m) => Some(*m),
                _ => None,
            })
            .collect()
    }
}
