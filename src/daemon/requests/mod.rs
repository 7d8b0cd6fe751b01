//! The daemon's request handler: what each request of the control socket does in `plcd run`.
//! It turns protocol requests into scan-thread commands and snapshot reads, and their outcomes
//! into replies. It runs on the control thread (not real time), behind the control socket's
//! server ([`crate::services::control`]), and never waits for the scan thread: a request that
//! needs an END is parked until its completion or snapshot arrives.
//!
//! - Commands that change PLC state (mode, writes, forces, debugger, programs) go through the
//!   command queue and are applied by the scan thread at a scan boundary; each carries a ticket
//!   that its [`Completion`] answers.
//! - Reads come from the [`Snapshot`] the scan thread publishes at a scan boundary when asked.
//!   Device reads always wait for a capture taken after the request; `status` accepts one
//!   younger than [`STATUS_MAX_AGE`] as long as no command completed since, so that any number
//!   of clients polling `status` cost the scan at most one capture per that period.
//!
//! One file a request family, each with its requests and its replies: `mode` (run, stop,
//! reset, debug), `devices` (get, set), `forces`, `debugger` (step, continue, breakpoints, where
//! execution is paused), `load` (a new project, stopped or online), `status`. How a request
//! waits for the scan thread — tickets, snapshot generations, timeouts — is `waiting`'s.

mod debugger;
mod devices;
mod forces;
mod load;
mod mode;
mod status;
mod waiting;

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::report::Names;
use crate::drivers::real_time::snapshot::{Snapshot, MAX_READ_WORDS};
use crate::drivers::real_time::{Command, Completion, Shared};
use crate::engine::ModeRequest;
use crate::project::Project;
use crate::services::control::{Caller, ClientId, Handler};
use plcd_ipc::{ErrorKind as Kind, Request, ResponseLine};
use waiting::{Then, Waiting};

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

/// Told of every engine the daemon is about to queue (a load, an online change, a reload),
/// with its project, before the scan thread can take it: how the OPC UA server's address space
/// follows the running project (`services::opcua::follow`).
pub type Announce = Arc<dyn Fn(&crate::engine::Engine, &Project) + Send + Sync>;

/// The queues and shared state the handler works with.
pub struct RequestLinks {
    pub shared: Arc<Shared>,
    pub commands: Arc<Mutex<rtrb::Producer<Command>>>,
    pub completions: rtrb::Consumer<Completion>,
    pub snapshot: Arc<Mutex<Box<Snapshot>>>,
    pub running: Arc<Mutex<Running>>,
    /// The remote I/O devices' counters.
    pub remote: crate::io::remote::RemoteBoard,
    /// Who is told of each engine a `load` queues.
    pub announce: Option<Announce>,
    /// The Sparkplug B edge node's figures, kept up to date by its connection thread.
    pub mqtt: Option<Arc<Mutex<plcd_ipc::MqttFigures>>>,
}

/// Answers the control socket's requests. See the module docs.
pub struct RequestHandler {
    links: RequestLinks,
    started: Instant,
    next_ticket: u64,
    waiting: Vec<Waiting>,
    /// The last snapshot generation seen, and until when `status` may use it.
    fresh_until: Option<(u64, Instant)>,
    /// When a capture was last asked for.
    last_want: Instant,
}

fn failure(kind: Kind, message: impl Into<String>) -> ResponseLine {
    ResponseLine::error(kind, message)
}

impl RequestHandler {
    pub fn new(links: RequestLinks) -> RequestHandler {
        RequestHandler {
            links,
            started: Instant::now(),
            next_ticket: 1,
            waiting: Vec::new(),
            fresh_until: None,
            last_want: Instant::now(),
        }
    }

    /// The running project; a lock poisoned by a holder that panicked is taken all the same.
    fn running(&self) -> std::sync::MutexGuard<'_, Running> {
        self.links.running.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Each request to its family. `Some`: the answer now; `None`: parked.
    fn handle(&mut self, client: ClientId, request: Request) -> Option<ResponseLine> {
        match request {
            Request::Status => self.status_request(client),
            Request::Run => self.mode(client, ModeRequest::Run),
            Request::Stop => self.mode(client, ModeRequest::Stop),
            Request::Reset { cold } => self.mode(client, ModeRequest::Reset { cold }),
            Request::Debug => self.mode(client, ModeRequest::Debug),
            Request::Get { devices } => self.get(client, &devices),
            Request::Set { writes } => self.set(client, &writes),
            Request::Force { dev, value } => self.force(client, &dev, value),
            Request::Unforce { dev } => self.unforce(client, &dev),
            Request::UnforceAll => self.unforce_all(client),
            Request::Forces => self.forces(client),
            Request::Step { scan } => self.step(client, scan),
            Request::Continue => self.continue_(client),
            Request::Break { at } => self.set_breakpoint(client, &at),
            Request::Unbreak { at } => self.unbreak(client, at),
            Request::Load { config, online } => self.load(client, &config, online),
        }
    }
}

impl Handler for RequestHandler {
    fn request(
        &mut self,
        client: ClientId,
        caller: &Caller,
        request: Request,
    ) -> Option<ResponseLine> {
        if !matches!(request, Request::Status | Request::Get { .. } | Request::Forces) {
            log::info!("control: {} from {caller}", request.name());
        }
        self.handle(client, request)
    }

    fn completions(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>) {
        self.collect_answers(ready);
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
