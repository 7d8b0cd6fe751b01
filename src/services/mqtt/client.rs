//! The edge node on a broker: the MQTT connection (the `rumqttc` crate) driven on a tokio
//! runtime of one thread, `plcd-mqtt`, and the sampler thread `plcd-mqtt-sample`, which copies
//! the metrics at scan boundaries through a mirror and hands each copy over. Neither is real
//! time; the scan never waits for them (docs/MQTT.md, "Faults").
//!
//! The connection loop carries out what [`Edge`] decides: each connect makes a new client with
//! the will [`Edge::will`] gives (its `bdSeq`), and after a failure the next broker of the list
//! is tried after a backoff that doubles from `reconnect_min_ms` to `reconnect_max_ms`, with
//! jitter. Copies keep coming while it is disconnected, so that the edge stores what changed.
//! Commands' writes go to the request handler through the in-process door, as `plcctl set`
//! does; a refusal comes back as a DATA message of the value the PLC holds.

use std::collections::VecDeque;
use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use plcd_ipc::{MqttFigures, Outcome, Request, ResponseLine};
use rumqttc::{
    AsyncClient, ConnectionError, Event, EventLoop, LastWill, MqttOptions, NetworkOptions, Packet,
    QoS, Transport,
};
use tokio::sync::{mpsc, Notify};

use super::edge::{Action, Edge, MetricRef, RemoteState, Settings, Status, Topics};
use super::metrics::Plan;
use super::store::DiskBacklog;
use super::MqttError;
use crate::config::{BrokerUrl, MqttConfig};
use crate::drivers::real_time::door::{Caller, LocalDoor};
use crate::drivers::real_time::mirror::Mirror;
use crate::drivers::real_time::{pending, Shared, PLAIN_THREAD_STACK};
use crate::engine::Engine;
use crate::io::remote::RemoteBoard;
use crate::project::MqttNames;
use crate::symbols::Symbols;
use crate::vm::retained::RetainedVariables;

/// How long the sampler waits for a scan boundary before it tries again.
const BOUNDARY_WAIT: Duration = Duration::from_secs(2);
/// MQTT requests queued in the client for its event loop: births and data of a connection.
const REQUESTS: usize = 1024;
/// Plans kept for engines announced and not yet seen in a copy.
const KEPT: usize = 4;
/// Connection faults remembered as logged (one per broker and reason).
const TOLD_KEPT: usize = 64;
/// How long a clean stop waits for its NDEATH to be sent.
const STOP_WAIT: Duration = Duration::from_secs(2);

/// The engineering ranges of variables, by full name (`[[opcua.analog]]`).
pub type Ranges = std::collections::BTreeMap<String, crate::config::EuRange>;

/// The plans of the engines the daemon announced (a reload, a load, an online change), so that
/// the node is born again with the new project's metrics when a copy shows its engine.
pub struct Following {
    config: MqttConfig,
    /// The `[[remote]]` devices' names: fixed while the daemon runs.
    remotes: Vec<String>,
    words: u16,
    plans: Mutex<VecDeque<(Arc<RetainedVariables>, Plan)>>,
    mirror: Arc<Mirror>,
}

impl Following {
    fn plan(&self, symbols: &Symbols, names: &MqttNames, ranges: &Ranges) -> Plan {
        Plan::of(symbols, &self.config, names, self.words)
            .with_ranges(ranges)
            .with_remotes(&self.remotes)
    }

    /// An engine the daemon is about to queue: `layout` is its
    /// [`Engine::retained_variables`], `symbols`, `names` and `ranges` its project's.
    pub fn announce(
        &self,
        layout: &Arc<RetainedVariables>,
        symbols: &Symbols,
        names: &MqttNames,
        ranges: &Ranges,
    ) {
        let plan = self.plan(symbols, names, ranges);
        self.mirror.serve_also(layout, plan.variable_bytes());
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        if plans.len() >= KEPT {
            plans.pop_front();
        }
        plans.push_back((Arc::clone(layout), plan));
    }

    /// The plan announced for the engine of `layout`, taken.
    fn plan_of(&self, layout: &Arc<RetainedVariables>) -> Option<Plan> {
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        let at = plans.iter().position(|(l, _)| Arc::ptr_eq(l, layout))?;
        // The older ones will never run now.
        plans.drain(..at);
        plans.pop_front().map(|(_, plan)| plan)
    }
}

