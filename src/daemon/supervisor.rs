//! `plcd run`: starts the real-time driver on a loaded project, then supervises it from the
//! main thread — signals, the service manager, the log, reloads — and shuts it down cleanly.
//!
//! Nothing here runs on a real-time thread, so this is where allocation, logging and blocking
//! I/O belong.

use std::io::Read;
use std::os::fd::AsFd;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::notify::{self, Notifier};
use super::report;
use super::requests::{Announce, RequestHandler, RequestLinks, Running};
use crate::config::{Backend, ControlConfig, ProjectChange};
use crate::diag::Diagnostics;
use crate::drivers::real_time::driver::{Driver, DriverError};
use crate::drivers::real_time::sys::{self, SysError};
use crate::drivers::real_time::{Command, Report, Shared, Source};
use crate::engine::event::{Event, Mode};
use crate::engine::Engine;
use crate::files;
use crate::project::Project;
use crate::services::control::server::{ControlServer, ServerError, Stopper};

/// How often the supervisor looks at reports, the service watchdog and the status.
const TICK: Duration = Duration::from_millis(50);
/// How often `STATUS=` is refreshed.
const STATUS_EVERY: Duration = Duration::from_secs(1);

/// Why the daemon could not start or had to stop.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("{0}")]
    Invalid(Diagnostics),
    #[error(transparent)]
    Driver(#[from] DriverError),
    #[error("{0}")]
    Sys(#[from] SysError),
    #[error("the {0} thread ended unexpectedly")]
    ThreadDied(&'static str),
    #[error("cannot start the {thread} thread: {source}")]
    Spawn { thread: &'static str, source: std::io::Error },
    #[error("control socket: {0}")]
    Control(#[from] ServerError),
    #[error(transparent)]
    Modbus(#[from] crate::services::modbus::ModbusError),
    #[cfg(feature = "opcua")]
    #[error("opcua: {0}")]
    Opcua(#[from] crate::services::opcua::OpcuaError),
    #[cfg(not(feature = "opcua"))]
    #[error("[opcua] listen is set, but this plcd was built without its `opcua` feature")]
    NoOpcua,
    #[cfg(feature = "mqtt")]
    #[error("mqtt: {0}")]
    Mqtt(#[from] crate::services::mqtt::MqttError),
    #[cfg(not(feature = "mqtt"))]
    #[error("[mqtt] brokers is set, but this plcd was built without its `mqtt` feature")]
    NoMqtt,
}

/// The daemon's options from the command line.
#[derive(Debug, Clone)]
pub struct Options {
    pub config: PathBuf,
}

/// Runs the daemon until SIGTERM or SIGINT. Ok after a clean stop.
pub fn run(options: &Options) -> Result<(), DaemonError> {
    // Absolute from the start, so that the paths in the config resolve the same way whether the
    // project is reloaded by SIGHUP or loaded again by `plcctl load` (which sends an absolute
    // path), and compare equal when nothing changed.
    let config = std::fs::canonicalize(&options.config).unwrap_or_else(|_| options.config.clone());
    let project = files::project(&config).map_err(DaemonError::Invalid)?;
    let mut daemon = Daemon::start(&config, project)?;
    daemon.supervise()
}

struct Daemon {
    config_path: PathBuf,
    /// The running project and its names, shared with the control thread.
    running: Arc<Mutex<Running>>,
    /// The real-time threads; `None` once shut down.
    driver: Option<Driver>,
    shared: Arc<Shared>,
    /// The control socket's thread, and how to stop it.
    control: Option<ControlThread>,
    /// The Modbus servers (`[modbus] listen`, `[modbus.rtu]`).
    modbus: Option<crate::services::modbus::RunningServer>,
    /// The OPC UA server (`[opcua] listen`).
    opcua: Option<Opcua>,
    /// The Sparkplug B edge node (`[mqtt] brokers`).
    mqtt: Option<Mqtt>,
    /// Who is told of each engine a reload queues (the OPC UA server's address space).
    announce: Option<Announce>,
    log_outputs: log::Level,
    notifier: Option<Notifier>,
    started: Instant,
    signals: Signals,
    /// Counters already reported, to log only increases.
    seen_lost_edges: u64,
    seen_dropped: u64,
    seen_dropped_messages: u64,
    seen_trips: u64,
    /// What was last logged about each I/O path of the field.
    field_faults: report::FieldFaultLog,
    /// Retained memory: restored at start, written in the background (docs/RETAIN.md).
    retain: crate::services::retain::service::Persistence,
}

impl Daemon {
    fn start(config_path: &Path, project: Project) -> Result<Daemon, DaemonError> {
        // Bound before the real-time threads start: a port in use stops the start.
        let modbus = crate::services::modbus::ModbusServer::bind(&project.config.modbus)?;
        let opcua = bind_opcua(&project)?;
        let mqtt = bind_mqtt(&project)?;
        let mut retain = crate::services::retain::service::Persistence::open(&project.config);
        let mut mirrors = retain.mirrors();
        mirrors.extend(modbus.iter().map(|m| m.mirror()));
        #[cfg(feature = "opcua")]
        mirrors.extend(opcua.iter().map(|o| o.mirror()));
        #[cfg(feature = "mqtt")]
        mirrors.extend(mqtt.iter().map(|m| m.mirror()));
        let mut driver = Driver::start_with(&project, mirrors, |engine| {
            retain.restore_into(engine);
            #[cfg(feature = "opcua")]
            if let Some(opcua) = &opcua {
                opcua.prepare(engine);
            }
            #[cfg(feature = "mqtt")]
            if let Some(mqtt) = &mqtt {
                mqtt.prepare(engine);
            }
        })?;
        retain.start(Arc::clone(&driver.shared));
        if !driver.problems.is_empty() {
            log::warn!(
                "running without full real-time guarantees: {}; grant CAP_SYS_NICE and \
                 CAP_IPC_LOCK, or set [rt] policy = \"other\" and lock_memory = false to run \
                 without them on purpose (docs/CONFIG.md)",
                driver.problems.join("; ")
            );
        }
        let log_outputs = if project.config.io.backend == Backend::Sim {
            log::Level::Info
        } else {
            log::Level::Debug
        };
        let shared = Arc::clone(&driver.shared);
        let announce = announcer(&opcua, &mqtt);

        let signals = Signals::register()?;
        let has_switch = project.config.switch.is_some();
        let control_config = project.config.control.clone();
        let running = Arc::new(Mutex::new(Running::new(config_path, project)));
        let Some(completions) = driver.take_completions() else {
            unreachable!("a new driver has its completions")
        };
        let links = RequestLinks {
            shared: Arc::clone(&shared),
            commands: Arc::clone(&driver.commands),
            completions,
            snapshot: Arc::clone(&driver.snapshot),
            running: Arc::clone(&running),
            remote: driver.remote_board(),
            announce: announce.clone(),
            mqtt: mqtt_figures(&mqtt),
        };
        // On an error, dropping the driver stops the threads.
        let modbus = match modbus {
            Some(server) => {
                let links = crate::services::modbus::ModbusLinks {
                    shared: Arc::clone(&shared),
                    commands: Arc::clone(&driver.commands),
                };
                let server = server.start(links)?;
                for what in server.serving() {
                    log::info!("modbus: serving {what}");
                }
                Some(server)
            }
            None => None,
        };
        // The OPC UA server's writes and methods go to the request handler, as plcctl's do,
        // through the control server's in-process door.
        let (door, inbox) = match (&opcua, &mqtt) {
            (None, None) => (None, None),
            _ => {
                let (door, inbox) = crate::drivers::real_time::door::door()
                    .map_err(|source| DaemonError::Spawn { thread: "control", source })?;
                (Some(door), Some(inbox))
            }
        };
        #[cfg(feature = "mqtt")]
        let mqtt = match (mqtt, &door) {
            (Some(node), Some(door)) => {
                let node = node.start(Arc::clone(&shared), door.clone(), driver.remote_board())?;
                log::info!("mqtt: edge node {} connecting", node.serving());
                Some(node)
            }
            _ => None,
        };
        #[cfg(feature = "opcua")]
        let opcua = match (opcua, door) {
            (Some(server), Some(door)) => {
                let server = server.start(Arc::clone(&shared), door)?;
                log::info!("opcua: serving {}", server.serving());
                Some(server)
            }
            _ => None,
        };
        #[cfg(not(feature = "opcua"))]
        drop(door);
        let control = start_control(&control_config, links, inbox)?;
        let daemon = Daemon {
            config_path: config_path.to_path_buf(),
            running,
            driver: Some(driver),
            shared,
            control,
            modbus,
            opcua,
            mqtt,
            announce,
            log_outputs,
            notifier: Notifier::from_env(),
            started: Instant::now(),
            signals,
            seen_lost_edges: 0,
            seen_dropped: 0,
            seen_dropped_messages: 0,
            seen_trips: 0,
            field_faults: report::FieldFaultLog::default(),
            retain,
        };
        if has_switch {
            log::info!("RUN/STOP key switch configured: the mode follows it (XGB §5.2.3)");
        } else {
            daemon.command(Command::Mode(Mode::Run, Source::Startup));
        }
        {
            let running = daemon.running();
            log::info!(
                "plcd {} running {} ({} programs, {} tasks, {} backend)",
                env!("CARGO_PKG_VERSION"),
                config_path.display(),
                running.project.programs.len(),
                running.project.config.tasks.len(),
                running.project.config.io.backend.as_str()
            );
        }
        if let Some(n) = &daemon.notifier {
            let _ = n.ready();
        }
        Ok(daemon)
    }

    fn running(&self) -> std::sync::MutexGuard<'_, Running> {
        self.running.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn command(&self, command: Command) {
        let pushed = self.driver.as_ref().is_some_and(|d| d.command(command));
        if !pushed {
            log::error!("the command queue is full; a command was dropped");
        }
    }

    fn supervise(&mut self) -> Result<(), DaemonError> {
        let mut keepalive = notify::watchdog_interval().map(|full| Keepalive::new(full / 2));
        let mut last_status = Instant::now() - STATUS_EVERY;
        loop {
            let signal = self.signals.wait(TICK);
            self.drain_reports();
            self.log_counters();
            match signal {
                Some(Signal::Stop(name)) => {
                    log::info!("{name}: stopping");
                    return self.shutdown();
                }
                Some(Signal::Reload) => self.reload(),
                None => {}
            }
            if let Some(which) = self.dead_thread() {
                log::error!("the {which} thread ended unexpectedly; stopping");
                let _ = self.shutdown();
                return Err(DaemonError::ThreadDied(which));
            }
            if let (Some(n), Some(keepalive)) = (&self.notifier, &mut keepalive) {
                let progress = self.shared.progress.load(Ordering::Relaxed);
                if keepalive.due(Instant::now(), progress) {
                    let _ = n.watchdog();
                }
            }
            if last_status.elapsed() >= STATUS_EVERY {
                last_status = Instant::now();
                if let Some(n) = &self.notifier {
                    let _ = n.status(&report::status_line(&self.shared, self.started.elapsed()));
                }
            }
        }
    }

    fn dead_thread(&self) -> Option<&'static str> {
        self.driver.as_ref()?.dead_thread()
    }

    fn drain_reports(&mut self) {
        let Some(driver) = &mut self.driver else { return };
        let mut reports = Vec::new();
        while let Ok(report) = driver.reports.pop() {
            reports.push(report);
        }
        for report in reports {
            match report {
                Report::Mode(_, mode, source) => {
                    let why = match (source, mode) {
                        (Some(source), _) => source.as_str(),
                        (None, Mode::Error) => "error",
                        (None, _) => "STOP instruction",
                    };
                    log::info!("mode {} ({why})", mode.as_str());
                    if mode == Mode::Stop {
                        self.retain.flush();
                    }
                }
                Report::Retired(old) => drop(old),
                Report::RetiredChange(change) => drop(change),
                Report::Switch(_, position) => {
                    log::info!("key switch at {}", position.as_str());
                }
                Report::Event(_, event) => self.log_event(event),
            }
        }
        self.log_messages();
    }

    /// The programs' ADS log messages (docs/ST.md, "ADS log messages"), a line each at the
    /// level their kind says.
    fn log_messages(&mut self) {
        let Some(driver) = &mut self.driver else { return };
        let mut messages = Vec::new();
        while let Ok(message) = driver.messages.pop() {
            messages.push(message);
        }
        for message in messages {
            let kind = crate::engine::event::message_kind(message.mask);
            let level = match kind {
                "error" => log::Level::Error,
                "warning" => log::Level::Warn,
                _ => log::Level::Info,
            };
            let task = self.running().names.task(message.task);
            let text = crate::value::decode_str(message.bytes());
            log::log!(level, "message {task} {kind}: {text}");
        }
        let dropped = self.shared.dropped_messages.load(Ordering::Relaxed);
        if dropped > self.seen_dropped_messages {
            let more = dropped - self.seen_dropped_messages;
            log::warn!("{more} messages not logged: more than a task run may log");
            self.seen_dropped_messages = dropped;
        }
    }

    fn log_event(&mut self, event: Event) {
        match event {
            Event::Error(kind) => {
                let (code, detail) = self.running().names.describe_error(kind);
                log::error!("error {code}: {detail}");
            }
            Event::Set { watch, value } => {
                let level = self.log_outputs;
                log::log!(level, "{} = {value}", self.running().names.watch(watch));
            }
            _ => {}
        }
    }

    fn log_counters(&mut self) {
        let lost = self.shared.lost_edges.load(Ordering::Relaxed);
        if lost > self.seen_lost_edges {
            log::warn!("{} input edges lost ({lost} in all)", lost - self.seen_lost_edges);
            self.seen_lost_edges = lost;
        }
        for (level, line) in self.field_faults.update(&self.shared.field_faults) {
            log::log!(level, "{line}");
        }
        let dropped = self.shared.dropped_reports.load(Ordering::Relaxed);
        if dropped > self.seen_dropped {
            log::warn!(
                "{} events not logged: the report queue was full",
                dropped - self.seen_dropped
            );
            self.seen_dropped = dropped;
        }
        let trips = self.shared.watchdog_trips.load(Ordering::Relaxed);
        if trips > self.seen_trips {
            let late = self.shared.watchdog_late_ns.load(Ordering::Relaxed);
            log::error!(
                "watchdog: the scan thread did not finish the scan in time; outputs made safe \
                 {:.3} ms after the expiry",
                late as f64 / 1e6
            );
            self.seen_trips = trips;
        }
    }

    /// SIGHUP: the config and programs are loaded and checked; on any error the diagnostics are
    /// logged and the running project goes on untouched.
    fn reload(&mut self) {
        if let Some(n) = &self.notifier {
            let _ = n.reloading();
        }
        log::info!("SIGHUP: reloading {}", self.config_path.display());
        match files::project(&self.config_path) {
            Err(diagnostics) => {
                for d in diagnostics.iter() {
                    log::error!("{d}");
                }
                log::error!(
                    "reload refused ({} errors); still running the project loaded before",
                    diagnostics.len()
                );
            }
            Ok(new) => {
                let mut running = self.running.lock().unwrap_or_else(|e| e.into_inner());
                let changed =
                    running.project.config.refused_sections(&new.config, ProjectChange::Reload);
                if !changed.is_empty() {
                    log::error!(
                        "reload refused: {} changed, which takes a restart of the service; \
                         still running the project loaded before",
                        changed.join(" and ")
                    );
                } else {
                    let watch = new.output_bits();
                    let engine = Box::new(Engine::new(&new, &watch));
                    if let Some(announce) = &self.announce {
                        announce(&engine, &new);
                    }
                    // Queued first, with the running project held: the project the control
                    // thread names things by changes only if the engine will change too.
                    let queued =
                        self.driver.as_ref().is_some_and(|d| d.command(Command::Replace(engine)));
                    if queued {
                        log::info!(
                            "reloaded: {} programs, {} tasks; restarting them",
                            new.programs.len(),
                            new.config.tasks.len()
                        );
                        *running = Running::new(&self.config_path, new);
                    } else {
                        log::error!(
                            "reload refused: the scan thread's command queue is full; still \
                             running the project loaded before"
                        );
                    }
                }
            }
        }
        if let Some(n) = &self.notifier {
            let _ = n.ready();
        }
    }

    fn shutdown(&mut self) -> Result<(), DaemonError> {
        if let Some(n) = &self.notifier {
            let _ = n.stopping();
        }
        if let Some(control) = self.control.take() {
            control.stop();
        }
        if let Some(modbus) = self.modbus.take() {
            modbus.stop();
        }
        if let Some(opcua) = self.opcua.take() {
            stop_opcua(opcua);
        }
        if let Some(mqtt) = self.mqtt.take() {
            stop_mqtt(mqtt);
        }
        let Some(driver) = &mut self.driver else { return Ok(()) };
        self.retain.stop_writer();
        let engine = driver.stop();
        self.retain.final_write(engine.as_deref());
        self.drain_reports();
        self.driver = None;
        self.log_counters();
        if let Some(engine) = engine {
            for line in report::statistics(&engine, &self.shared) {
                log::info!("{line}");
            }
        }
        log::info!("stopped; outputs off");
        Ok(())
    }
}

/// The OPC UA server, running.
#[cfg(feature = "opcua")]
type Opcua = crate::services::opcua::RunningOpcua;
/// Without the `opcua` feature there is none ([`bind_opcua`] refuses a config that asks).
#[cfg(not(feature = "opcua"))]
type Opcua = std::convert::Infallible;

/// Binds `[opcua] listen` before the real-time threads start (a port in use stops the start);
/// its certificates go to `[opcua] pki_dir`, else `opcua-pki` in the retain directory
/// (`[retain] dir`, else `$STATE_DIRECTORY`).
#[cfg(feature = "opcua")]
fn bind_opcua(
    project: &Project,
) -> Result<Option<crate::services::opcua::OpcuaServer>, DaemonError> {
    let config = &project.config;
    let pki_dir = config.opcua.pki_dir.clone().or_else(|| {
        let state_directory = std::env::var("STATE_DIRECTORY").ok();
        crate::services::retain::directory(&config.retain, state_directory.as_deref())
            .map(|dir| dir.join("opcua-pki"))
    });
    let symbols = &project.variables.symbols;
    // The named logins: the users file, read here (a file with errors stops the start, as
    // `plcd check` would have said), and again when it changes (`files::LiveUsers`).
    let users = match (&config.opcua.listen, &config.users.file) {
        (Some(_), Some(path)) => Some(files::LiveUsers::open(path).map_err(DaemonError::Invalid)?),
        _ => None,
    };
    // Checked when the project was built; a project built otherwise is checked again here.
    let names = project.opcua_names().map_err(|e| DaemonError::Invalid(Diagnostics(e)))?;
    Ok(crate::services::opcua::OpcuaServer::bind(&config.opcua, pki_dir, symbols, &names, users)?)
}

#[cfg(not(feature = "opcua"))]
fn bind_opcua(project: &Project) -> Result<Option<Opcua>, DaemonError> {
    match project.config.opcua.listen {
        Some(_) => Err(DaemonError::NoOpcua),
        None => Ok(None),
    }
}

/// How the OPC UA server and the MQTT edge node hear of each engine the daemon queues, so that
/// their address space and metrics follow the running project.
fn announcer(opcua: &Option<OpcuaServer>, mqtt: &Option<MqttNode>) -> Option<Announce> {
    #[cfg(feature = "opcua")]
    let opcua = opcua.as_ref().map(|server| server.following());
    #[cfg(not(feature = "opcua"))]
    let opcua: Option<()> = opcua.as_ref().map(|never| match *never {});
    #[cfg(feature = "mqtt")]
    let mqtt = mqtt.as_ref().map(|node| node.following());
    #[cfg(not(feature = "mqtt"))]
    let mqtt: Option<()> = mqtt.as_ref().map(|never| match *never {});
    if opcua.is_none() && mqtt.is_none() {
        return None;
    }
    Some(Arc::new(move |engine: &Engine, project: &Project| {
        // A project that reached a queue was built, and so checked: its names resolve.
        #[cfg(feature = "opcua")]
        if let Some(following) = &opcua {
            let names = project.opcua_names().unwrap_or_default();
            following.announce(engine.retained_variables(), &project.variables.symbols, &names);
        }
        #[cfg(feature = "mqtt")]
        if let Some(following) = &mqtt {
            let names = project.mqtt_names().unwrap_or_default();
            let ranges = project.opcua_names().map(|n| n.analog).unwrap_or_default();
            let symbols = &project.variables.symbols;
            following.announce(engine.retained_variables(), symbols, &names, &ranges);
        }
        // Without a feature, its service is never there.
        let _ = (engine, project, &opcua, &mqtt);
    }))
}

/// The Sparkplug B edge node, running.
#[cfg(feature = "mqtt")]
type Mqtt = crate::services::mqtt::RunningMqtt;
/// Without the `mqtt` feature there is none ([`bind_mqtt`] refuses a config that asks).
#[cfg(not(feature = "mqtt"))]
type Mqtt = std::convert::Infallible;
#[cfg(feature = "mqtt")]
type MqttNode = crate::services::mqtt::MqttNode;
#[cfg(not(feature = "mqtt"))]
type MqttNode = std::convert::Infallible;
#[cfg(feature = "opcua")]
type OpcuaServer = crate::services::opcua::OpcuaServer;
#[cfg(not(feature = "opcua"))]
type OpcuaServer = std::convert::Infallible;

/// The edge node of `[mqtt]`, set up before the real-time threads start: a password or TLS
/// file that cannot be read stops the start.
#[cfg(feature = "mqtt")]
fn bind_mqtt(project: &Project) -> Result<Option<MqttNode>, DaemonError> {
    // Checked when the project was built; a project built otherwise is checked again here.
    let names = project.mqtt_names().map_err(|e| DaemonError::Invalid(Diagnostics(e)))?;
    let symbols = &project.variables.symbols;
    let remotes: Vec<String> = project.config.remotes.iter().map(|r| r.name.clone()).collect();
    // The engineering ranges of `[[opcua.analog]]`, published as the metrics' properties.
    let ranges = project.opcua_names().map(|n| n.analog).unwrap_or_default();
    let config = &project.config.mqtt;
    Ok(crate::services::mqtt::MqttNode::new(config, &remotes, symbols, &names, &ranges)?)
}

#[cfg(not(feature = "mqtt"))]
fn bind_mqtt(project: &Project) -> Result<Option<MqttNode>, DaemonError> {
    match project.config.mqtt.enabled() {
        true => Err(DaemonError::NoMqtt),
        false => Ok(None),
    }
}

/// The edge node's figures for `plcctl status`.
#[cfg(feature = "mqtt")]
fn mqtt_figures(mqtt: &Option<MqttNode>) -> Option<Arc<Mutex<plcd_ipc::MqttFigures>>> {
    mqtt.as_ref().map(|node| node.figures())
}

#[cfg(not(feature = "mqtt"))]
fn mqtt_figures(_: &Option<MqttNode>) -> Option<Arc<Mutex<plcd_ipc::MqttFigures>>> {
    None
}

#[cfg(feature = "mqtt")]
fn stop_mqtt(mqtt: Mqtt) {
    mqtt.stop();
}

#[cfg(not(feature = "mqtt"))]
fn stop_mqtt(mqtt: Mqtt) {
    match mqtt {}
}

#[cfg(feature = "opcua")]
fn stop_opcua(opcua: Opcua) {
    opcua.stop();
}

#[cfg(not(feature = "opcua"))]
fn stop_opcua(opcua: Opcua) {
    match opcua {}
}

/// The control socket's server thread.
struct ControlThread {
    handle: JoinHandle<()>,
    stopper: Stopper,
}

impl ControlThread {
    /// Stops serving; the socket file is removed when the server is dropped.
    fn stop(self) {
        self.stopper.stop();
        let _ = self.handle.join();
    }
}

/// Binds the control socket and starts its thread; `None` when `[control] enabled = false`.
/// The control thread: the control socket's server, with `inbox`, the in-process door of the
/// services that act through the request handler, if any; without the socket
/// (`[control] enabled = false`), the door's server alone, or nothing.
fn start_control(
    config: &ControlConfig,
    links: RequestLinks,
    inbox: Option<crate::drivers::real_time::door::LocalInbox>,
) -> Result<Option<ControlThread>, DaemonError> {
    let mut server = match (config.enabled, inbox) {
        (true, inbox) => {
            let server = ControlServer::bind(config)?;
            if let Some(path) = server.path() {
                log::info!("control socket {}", path.display());
            }
            match inbox {
                Some(inbox) => server.with_local(inbox),
                None => server,
            }
        }
        (false, Some(inbox)) => {
            log::info!(
                "control socket disabled ([control] enabled = false); the request handler serves \
                 the OPC UA server's writes and methods alone"
            );
            ControlServer::local_only(inbox)?
        }
        (false, None) => {
            log::info!("control socket disabled ([control] enabled = false)");
            return Ok(None);
        }
    };
    let stopper = server.stopper();
    let handle = std::thread::Builder::new()
        .name("plcd-control".into())
        .stack_size(crate::drivers::real_time::CONTROL_THREAD_STACK)
        .spawn(move || {
            let mut handler = RequestHandler::new(links);
            if let Err(e) = server.serve(&mut handler) {
                log::error!("control socket: {e}; plcctl cannot reach this daemon any more");
            }
        })
        .map_err(|source| DaemonError::Spawn { thread: "control", source })?;
    Ok(Some(ControlThread { handle, stopper }))
}

/// When to send `WATCHDOG=1`: every `interval` (half of `WATCHDOG_USEC`), and only if the
/// engine made progress since the last one (a scan ended, or the STOP/ERROR loop went round),
/// so that systemd restarts a daemon whose engine hangs even though this thread lives.
struct Keepalive {
    interval: Duration,
    last: Option<(Instant, u64)>,
}

impl Keepalive {
    fn new(interval: Duration) -> Keepalive {
        Keepalive { interval, last: None }
    }

    /// True if a keepalive is to be sent now; records it.
    fn due(&mut self, now: Instant, progress: u64) -> bool {
        let due = match self.last {
            None => true,
            Some((at, seen)) => now.duration_since(at) >= self.interval && progress != seen,
        };
        if due {
            self.last = Some((now, progress));
        }
        due
    }
}

/// What the supervisor heard.
enum Signal {
    Stop(&'static str),
    Reload,
}

/// SIGTERM, SIGINT and SIGHUP as flags, with a self-pipe that wakes the supervisor.
struct Signals {
    term: Arc<AtomicBool>,
    int: Arc<AtomicBool>,
    hup: Arc<AtomicBool>,
    wake: UnixStream,
}

impl Signals {
    fn register() -> Result<Signals, DaemonError> {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let to_sys = |call| {
            move |e: std::io::Error| SysError {
                call,
                errno: nix::errno::Errno::from_raw(e.raw_os_error().unwrap_or(0)),
            }
        };
        let (read, write) = UnixStream::pair().map_err(to_sys("socketpair"))?;
        read.set_nonblocking(true).map_err(to_sys("fcntl"))?;
        write.set_nonblocking(true).map_err(to_sys("fcntl"))?;
        let signals = Signals {
            term: Arc::new(AtomicBool::new(false)),
            int: Arc::new(AtomicBool::new(false)),
            hup: Arc::new(AtomicBool::new(false)),
            wake: read,
        };
        for (signal, flag) in
            [(SIGTERM, &signals.term), (SIGINT, &signals.int), (SIGHUP, &signals.hup)]
        {
            signal_hook::flag::register(signal, Arc::clone(flag)).map_err(to_sys("sigaction"))?;
            let write = write.try_clone().map_err(to_sys("dup"))?;
            signal_hook::low_level::pipe::register(signal, write).map_err(to_sys("sigaction"))?;
        }
        Ok(signals)
    }

    /// Waits up to `timeout` for a signal.
    fn wait(&mut self, timeout: Duration) -> Option<Signal> {
        if !self.pending() {
            let _ = sys::wait_readable(&[self.wake.as_fd()], Some(timeout.as_nanos() as u64));
        }
        let mut buf = [0u8; 64];
        while matches!(self.wake.read(&mut buf), Ok(n) if n > 0) {}
        if self.term.swap(false, Ordering::SeqCst) {
            return Some(Signal::Stop("SIGTERM"));
        }
        if self.int.swap(false, Ordering::SeqCst) {
            return Some(Signal::Stop("SIGINT"));
        }
        if self.hup.swap(false, Ordering::SeqCst) {
            return Some(Signal::Reload);
        }
        None
    }

    fn pending(&self) -> bool {
        [&self.term, &self.int, &self.hup].iter().any(|f| f.load(Ordering::SeqCst))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keepalives_need_progress_and_the_interval() {
        let t0 = Instant::now();
        let ms = |n| t0 + Duration::from_millis(n);
        let mut k = Keepalive::new(Duration::from_millis(100));
        assert!(k.due(ms(0), 1), "the first one at once");
        assert!(!k.due(ms(50), 2), "not before the interval");
        assert!(k.due(ms(100), 2));
        assert!(!k.due(ms(300), 2), "no progress: the engine hangs, systemd must see silence");
        assert!(!k.due(ms(900), 2));
        assert!(k.due(ms(901), 3), "progress again");
    }
}
