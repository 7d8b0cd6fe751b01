//! How a request waits for the scan thread, and how its answer is found when the wait is over.
//!
//! A request that changes PLC state sends its commands through the command queue and waits
//! for their tickets' completions ([`Stage::Commands`]); one that reads waits for a snapshot
//! captured after it arrived ([`Stage::Snapshot`]). [`Then`] says what the request does once its
//! wait is over — answer, or wait for a capture next (a `step` until execution pauses again, a
//! write followed by the state it left). Every wait ends within [`ANSWER_TIMEOUT`]. The replies
//! themselves are the request families' (`mode`, `devices`, `forces`, `debugger`, `load`,
//! `status`).

use std::sync::atomic::Ordering;
use std::time::Instant;

use super::devices::{self, word_of, Item};
use super::{debugger, failure, forces, mode, RequestHandler, Running, ANSWER_TIMEOUT, STEP_POLL};
use crate::device::Address;
use crate::drivers::real_time::snapshot::{
    VarRead, MAX_READ_TEXT, MAX_READ_VALUES, MAX_READ_WORDS,
};
use crate::drivers::real_time::{pending, Applied, Command, Completion, ControlCommand};
use crate::engine::Refusal;
use crate::project::Through;
use crate::services::control::ClientId;
use plcd_ipc::{ErrorKind as Kind, Failure, NamedValue, ResponseLine};

/// A parked request.
pub(super) struct Waiting {
    pub(super) client: ClientId,
    pub(super) since: Instant,
    pub(super) stage: Stage,
    pub(super) then: Then,
}

/// What a parked request waits for.
pub(super) enum Stage {
    /// Tickets not yet completed; the last completion's state; the first refusal.
    Commands { tickets: Vec<u64>, applied: Option<Applied>, refused: Option<Refusal> },
    /// A capture newer than this generation.
    Snapshot { after: u64 },
}

/// What a parked request does once its wait is over.
pub(super) enum Then {
    Mode,
    Written {
        count: usize,
    },
    /// `unforced`: the bit an `unforce` names, as its answer shows it (`P0040`,
    /// `main.lamp (P0040)`).
    Forces {
        unforced: Option<String>,
    },
    /// `until_paused`: `step` answers once the step is done (execution paused again).
    Debug {
        unbroken: Option<String>,
        devices: Option<Vec<Address>>,
        until_paused: bool,
    },
    /// `devices`: those the line execution is paused before names (in DEBUG), once a capture
    /// lacked them.
    Status {
        devices: Option<Vec<Address>>,
    },
    Values {
        items: Vec<Item>,
    },
    /// A `set` that names variables through references (`main.r^`): once a capture read the
    /// references, its writes are queued where they point.
    SetThrough {
        writes: Vec<NamedValue>,
        references: Vec<Through>,
    },
    Loaded {
        online: bool,
        programs: usize,
        tasks: usize,
        previous: Option<Box<Running>>,
    },
}

impl Then {
    /// The device words the answer reads from the snapshot.
    fn words(&self) -> Vec<u16> {
        match self {
            Then::Values { items } => items
                .iter()
                .filter_map(|i| match i {
                    Item::Device(d) => Some(word_of(d)),
                    Item::Variable(_) | Item::Through(_) => None,
                })
                .collect(),
            Then::Debug { devices: Some(devices), .. }
            | Then::Status { devices: Some(devices) } => devices.iter().map(word_of).collect(),
            _ => Vec::new(),
        }
    }

    /// The variables the answer reads from the snapshot.
    fn var_reads(&self) -> Vec<VarRead> {
        match self {
            Then::Values { items } => items.iter().filter_map(Item::var_read).collect(),
            Then::SetThrough { references, .. } => {
                references.iter().map(devices::reference_read).collect()
            }
            _ => Vec::new(),
        }
    }

    /// Whether `snapshot` holds everything the answer reads.
    fn captured(&self, snapshot: &crate::drivers::real_time::snapshot::Snapshot) -> bool {
        match self {
            Then::Values { items } => devices::captured(items, snapshot),
            Then::SetThrough { references, .. } => {
                references.iter().all(|r| snapshot.has(&devices::reference_read(r)))
            }
            Then::Debug { devices: Some(devices), .. }
            | Then::Status { devices: Some(devices) } => {
                devices.iter().all(|d| snapshot.word(word_of(d)).is_some())
            }
            _ => true,
        }
    }
}

