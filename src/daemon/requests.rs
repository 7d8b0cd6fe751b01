//! The daemon's side of the control socket: turns protocol requests into scan-thread commands
//! and snapshot reads, and their outcomes into replies. It runs on the control thread (not
//! real time) behind [`crate::services::control::server`], and never waits for the scan thread: a request
//! that needs an END is parked until its completion or snapshot arrives.
//!
//! - Commands that change PLC state (mode, writes, forces, debugger, programs) go through the
//!   command queue and are applied by the scan thread at a scan boundary; each carries a ticket
//!   that its [`Completion`] answers.
//! - Reads come from the [`Snapshot`] the scan thread publishes at a scan boundary when asked.
//!   Device reads always wait for a capture taken after the request; `status` accepts one
//!   younger than [`STATUS_MAX_AGE`] as long as no command completed since, so that any number
//!   of clients polling `status` cost the scan at most one capture per that period.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::report::Names;
use crate::config::Backend;
use crate::device::{Address, Area, Writer, WORD_VALUES};
use crate::drivers::real_time::snapshot::{Snapshot, MAX_READ_WORDS};
use crate::drivers::real_time::{
    pending, Applied, Command, Completion, ControlCommand, Shared, WRITES_PER_COMMAND,
};
use crate::engine::debug::{self, Breakpoint, DebugRun};
use crate::engine::event::Mode;
use crate::engine::{force, online, Engine, ModeRequest, Refusal};
use crate::files;
use crate::io::SwitchPosition;
use crate::project::Project;
use crate::services::control::{ClientId, Handler, Peer};
use crate::stats::Histogram;
use plcd_ipc::{
    DebugState, DeviceValue, ErrorInfo, ErrorKind as Kind, Failure, Location, ModeName,
    Percentiles, Reply, Request, ResponseLine, ScanFigures, Status, SwitchName, TaskFigures,
};

/// How old a snapshot `status` may answer from.
pub const STATUS_MAX_AGE: Duration = Duration::from_millis(20);
/// How long a request may wait for the scan thread before it is answered `unavailable`.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(10);
/// How often a `step` in progress is looked at.
const STEP_POLL: Duration = Duration::from_millis(5);
/// Devices one `get` may name.
pub const MAX_GET: usize = MAX_READ_WORDS;

/// The project the PLC runs, with the names its reports need. Shared by the supervisor (log
/// lines, SIGHUP) and the control thread (breakpoints, online change).
pub struct Running {
    pub config_path: PathBuf,
    pub project: Project,
    pub names: Names,
}

impl Running {
    pub fn new(config_path: &Path, project: Project) -> Running {
        let watch = project.output_bits();
        let names = Names::new(&project, &watch);
        let config_path =
            std::fs::canonicalize(config_path).unwrap_or_else(|_| config_path.to_path_buf());
        Running { config_path, project, names }
    }
}

/// The queues and shared state the handler works with.
pub struct ControlLinks {
    pub shared: Arc<Shared>,
    pub commands: Arc<Mutex<rtrb::Producer<Command>>>,
    pub completions: rtrb::Consumer<Completion>,
    pub snapshot: Arc<Mutex<Box<Snapshot>>>,
    pub running: Arc<Mutex<Running>>,
}

pub struct ControlHandler {
    links: ControlLinks,
    started: Instant,
    next_ticket: u64,
    waiting: Vec<Waiting>,
    /// The last snapshot generation seen, and until when `status` may use it.
    fresh_until: Option<(u64, Instant)>,
    /// When a capture was last asked for.
    last_want: Instant,
}

struct Waiting {
    client: ClientId,
    since: Instant,
    stage: Stage,
    then: Then,
}

enum Stage {
    /// Tickets not yet completed; the last completion's state; the first refusal.
    Commands { tickets: Vec<u64>, applied: Option<Applied>, refused: Option<Refusal> },
    /// A capture newer than this generation.
    Snapshot { after: u64 },
}