/// The edge node, set up at the daemon's start: its plan, its mirror, its secrets read.
pub struct MqttNode {
    config: MqttConfig,
    plan: Plan,
    following: Arc<Following>,
    mirror: Arc<Mirror>,
    password: Option<String>,
    tls: Option<Arc<rustls::ClientConfig>>,
    layout: Mutex<Option<Arc<RetainedVariables>>>,
    figures: Arc<Mutex<MqttFigures>>,
    /// `store_forward_dir`'s messages.
    disk: Option<DiskBacklog>,
}

impl MqttNode {
    /// The node of `config`, with a Sparkplug device for each remote I/O device of `remotes`
    /// (the `[[remote]]` names) and the engineering `ranges` of the variables that have one;
    /// `None` unless `brokers` is set. Reads the password file and the TLS files now, so that a
    /// missing one stops the start.
    pub fn new(
        config: &MqttConfig,
        remotes: &[String],
        symbols: &Symbols,
        names: &MqttNames,
        ranges: &Ranges,
    ) -> Result<Option<MqttNode>, MqttError> {
        if !config.enabled() {
            return Ok(None);
        }
        let password = match &config.password_file {
            Some(path) => Some(read_password(path)?),
            None => None,
        };
        let tls =
            if config.brokers.iter().any(|b| b.tls) { Some(tls_config(config)?) } else { None };
        // All of device memory, so that a place indexes the copy as it indexes device memory.
        let words = crate::device::layout::TOTAL_WORDS as u16;
        let mirror = Arc::new(Mirror::with_all_variables(std::iter::once(0..words)));
        let following = Arc::new(Following {
            config: config.clone(),
            remotes: remotes.to_vec(),
            words,
            plans: Mutex::new(VecDeque::new()),
            mirror: Arc::clone(&mirror),
        });
        let plan = following.plan(symbols, names, ranges);
        let disk = match &config.store_forward_dir {
            Some(dir) => Some(
                DiskBacklog::open(dir, config.store_forward_disk_bytes)
                    .map_err(|source| MqttError::Store { path: dir.clone(), source })?,
            ),
            None => None,
        };
        let figures = MqttFigures {
            node: format!("{}/{}/{}", super::edge::NAMESPACE, config.group_id, config.edge_node_id),
            broker: config.brokers[0].to_string(),
            state: "connecting".into(),
            ..MqttFigures::default()
        };
        Ok(Some(MqttNode {
            config: config.clone(),
            plan,
            following,
            mirror,
            password,
            tls,
            layout: Mutex::new(None),
            figures: Arc::new(Mutex::new(figures)),
            disk,
        }))
    }

    /// The mirror the scan thread copies for it.
    pub fn mirror(&self) -> Arc<Mirror> {
        Arc::clone(&self.mirror)
    }

    /// Its state and counters, for `plcctl status`, kept up to date by the connection.
    pub fn figures(&self) -> Arc<Mutex<MqttFigures>> {
        Arc::clone(&self.figures)
    }

    /// Where the daemon announces the engines it queues.
    pub fn following(&self) -> Arc<Following> {
        Arc::clone(&self.following)
    }

    /// Before the scan thread starts: room for `engine`'s variable memory in the mirror, and
    /// the plan's bytes as the ones to copy.
    pub fn prepare(&self, engine: &Engine) {
        let layout = engine.retained_variables();
        self.mirror.prepare(layout, engine.vm().vars().len());
        self.mirror.serve_only(layout, self.plan.variable_bytes());
        *self.layout.lock().unwrap_or_else(|e| e.into_inner()) = Some(Arc::clone(layout));
    }