/// What a finished snapshot wait comes to.
pub(super) enum Outcome {
    Answer(ResponseLine),
    /// Wait for a later capture; `again`: ask for one at once.
    Wait {
        then: Then,
        again: bool,
    },
    /// Queue `commands`, then wait for their completions.
    Send {
        commands: Vec<ControlCommand>,
        then: Then,
    },
}

impl RequestHandler {
    /// Queues control commands, all in one chunk so that the scan thread takes all of them in
    /// the same pass (the writes of one `set` at the same END); their tickets, or `busy` when
    /// the queue has no room for all.
    pub(super) fn send(&mut self, commands: Vec<ControlCommand>) -> Result<Vec<u64>, Failure> {
        let busy = || Failure::new(Kind::Busy, "the command queue is full; try again");
        let mut queue = self.links.commands.lock().unwrap_or_else(|e| e.into_inner());
        let count = commands.len();
        let Ok(chunk) = queue.write_chunk_uninit(count) else {
            return Err(busy());
        };
        let first = self.next_ticket;
        self.next_ticket += count as u64;
        let tickets: Vec<u64> = (first..first + count as u64).collect();
        let pushed = chunk.fill_from_iter(
            tickets
                .iter()
                .zip(commands)
                .map(|(&ticket, command)| Command::Control(ticket, command)),
        );
        debug_assert_eq!(pushed, count);
        drop(queue);
        self.links.shared.signal(pending::COMMAND);
        Ok(tickets)
    }

    /// Parks `client` until the completions of `tickets` (already sent) arrive.
    pub(super) fn wait_for(&mut self, client: ClientId, tickets: Vec<u64>, then: Then) {
        let stage = Stage::Commands { tickets, applied: None, refused: None };
        self.waiting.push(Waiting { client, since: Instant::now(), stage, then });
    }

    /// Sends `commands` and parks `client` until they are applied; `busy` at once when the
    /// queue is full.
    pub(super) fn park(
        &mut self,
        client: ClientId,
        commands: Vec<ControlCommand>,
        then: Then,
    ) -> Option<ResponseLine> {
        match self.send(commands) {
            Ok(tickets) => {
                self.wait_for(client, tickets, then);
                None
            }
            Err(f) => Some(ResponseLine::failure(f)),
        }
    }