enum Then {
    Mode,
    Written {
        count: usize,
    },
    Forces {
        unforced: Option<Address>,
    },
    /// `until_paused`: `step` answers once the step is done (execution paused again).
    Debug {
        unbroken: Option<String>,
        devices: Option<Vec<Address>>,
        until_paused: bool,
    },
    Status,
    Values {
        devices: Vec<Address>,
    },
    Loaded {
        online: bool,
        programs: usize,
        tasks: usize,
        previous: Option<Box<Running>>,
    },
}

fn failure(kind: Kind, message: impl Into<String>) -> ResponseLine {
    ResponseLine::error(kind, message)
}

fn mode_name(mode: Mode) -> ModeName {
    match mode {
        Mode::Run => ModeName::Run,
        Mode::Stop => ModeName::Stop,
        Mode::Error => ModeName::Error,
        Mode::Debug => ModeName::Debug,
    }
}

/// The word a device lives in, and how to read it out of that word.
fn word_of(address: &Address) -> u16 {
    match address.as_word() {
        Ok(word) => word.0,
        Err(_) => address.as_bit().map(|b| b.word).unwrap_or(0),
    }
}

fn value_in(address: &Address, word: u16) -> i32 {
    match address.as_word() {
        Ok(_) => i32::from(word as i16),
        Err(_) => address.as_bit().map(|b| i32::from(word & b.mask != 0)).unwrap_or(0),
    }
}

fn parse_device(text: &str) -> Result<Address, Failure> {
    Address::parse(text.trim()).map_err(|e| Failure::new(Kind::Invalid, e.to_string()))
}

/// A device that can be forced: a P bit.
fn parse_io_bit(text: &str) -> Result<(Address, crate::device::BitRef), Failure> {
    let address = parse_device(text)?;
    let bit = force::io_bit(&address).map_err(|e| Failure::new(Kind::Invalid, e.to_string()))?;
    Ok((address, bit))
}

impl ControlHandler {
    pub fn new(links: ControlLinks) -> ControlHandler {
        ControlHandler {
            links,
            started: Instant::now(),
            next_ticket: 1,
            waiting: Vec::new(),
            fresh_until: None,
            last_want: Instant::now(),
        }
    }

    /// Queues control commands; their tickets, or `busy` when the queue is full.
    fn send(&mut self, commands: Vec<ControlCommand>) -> Result<Vec<u64>, Failure> {
        let busy = || Failure::new(Kind::Busy, "the command queue is full; try again");
        let mut queue = self.links.commands.lock().unwrap_or_else(|e| e.into_inner());
        if queue.slots() < commands.len() {
            return Err(busy());
        }
        let mut tickets = Vec::with_capacity(commands.len());
        for command in commands {
            let ticket = self.next_ticket;
            self.next_ticket += 1;
            if queue.push(Command::Control(ticket, command)).is_err() {
                return Err(busy());
            }
            tickets.push(ticket);
        }
        drop(queue);
        self.links.shared.signal(pending::COMMAND);
        Ok(tickets)
    }

    fn park(
        &mut self,
        client: ClientId,
        commands: Vec<ControlCommand>,
        then: Then,
    ) -> Option<ResponseLine> {
        match self.send(commands) {
            Ok(tickets) => {
                self.waiting.push(Waiting {
                    client,
                    since: Instant::now(),
                    stage: Stage::Commands { tickets, applied: None, refused: None },
                    then,
                });
                None
            }
            Err(f) => Some(ResponseLine::failure(f)),
        }
    }

    fn park_for_snapshot(&mut self, client: ClientId, then: Then) -> Option<ResponseLine> {
        let after = self.generation();
        self.waiting.push(Waiting {
            client,
            since: Instant::now(),
            stage: Stage::Snapshot { after },
            then,
        });
        self.want_snapshot();
        None
    }

    fn generation(&self) -> u64 {
        self.links.snapshot.lock().map(|s| s.generation).unwrap_or(0)
    }