    /// Starts the sampler and the connection; `board` has the remote I/O devices' states.
    pub fn start(
        self,
        shared: Arc<Shared>,
        door: LocalDoor,
        board: RemoteBoard,
    ) -> Result<RunningMqtt, MqttError> {
        let MqttNode { config, plan, following, mirror, password, tls, layout, figures, disk } =
            self;
        let layout = layout.into_inner().unwrap_or_else(|e| e.into_inner());
        log::info!(
            "mqtt: {} metrics in {} devices{}",
            plan.len(),
            plan.devices.len(),
            match (plan.left_out, plan.unserved) {
                (0, 0) => String::new(),
                (left, unserved) => format!(
                    " ({left} left out past max_metrics, {unserved} not published: references and \
                     variables beyond the copy)"
                ),
            }
        );
        let rate = Arc::new(AtomicU32::new(config.sample_interval_ms));
        let stop = Arc::new(Stopping::default());
        let (samples_tx, samples) = mpsc::channel(2);
        let sampler = Sampler {
            remotes: following.remotes.clone(),
            board,
            mirror: Arc::clone(&mirror),
            shared: Arc::clone(&shared),
            rate: Arc::clone(&rate),
            stop: Arc::clone(&stop),
            out: samples_tx,
        };
        let sampler = std::thread::Builder::new()
            .name("plcd-mqtt-sample".into())
            .stack_size(PLAIN_THREAD_STACK)
            .spawn(move || sampler.run())
            .map_err(|source| MqttError::Spawn { source })?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|source| MqttError::Runtime { source })?;
        let settings = Settings {
            topics: Topics::new(&config.group_id, &config.edge_node_id),
            primary: config.primary_host.clone(),
            scan_rate_ms: config.sample_interval_ms,
            scan_rates: MqttConfig::SAMPLE_INTERVAL_MS,
            store_limit: config.store_forward_messages as usize,
        };
        let node =
            format!("{}/{}/{}", super::edge::NAMESPACE, config.group_id, config.edge_node_id);
        let mut edge = Edge::new(settings, plan);
        if let Some(disk) = disk {
            edge.set_overflow(Box::new(disk));
        }
        let connection = Connection {
            edge,
            config,
            password,
            tls,
            door,
            following,
            mirror,
            layout,
            rate,
            samples,
            stop: Arc::clone(&stop),
            told: Vec::new(),
            failures: 0,
            connects: 0,
            failed: 0,
            node: node.clone(),
            figures,
        };
        let thread_stop = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("plcd-mqtt".into())
            .spawn(move || {
                runtime.block_on(connection.run());
                drop(thread_stop);
            })
            .map_err(|source| MqttError::Spawn { source })?;
        Ok(RunningMqtt { node, thread, sampler, stop, shared })
    }
}

/// How the threads are told to stop.
#[derive(Default)]
struct Stopping {
    stopped: std::sync::atomic::AtomicBool,
    notify: Notify,
    sleep: std::sync::Condvar,
    lock: Mutex<()>,
}

impl Stopping {
    fn stop(&self) {
        self.stopped.store(true, Ordering::Release);
        self.notify.notify_one();
        let _guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        self.sleep.notify_all();
    }

    fn is_stopped(&self) -> bool {
        self.stopped.load(Ordering::Acquire)
    }

    /// Sleeps `timeout` or until stopped (sampler side); true if stopped.
    fn sleep(&self, timeout: Duration) -> bool {
        let guard = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        let _ = self
            .sleep
            .wait_timeout_while(guard, timeout, |_| !self.is_stopped())
            .unwrap_or_else(|e| e.into_inner());
        self.is_stopped()
    }
}

/// One copy, handed from the sampler to the connection.
struct Copied {
    at_ms: u64,
    words: Vec<u16>,
    vars: Vec<u8>,
    status: Status,
    layout: Option<Arc<RetainedVariables>>,
    /// The remote I/O devices' states, in `[[remote]]` order.
    remotes: Vec<RemoteState>,
}

/// The sampler thread: a copy at a scan boundary every scan-rate interval.
struct Sampler {
    /// The `[[remote]]` names, in config order, and their counters.
    remotes: Vec<String>,
    board: RemoteBoard,
    mirror: Arc<Mirror>,
    shared: Arc<Shared>,
    rate: Arc<AtomicU32>,
    stop: Arc<Stopping>,
    out: mpsc::Sender<Copied>,
}

impl Sampler {
    /// The remote devices' states now, in `[[remote]]` order.
    fn remote_states(&self) -> Vec<RemoteState> {
        let reports = self.board.reports();
        self.remotes
            .iter()
            .map(|name| match reports.iter().find(|r| &r.name == name) {
                Some(report) => RemoteState {
                    state: report.stats.state.as_str().to_string(),
                    requests: report.stats.requests,
                    failures: report.stats.failures,
                    losses: report.stats.losses,
                },
                None => RemoteState::default(),
            })
            .collect()
    }

