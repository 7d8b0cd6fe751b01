//! The OPC UA server: its socket bound at start, the `async-opcua` stack on a small tokio runtime
//! of its own (two worker threads named `plcd-opcua`, ordinary scheduling), the certificate
//! store in `pki_dir`, the access rules, the address space and the sampler thread.
//!
//! The sampler (`plcd-opcua-sample`) asks the mirror for a copy every
//! `min_sampling_interval_ms`, waits for the scan boundary that takes it, reads every served
//! variable out of the copy and hands the stack the values that changed; the stack answers
//! reads from them and notifies subscriptions. All the values of one hand-over are of one scan
//! boundary: no struct or array is ever torn.

use std::net::SocketAddr;
use std::os::unix::fs::{DirBuilderExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use opcua::crypto::SecurityPolicy;
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::InMemoryNodeManagerBuilder;
use opcua::server::{ServerBuilder, ServerEndpoint, ServerHandle, ANONYMOUS_USER_TOKEN_ID};
use opcua::types::{DataValue, LocalizedText, MessageSecurityMode, NodeId, StatusCode, Variant};

use super::access::Access;
use super::follow::{variable_bytes, Following};
use super::front::{self, Front};
use super::manager::{Forget, PlcManager, PlcNodesBuilder, Target, Targets};
use super::nodes::{self, Plan, STATUS_NODES};
use super::space::{self, id};
use super::status::StatusNodes;
use super::{values, OpcuaError};
use crate::config::{Anonymous, OpcuaConfig, OpcuaPolicy};
use crate::drivers::real_time::door::LocalDoor;
use crate::drivers::real_time::mirror::Mirror;
use crate::drivers::real_time::{pending, Shared, PLAIN_THREAD_STACK};
use crate::engine::event::ErrorKind;
use crate::engine::Engine;
use crate::files::LiveUsers;
use crate::project::OpcuaNames;
use crate::symbols::Symbols;
use crate::value::ValueType;
use crate::vm::retained::RetainedVariables;

/// plcd's namespace URI: its index in the server's namespace array is 2 (0 is OPC UA's, 1 the
/// server's own, which the stack's diagnostics use).
pub const NAMESPACE_URI: &str = "urn:plcd:plc";
/// The application URI in the server's certificate and description.
pub const APPLICATION_URI: &str = "urn:plcd:server";
/// The server certificate (DER) and its private key (PEM, mode 0600), in `pki_dir`.
pub const CERTIFICATE: &str = "own/cert.der";
pub const PRIVATE_KEY: &str = "private/private.pem";

/// How long the sampler waits for a scan boundary before it tries again: longer than any scan
/// within its watchdog.
const BOUNDARY_WAIT: Duration = Duration::from_secs(2);

/// The server, bound, before the real-time threads start.
pub struct OpcuaServer {
    listener: std::net::TcpListener,
    addr: SocketAddr,
    config: OpcuaConfig,
    pki_dir: PathBuf,
    plan: Plan,
    /// The plans of the engines the daemon announces.
    following: Arc<Following>,
    /// The users file (`[users] file`): the named logins.
    users: Option<Arc<LiveUsers>>,
    mirror: Arc<Mirror>,
    /// The layout of the engine the plan was made for (set by [`OpcuaServer::prepare`]): a copy
    /// of another engine's variables is not served.
    layout: Mutex<Option<Arc<RetainedVariables>>>,
}

impl OpcuaServer {
    /// Binds `[opcua] listen`; `None` when it is not set. `pki_dir` is where the certificates
    /// live (`[opcua] pki_dir`, else `opcua-pki` in the retain directory: the daemon says);
    /// `symbols` are the project's variables, `names` those clients may write and those with
    /// an engineering range ([`crate::project::Project::opcua_names`]), `users` the users file's users
    /// (`[users] file`, read by the daemon), if any.
    pub fn bind(
        config: &OpcuaConfig,
        pki_dir: Option<PathBuf>,
        symbols: &Symbols,
        names: &OpcuaNames,
        users: Option<LiveUsers>,
    ) -> Result<Option<OpcuaServer>, OpcuaError> {
        let Some(addr) = config.listen else {
            return Ok(None);
        };
        let pki_dir = pki_dir.ok_or(OpcuaError::NoPkiDir)?;
        let listener = std::net::TcpListener::bind(addr)
            .and_then(|l| l.set_nonblocking(true).map(|()| l))
            .map_err(|source| OpcuaError::Bind { addr, source })?;
        let addr = listener.local_addr().map_err(|source| OpcuaError::Bind { addr, source })?;
        // All of device memory (at most 64 Ki words), so that a place indexes the copy as it
        // indexes device memory, and a located variable of a project loaded later is in it too.
        let words = crate::device::layout::TOTAL_WORDS as u16;
        let mirror = Arc::new(Mirror::with_all_variables(std::iter::once(0..words)));
        let following = Arc::new(Following::new(
            config.max_nodes as usize,
            words,
            config.devices.clone(),
            Arc::clone(&mirror),
        ));
        let plan = following.plan(symbols, names);
        Ok(Some(OpcuaServer {
            listener,
            addr,
            config: config.clone(),
            pki_dir,
            plan,
            following,
            users: users.map(Arc::new),
            mirror,
            layout: Mutex::new(None),
        }))
    }

    /// The mirror the scan thread copies for it.
    pub fn mirror(&self) -> Arc<Mirror> {
        Arc::clone(&self.mirror)
    }

    /// Where the daemon announces each engine it queues (a reload, a load, an online change),
    /// so that the address space follows the running project.
    pub fn following(&self) -> Arc<Following> {
        Arc::clone(&self.following)
    }

    /// Before the scan thread starts: room for `engine`'s variable memory in the mirror, and
    /// its layout as the one served.
    pub fn prepare(&self, engine: &Engine) {
        let layout = engine.retained_variables();
        self.mirror.prepare(layout, engine.vm().vars().len());
        self.mirror.serve_only(layout, variable_bytes(&self.plan));
        *self.layout.lock().unwrap_or_else(|e| e.into_inner()) = Some(Arc::clone(layout));
    }

    /// The address bound (with the port taken when `listen` asked for port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Starts the runtime, the stack and the sampler; writes and method calls go through
    /// `door` to the request handler.
    pub fn start(self, shared: Arc<Shared>, door: LocalDoor) -> Result<RunningOpcua, OpcuaError> {
        let OpcuaServer { listener, addr, config, pki_dir, plan, following, users, mirror, layout } =
            self;
        prepare_pki(&pki_dir)?;
        let host = config.endpoint_host.clone().unwrap_or_else(|| addr.ip().to_string());
        let url = format!("opc.tcp://{}:{}/", url_host(&host), addr.port());
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .max_blocking_threads(2)
            .thread_name("plcd-opcua")
            .enable_all()
            .build()
            .map_err(|source| OpcuaError::Runtime { source })?;
        // The stack starts its own tasks as it is built: inside the runtime.
        let _runtime = runtime.enter();
        let access = Arc::new(Access::new(config.anonymous.role(), users));
        let forget = Arc::new(Mutex::new(Forget::default()));
        let targets: Targets = Arc::new(std::sync::RwLock::new(targets_of(&plan)));
        let nodes = PlcNodesBuilder {
            namespace: NamespaceMetadata {
                namespace_uri: NAMESPACE_URI.to_string(),
                ..Default::default()
            },
            targets: Arc::clone(&targets),
            door: door.clone(),
            forget: Arc::clone(&forget),
        };
        let (server, handle) = builder(&config, &pki_dir, &host, addr.port(), access, nodes)
            .build()
            .map_err(OpcuaError::Stack)?;
        secure_key(&pki_dir)?;
        let Some(manager) = handle.node_managers().get_of_type::<PlcManager>() else {
            return Err(OpcuaError::Stack("plcd's node manager is missing".into()));
        };
        let ns = handle
            .get_namespace_index(NAMESPACE_URI)
            .ok_or_else(|| OpcuaError::Stack(format!("namespace {NAMESPACE_URI} is missing")))?;
        space::populate(&manager, ns, &plan);
        let status = StatusNodes::new(&manager, ns, door);
        // The stack listens on the loopback interface only; the public socket is the front's
        // (front.rs: the limits the stack has no hook for).
        let loopback = (std::net::Ipv4Addr::LOCALHOST, 0);
        let inner = std::net::TcpListener::bind(loopback)
            .and_then(|l| l.set_nonblocking(true).map(|()| l))
            .and_then(tokio::net::TcpListener::from_std)
            .map_err(|source| OpcuaError::Loopback { source })?;
        let inner_addr = inner.local_addr().map_err(|source| OpcuaError::Loopback { source })?;
        let listener = tokio::net::TcpListener::from_std(listener)
            .map_err(|source| OpcuaError::Bind { addr, source })?;
        let stack = runtime.spawn(async move {
            if let Err(e) = server.run_with(inner).await {
                log::error!("opcua: the server stopped: {e}");
            }
        });
        let front = Arc::new(Front::new(front::Limits::of(&config)));
        runtime.spawn(front::serve(
            listener,
            inner_addr,
            Arc::clone(&front),
            Arc::clone(handle.info()),
            addr.port(),
        ));
        let stop = Arc::new(Stop::default());
        let layout = layout.lock().unwrap_or_else(|e| e.into_inner()).take();
        report(&plan, &config);
        let sampler = Sampler {
            mirror,
            shared,
            manager,
            handle: handle.clone(),
            ns,
            status,
            served: Served::new(ns, &plan),
            plan: Arc::new(plan),
            following,
            targets,
            interval: Duration::from_millis(u64::from(config.min_sampling_interval_ms)),
            layout,
            forget,
            stop: Arc::clone(&stop),
            words: Vec::new(),
            vars: Vec::new(),
            last: Vec::new(),
            told_changed: false,
        };
        let thread = std::thread::Builder::new()
            .name("plcd-opcua-sample".into())
            .stack_size(PLAIN_THREAD_STACK)
            .spawn(move || sampler.run())
            .map_err(|source| OpcuaError::Spawn { source })?;
        Ok(RunningOpcua { runtime, handle, stack, sampler: thread, stop, url, addr })
    }
}

/// The writable variables of `plan`, by their node ids' strings: its leaves and its arrays.
fn targets_of(plan: &Plan) -> std::collections::HashMap<String, Target> {
    let leaves = plan.leaves.iter().enumerate().filter(|(_, leaf)| leaf.writable).map(|(i, l)| {
        // A device is written by its name (`D00100`), a variable by its node id's (its name).
        let name = if l.device { l.browse.clone() } else { l.id.clone() };
        let target = Target {
            ty: l.ty.clone(),
            elements: vec![(name, i)],
            dimensions: None,
            device: l.device,
        };
        (l.id.clone(), target)
    });
    let arrays = plan.arrays.iter().filter(|a| a.writable).map(|a| {
        let elements = a.elements.iter().map(|&e| (plan.leaves[e].id.clone(), e)).collect();
        let ty = plan.leaves[a.elements[0]].ty.clone();
        let dimensions = Some(a.dimensions.clone());
        (a.id.clone(), Target { ty, elements, dimensions, device: false })
    });
    leaves.chain(arrays).collect()
}

/// What of a plan's variables is not served, for the log.
fn report(plan: &Plan, config: &OpcuaConfig) {
    if plan.left_out > 0 {
        log::warn!(
            "opcua: {} variables left out: more than [opcua] max_nodes = {}",
            plan.left_out,
            config.max_nodes
        );
    }
    if plan.unserved > 0 {
        log::info!(
            "opcua: {} variables not served (references, or a node id another node has)",
            plan.unserved
        );
    }
}

/// An IPv6 address in a URL is written in brackets.
fn url_host(host: &str) -> String {
    if host.contains(':') {
        format!("[{host}]")
    } else {
        host.to_string()
    }
}

/// The PKI directory and its `private` directory, mode 0700, so that the key the stack writes
/// is never readable by others, not even before [`secure_key`] makes it 0600.
fn prepare_pki(dir: &Path) -> Result<(), OpcuaError> {
    let error = |source| OpcuaError::Pki { dir: dir.to_path_buf(), source };
    let mut builder = std::fs::DirBuilder::new();
    builder.recursive(true).mode(0o700);
    builder.create(dir.join("private")).map_err(error)?;
    for sub in ["own", "trusted", "rejected"] {
        builder.create(dir.join(sub)).map_err(error)?;
    }
    std::fs::set_permissions(dir.join("private"), std::fs::Permissions::from_mode(0o700))
        .map_err(error)
}

/// After the stack created or read the certificate and key: both there, the key 0600.
fn secure_key(dir: &Path) -> Result<(), OpcuaError> {
    let (cert, key) = (dir.join(CERTIFICATE), dir.join(PRIVATE_KEY));
    if !cert.is_file() || !key.is_file() {
        return Err(OpcuaError::Certificate { dir: dir.to_path_buf() });
    }
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600))
        .map_err(|source| OpcuaError::Pki { dir: dir.to_path_buf(), source })
}