    /// Asks for a capture of every word the waiting requests need.
    fn want_snapshot(&mut self) {
        self.last_want = Instant::now();
        if let Ok(mut snapshot) = self.links.snapshot.lock() {
            let mut len = 0;
            for waiting in &self.waiting {
                let devices = match &waiting.then {
                    Then::Values { devices } => devices.as_slice(),
                    Then::Debug { devices: Some(devices), .. } => devices.as_slice(),
                    _ => continue,
                };
                for device in devices {
                    let word = word_of(device);
                    if !snapshot.want[..len].contains(&word) && len < MAX_READ_WORDS {
                        snapshot.want[len] = word;
                        len += 1;
                    }
                }
            }
            snapshot.want_len = len;
        }
        self.links.shared.snapshot_wanted.store(true, Ordering::Release);
        self.links.shared.signal(pending::COMMAND);
    }

    fn handle(&mut self, client: ClientId, request: Request) -> Option<ResponseLine> {
        let remote = |request| Some(ControlCommand::Mode(request));
        let (commands, then) = match request {
            Request::Status => {
                if let Some((generation, until)) = self.fresh_until {
                    if Instant::now() < until && generation == self.generation() {
                        let snapshot = self.links.snapshot.lock().ok()?;
                        return Some(ResponseLine::ok(Reply::Status(Box::new(
                            self.status(&snapshot),
                        ))));
                    }
                }
                return self.park_for_snapshot(client, Then::Status);
            }
            Request::Run => (remote(ModeRequest::Run), Then::Mode),
            Request::Stop => (remote(ModeRequest::Stop), Then::Mode),
            Request::Reset { cold } => (remote(ModeRequest::Reset { cold }), Then::Mode),
            // From RUN the current scan ends first: answered once paused.
            Request::Debug => (
                remote(ModeRequest::Debug),
                Then::Debug { unbroken: None, devices: None, until_paused: true },
            ),
            Request::Get { devices } => {
                if devices.is_empty() {
                    return Some(failure(Kind::Invalid, "name at least one device"));
                }
                if devices.len() > MAX_GET {
                    return Some(failure(
                        Kind::Invalid,
                        format!("at most {MAX_GET} devices per get"),
                    ));
                }
                let mut parsed = Vec::with_capacity(devices.len());
                for text in &devices {
                    match parse_device(text) {
                        Ok(address) => parsed.push(address),
                        Err(f) => return Some(ResponseLine::failure(f)),
                    }
                }
                return self.park_for_snapshot(client, Then::Values { devices: parsed });
            }
            Request::Set { writes } => {
                if writes.is_empty() {
                    return Some(failure(Kind::Invalid, "name at least one DEVICE=VALUE"));
                }
                let mut items = Vec::with_capacity(writes.len());
                for DeviceValue { dev, value } in &writes {
                    let address = match parse_device(dev) {
                        Ok(address) => address,
                        Err(f) => return Some(ResponseLine::failure(f)),
                    };
                    if !address.writable_by(Writer::Client) {
                        return Some(failure(
                            Kind::Invalid,
                            format!("{address} is a system device; the PLC maintains it"),
                        ));
                    }
                    if !WORD_VALUES.contains(value) {
                        return Some(failure(
                            Kind::Invalid,
                            format!("{address}={value}: a value is 16 bits ({WORD_VALUES:?})"),
                        ));
                    }
                    items.push((address, *value));
                }
                let count = items.len();
                let commands = items
                    .chunks(WRITES_PER_COMMAND)
                    .map(|chunk| {
                        let mut fixed = [(Address { area: Area::D, number: 0, bit: None }, 0);
                            WRITES_PER_COMMAND];
                        fixed[..chunk.len()].copy_from_slice(chunk);
                        ControlCommand::Writes { items: fixed, len: chunk.len() }
                    })
                    .collect();
                return self.park(client, commands, Then::Written { count });
            }
            Request::Force { dev, value } => {
                let (address, bit) = match parse_io_bit(&dev) {
                    Ok(found) => found,
                    Err(f) => return Some(ResponseLine::failure(f)),
                };
                if !(0..=1).contains(&value) {
                    return Some(failure(
                        Kind::Invalid,
                        format!("{address}={value}: a bit is forced to 0 or 1"),
                    ));
                }
                (Some(ControlCommand::Force(bit, value == 1)), Then::Forces { unforced: None })
            }
            Request::Unforce { dev } => {
                let (address, bit) = match parse_io_bit(&dev) {
                    Ok(found) => found,
                    Err(f) => return Some(ResponseLine::failure(f)),
                };
                (Some(ControlCommand::Unforce(bit)), Then::Forces { unforced: Some(address) })
            }
            Request::UnforceAll => {
                (Some(ControlCommand::UnforceAll), Then::Forces { unforced: None })
            }
            Request::Forces => {
                return self.park_for_snapshot(client, Then::Forces { unforced: None })
            }
            Request::Step => (
                Some(ControlCommand::Step),
                Then::Debug { unbroken: None, devices: None, until_paused: true },
            ),
            Request::Continue => (
                Some(ControlCommand::Continue),
                Then::Debug { unbroken: None, devices: None, until_paused: false },
            ),
            Request::Break { at } => match self.resolve(&at) {
                Ok(bp) => (
                    Some(ControlCommand::Break(bp)),
                    Then::Debug { unbroken: None, devices: None, until_paused: false },
                ),
                Err(f) => return Some(ResponseLine::failure(f)),
            },
            Request::Unbreak { at: Some(at) } => match self.resolve(&at) {
                Ok(bp) => (
                    Some(ControlCommand::Unbreak(Some(bp))),
                    Then::Debug { unbroken: Some(at), devices: None, until_paused: false },
                ),
                Err(f) => return Some(ResponseLine::failure(f)),
            },
            Request::Unbreak { at: None } => (
                Some(ControlCommand::Unbreak(None)),
                Then::Debug { unbroken: None, devices: None, until_paused: false },
            ),
            Request::Load { config, online } => return self.load(client, &config, online),
        };
        self.park(client, commands.into_iter().collect(), then)
    }