    fn run(self) {
        let mut generation = 0;
        let mut next = Instant::now();
        loop {
            self.mirror.request();
            self.shared.signal(pending::MIRROR);
            let copied = {
                let mut image = self.mirror.wait_newer(generation, BOUNDARY_WAIT);
                image.serve_reader();
                let fresh = image.generation > generation;
                generation = image.generation;
                fresh.then(|| Copied {
                    at_ms: now_ms(),
                    words: image.words.to_vec(),
                    vars: image.vars.clone(),
                    status: Status {
                        mode: image.mode.as_str().to_string(),
                        error: image.error.map(|e| e.describe(&[], &[]).0).unwrap_or_default(),
                        scans: image.scans,
                        scan_ms: self.shared.scan_last_ns.load(Ordering::Relaxed) as f64 / 1e6,
                    },
                    layout: image.layout.clone(),
                    remotes: Vec::new(),
                })
            };
            let copied = copied.map(|copied| Copied { remotes: self.remote_states(), ..copied });
            if let Some(copied) = copied {
                // A connection busy with a slow broker takes the next copy instead: the values
                // of one copy are compared with what was sent, so none is lost but the
                // in-between ones.
                let _ = self.out.try_send(copied);
            }
            next += Duration::from_millis(u64::from(self.rate.load(Ordering::Relaxed)));
            let now = Instant::now();
            if next < now {
                next = now;
            }
            if self.stop.sleep(next - now) {
                return;
            }
        }
    }
}

/// The connection loop's state.
struct Connection {
    edge: Edge,
    config: MqttConfig,
    password: Option<String>,
    tls: Option<Arc<rustls::ClientConfig>>,
    door: LocalDoor,
    following: Arc<Following>,
    mirror: Arc<Mirror>,
    /// The engine the edge's plan is of.
    layout: Option<Arc<RetainedVariables>>,
    rate: Arc<AtomicU32>,
    samples: mpsc::Receiver<Copied>,
    stop: Arc<Stopping>,
    /// The faults logged since the last connection, one per broker and reason, the last the
    /// newest: a broker that stays down is one line, however many brokers are tried in turn.
    told: Vec<String>,
    /// Connection attempts failed in a row (0 once the broker took one).
    failures: u32,
    /// `spBv1.0/GROUP/NODE`, for the log.
    node: String,
    /// Connections the brokers took, and attempts failed or connections lost, since start.
    connects: u64,
    failed: u64,
    /// What `plcctl status` shows.
    figures: Arc<Mutex<MqttFigures>>,
}

/// What ended a connection.
enum Ended {
    Stopped,
    Failed(String),
    NextServer,
}

impl Connection {
    async fn run(mut self) {
        let (replies_tx, mut replies) = mpsc::unbounded_channel::<(Vec<MetricRef>, ResponseLine)>();
        let mut broker = 0usize;
        let min = Duration::from_millis(u64::from(self.config.reconnect_min_ms));
        let max = Duration::from_millis(u64::from(self.config.reconnect_max_ms));
        let mut backoff = min;
        loop {
            let url = self.config.brokers[broker].clone();
            self.report(&url);
            let ended = self.connection(&url, &replies_tx, &mut replies).await;
            self.edge.disconnected();
            self.report(&url);
            let wait = match ended {
                Ended::Stopped => return,
                Ended::NextServer => Duration::ZERO,
                Ended::Failed(why) => {
                    if self.failures == 0 {
                        // The broker had taken this connection: start the backoff over.
                        backoff = min;
                    }
                    self.failures += 1;
                    self.failed += 1;
                    let line = format!("{url}: {why}");
                    if !self.told.contains(&line) {
                        log::warn!("mqtt: {line}; trying again, the next broker first");
                    }
                    self.told.retain(|told| told != &line);
                    self.told.push(line);
                    if self.told.len() > TOLD_KEPT {
                        self.told.remove(0);
                    }
                    let wait = jitter(backoff);
                    backoff = (backoff * 2).min(max);
                    wait
                }
            };
            broker = (broker + 1) % self.config.brokers.len();
            // Copies go on being compared (and stored) while no broker is connected.
            let until = tokio::time::Instant::now() + wait;
            loop {
                tokio::select! {
                    _ = tokio::time::sleep_until(until) => break,
                    _ = self.stop.notify.notified() => return,
                    copied = self.samples.recv() => match copied {
                        Some(copied) => { self.sampled(copied); }
                        None => return,
                    },
                }
            }
            if self.stop.is_stopped() {
                return;
            }
        }
    }

