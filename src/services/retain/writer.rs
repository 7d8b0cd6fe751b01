//! The retain writer: not real time, never in the scan thread's way.
//!
//! Every `interval_ms` (or at once when asked: STOP) it asks the scan thread for a copy of the
//! retained words and variables through its [`Mirror`] — taken at the next scan boundary, after
//! END, so the copy is one scan's consistent state — and writes it to the older generation file
//! if it differs from the last one written. A failing write (full disk, read-only file system) is
//! logged once per condition; the next interval tries again, and success is logged once.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{RetainError, Store};
use crate::device::RetainedWords;
use crate::drivers::real_time::mirror::Mirror;
use crate::drivers::real_time::{pending, Shared};
use crate::vm::retained::{RetainedVariables, SavedVariable};

/// How long the writer waits for the scan thread's copy before trying again at the next
/// interval (a scan lasts at most the watchdog time, 1 s).
const COPY_TIMEOUT: Duration = Duration::from_secs(2);

/// Figures of the writer, for the log and the bench.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WriterStats {
    pub writes: u64,
    pub failures: u64,
    pub bytes_per_write: usize,
    pub longest_write: Duration,
}

/// The writing state: the files, what was written last and where the next write goes. The
/// thread owns it while it runs; the daemon's main thread takes it back for the final write.
pub struct Writer {
    store: Store,
    ranges: Box<[RetainedWords]>,
    next_slot: usize,
    next_seq: u64,
    /// The words of the last acknowledged (durably written) generation.
    last: Option<Vec<u16>>,
    /// Its variables section.
    last_variables: Vec<u8>,
    /// The variables section being written.
    variables: Vec<u8>,
    buf: Vec<u8>,
    /// The condition of the failing writes, while they fail.
    failing: Option<String>,
    pub stats: WriterStats,
}

impl Writer {
    /// `last`: the words restored at start (the file already holds them), if any.
    pub fn new(
        store: Store,
        ranges: &[RetainedWords],
        next_slot: usize,
        next_seq: u64,
        last: Option<Vec<u16>>,
    ) -> Writer {
        Writer {
            store,
            ranges: ranges.into(),
            next_slot,
            next_seq,
            last,
            last_variables: Vec::new(),
            variables: Vec::new(),
            buf: Vec::new(),
            failing: None,
            stats: WriterStats::default(),
        }
    }

    /// The variables the restored generation held (the file already holds them).
    pub fn with_last_variables(mut self, saved: &[SavedVariable]) -> Writer {
        super::format::encode_saved(saved, &mut self.last_variables);
        self
    }

    /// Writes `words` (the retained ranges, range after range; masked here) and no variables
    /// unless they equal the last generation written. Ok(true) when a generation was written
    /// and is durable.
    pub fn write_if_changed(&mut self, words: &mut [u16]) -> Result<bool, RetainError> {
        self.write_state(words, None)
    }

    /// [`Writer::write_if_changed`] with the retained variables: `copy` (as
    /// [`RetainedVariables::copy`] made it) of `layout`'s records.
    pub fn write_state(
        &mut self,
        words: &mut [u16],
        variables: Option<(&RetainedVariables, &[u8])>,
    ) -> Result<bool, RetainError> {
        let mut at = 0;
        for r in self.ranges.iter() {
            for w in &mut words[at..at + r.len()] {
                *w &= r.mask;
            }
            at += r.len();
        }
        match variables {
            Some((layout, copy)) => {
                super::format::encode_records(layout, copy, &mut self.variables)
            }
            None => super::format::encode_variables(std::iter::empty(), &mut self.variables),
        }
        if self.last.as_deref() == Some(&*words) && self.last_variables == self.variables {
            return Ok(false);
        }
        let (slot, seq) = (self.next_slot, self.next_seq);
        let ms = super::unix_ms();
        super::format::encode(seq, ms, &self.ranges, words, &self.variables, &mut self.buf);
        let began = Instant::now();
        // The sequence number is used up either way: a failed write may have left it on disk.
        self.next_seq += 1;
        match self.store.write(slot, seq, &self.buf) {
            Ok(()) => {
                let took = began.elapsed();
                self.stats.writes += 1;
                self.stats.bytes_per_write = self.buf.len();
                self.stats.longest_write = self.stats.longest_write.max(took);
                self.next_slot = 1 - slot;
                match &mut self.last {
                    Some(last) => last.clone_from_slice(words),
                    None => self.last = Some(words.to_vec()),
                }
                std::mem::swap(&mut self.last_variables, &mut self.variables);
                let path = self.store.slot_path(slot);
                if self.failing.take().is_some() {
                    log::info!(
                        "retain: writing works again: wrote generation {} (seq {seq})",
                        path.display()
                    );
                } else {
                    log::debug!("retain: wrote generation {} (seq {seq})", path.display());
                }
                Ok(true)
            }
            Err(e) => {
                self.stats.failures += 1;
                let condition = e.condition();
                if self.failing.as_deref() != Some(condition.as_str()) {
                    log::error!(
                        "retain: {e}; the PLC keeps running, the last generation written stays \
                         on disk, and the writer tries again every interval (logged again only \
                         when the error changes)"
                    );
                    self.failing = Some(condition);
                }
                Err(e)
            }
        }
    }