/// The stack's configuration from `[opcua]`.
fn builder(
    config: &OpcuaConfig,
    pki_dir: &Path,
    host: &str,
    port: u16,
    access: Arc<Access>,
    nodes: PlcNodesBuilder,
) -> ServerBuilder {
    let anonymous = config.anonymous != Anonymous::None;
    let tokens: Vec<String> =
        if anonymous { vec![ANONYMOUS_USER_TOKEN_ID.to_string()] } else { Vec::new() };
    let mut builder = ServerBuilder::new()
        .application_name("plcd")
        .application_uri(APPLICATION_URI)
        .product_uri("urn:plcd")
        .create_sample_keypair(true)
        .certificate_path(CERTIFICATE)
        .private_key_path(PRIVATE_KEY)
        .pki_dir(pki_dir)
        // Only the certificates an administrator moved to trusted/ (docs/OPCUA.md).
        .trust_client_certs(false)
        .check_cert_time(true)
        .host(host)
        .port(port)
        .discovery_urls(vec!["/".to_string()])
        .max_sessions(config.max_sessions as usize)
        .max_message_size(config.max_request_bytes as usize)
        .with_authenticator(access)
        .with_node_manager(InMemoryNodeManagerBuilder::new(nodes));
    {
        let limits = builder.limits_mut();
        let subscriptions = &mut limits.subscriptions;
        subscriptions.max_subscriptions_per_session = config.max_subscriptions_per_session as usize;
        subscriptions.max_monitored_items_per_sub =
            config.monitored_items_per_subscription() as usize;
        subscriptions.min_sampling_interval_ms = f64::from(config.min_sampling_interval_ms);
        subscriptions.min_publishing_interval_ms = f64::from(config.min_sampling_interval_ms);
    }
    for policy in &config.security_policies {
        let (policy, name) = match policy {
            OpcuaPolicy::None => {
                let endpoint = ServerEndpoint::new(
                    "/",
                    SecurityPolicy::None,
                    MessageSecurityMode::None,
                    &tokens,
                );
                builder = builder.add_endpoint("none", endpoint);
                continue;
            }
            OpcuaPolicy::Basic256Sha256 => (SecurityPolicy::Basic256Sha256, "basic256sha256"),
            OpcuaPolicy::Aes128Sha256RsaOaep => {
                (SecurityPolicy::Aes128Sha256RsaOaep, "aes128sha256rsaoaep")
            }
            OpcuaPolicy::Aes256Sha256RsaPss => {
                (SecurityPolicy::Aes256Sha256RsaPss, "aes256sha256rsapss")
            }
        };
        for (mode, suffix) in [
            (MessageSecurityMode::Sign, "sign"),
            (MessageSecurityMode::SignAndEncrypt, "sign_encrypt"),
        ] {
            let endpoint = ServerEndpoint::new("/", policy, mode, &tokens);
            builder = builder.add_endpoint(format!("{name}_{suffix}"), endpoint);
        }
    }
    builder
}