    /// One connection to `url`, until it fails, the node moves on, or the daemon stops.
    async fn connection(
        &mut self,
        url: &BrokerUrl,
        replies_tx: &mpsc::UnboundedSender<(Vec<MetricRef>, ResponseLine)>,
        replies: &mut mpsc::UnboundedReceiver<(Vec<MetricRef>, ResponseLine)>,
    ) -> Ended {
        let will = self.edge.will();
        let options =
            self.options(url, LastWill::new(will.topic, will.payload, QoS::AtMostOnce, false));
        let (client, mut events): (AsyncClient, EventLoop) = AsyncClient::new(options, REQUESTS);
        // Each DATA is a small message sent at once: without TCP_NODELAY, Nagle's algorithm held
        // one back until the broker's delayed ACK (about 40 ms) whenever a host sent commands
        // (BENCHMARKS.md, "MQTT").
        let mut network = NetworkOptions::new();
        network.set_tcp_nodelay(true);
        events.set_network_options(network);
        // rumqttc's connect (TCP, TLS, CONNECT, CONNACK) inside `poll` is not cancel safe: a
        // copy arriving in the middle of it must not drop it (the broker would publish the
        // will of a session that was never born). It is awaited whole; only a stop cuts it.
        let first = tokio::select! {
            _ = self.stop.notify.notified() => return Ended::Stopped,
            event = events.poll() => event,
        };
        let mut first = Some(first);
        let mut acknowledged = false;
        loop {
            self.report(url);
            let event = async {
                match first.take() {
                    Some(event) => event,
                    None => events.poll().await,
                }
            };
            tokio::select! {
                event = event => match event {
                    Ok(Event::Incoming(Packet::ConnAck(_))) => {
                        acknowledged = true;
                        let node = &self.node;
                        match std::mem::take(&mut self.told).last() {
                            Some(_) => log::info!(
                                "mqtt: edge node {node} on {url}, after {} failed attempts",
                                self.failures
                            ),
                            None => log::info!("mqtt: edge node {node} on {url}"),
                        }
                        self.failures = 0;
                        self.connects += 1;
                        let topics = self.edge.topics().subscriptions(self.edge.primary());
                        for topic in topics {
                            let _ = client.try_subscribe(topic, QoS::AtLeastOnce);
                        }
                        let actions = self.edge.connected(now_ms());
                        if let Some(ended) = self.apply(&client, actions, replies_tx) {
                            return self.end(&client, &mut events, ended).await;
                        }
                    }
                    Ok(Event::Incoming(Packet::Publish(publish))) => {
                        if publish.payload.len() > self.config.max_message_bytes as usize {
                            self.edge.counters.malformed += 1;
                            continue;
                        }
                        let actions = self.edge.message(&publish.topic, &publish.payload, now_ms());
                        if let Some(ended) = self.apply(&client, actions, replies_tx) {
                            return self.end(&client, &mut events, ended).await;
                        }
                    }
                    Ok(_) => {}
                    Err(e) => {
                        if !acknowledged && matches!(e, ConnectionError::Io(_) | ConnectionError::Tls(_)) {
                            self.edge.will_unsent();
                        }
                        return Ended::Failed(e.to_string());
                    }
                },
                copied = self.samples.recv() => match copied {
                    Some(copied) => {
                        let actions = self.sampled(copied);
                        if let Some(ended) = self.apply(&client, actions, replies_tx) {
                            return self.end(&client, &mut events, ended).await;
                        }
                    }
                    None => return Ended::Stopped,
                },
                reply = replies.recv() => {
                    if let Some((metrics, line)) = reply {
                        if let Outcome::Error(failure) = &line.outcome {
                            log::warn!("mqtt: a command's write was refused: {}", failure.message);
                            let actions = self.edge.refused(&metrics, now_ms());
                            let _ = self.apply(&client, actions, replies_tx);
                        }
                    }
                },
                _ = self.stop.notify.notified() => {
                    self.report(url);
                    // A clean disconnect does not send the will: the NDEATH is published.
                    let death = self.edge.death();
                    let _ = client.try_publish(death.topic, QoS::AtMostOnce, false, death.payload);
                    return self.end(&client, &mut events, Ended::Stopped).await;
                },
            }
        }
    }

