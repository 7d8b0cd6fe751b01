//! The real-time driver as one object: [`Driver::start`] opens the field of a loaded project,
//! starts the scan, event and watchdog threads (and, with the simulated field, the stimulus
//! player) under `[rt]`, and hands out the ends of the queues that talk to them; [`Driver::stop`]
//! takes the outputs to STOP's safe state and gives the engine back.
//!
//! The daemon supervises one (`plcd run`), and `plcd bench` runs one to measure it: the same
//! threads either way.

use std::path::PathBuf;
use std::sync::{mpsc, Arc, Mutex};
use std::thread::JoinHandle;

use super::events::EventThread;
use super::io::{FieldIo, FieldSafeOutputs, GatedIo, SafeOutputs};
use super::mirror::Mirror;
use super::scan::ScanThread;
use super::snapshot::Snapshot;
use super::stimulus::StimulusThread;
use super::sys::{self, SysError, Timer};
use super::watchdog::WatchdogThread;
use super::{
    pending, setup_thread, Command, Completion, LogMessage, Report, Role, RtSetupError, Shared,
    COMMAND_QUEUE, COMPLETION_QUEUE, EDGE_QUEUE, MESSAGE_QUEUE, PLAIN_THREAD_STACK, REPORT_QUEUE,
    THREAD_STACK,
};
use crate::config::{Backend, OnFault, RtConfig, RtPolicy};
use crate::diag::Diagnostics;
use crate::engine::Engine;
use crate::files;
use crate::io::gate::OutputGate;
use crate::io::gpio::{self, GpioError};
use crate::io::remote::{self, RemoteError, RemoteService};
use crate::io::simulated::SimulatedIo;
use crate::io::InputEdge;
use crate::project::Project;