    /// The directory and the slot the next write goes to.
    pub fn store(&self) -> &Store {
        &self.store
    }
}

#[derive(Default)]
struct Control {
    stop: bool,
    flush: bool,
}

/// The writer's thread.
pub struct WriterThread {
    handle: JoinHandle<Writer>,
    control: Arc<(Mutex<Control>, Condvar)>,
}

impl WriterThread {
    /// Starts writing every `interval` what `mirror` copies; `shared` wakes the scan thread.
    pub fn spawn(
        mut writer: Writer,
        mirror: Arc<Mirror>,
        shared: Arc<Shared>,
        interval: Duration,
    ) -> std::io::Result<WriterThread> {
        let control = Arc::new((Mutex::new(Control::default()), Condvar::new()));
        let ctl = Arc::clone(&control);
        let handle = std::thread::Builder::new()
            .name("plcd-retain".into())
            .stack_size(crate::drivers::real_time::PLAIN_THREAD_STACK)
            .spawn(move || {
                let mut seen = mirror.lock().generation;
                let mut words: Vec<u16> = Vec::with_capacity(mirror.lock().words.len());
                let mut vars: Vec<u8> = Vec::new();
                let mut layout = None;
                loop {
                    {
                        let (lock, wake) = &*ctl;
                        let guard = lock.lock().unwrap_or_else(|e| e.into_inner());
                        let (mut guard, _) = wake
                            .wait_timeout_while(guard, interval, |c| !c.stop && !c.flush)
                            .unwrap_or_else(|e| e.into_inner());
                        if guard.stop {
                            break;
                        }
                        guard.flush = false;
                    }
                    // A copy the scan thread could not take without allocating or freeing is
                    // asked for again once the image is served (each time, one more engine
                    // replaced it: this ends).
                    let mut copied = false;
                    loop {
                        mirror.request();
                        shared.signal(pending::MIRROR);
                        let mut image = mirror.wait_newer(seen, COPY_TIMEOUT);
                        let waited = image.serve_reader();
                        if image.generation != seen {
                            seen = image.generation;
                            words.clear();
                            words.extend_from_slice(&image.words);
                            vars.clear();
                            vars.extend_from_slice(&image.vars);
                            layout.clone_from(&image.layout);
                            copied = true;
                            break;
                        }
                        if !waited {
                            break;
                        }
                    }
                    if copied {
                        // Errors are logged by the writer; the next interval tries again.
                        let variables = layout.as_deref().map(|l| (l, &vars[..]));
                        let _ = writer.write_state(&mut words, variables);
                    }
                }
                writer
            })?;
        Ok(WriterThread { handle, control })
    }

    /// Asks for a write as soon as possible (STOP).
    pub fn flush(&self) {
        let (lock, wake) = &*self.control;
        lock.lock().unwrap_or_else(|e| e.into_inner()).flush = true;
        wake.notify_all();
    }

    /// Stops the thread (after the write it may be doing) and gives the writer back.
    pub fn stop(self) -> Option<Writer> {
        let (lock, wake) = &*self.control;
        lock.lock().unwrap_or_else(|e| e.into_inner()).stop = true;
        wake.notify_all();
        self.handle.join().ok()
    }
}
