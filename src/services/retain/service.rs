//! Retained memory in `plcd run`: the daemon's supervisor calls these at start (read the
//! files, restore into the engine before the first RUN), at STOP (write soon), and at a clean
//! shutdown (stop the writer, write the final state from the stopped engine's memory).

use std::sync::Arc;
use std::time::Duration;

use super::writer::{Writer, WriterThread};
use super::{RetainSet, Startup, Store};
use crate::config::Config;
use crate::drivers::real_time::mirror::Mirror;
use crate::drivers::real_time::Shared;
use crate::engine::Engine;
use crate::vm::retained::list_names;

/// The names a log line lists at most (then how many more).
const NAMES_LOGGED: usize = 20;

/// The daemon's retained memory.
pub struct Persistence {
    set: RetainSet,
    mirror: Arc<Mirror>,
    interval: Duration,
    startup: Option<Startup>,
    /// Before the thread starts and after it stopped.
    writer: Option<Writer>,
    thread: Option<WriterThread>,
}

impl Persistence {
    /// Reads the files (if there is a directory) and decides what to restore. Never fails: a
    /// directory that cannot be created is logged and nothing is persisted.
    pub fn open(config: &Config) -> Persistence {
        let set = RetainSet::new(&config.retain.ranges);
        let mirror = Arc::new(Mirror::with_variables(set.words.iter().map(|w| w.range())));
        let state_directory = std::env::var("STATE_DIRECTORY").ok();
        let mut persistence = Persistence {
            mirror,
            interval: Duration::from_millis(u64::from(config.retain.interval_ms)),
            startup: None,
            writer: None,
            thread: None,
            set,
        };
        let Some(dir) = super::directory(&config.retain, state_directory.as_deref()) else {
            log::warn!(
                "retain: no directory ([retain] dir unset and no $STATE_DIRECTORY): K and the \
                 retained ranges survive STOP and RUN but not a restart of the daemon"
            );
            return persistence;
        };
        let store = match Store::open(&dir) {
            Ok(store) => store,
            Err(e) => {
                log::error!("retain: {e}; retained memory is not persisted until a restart");
                return persistence;
            }
        };
        let startup = super::startup(&store, &persistence.set, config.retain.restart);
        let writer = Writer::new(
            store,
            &persistence.set.words,
            startup.next_slot,
            startup.next_seq,
            startup.words.clone(),
        )
        .with_last_variables(&startup.variables);
        persistence.writer = Some(writer);
        persistence.startup = Some(startup);
        persistence
    }

    /// The mirror the scan thread copies the retained words into.
    pub fn mirrors(&self) -> Vec<Arc<Mirror>> {
        vec![Arc::clone(&self.mirror)]
    }

    /// Before the driver starts the engine: the restored words and variables, if any; the
    /// mirror made ready for the engine's retained variables.
    pub fn restore_into(&self, engine: &mut Engine) {
        self.mirror.prepare(engine.retained_variables(), 0);
        let Some(startup) = &self.startup else { return };
        let (Some(words), Some((path, seq))) = (&startup.words, &startup.from) else { return };
        engine.restore_retained(words);
        let plan = engine.restore_retained_variables(&startup.variables);
        log::info!(
            "retain: restored generation {} (seq {seq}, {} words, {} variables) in {:.3} ms",
            path.display(),
            words.len(),
            plan.restore.len(),
            startup.took.as_secs_f64() * 1e3
        );
        if startup.version == super::format::VERSION_1 {
            if !plan.new.is_empty() {
                log::info!(
                    "retain: {} is a version 1 file, without variables: the RETAIN variables \
                     start from their initial values",
                    path.display()
                );
            }
            return;
        }
        if !plan.dropped.is_empty() {
            log::warn!(
                "retain: {} saved variable(s) not restored, the program no longer retains them \
                 with that name and type: {}",
                plan.dropped.len(),
                list_names(&plan.dropped, NAMES_LOGGED)
            );
        }
        if !plan.new.is_empty() {
            log::info!(
                "retain: {} RETAIN variable(s) not in the file start from their initial values: \
                 {}",
                plan.new.len(),
                list_names(&plan.new, NAMES_LOGGED)
            );
        }
    }

    /// Starts the writer thread, once the driver runs.
    pub fn start(&mut self, shared: Arc<Shared>) {
        let Some(writer) = self.writer.take() else { return };
        log::info!(
            "retain: {} words to {} every {} ms while they change",
            self.set.word_count(),
            writer.store().dir().display(),
            self.interval.as_millis()
        );
        match WriterThread::spawn(writer, Arc::clone(&self.mirror), shared, self.interval) {
            Ok(thread) => self.thread = Some(thread),
            Err(e) => log::error!("retain: cannot start the writer thread: {e}; not persisted"),
        }
    }

    /// The PLC went to STOP: write without waiting for the interval.
    pub fn flush(&self) {
        if let Some(thread) = &self.thread {
            thread.flush();
        }
    }

    /// Clean shutdown, first step (the scan thread still runs): stops the writer thread.
    pub fn stop_writer(&mut self) {
        if let Some(thread) = self.thread.take() {
            self.writer = thread.stop();
        }
    }

    /// Clean shutdown, last step: writes the stopped engine's retained words if they changed.
    pub fn final_write(&mut self, engine: Option<&Engine>) {
        let Some(writer) = &mut self.writer else { return };
        let Some(engine) = engine else {
            log::warn!("retain: no engine to take the final state from; the last write stands");
            return;
        };
        let mut words = Vec::new();
        self.set.capture(engine.vm().mem.words(), &mut words);
        let (layout, mut vars) = (engine.retained_variables(), Vec::new());
        layout.copy(engine.vm().vars(), &mut vars);
        match writer.write_state(&mut words, Some((layout, &vars))) {
            Ok(true) => log::info!("retain: final state written"),
            Ok(false) => log::info!("retain: final state already on disk"),
            Err(_) => {}
        }
    }
}