    /// Parks `client` until a capture newer than the current one.
    pub(super) fn park_for_snapshot(
        &mut self,
        client: ClientId,
        then: Then,
    ) -> Option<ResponseLine> {
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

    pub(super) fn generation(&self) -> u64 {
        self.links.snapshot.lock().map(|s| s.generation).unwrap_or(0)
    }

    /// Asks for a capture of every word and variable the waiting requests need, as many as
    /// one capture holds (the others at the next: a request is answered from a capture that
    /// holds all it reads, and one request alone always fits).
    fn want_snapshot(&mut self) {
        self.last_want = Instant::now();
        if let Ok(mut snapshot) = self.links.snapshot.lock() {
            let (mut len, mut vars, mut text) = (0, 0, 0);
            for waiting in &self.waiting {
                for word in waiting.then.words() {
                    if !snapshot.want[..len].contains(&word) && len < MAX_READ_WORDS {
                        snapshot.want[len] = word;
                        len += 1;
                    }
                }
                for read in waiting.then.var_reads() {
                    let fits = vars < MAX_READ_VALUES && text + read.text_bytes() <= MAX_READ_TEXT;
                    if fits && !snapshot.want_vars[..vars].contains(&read) {
                        snapshot.want_vars[vars] = read;
                        vars += 1;
                        text += read.text_bytes();
                    }
                }
            }
            snapshot.want_len = len;
            snapshot.want_vars_len = vars;
        }
        self.links.shared.snapshot_wanted.store(true, Ordering::Release);
        self.links.shared.signal(pending::COMMAND);
    }

    /// The answers that became ready: completions taken, snapshot waits served, a step in
    /// progress looked at, waits past [`ANSWER_TIMEOUT`] answered `unavailable`.
    pub(super) fn collect_answers(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>) {
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
                *self.running() = *previous;
            }
            ready.push((waiting.client, failure(Kind::Refused, refusal.to_string())));
            return;
        }
        let Some(applied) = applied else { return };
        self.fresh_until = None;
        let answer = match waiting.then {
            Then::Mode => mode::applied(applied),
            Then::Written { count } => devices::written(applied, count),
            Then::Loaded { online, programs, tasks, .. } => {
                self.loaded(online, programs, tasks, applied)
            }
            Then::Forces { unforced: Some(shown) } if !applied.changed => {
                forces::not_forced(&shown)
            }
            Then::Debug { unbroken: Some(at), .. } if !applied.changed => {
                debugger::no_breakpoint(&at)
            }
            then => {
                let after = self.generation();
                self.waiting.push(Waiting {
                    client: waiting.client,
                    since: waiting.since,
                    stage: Stage::Snapshot { after },
                    then,
                });
                self.want_snapshot();
                return;
            }
        };
        ready.push((waiting.client, answer));
    }

    /// Answers the snapshot waits a new capture satisfies.
    fn serve_snapshot(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>) {
        let Ok(snapshot) = self.links.snapshot.lock() else { return };
        let generation = snapshot.generation;
        let mut again = false;
        let mut sends = Vec::new();
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
            if !self.waiting[index].then.captured(&snapshot) {
                // Another request's words filled the capture: next round.
                self.waiting[index].stage = Stage::Snapshot { after: generation };
                again = true;
                index += 1;
                continue;
            }
            let waiting = self.waiting.swap_remove(index);
            let client = waiting.client;
            let outcome = match waiting.then {
                Then::Status { devices } => self.status_outcome(devices, &snapshot),
                Then::Values { items } if items.iter().any(|i| matches!(i, Item::Through(_))) => {
                    // The references are read: the variables they point to (or a chain's next
                    // reference), at the next capture.
                    let project = &self.running().project;
                    match devices::through_resolved(items, &snapshot, project) {
                        Ok(items) => Outcome::Wait { then: Then::Values { items }, again: true },
                        Err(f) => Outcome::Answer(ResponseLine::failure(f)),
                    }
                }
                Then::Values { items } => {
                    let symbols = &self.running().project.variables.symbols;
                    Outcome::Answer(devices::values(&items, &snapshot, symbols))
                }
                Then::SetThrough { writes, references } => {
                    let project = &self.running().project;
                    match devices::set_through(project, &writes, &references, &snapshot) {
                        Ok(devices::SetThrough::Commands(commands)) => {
                            let then = Then::Written { count: writes.len() };
                            Outcome::Send { commands, then }
                        }
                        // a chain's next reference, read at the next capture
                        Ok(devices::SetThrough::Again(references)) => Outcome::Wait {
                            then: Then::SetThrough { writes, references },
                            again: true,
                        },
                        Err(f) => Outcome::Answer(ResponseLine::failure(f)),
                    }
                }
                Then::Forces { .. } => Outcome::Answer(forces::table(&snapshot)),
                Then::Debug { unbroken, devices, until_paused } => {
                    self.debug_outcome(unbroken, devices, until_paused, &snapshot)
                }
                // Answered at their completion: never waiting for a capture.
                Then::Mode | Then::Written { .. } | Then::Loaded { .. } => continue,
            };
            match outcome {
                Outcome::Answer(answer) => ready.push((client, answer)),
                Outcome::Wait { then, again: ask } => {
                    self.waiting.push(Waiting {
                        client,
                        since: waiting.since,
                        stage: Stage::Snapshot { after: generation },
                        then,
                    });
                    again |= ask;
                }
                Outcome::Send { commands, then } => {
                    sends.push((client, waiting.since, commands, then))
                }
            }
        }
        self.fresh_until = Some((generation, Instant::now() + super::STATUS_MAX_AGE));
        drop(snapshot);
        for (client, since, commands, then) in sends {
            match self.send(commands) {
                Ok(tickets) => {
                    let stage = Stage::Commands { tickets, applied: None, refused: None };
                    self.waiting.push(Waiting { client, since, stage, then });
                }
                Err(f) => ready.push((client, ResponseLine::failure(f))),
            }
        }
        if again {
            self.want_snapshot();
        }
    }
}