    /// Hands `plcctl status` the node's state and counters now.
    fn report(&self, url: &BrokerUrl) {
        let counters = &self.edge.counters;
        let state = match (self.edge.is_connected(), self.edge.is_born()) {
            (_, true) => "born",
            (true, false) => "waiting",
            (false, false) => "connecting",
        };
        let mut figures = self.figures.lock().unwrap_or_else(|e| e.into_inner());
        figures.broker = url.to_string();
        figures.state = state.into();
        figures.connects = self.connects;
        figures.failures = self.failed;
        figures.births = counters.births;
        figures.data = counters.data;
        figures.queued = self.edge.stored() as u64;
        figures.dropped = counters.dropped;
        figures.commands = counters.commands;
        figures.refused = counters.refused;
        figures.malformed = counters.malformed;
        figures.last_error = self.told.last().cloned();
    }

    /// Disconnects cleanly (what was published goes first), waiting at most [`STOP_WAIT`].
    async fn end(&mut self, client: &AsyncClient, events: &mut EventLoop, ended: Ended) -> Ended {
        let _ = client.try_disconnect();
        let _ = tokio::time::timeout(STOP_WAIT, async {
            loop {
                match events.poll().await {
                    Ok(Event::Outgoing(rumqttc::Outgoing::Disconnect)) | Err(_) => break,
                    Ok(_) => {}
                }
            }
        })
        .await;
        ended
    }

    /// A copy: a new plan first if it is of an engine the daemon announced, then its changes.
    fn sampled(&mut self, copied: Copied) -> Vec<Action> {
        let mut actions = Vec::new();
        let same = match (&self.layout, &copied.layout) {
            (Some(served), Some(copy)) => Arc::ptr_eq(served, copy),
            _ => false,
        };
        if !same {
            let Some(layout) = copied.layout.clone() else { return actions };
            let Some(plan) = self.following.plan_of(&layout) else {
                // An engine nobody announced: its variables' places are unknown.
                return actions;
            };
            log::info!("mqtt: the metrics follow the new project: {} metrics", plan.len());
            self.mirror.serve_only(&layout, plan.variable_bytes());
            self.layout = Some(layout);
            actions.extend(self.edge.replan(plan, copied.at_ms));
        }
        actions.extend(self.edge.remotes(copied.remotes.clone(), copied.at_ms));
        let sample = super::edge::Sample {
            at_ms: copied.at_ms,
            words: &copied.words,
            vars: &copied.vars,
            status: &copied.status,
        };
        actions.extend(self.edge.sample(&sample));
        actions
    }

    /// Carries out `actions`; what ends the connection, if one does.
    fn apply(
        &mut self,
        client: &AsyncClient,
        actions: Vec<Action>,
        replies_tx: &mpsc::UnboundedSender<(Vec<MetricRef>, ResponseLine)>,
    ) -> Option<Ended> {
        // A move to the next broker is carried out after the rest of the list: the writes of
        // the same NCMD still go to the request handler.
        let mut moving = None;
        for action in actions {
            match action {
                Action::Publish(message) => {
                    if client
                        .try_publish(message.topic, QoS::AtMostOnce, false, message.payload)
                        .is_err()
                    {
                        // The client's queue is full: the broker does not take what is sent.
                        // Hosts see the gap in `seq` and ask for a rebirth.
                        self.edge.counters.dropped += 1;
                    }
                }
                Action::Set { writes, metrics } => {
                    let tx = replies_tx.clone();
                    let back = metrics.clone();
                    let reply = Box::new(move |line: ResponseLine| {
                        let _ = tx.send((back, line));
                    });
                    let caller = Caller::Service("mqtt host".into());
                    if self.door.submit(Request::Set { writes }, caller, reply).is_err() {
                        log::warn!(
                            "mqtt: a command's write was refused: the control thread is busy"
                        );
                        let again = self.edge.refused(&metrics, now_ms());
                        for action in again {
                            if let Action::Publish(m) = action {
                                let _ =
                                    client.try_publish(m.topic, QoS::AtMostOnce, false, m.payload);
                            }
                        }
                    }
                }
                Action::NextServer(death) => moving = Some(death),
                Action::ScanRate(ms) => {
                    self.rate.store(ms, Ordering::Relaxed);
                    log::info!("mqtt: scan rate {ms} ms (Node Control/Scan Rate)");
                }
            }
        }
        let death = moving?;
        let _ = client.try_publish(death.topic, QoS::AtMostOnce, false, death.payload);
        log::info!(
            "mqtt: moving to the next broker (Node Control/Next Server or the primary host offline)"
        );
        Some(Ended::NextServer)
    }