    fn resolve(&self, at: &str) -> Result<Breakpoint, Failure> {
        let running = self.links.running.lock().unwrap_or_else(|e| e.into_inner());
        debug::resolve(&running.project.programs, at)
            .map_err(|e| Failure::new(Kind::Invalid, e.to_string()))
    }

    fn load(&mut self, client: ClientId, config: &str, online: bool) -> Option<ResponseLine> {
        let path = Path::new(config);
        if !path.is_absolute() {
            return Some(failure(
                Kind::Invalid,
                format!("`{config}`: give the daemon an absolute path"),
            ));
        }
        let new = match files::project(path) {
            Ok(project) => project,
            Err(diagnostics) => {
                let details = diagnostics.iter().map(ToString::to_string).collect();
                return Some(ResponseLine::failure(
                    Failure::new(
                        Kind::Invalid,
                        format!(
                            "{} errors in {config}; the running project is unchanged",
                            diagnostics.len()
                        ),
                    )
                    .with_details(details),
                ));
            }
        };
        let mut running = self.links.running.lock().unwrap_or_else(|e| e.into_inner());
        let old = &running.project.config;
        let restart: Vec<String> = [
            ("[io]", new.config.io != old.io),
            ("[rt]", new.config.rt != old.rt),
            ("[control]", new.config.control != old.control),
            ("[switch]", new.config.switch != old.switch),
            ("[retain]", new.config.retain != old.retain),
            ("[modbus]", new.config.modbus != old.modbus),
        ]
        .into_iter()
        .filter(|(_, changed)| *changed)
        .map(|(name, _)| format!("{name} changed, which takes a restart of the service"))
        .collect();
        if !restart.is_empty() {
            return Some(ResponseLine::failure(
                Failure::new(Kind::Refused, "load refused; the running project is unchanged")
                    .with_details(restart),
            ));
        }
        let mode = self.links.shared.mode();
        let running_now = matches!(mode, Mode::Run | Mode::Debug);
        if running_now && !online {
            return Some(failure(
                Kind::Refused,
                "the PLC is in RUN: stop it first, or load --online",
            ));
        }
        let watch = new.output_bits();
        let command = if running_now {
            match online::prepare(&running.project, &new, &watch) {
                Ok(change) => ControlCommand::Online(Box::new(change)),
                Err(reasons) => {
                    return Some(ResponseLine::failure(
                        Failure::new(
                            Kind::Refused,
                            "online change refused; the running project is unchanged",
                        )
                        .with_details(reasons),
                    ))
                }
            }
        } else {
            ControlCommand::Load(Box::new(Engine::new(&new, &watch)))
        };
        let (programs, tasks) = (new.programs.len(), new.config.tasks.len());
        // The new project is the running one from now on (the supervisor names the new
        // engine's reports with it); a refusal at the scan thread puts the old one back.
        let previous = std::mem::replace(&mut *running, Running::new(path, new));
        drop(running);
        match self.send(vec![command]) {
            Ok(tickets) => {
                let then = Then::Loaded {
                    online: running_now,
                    programs,
                    tasks,
                    previous: Some(Box::new(previous)),
                };
                let stage = Stage::Commands { tickets, applied: None, refused: None };
                self.waiting.push(Waiting { client, since: Instant::now(), stage, then });
                None
            }
            Err(f) => {
                *self.links.running.lock().unwrap_or_else(|e| e.into_inner()) = previous;
                Some(ResponseLine::failure(f))
            }
        }
    }