/// The node ids the sampler updates, in the order of its values: the status variables, then
/// the plan's leaves.
struct Served {
    status: Vec<NodeId>,
    leaves: Vec<NodeId>,
    /// An enumeration leaf's ValueAsText property, in `leaves` order.
    texts: Vec<Option<NodeId>>,
    /// The array variables, their elements' indices in `leaves` and their dimensions.
    arrays: Vec<(NodeId, Vec<usize>, Vec<u32>)>,
}

impl Served {
    fn new(ns: u16, plan: &Plan) -> Served {
        let text = |leaf: &nodes::Leaf| match leaf.ty {
            ValueType::Enum { .. } => Some(id(ns, &space::value_as_text_id(&leaf.id))),
            _ => None,
        };
        Served {
            status: STATUS_NODES.iter().map(|(name, _)| id(ns, &nodes::status_id(name))).collect(),
            leaves: plan.leaves.iter().map(|leaf| id(ns, &leaf.id)).collect(),
            texts: plan.leaves.iter().map(text).collect(),
            arrays: plan
                .arrays
                .iter()
                .map(|a| (id(ns, &a.id), a.elements.clone(), a.dimensions.clone()))
                .collect(),
        }
    }
}

/// How the sampler is told to stop.
#[derive(Default)]
struct Stop {
    stopped: Mutex<bool>,
    wake: Condvar,
}

