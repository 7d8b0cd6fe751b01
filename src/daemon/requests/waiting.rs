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

use super::devices::{self, word_of};
use super::{debugger, failure, forces, mode, RequestHandler, Running, ANSWER_TIMEOUT, STEP_POLL};
use crate::device::Address;
use crate::drivers::real_time::snapshot::MAX_READ_WORDS;
use crate::drivers::real_time::{pending, Applied, Command, Completion, ControlCommand};
use crate::engine::Refusal;
use crate::services::control::ClientId;
use plcd_ipc::{ErrorKind as Kind, Failure, Reply, ResponseLine};

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

impl Then {
    /// The devices the answer reads from the snapshot.
    fn devices(&self) -> &[Address] {
        match self {
            Then::Values { devices } => devices,
            Then::Debug { devices: Some(devices), .. } => devices,
            _ => &[],
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
}

impl RequestHandler {
    /// Queues control commands; their tickets, or `busy` when the queue is full.
    pub(super) fn send(&mut self, commands: Vec<ControlCommand>) -> Result<Vec<u64>, Failure> {
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

    /// Asks for a capture of every word the waiting requests need.
    fn want_snapshot(&mut self) {
        self.last_want = Instant::now();
        if let Ok(mut snapshot) = self.links.snapshot.lock() {
            let mut len = 0;
            for waiting in &self.waiting {
                for device in waiting.then.devices() {
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
            Then::Forces { unforced: Some(address) } if !applied.changed => {
                forces::not_forced(&address)
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
            let needs = self.waiting[index].then.devices();
            if needs.iter().any(|d| snapshot.word(word_of(d)).is_none()) {
                // Another request's words filled the capture: next round.
                self.waiting[index].stage = Stage::Snapshot { after: generation };
                again = true;
                index += 1;
                continue;
            }
            let waiting = self.waiting.swap_remove(index);
            let client = waiting.client;
            let outcome = match waiting.then {
                Then::Status => Outcome::Answer(ResponseLine::ok(Reply::Status(Box::new(
                    self.status(&snapshot),
                )))),
                Then::Values { devices } => Outcome::Answer(devices::values(&devices, &snapshot)),
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
            }
        }
        self.fresh_until = Some((generation, Instant::now() + super::STATUS_MAX_AGE));
        drop(snapshot);
        if again {
            self.want_snapshot();
        }
    }
}