    /// Turns a finished wait into its answer, or into a snapshot wait.
    fn advance(&mut self, index: usize, ready: &mut Vec<(ClientId, ResponseLine)>) {
        let waiting = &mut self.waiting[index];
        let Stage::Commands { tickets, applied, refused } = &waiting.stage else { return };
        if !tickets.is_empty() {
            return;
        }
        let (applied, refused) = (*applied, *refused);
        let waiting = self.waiting.swap_remove(index);
        if let Some(refusal) = refused {
            if let Then::Loaded { previous: Some(previous), .. } = waiting.then {
                *self.links.running.lock().unwrap_or_else(|e| e.into_inner()) = *previous;
            }
            ready.push((waiting.client, failure(Kind::Refused, refusal.to_string())));
            return;
        }
        let Some(applied) = applied else { return };
        self.fresh_until = None;
        match waiting.then {
            Then::Mode => ready.push((
                waiting.client,
                ResponseLine::ok(Reply::Mode { mode: mode_name(applied.mode) }),
            )),
            Then::Written { count } => ready.push((
                waiting.client,
                ResponseLine::ok(Reply::Written { scan: applied.scan, count }),
            )),
            Then::Loaded { online, programs, tasks, .. } => {
                let running = self.links.running.lock().unwrap_or_else(|e| e.into_inner());
                log::info!(
                    "loaded {} ({programs} programs, {tasks} tasks){}",
                    running.config_path.display(),
                    if online { " as an online change" } else { "" }
                );
                drop(running);
                ready.push((
                    waiting.client,
                    ResponseLine::ok(Reply::Loaded {
                        online,
                        programs,
                        tasks,
                        mode: mode_name(applied.mode),
                    }),
                ));
            }
            Then::Forces { unforced: Some(address) } if !applied.changed => ready
                .push((waiting.client, failure(Kind::Invalid, format!("{address} is not forced")))),
            Then::Debug { unbroken: Some(at), .. } if !applied.changed => ready
                .push((waiting.client, failure(Kind::Invalid, format!("no breakpoint at {at}")))),
            then => {
                let after = self.generation();
                self.waiting.push(Waiting {
                    client: waiting.client,
                    since: waiting.since,
                    stage: Stage::Snapshot { after },
                    then,
                });
                self.want_snapshot();
            }
        }
    }