impl Stop {
    /// Sleeps `timeout` or until stopped; true if stopped.
    fn sleep(&self, timeout: Duration) -> bool {
        let stopped = self.stopped.lock().unwrap_or_else(|e| e.into_inner());
        let (stopped, _) = self
            .wake
            .wait_timeout_while(stopped, timeout, |stopped| !*stopped)
            .unwrap_or_else(|e| e.into_inner());
        *stopped
    }

    fn stop(&self) {
        *self.stopped.lock().unwrap_or_else(|e| e.into_inner()) = true;
        self.wake.notify_all();
    }
}

/// The sampler thread's state.
struct Sampler {
    mirror: Arc<Mirror>,
    shared: Arc<Shared>,
    manager: Arc<PlcManager>,
    handle: ServerHandle,
    /// plcd's namespace index.
    ns: u16,
    /// The figures of the daemon's status answer.
    status: StatusNodes,
    served: Served,
    /// The plan served: its leaves in `served.leaves` order.
    plan: Arc<Plan>,
    /// The plans of the engines the daemon announced.
    following: Arc<Following>,
    /// The writable variables the node manager looks up: the plan's.
    targets: Targets,
    interval: Duration,
    /// The layout of the engine the plan is of.
    layout: Option<Arc<RetainedVariables>>,
    /// The leaves written since the last hand-over.
    forget: Arc<Mutex<Forget>>,
    stop: Arc<Stop>,
    /// The last copy, taken out of the image so that the lock is held for a copy only.
    words: Vec<u16>,
    vars: Vec<u8>,
    /// The values last handed over: the status's, then the leaves'.
    last: Vec<Option<Variant>>,
    /// The engine changed to one nobody announced and the variables were marked bad (logged
    /// once).
    told_changed: bool,
}