/// Why the driver could not start.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    #[error("{path}: {source}", path = .path.display())]
    Stimulus { path: PathBuf, source: Diagnostics },
    #[error("I/O: {0}")]
    Io(#[from] GpioError),
    #[error("{0}")]
    Sys(#[from] SysError),
    #[error("real time required by [rt] require = true, but: {}", .0.join("; "))]
    RtRefused(Vec<String>),
    #[error("cannot start the {thread} thread: {source}")]
    Spawn { thread: &'static str, source: std::io::Error },
    #[error("{0}")]
    Remote(#[from] RemoteError),
}

struct Threads {
    scan: JoinHandle<Box<Engine>>,
    events: JoinHandle<Result<(), SysError>>,
    watchdog: JoinHandle<()>,
    stimulus: Option<JoinHandle<()>>,
    /// To make the outputs safe if the scan thread dies instead of stopping.
    gate: Arc<OutputGate>,
    safe: SafeOutputs,
}

/// What the driver got of what `[rt]` asked for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Granted {
    /// Every real-time thread runs under SCHED_FIFO.
    pub fifo: bool,
    pub memory_locked: bool,
    /// The PM QoS wake-up latency held, in µs.
    pub cpu_latency_us: Option<u32>,
}

/// The running real-time threads of one project, and the ends of their queues.
pub struct Driver {
    pub shared: Arc<Shared>,
    /// Commands to the scan thread; shared with the stimulus player, the control socket's
    /// requests and the Modbus server.
    pub commands: Arc<Mutex<rtrb::Producer<Command>>>,
    /// What the scan thread reports, in order.
    pub reports: rtrb::Consumer<Report>,
    /// The programs' ADS log messages, in order.
    pub messages: rtrb::Consumer<LogMessage>,
    completions: Option<rtrb::Consumer<Completion>>,
    /// Captured by the scan thread at a scan boundary when `shared.snapshot_wanted`.
    pub snapshot: Arc<Mutex<Box<Snapshot>>>,
    /// What `[rt]` asked for and did not get (only when `require = false`); for the caller to
    /// warn about.
    pub problems: Vec<String>,
    pub granted: Granted,
    threads: Option<Threads>,
    /// The poller threads of the remote devices (`[[remote]]`).
    remote: Option<RemoteService>,
    /// `[rt] cpu_dma_latency_us`, held until the driver is dropped.
    _cpu_latency: Option<sys::CpuLatencyRequest>,
}

impl Driver {
    /// Locks memory (if `[rt] lock_memory`), opens the field and starts the threads; the engine
    /// starts in STOP. With `[rt] require = true`, any real-time setting refused is an error
    /// and nothing keeps running.
    ///
    /// `mirrors` are copied by the scan thread at scan boundaries when their consumers ask
    /// (see [`super::mirror`]).
    pub fn start(project: &Project, mirrors: Vec<Arc<Mirror>>) -> Result<Driver, DriverError> {
        Driver::start_with(project, mirrors, |_| {})
    }

    /// [`Driver::start`], with `prepare` applied to the new engine before the threads start
    /// (the retained memory restored at start).
    pub fn start_with(
        project: &Project,
        mirrors: Vec<Arc<Mirror>>,
        prepare: impl FnOnce(&mut Engine),
    ) -> Result<Driver, DriverError> {
        let config = &project.config;
        let rt = config.rt.clone();
        let mut problems: Vec<String> = Vec::new();
        let mut granted = Granted { fifo: rt.policy == RtPolicy::Fifo, ..Granted::default() };
        if rt.lock_memory {
            match sys::lock_memory() {
                Ok(()) => granted.memory_locked = true,
                Err(e) => problems.push(e),
            }
        }
        let mut cpu_latency = None;
        if let (RtPolicy::Fifo, Some(us)) = (rt.policy, rt.cpu_dma_latency_us) {
            match sys::request_cpu_latency(us) {
                Ok(request) => {
                    cpu_latency = Some(request);
                    granted.cpu_latency_us = Some(us);
                }
                Err(e) => problems.push(format!("cpu_dma_latency_us = {us}: {e}")),
            }
        }
        let shared = Arc::new(Shared::new()?);
        let gate = Arc::new(OutputGate::default());
        let (edge_tx, edge_rx) = rtrb::RingBuffer::<InputEdge>::new(EDGE_QUEUE);
        let (command_tx, command_rx) = rtrb::RingBuffer::<Command>::new(COMMAND_QUEUE);
        let (report_tx, report_rx) = rtrb::RingBuffer::<Report>::new(REPORT_QUEUE);
        let (message_tx, message_rx) = rtrb::RingBuffer::<LogMessage>::new(MESSAGE_QUEUE);
        let (completion_tx, completion_rx) = rtrb::RingBuffer::<Completion>::new(COMPLETION_QUEUE);
        let commands = Arc::new(Mutex::new(command_tx));
        let snapshot = Arc::new(Mutex::new(Snapshot::new()));

        // The field.
        let mut events = EventThread::new(Arc::clone(&shared));
        let mut stimulus_thread = None;
        let (field, safe) = match config.io.backend {
            Backend::Sim => {
                let stimuli = match &config.io.stimulus {
                    Some(path) => files::stimulus_for(path, config)
                        .map_err(|source| DriverError::Stimulus { path: path.clone(), source })?,
                    None => Vec::new(),
                };
                let io = SimulatedIo::for_project(project, &stimuli);
                let field = io.field();
                if !stimuli.is_empty() {
                    stimulus_thread = Some(StimulusThread {
                        shared: Arc::clone(&shared),
                        stimuli,
                        looped: config.io.stimulus_loop,
                        field: Arc::clone(&field),
                        edges: edge_tx,
                        commands: Arc::clone(&commands),
                    });
                }
                (FieldIo::Simulated(io), FieldSafeOutputs::Simulated(field))
            }
            Backend::Gpiocdev => {
                let opened = gpio::open(config, "plcd", Arc::clone(&shared.field_faults))?;
                events.gpio = opened.edges;
                events.edges = Some(edge_tx);
                (FieldIo::Gpio(opened.io), FieldSafeOutputs::Gpio(opened.outputs))
            }
        };
        let (remote, remote_service) = remote::start(&config.remotes)?;
        let safe = SafeOutputs { field: safe, remote: remote.safe_state() };
        let clear = config.plc.on_fault == OnFault::Clear;
        let io = GatedIo {
            field,
            remote,
            gate: Arc::clone(&gate),
            safe: safe.clone(),
            clear_on_trip: clear,
        };

        let watch = project.output_bits();
        let mut engine = Box::new(Engine::new(project, &watch));
        prepare(&mut engine);

        // The threads, each reporting how its [rt] setup went before it starts working.
        let (setup_tx, setup_rx) = mpsc::channel::<Vec<RtSetupError>>();
        let watchdog = spawn_rt(Role::Watchdog, &rt, setup_tx.clone(), {
            let thread = WatchdogThread {
                shared: Arc::clone(&shared),
                gate: Arc::clone(&gate),
                safe: safe.clone(),
                clear,
            };
            move || thread.run()
        })?;
        let events = spawn_rt(Role::Events, &rt, setup_tx.clone(), move || events.run())?;
        let scan_thread = ScanThread {
            engine,
            io,
            shared: Arc::clone(&shared),
            edges: edge_rx,
            commands: command_rx,
            reports: report_tx,
            messages: message_tx,
            completions: completion_tx,
            snapshot: Arc::clone(&snapshot),
            timer: Timer::new()?,
            mirrors,
        };
        let scan = spawn_rt(Role::Scan, &rt, setup_tx, move || scan_thread.run())?;
        for _ in 0..3 {
            let errors = setup_rx.recv().unwrap_or_default();
            // set_fifo's is the one error that leaves a thread without SCHED_FIFO.
            granted.fifo &= !errors.iter().any(|e| e.error.call.starts_with("sched_setscheduler"));
            problems.extend(errors.iter().map(|e| e.to_string()));
        }
        let mut driver = Driver {
            shared,
            commands,
            reports: report_rx,
            messages: message_rx,
            completions: Some(completion_rx),
            snapshot,
            problems: Vec::new(),
            granted,
            threads: Some(Threads { scan, events, watchdog, stimulus: None, gate, safe }),
            remote: Some(remote_service),
            _cpu_latency: cpu_latency,
        };
        if !problems.is_empty() && rt.require {
            driver.stop();
            return Err(DriverError::RtRefused(problems));
        }
        driver.problems = problems;
        if let Some(player) = stimulus_thread {
            let handle = std::thread::Builder::new()
                .name("plcd-stimulus".into())
                .stack_size(PLAIN_THREAD_STACK)
                .spawn(move || player.run())
                .map_err(|source| DriverError::Spawn { thread: "stimulus", source });
            match handle {
                Ok(handle) => {
                    if let Some(threads) = &mut driver.threads {
                        threads.stimulus = Some(handle);
                    }
                }
                Err(e) => {
                    driver.stop();
                    return Err(e);
                }
            }
        }
        Ok(driver)
    }

    /// Queues a command for the scan thread; false if the queue is full.
    pub fn command(&self, command: Command) -> bool {
        let pushed = self.commands.lock().map(|mut q| q.push(command).is_ok()).unwrap_or(false);
        if pushed {
            self.shared.signal(pending::COMMAND);
        }
        pushed
    }

    /// The completions of control commands, for the one control thread (once).
    pub fn take_completions(&mut self) -> Option<rtrb::Consumer<Completion>> {
        self.completions.take()
    }

    /// The remote devices' counters, for `plcctl status`.
    pub fn remote_board(&self) -> remote::RemoteBoard {
        self.remote.as_ref().map(RemoteService::board).unwrap_or_default()
    }

    /// The real-time thread that ended although no stop was asked for, if one did.
    pub fn dead_thread(&self) -> Option<&'static str> {
        let threads = self.threads.as_ref()?;
        if threads.scan.is_finished() {
            Some("scan")
        } else if threads.events.is_finished() {
            Some("events")
        } else if threads.watchdog.is_finished() {
            Some("watchdog")
        } else {
            None
        }
    }

    /// Stops every thread; the scan thread stops between two instructions and puts the
    /// outputs into their safe state first. Returns its engine unless it had died (or the
    /// driver was stopped before).
    pub fn stop(&mut self) -> Option<Box<Engine>> {
        let threads = self.threads.take()?;
        let shared = &self.shared;
        shared.request_shutdown();
        threads.watchdog.thread().unpark();
        if let Some(stimulus) = &threads.stimulus {
            stimulus.thread().unpark();
        }
        let engine = threads.scan.join().ok();
        if engine.is_none() {
            // The scan thread panicked: nobody took the outputs to STOP's safe state.
            threads.gate.trip();
            threads.safe.apply();
            log::error!("the scan thread died; outputs switched off");
        }
        // The remote devices' outputs go to their safe state too: their pollers write zeros
        // to every write table (each within its timeout) before they stop.
        threads.safe.remote.apply();
        drop(self.remote.take());
        if let Ok(Err(e)) = threads.events.join() {
            log::error!("event thread: {e}");
        }
        let _ = threads.watchdog.join();
        if let Some(stimulus) = threads.stimulus {
            let _ = stimulus.join();
        }
        engine
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        self.stop();
    }
}

fn spawn_rt<T: Send + 'static>(
    role: Role,
    rt: &RtConfig,
    setup: mpsc::Sender<Vec<RtSetupError>>,
    body: impl FnOnce() -> T + Send + 'static,
) -> Result<JoinHandle<T>, DriverError> {
    let rt = rt.clone();
    std::thread::Builder::new()
        .name(format!("plcd-{}", role.name()))
        .stack_size(THREAD_STACK)
        .spawn(move || {
            let _ = setup.send(setup_thread(&rt, role));
            body()
        })
        .map_err(|source| DriverError::Spawn { thread: role.name(), source })
}