    /// Answers the snapshot waits a new capture satisfies.
    fn serve_snapshot(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>) {
        let Ok(snapshot) = self.links.snapshot.lock() else { return };
        let generation = snapshot.generation;
        let mut again = false;
        let mut index = 0;
        while index < self.waiting.len() {
            let Stage::Snapshot { after } = self.waiting[index].stage else {
                index += 1;
                continue;
            };
            if generation <= after {
                index += 1;
                continue;
            }
            let needs: &[Address] = match &self.waiting[index].then {
                Then::Values { devices } => devices,
                Then::Debug { devices: Some(devices), .. } => devices,
                _ => &[],
            };
            if needs.iter().any(|d| snapshot.word(word_of(d)).is_none()) {
                // Another request's words filled the capture: next round.
                self.waiting[index].stage = Stage::Snapshot { after: generation };
                again = true;
                index += 1;
                continue;
            }
            let waiting = self.waiting.swap_remove(index);
            let client = waiting.client;
            match waiting.then {
                Then::Status => ready.push((
                    client,
                    ResponseLine::ok(Reply::Status(Box::new(self.status(&snapshot)))),
                )),
                Then::Values { devices } => {
                    let values = devices
                        .iter()
                        .map(|d| DeviceValue {
                            dev: d.to_string(),
                            value: value_in(d, snapshot.word(word_of(d)).unwrap_or(0)),
                        })
                        .collect();
                    ready.push((
                        client,
                        ResponseLine::ok(Reply::Values { scan: snapshot.scan.count, values }),
                    ));
                }
                Then::Forces { .. } => ready.push((
                    client,
                    ResponseLine::ok(Reply::Forces { forces: forces_of(&snapshot) }),
                )),
                Then::Debug { until_paused: true, unbroken, devices }
                    if snapshot.mode == Mode::Debug && snapshot.debug_run != DebugRun::Paused =>
                {
                    // Still stepping: look again at the next round (see `completions`).
                    self.waiting.push(Waiting {
                        client,
                        since: waiting.since,
                        stage: Stage::Snapshot { after: generation },
                        then: Then::Debug { unbroken, devices, until_paused: true },
                    });
                }
                Then::Debug { devices: None, unbroken, .. } => {
                    let devices = self.paused_devices(&snapshot);
                    if devices.is_empty() {
                        ready.push((
                            client,
                            ResponseLine::ok(Reply::Debug(self.debug_state(&snapshot))),
                        ));
                    } else {
                        // Paused at a breakpoint: read the devices its line names.
                        self.waiting.push(Waiting {
                            client,
                            since: waiting.since,
                            stage: Stage::Snapshot { after: generation },
                            then: Then::Debug {
                                unbroken,
                                devices: Some(devices),
                                until_paused: false,
                            },
                        });
                        again = true;
                    }
                }
                Then::Debug { devices: Some(_), .. } => ready
                    .push((client, ResponseLine::ok(Reply::Debug(self.debug_state(&snapshot))))),
                Then::Mode | Then::Written { .. } | Then::Loaded { .. } => {}
            }
        }
        self.fresh_until = Some((generation, Instant::now() + STATUS_MAX_AGE));
        drop(snapshot);
        if again {
            self.want_snapshot();
        }
    }

    fn status(&self, snapshot: &Snapshot) -> Status {
        let shared = &self.links.shared;
        let running = self.links.running.lock().unwrap_or_else(|e| e.into_inner());
        let config = &running.project.config;
        let mode = shared.mode();
        let error = match mode {
            Mode::Error => snapshot.latched_error,
            _ => snapshot.last_operation_error,
        }
        .map(|kind| {
            let (code, detail) = running.names.describe_error(kind);
            ErrorInfo { code, detail }
        });
        let scan_time = snapshot.scan.time.summary();
        let names = crate::engine::task_names(config);
        let kinds = ["scan".to_string(), "init".to_string()].into_iter().chain(
            config.tasks.iter().map(|t| {
                match t.kind {
                    crate::config::TaskKind::Cycle { .. } => "cycle",
                    crate::config::TaskKind::Io { .. } => "io",
                    crate::config::TaskKind::Device { .. } => "device",
                }
                .to_string()
            }),
        );
        let has_init =
            running.project.config.programs.iter().any(|p| p.task == crate::config::TaskRef::Init);
        let tasks = names
            .into_iter()
            .zip(kinds)
            .zip(snapshot.tasks.iter().take(snapshot.task_count))
            .enumerate()
            .filter(|(id, _)| *id != 1 || has_init)
            .map(|(_, ((name, kind), stats))| TaskFigures {
                name,
                kind,
                runs: stats.runs,
                ignored: stats.ignored,
                overruns: stats.overruns,
                latency: percentiles(&stats.start_latency),
                exec: percentiles(&stats.exec_time),
            })
            .collect();
        Status {
            version: env!("CARGO_PKG_VERSION").to_string(),
            config: running.config_path.display().to_string(),
            backend: match config.io.backend {
                Backend::Sim => "sim",
                Backend::Gpiocdev => "gpiocdev",
            }
            .to_string(),
            uptime_ms: self.started.elapsed().as_millis() as u64,
            mode: mode_name(mode),
            error,
            switch: snapshot.switch.map(|p| match p {
                SwitchPosition::Run => SwitchName::Run,
                SwitchPosition::Stop => SwitchName::Stop,
            }),
            remote_allowed: snapshot.remote_allowed,
            scan: ScanFigures {
                count: shared.scans.load(Ordering::Relaxed),
                cur_ns: shared.scan_last_ns.load(Ordering::Relaxed),
                min_ns: shared.scan_min_ns.load(Ordering::Relaxed),
                max_ns: shared.scan_max_ns.load(Ordering::Relaxed),
                p50_ns: scan_time.p50,
                p99_ns: scan_time.p99,
            },
            tasks,
            lost_edges: shared.lost_edges.load(Ordering::Relaxed),
            missed_timer_expirations: shared.missed_deadlines.load(Ordering::Relaxed),
            watchdog_trips: shared.watchdog_trips.load(Ordering::Relaxed),
            forces: forces_of(snapshot),
            debug: (mode == Mode::Debug).then(|| self.debug_state_with(snapshot, &running)),
        }
    }