    /// The MQTT options of a connection to `url` with `will`.
    fn options(&self, url: &BrokerUrl, will: LastWill) -> MqttOptions {
        let mut options =
            MqttOptions::new(self.config.client_id_or_default(), url.host.clone(), url.port);
        options.set_keep_alive(Duration::from_secs(u64::from(self.config.keep_alive_s)));
        // Sparkplug: a clean session, no state kept across connections.
        options.set_clean_session(true);
        options.set_last_will(will);
        let max = self.config.max_message_bytes as usize;
        // What plcd sends is a birth of every metric: the incoming bound is the config's.
        options.set_max_packet_size(max, usize::MAX / 2);
        if let (Some(user), Some(password)) = (&self.config.username, &self.password) {
            options.set_credentials(user.clone(), password.clone());
        } else if let Some(user) = &self.config.username {
            options.set_credentials(user.clone(), String::new());
        }
        if url.tls {
            if let Some(tls) = &self.tls {
                options.set_transport(Transport::tls_with_config(
                    rumqttc::TlsConfiguration::Rustls(Arc::clone(tls)),
                ));
            }
        }
        options
    }
}

/// `wait` less up to a quarter of it, so that nodes that lost one broker together do not all
/// come back in the same instant.
fn jitter(wait: Duration) -> Duration {
    let nanos = SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.subsec_nanos()).unwrap_or(0);
    let quarter = wait / 4;
    wait - quarter.mul_f64(f64::from(nanos % 1000) / 1000.0)
}

/// Milliseconds since 1970.
fn now_ms() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_millis() as u64).unwrap_or(0)
}

/// The password: the file's first line.
fn read_password(path: &Path) -> Result<String, MqttError> {
    let text = std::fs::read_to_string(path).map_err(|source| MqttError::Read {
        key: "password_file",
        path: path.to_path_buf(),
        source,
    })?;
    Ok(text.lines().next().unwrap_or_default().to_string())
}

/// The TLS settings: the CA file's certificates (else the system's), and the client
/// certificate and key if given; ring as the crypto provider.
fn tls_config(config: &MqttConfig) -> Result<Arc<rustls::ClientConfig>, MqttError> {
    use rustls::pki_types::pem::PemObject;
    use rustls::pki_types::{CertificateDer, PrivateKeyDer};
    let pem = |key: &'static str, path: &Path, message: String| MqttError::Pem {
        key,
        path: path.to_path_buf(),
        message,
    };
    let mut roots = rustls::RootCertStore::empty();
    match &config.ca_file {
        Some(path) => {
            let certs = CertificateDer::pem_file_iter(path)
                .map_err(|e| pem("ca_file", path, e.to_string()))?
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| pem("ca_file", path, e.to_string()))?;
            if certs.is_empty() {
                return Err(pem("ca_file", path, "no certificate in it".into()));
            }
            for cert in certs {
                roots.add(cert).map_err(|e| pem("ca_file", path, e.to_string()))?;
            }
        }
        None => {
            let found = rustls_native_certs::load_native_certs();
            for cert in found.certs {
                let _ = roots.add(cert);
            }
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| MqttError::Tls(e.to_string()))?
        .with_root_certificates(roots);
    let config = match (&config.client_cert, &config.client_key) {
        (Some(cert), Some(key)) => {
            let chain = CertificateDer::pem_file_iter(cert)
                .map_err(|e| pem("client_cert", cert, e.to_string()))?
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| pem("client_cert", cert, e.to_string()))?;
            let key_der = PrivateKeyDer::from_pem_file(key)
                .map_err(|e| pem("client_key", key, e.to_string()))?;
            builder
                .with_client_auth_cert(chain, key_der)
                .map_err(|e| MqttError::Tls(e.to_string()))?
        }
        _ => builder.with_no_client_auth(),
    };
    Ok(Arc::new(config))
}

/// The edge node, running.
pub struct RunningMqtt {
    node: String,
    thread: JoinHandle<()>,
    sampler: JoinHandle<()>,
    stop: Arc<Stopping>,
    shared: Arc<Shared>,
}

impl RunningMqtt {
    /// What it is, for the log: `spBv1.0/GROUP/NODE`.
    pub fn serving(&self) -> &str {
        &self.node
    }

    /// Publishes the NDEATH (if born), disconnects, and ends both threads.
    pub fn stop(self) {
        self.stop.stop();
        // A sampler waiting for a boundary is woken by the next one; wake the scan thread.
        self.shared.signal(pending::MIRROR);
        let _ = self.sampler.join();
        let _ = self.thread.join();
    }
}