impl Sampler {
    fn run(mut self) {
        let mut generation = 0;
        // At a fixed rate, so that the copies are one interval apart whatever they waited for.
        let mut next = Instant::now();
        loop {
            self.mirror.request();
            self.shared.signal(pending::MIRROR);
            let (fresh, same_engine, error, switch) = {
                let mut image = self.mirror.wait_newer(generation, BOUNDARY_WAIT);
                // Room for a larger engine's memory, and the replaced engine's layout dropped
                // here, never on the scan thread.
                image.serve_reader();
                let fresh = image.generation > generation;
                generation = image.generation;
                self.words.clear();
                self.words.extend_from_slice(&image.words);
                self.vars.clear();
                self.vars.extend_from_slice(&image.vars);
                let same = match (&self.layout, &image.layout) {
                    (Some(served), Some(copied)) => Arc::ptr_eq(served, copied),
                    _ => false,
                };
                let copied = if same { None } else { image.layout.clone() };
                (fresh, (same, copied), image.error, image.switch)
            };
            let (same, copied) = same_engine;
            let same_engine = same || self.follow(copied);
            if fresh {
                self.hand_over(same_engine, error, switch);
            }
            self.status.sample(&self.manager, self.handle.subscriptions());
            next += self.interval;
            let now = Instant::now();
            if next < now {
                // Late (a long wait for a boundary): start again from now, without a burst.
                next = now;
            }
            if self.stop.sleep(next - now) {
                return;
            }
        }
    }