    fn debug_state(&self, snapshot: &Snapshot) -> DebugState {
        let running = self.links.running.lock().unwrap_or_else(|e| e.into_inner());
        self.debug_state_with(snapshot, &running)
    }

    fn debug_state_with(&self, snapshot: &Snapshot, running: &Running) -> DebugState {
        let programs = &running.project.programs;
        let paused_at = snapshot.paused_at.map(|(task, at)| {
            let program = programs.get(at.program as usize);
            let line = program.map_or(0, |p| p.line_of(at.pc as usize));
            let source = program.map(|p| source_line(&p.path, line)).unwrap_or_default();
            let devices = devices_named(&source)
                .into_iter()
                .filter_map(|d| {
                    snapshot
                        .word(word_of(&d))
                        .map(|w| DeviceValue { dev: d.to_string(), value: value_in(&d, w) })
                })
                .collect();
            Location {
                program: program.map_or_else(String::new, |p| p.name.clone()),
                line,
                task: crate::engine::task_names(&running.project.config)
                    .get(usize::from(task))
                    .cloned()
                    .unwrap_or_default(),
                source,
                devices,
            }
        });
        DebugState {
            paused_at,
            running: snapshot.mode == Mode::Debug && snapshot.debug_run != DebugRun::Paused,
            scan: snapshot.scan.count,
            breakpoints: snapshot.breakpoints[..snapshot.breakpoint_count]
                .iter()
                .map(|b| debug::describe(programs, *b))
                .collect(),
        }
    }

    /// The devices named on the line execution is paused before.
    fn paused_devices(&self, snapshot: &Snapshot) -> Vec<Address> {
        let Some((_, at)) = snapshot.paused_at else { return Vec::new() };
        let running = self.links.running.lock().unwrap_or_else(|e| e.into_inner());
        let Some(program) = running.project.programs.get(at.program as usize) else {
            return Vec::new();
        };
        devices_named(&source_line(&program.path, program.line_of(at.pc as usize)))
    }
}

fn forces_of(snapshot: &Snapshot) -> Vec<DeviceValue> {
    snapshot
        .forces
        .iter()
        .map(|(a, on)| DeviceValue { dev: a.to_string(), value: i32::from(on) })
        .collect()
}

fn percentiles(histogram: &Histogram) -> Percentiles {
    let s = histogram.summary();
    Percentiles { p50_ns: s.p50, p99_ns: s.p99, p999_ns: s.p999, max_ns: s.max }
}