    /// A copy of another engine than the plan's: the address space changed to the plan the
    /// daemon announced for it. False if there is none (an engine nobody announced).
    fn follow(&mut self, copied: Option<Arc<RetainedVariables>>) -> bool {
        let Some(layout) = copied else { return false };
        let Some(plan) = self.following.plan_of(&layout) else { return false };
        let changes = self.plan.changes_to(&plan);
        space::change(&self.manager, self.handle.subscriptions(), self.ns, &changes, &plan);
        *self.targets.write().unwrap_or_else(|e| e.into_inner()) = targets_of(&plan);
        log::info!(
            "opcua: the address space follows the new project: {} variables, {} removed or \
             changed, {} added",
            plan.leaves.len(),
            changes.remove_leaves.len(),
            changes.add_leaves.len()
        );
        self.served = Served::new(self.ns, &plan);
        self.plan = plan;
        // From the next copy on, the new plan's bytes only.
        self.mirror.serve_only(&layout, variable_bytes(&self.plan));
        self.layout = Some(layout);
        // Every value handed over again: the kept nodes may have new places.
        self.last.clear();
        self.told_changed = false;
        true
    }

    /// Hands the stack the values that changed since the last copy.
    fn hand_over(
        &mut self,
        same_engine: bool,
        error: Option<ErrorKind>,
        switch: Option<crate::io::SwitchPosition>,
    ) {
        let shared = &self.shared;
        let ms = |ns: u64| ns as f64 / 1e6;
        let code = error.map(|e| e.describe(&[], &[]).0).unwrap_or_default();
        let status = [
            Variant::from(shared.mode().as_str().to_string()),
            Variant::from(code),
            Variant::Double(ms(shared.scan_last_ns.load(Ordering::Relaxed))),
            Variant::Double(ms(shared.scan_min_ns.load(Ordering::Relaxed))),
            Variant::Double(ms(shared.scan_max_ns.load(Ordering::Relaxed))),
            Variant::UInt64(shared.scans.load(Ordering::Relaxed)),
            Variant::from(switch.map(|s| s.as_str()).unwrap_or_default().to_string()),
        ];
        let count = status.len() + self.plan.leaves.len();
        self.last.resize(count, None);
        {
            // A write replaced these values in the address space: hand the copy's over.
            let mut forget = self.forget.lock().unwrap_or_else(|e| e.into_inner());
            if forget.all {
                self.last[STATUS_NODES.len()..].fill(None);
            }
            for &leaf in &forget.leaves {
                if let Some(last) = self.last.get_mut(STATUS_NODES.len() + leaf) {
                    *last = None;
                }
            }
            *forget = Forget::default();
        }
        if !same_engine && !self.told_changed {
            log::warn!(
                "opcua: the running engine is not one the daemon announced; the program \
                 variables read BadOutOfService until the next reload or load"
            );
            self.told_changed = true;
        }
        let mut changed: Vec<(&NodeId, DataValue)> = Vec::new();
        for (i, (value, node)) in status.into_iter().zip(&self.served.status).enumerate() {
            if self.last[i].as_ref() != Some(&value) {
                self.last[i] = Some(value.clone());
                changed.push((node, DataValue::new_now(value)));
            }
        }
        let mut moved = vec![false; self.plan.leaves.len()];
        for (k, (leaf, node)) in self.plan.leaves.iter().zip(&self.served.leaves).enumerate() {
            let (ty, at) = (&leaf.ty, &leaf.at);
            let i = STATUS_NODES.len() + k;
            moved[k] = true;
            if same_engine {
                let value = values::read(ty, *at, &self.words, &self.vars);
                if self.last[i].as_ref() != Some(&value) {
                    if let (Some(text), Some(name)) =
                        (&self.served.texts[k], values::enum_text(ty, &value))
                    {
                        let name = LocalizedText::new("", &name);
                        changed.push((text, DataValue::new_now(Variant::from(name))));
                    }
                    self.last[i] = Some(value.clone());
                    changed.push((node, DataValue::new_now(value)));
                } else {
                    moved[k] = false;
                }
            } else if self.last[i].is_some() {
                self.last[i] = None;
                let bad = DataValue::new_now_status(Variant::Empty, StatusCode::BadOutOfService);
                changed.push((node, bad));
            } else {
                moved[k] = false;
            }
        }
        // An array whose element moved: all its elements of this copy, as one value.
        for (node, elements, dimensions) in &self.served.arrays {
            if !elements.iter().any(|&e| moved[e]) {
                continue;
            }
            let value = if same_engine {
                let values: Option<Vec<Variant>> =
                    elements.iter().map(|&e| self.last[STATUS_NODES.len() + e].clone()).collect();
                values.and_then(|v| values::array(v, dimensions)).map(DataValue::new_now)
            } else {
                None
            };
            let value = value.unwrap_or_else(|| {
                DataValue::new_now_status(Variant::Empty, StatusCode::BadOutOfService)
            });
            changed.push((node, value));
        }
        if changed.is_empty() {
            return;
        }
        let subscriptions = self.handle.subscriptions();
        let values = changed.into_iter().map(|(node, value)| (node, None, value));
        if let Err(status) = self.manager.set_values(subscriptions, values) {
            log::error!("opcua: values not handed to the server: {status}");
        }
    }
}

/// The server, running.
pub struct RunningOpcua {
    runtime: tokio::runtime::Runtime,
    handle: ServerHandle,
    stack: tokio::task::JoinHandle<()>,
    sampler: JoinHandle<()>,
    stop: Arc<Stop>,
    url: String,
    addr: SocketAddr,
}

impl RunningOpcua {
    /// What it serves, for the log: `opc.tcp://127.0.0.1:4840/ (bound 127.0.0.1:4840)`.
    pub fn serving(&self) -> String {
        format!("{} (bound {})", self.url, self.addr)
    }

    /// Stops the sampler, closes the sessions and the socket, and ends the runtime's threads.
    pub fn stop(self) {
        self.stop.stop();
        let _ = self.sampler.join();
        self.handle.cancel();
        let RunningOpcua { runtime, stack, .. } = self;
        let _ =
            runtime.block_on(async { tokio::time::timeout(Duration::from_secs(5), stack).await });
        runtime.shutdown_timeout(Duration::from_secs(2));
    }
}