/// Line `line` (1-based) of a program file as written now, without its comment.
fn source_line(path: &Path, line: u32) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let raw = text.lines().nth((line as usize).saturating_sub(1)).unwrap_or("");
    let code = raw.split(';').next().unwrap_or("");
    let code = code.split("//").next().unwrap_or("");
    code.trim().to_string()
}

/// The operands of an instruction line that are devices (not constants, not mnemonics).
fn devices_named(source: &str) -> Vec<Address> {
    let mut devices: Vec<Address> = Vec::new();
    for token in source.split_whitespace().skip(1) {
        if let Ok(address) = Address::parse(token) {
            if !devices.contains(&address) {
                devices.push(address);
            }
        }
    }
    devices
}

impl Handler for ControlHandler {
    fn request(&mut self, client: ClientId, peer: &Peer, request: Request) -> Option<ResponseLine> {
        if !matches!(request, Request::Status | Request::Get { .. } | Request::Forces) {
            log::info!("control: {} from uid {} (pid {})", request.name(), peer.uid, peer.pid);
        }
        self.handle(client, request)
    }

    fn completions(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>) {
        self.links.shared.control_wake.drain();
        while let Ok(Completion { ticket, result }) = self.links.completions.pop() {
            let Some(index) = self.waiting.iter().position(|w| {
                matches!(&w.stage, Stage::Commands { tickets, .. } if tickets.contains(&ticket))
            }) else {
                continue;
            };
            if let Stage::Commands { tickets, applied, refused } = &mut self.waiting[index].stage {
                tickets.retain(|t| *t != ticket);
                match result {
                    Ok(state) => *applied = Some(state),
                    Err(refusal) => *refused = refused.or(Some(refusal)),
                }
            }
            self.advance(index, ready);
        }
        let generation = self.generation();
        if self
            .waiting
            .iter()
            .any(|w| matches!(w.stage, Stage::Snapshot { after } if generation > after))
        {
            self.serve_snapshot(ready);
        }
        // A step in progress is looked at again every few ms, not at every boundary: between
        // two scans of a fixed period every pass of the scan thread is one.
        let stepping = self.waiting.iter().any(|w| {
            matches!(w.then, Then::Debug { until_paused: true, .. })
                && matches!(w.stage, Stage::Snapshot { .. })
        });
        if stepping && self.last_want.elapsed() >= STEP_POLL {
            self.want_snapshot();
        }
        let now = Instant::now();
        let mut index = 0;
        while index < self.waiting.len() {
            if now.duration_since(self.waiting[index].since) > ANSWER_TIMEOUT {
                let waiting = self.waiting.swap_remove(index);
                ready.push((
                    waiting.client,
                    failure(Kind::Unavailable, "the scan thread did not answer in time"),
                ));
            } else {
                index += 1;
            }
        }
    }

    fn wake_fd(&self) -> Option<std::os::fd::BorrowedFd<'_>> {
        use std::os::fd::AsFd;
        Some(self.links.shared.control_wake.as_fd())
    }

    fn tick(&self) -> Duration {
        if self.waiting.iter().any(|w| matches!(w.then, Then::Debug { until_paused: true, .. })) {
            STEP_POLL
        } else {
            Duration::from_millis(50)
        }
    }

    fn gone(&mut self, client: ClientId) {
        self.waiting.retain(|w| w.client != client);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_of_a_source_line() {
        let named = |s: &str| devices_named(s).iter().map(|a| a.to_string()).collect::<Vec<_>>();
        assert_eq!(named("LOAD P0000"), ["P0000"]);
        assert_eq!(named("ADD D00001 5 D00002"), ["D00001", "D00002"]);
        assert_eq!(named("TON T0001 50"), ["T0001"]);
        assert_eq!(named("END"), Vec::<String>::new());
    }

    #[test]
    fn bits_and_words_read_from_their_word() {
        let bit = Address::parse("P0043").unwrap();
        assert_eq!(value_in(&bit, 0b1000), 1);
        assert_eq!(value_in(&bit, 0b0111), 0);
        let word = Address::parse("D00001").unwrap();
        assert_eq!(value_in(&word, 0xFFFF), -1);
        assert_eq!(word_of(&bit), word_of(&Address::parse("P004").unwrap()));
    }
}
