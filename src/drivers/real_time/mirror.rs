//! Copies of chosen device words for the threads off the real-time path (the retain writer,
//! the Modbus server, the OPC UA server), taken by the scan thread at a scan boundary.
//!
//! A consumer asks for a copy ([`Mirror::request`]) and wakes the scan thread
//! ([`super::Shared::signal`] with [`super::pending::MIRROR`]); at the next scan boundary (after
//! END, or at once in STOP, ERROR or a paused DEBUG) the scan thread copies the mirror's word
//! ranges into its image and notifies the waiting consumers. The image lives behind a mutex the
//! scan thread only ever `try_lock`s: if a consumer holds it, the copy waits for the next
//! boundary, so the scan never waits. The image is allocated once; copying allocates nothing.
//!
//! Word ranges are indices into [`crate::device::Memory::words`]: the device layout is fixed,
//! so they stay valid when the engine is replaced (a reload, an online change).
//!
//! A mirror made [`Mirror::with_variables`] (the retain writer's) also copies the engine's
//! retained Structured Text variables ([`crate::vm::retained::RetainedVariables`]), whose
//! layout does change with the engine: the image holds the layout of its copy (an `Arc` the
//! engine shares). The scan thread neither allocates nor frees for it: a copy that would need
//! a larger buffer, or would drop the last reference to a replaced layout, is not taken; the
//! image says why ([`MirrorImage::waiting_for_reader`]) and the consumer, woken, makes room or
//! drops the replaced layout ([`MirrorImage::serve_reader`]) and asks again.
//!
//! A mirror made [`Mirror::with_all_variables`] (the OPC UA server's) copies the variable memory
//! instead, as bytes at their own offsets, so that every Structured Text variable, struct and
//! array of one image is as of the same scan boundary: the whole of it, or, once the consumer
//! said which bytes it reads for the engine that runs ([`Mirror::serve_only`]), those bytes
//! alone (the rest of the image keeps what an earlier copy left); the same rules keep the scan thread from allocating
//! (room for a larger memory) and from freeing (the replaced engine's layout, which tells the
//! consumer that the engine, and maybe its variables' places, changed). Every image also
//! carries the engine's error and key switch, for the status the OPC UA server shows.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use crate::engine::event::{ErrorKind, Mode};
use crate::engine::Engine;
use crate::io::SwitchPosition;
use crate::vm::retained::RetainedVariables;

/// Which Structured Text variables a mirror copies besides its words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Variables {
    None,
    /// The retained ones ([`RetainedVariables::copy`]).
    Retained,
    /// The whole variable memory, byte for byte.
    All,
}

/// Byte ranges of variable memory, sorted, not overlapping ([`byte_ranges`]).
pub type ServedBytes = Arc<[Range<u32>]>;

/// Engines whose served bytes a mirror keeps ([`MirrorImage::served`]): the one served now and
/// four announced.
pub const SERVED_KEPT: usize = 5;

/// Drops the oldest announcements (after the first entry, the engine served now) beyond
/// [`SERVED_KEPT`] entries. Consumer side: what it drops is freed there, never on the scan
/// thread.
fn keep_served_bounded(served: &mut Vec<(Arc<RetainedVariables>, ServedBytes)>) {
    while served.len() > SERVED_KEPT {
        served.remove(1);
    }
}

/// A set of device word ranges copied at scan boundaries on request.
pub struct Mirror {
    ranges: Box<[Range<u16>]>,
    /// The variables it copies too.
    variables: Variables,
    wanted: AtomicBool,
    image: Mutex<MirrorImage>,
    fresh: Condvar,
}

/// The mirrored words as of one scan boundary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MirrorImage {
    /// Bumped by each copy; 0 before the first.
    pub generation: u64,
    /// When it was taken (CLOCK_MONOTONIC ns).
    pub at_ns: u64,
    /// Scans since RUN at that boundary.
    pub scans: u64,
    pub mode: Mode,
    /// The engine's error as `plcctl status` shows it: the latched one in ERROR, else the
    /// last operation error since RUN.
    pub error: Option<ErrorKind>,
    /// The key switch's position, with a `[switch]`.
    pub switch: Option<SwitchPosition>,
    /// The words of every range, range after range, in the order given to [`Mirror::new`].
    pub words: Box<[u16]>,
    /// The retained variables' bytes ([`RetainedVariables::copy`]) of a mirror made
    /// [`Mirror::with_variables`], the whole variable memory of one made
    /// [`Mirror::with_all_variables`]; empty for the others.
    pub vars: Vec<u8>,
    /// The layout of `vars`: the copied engine's retained variables (for a mirror of all
    /// variables: which engine they are of).
    pub layout: Option<Arc<RetainedVariables>>,
    /// The layout a copy replaced, for the consumer to drop (the scan thread never frees).
    pub replaced: Option<Arc<RetainedVariables>>,
    /// Bytes `vars` must have room for before the next copy can be taken (0: enough).
    pub room: usize,
    /// For a mirror of all variables: the byte ranges of variable memory to copy for the engines
    /// of these layouts, the one served first ([`Mirror::serve_only`]), then engines announced
    /// and not yet served ([`Mirror::serve_also`]), at most [`SERVED_KEPT`] in all; for
    /// another engine the whole memory is copied.
    pub served: Vec<(Arc<RetainedVariables>, ServedBytes)>,
    /// A copy was not taken until the consumer serves the image ([`MirrorImage::serve_reader`]).
    pub waiting_for_reader: bool,
}

impl MirrorImage {
    /// Consumer side, with the image locked: reserves the room a copy needs and drops a
    /// replaced layout, so that the next copy is taken. True if a copy waited for it.
    pub fn serve_reader(&mut self) -> bool {
        if self.room > self.vars.capacity() {
            self.vars.reserve(self.room - self.vars.len());
        }
        self.room = 0;
        self.replaced = None;
        std::mem::take(&mut self.waiting_for_reader)
    }
}

impl Mirror {
    /// A mirror of `ranges` (word indices of device memory).
    pub fn new(ranges: impl IntoIterator<Item = Range<u16>>) -> Mirror {
        let ranges: Box<[Range<u16>]> = ranges.into_iter().collect();
        let len = ranges.iter().map(|r| r.len()).sum::<usize>();
        Mirror {
            ranges,
            variables: Variables::None,
            wanted: AtomicBool::new(false),
            image: Mutex::new(MirrorImage {
                generation: 0,
                at_ns: 0,
                scans: 0,
                mode: Mode::Stop,
                error: None,
                switch: None,
                words: vec![0; len].into_boxed_slice(),
                vars: Vec::new(),
                layout: None,
                replaced: None,
                room: 0,
                served: Vec::new(),
                waiting_for_reader: false,
            }),
            fresh: Condvar::new(),
        }
    }

    /// A mirror of `ranges` and of the engine's retained variables (the retain writer's).
    pub fn with_variables(ranges: impl IntoIterator<Item = Range<u16>>) -> Mirror {
        Mirror { variables: Variables::Retained, ..Mirror::new(ranges) }
    }

    /// A mirror of `ranges` and of the engine's whole variable memory (the OPC UA server's).
    pub fn with_all_variables(ranges: impl IntoIterator<Item = Range<u16>>) -> Mirror {
        Mirror { variables: Variables::All, ..Mirror::new(ranges) }
    }

    /// Before the scan thread starts: room for `layout`'s copies, and `layout` as the image's,
    /// so that the first copies need nothing from the consumer.
    pub fn prepare(&self, layout: &Arc<RetainedVariables>, variable_bytes: usize) {
        let mut image = self.lock();
        let need = match self.variables {
            Variables::All => variable_bytes,
            Variables::Retained | Variables::None => layout.bytes(),
        };
        let len = image.vars.len();
        image.vars.reserve(need.saturating_sub(len));
        image.layout = Some(Arc::clone(layout));
    }

    /// Consumer side: for the engine of `layout`, the one the consumer serves now, copy only the
    /// bytes `ranges` of variable memory (sorted, not overlapping: [`byte_ranges`] makes them).
    /// Taken by the copies from the next scan boundary of that engine on. Engines announced
    /// after it ([`Mirror::serve_also`]) keep their ranges; the others' are dropped.
    pub fn serve_only(&self, layout: &Arc<RetainedVariables>, ranges: ServedBytes) {
        let mut image = self.lock();
        let served = &mut image.served;
        // Those before it: the engine served until now, and announcements older than this one's.
        let announced_after =
            served.iter().position(|(l, _)| Arc::ptr_eq(l, layout)).map_or(0, |at| at + 1);
        served.drain(..announced_after);
        served.insert(0, (Arc::clone(layout), ranges));
        keep_served_bounded(served);
    }

    /// Consumer side: for the engine of `layout`, announced and not yet running, copy only the
    /// bytes `ranges` from its first scan boundary on (without it, the copies of a new engine
    /// take its whole variable memory until the consumer has seen one and called
    /// [`Mirror::serve_only`]). The oldest announcement goes beyond [`SERVED_KEPT`] entries;
    /// the engine served now stays.
    pub fn serve_also(&self, layout: &Arc<RetainedVariables>, ranges: ServedBytes) {
        let mut image = self.lock();
        let served = &mut image.served;
        served.retain(|(l, _)| !Arc::ptr_eq(l, layout));
        served.push((Arc::clone(layout), ranges));
        keep_served_bounded(served);
    }

    pub fn ranges(&self) -> &[Range<u16>] {
        &self.ranges
    }

    /// Asks for a copy at the next scan boundary. The caller then wakes the scan thread:
    /// `shared.signal(pending::MIRROR)`.
    pub fn request(&self) {
        self.wanted.store(true, Ordering::Release);
    }

    /// A copy was asked for and not taken yet.
    pub fn is_wanted(&self) -> bool {
        self.wanted.load(Ordering::Acquire)
    }

    /// The last image, whatever its age.
    pub fn lock(&self) -> MutexGuard<'_, MirrorImage> {
        self.image.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Waits until the image is newer than generation `than`, or waits for the reader
    /// ([`MirrorImage::waiting_for_reader`]), at most `timeout`. Returns the image either way:
    /// the caller compares its generation to know which happened.
    pub fn wait_newer(&self, than: u64, timeout: Duration) -> MutexGuard<'_, MirrorImage> {
        let until = Instant::now() + timeout;
        let mut image = self.lock();
        while image.generation <= than && !image.waiting_for_reader {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            image = match self.fresh.wait_timeout(image, left) {
                Ok((image, _)) => image,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        image
    }

    /// Scan thread, at a scan boundary: copies the ranges out of `words` if a copy was asked
    /// for and no reader holds the image. True if it copied.
    pub fn capture(&self, words: &[u16], scans: u64, mode: Mode, now_ns: u64) -> bool {
        self.capture_with_variables(words, None, scans, mode, now_ns)
    }

    /// Scan thread, at a scan boundary: [`Mirror::capture`] of `engine`'s device memory and,
    /// for a mirror [`Mirror::with_variables`], of its retained variables.
    pub fn capture_engine(&self, engine: &Engine, now_ns: u64) -> bool {
        let (vm, layout) = (engine.vm(), engine.retained_variables());
        let variables = Some((layout, vm.vars()));
        let words = vm.mem.words();
        let mode = engine.mode();
        let error = match mode {
            Mode::Error => engine.latched_error(),
            _ => engine.last_operation_error(),
        };
        let status = Status { scans: engine.scan_count(), mode, error, switch: engine.switch() };
        self.capture_status(words, variables, status, now_ns)
    }

    /// [`Mirror::capture`] with the retained variables `variables` (their layout and variable
    /// memory), for a mirror [`Mirror::with_variables`]. Not taken (false, and the request
    /// withdrawn) when the image needs the consumer first — room for a larger layout, or a
    /// replaced layout to drop: the consumer is woken to serve it and ask again.
    pub fn capture_with_variables(
        &self,
        words: &[u16],
        variables: Option<(&Arc<RetainedVariables>, &[u8])>,
        scans: u64,
        mode: Mode,
        now_ns: u64,
    ) -> bool {
        let status = Status { scans, mode, error: None, switch: None };
        self.capture_status(words, variables, status, now_ns)
    }

    fn capture_status(
        &self,
        words: &[u16],
        variables: Option<(&Arc<RetainedVariables>, &[u8])>,
        status: Status,
        now_ns: u64,
    ) -> bool {
        if !self.wanted.load(Ordering::Acquire) {
            return false;
        }
        let Ok(mut image) = self.image.try_lock() else {
            return false;
        };
        if let (Variables::Retained | Variables::All, Some((layout, vars))) =
            (self.variables, variables)
        {
            let need = match self.variables {
                Variables::All => vars.len(),
                Variables::Retained | Variables::None => layout.bytes(),
            };
            let new_layout = !image.layout.as_ref().is_some_and(|l| Arc::ptr_eq(l, layout));
            if need > image.vars.capacity() || (new_layout && image.replaced.is_some()) {
                // Not without allocating or freeing: the consumer makes room first, then asks
                // again (the request is withdrawn, so the scan thread does not spin on it).
                image.room = image.room.max(need);
                image.waiting_for_reader = true;
                self.wanted.store(false, Ordering::Release);
                drop(image);
                self.fresh.notify_all();
                return false;
            }
            if new_layout {
                image.replaced = image.layout.replace(Arc::clone(layout));
            }
            let only = image
                .served
                .iter()
                .find(|(served, _)| Arc::ptr_eq(served, layout))
                .map(|(_, ranges)| Arc::clone(ranges));
            match (self.variables, only) {
                (Variables::All, Some(ranges)) => {
                    // The consumer's bytes alone, at their own offsets. Within the capacity
                    // checked above: no allocation; the `Arc` clone is a count, and the image
                    // still holds it, so nothing is freed here.
                    if image.vars.len() != vars.len() {
                        image.vars.clear();
                        image.vars.resize(vars.len(), 0);
                    }
                    for range in ranges.iter() {
                        let end = (range.end as usize).min(vars.len());
                        let start = (range.start as usize).min(end);
                        image.vars[start..end].copy_from_slice(&vars[start..end]);
                    }
                }
                // Within the capacity checked above: no allocation.
                (Variables::All, None) => {
                    image.vars.clear();
                    image.vars.extend_from_slice(vars);
                }
                (Variables::Retained | Variables::None, _) => {
                    image.vars.clear();
                    layout.copy(vars, &mut image.vars);
                }
            }
        }
        let mut at = 0;
        for range in self.ranges.iter() {
            let source = &words[usize::from(range.start)..usize::from(range.end)];
            image.words[at..at + source.len()].copy_from_slice(source);
            at += source.len();
        }
        image.generation += 1;
        image.at_ns = now_ns;
        image.scans = status.scans;
        image.mode = status.mode;
        image.error = status.error;
        image.switch = status.switch;
        self.wanted.store(false, Ordering::Release);
        drop(image);
        self.fresh.notify_all();
        true
    }
}

/// Byte ranges of variable memory covering `pieces` (start, length), sorted, merged where they
/// touch or lie closer than `gap` bytes (one copy of a few bytes more is cheaper than two), for
/// [`Mirror::serve_only`].
pub fn byte_ranges(pieces: impl IntoIterator<Item = (u32, u32)>, gap: u32) -> ServedBytes {
    let mut pieces: Vec<Range<u32>> =
        pieces.into_iter().map(|(start, len)| start..start.saturating_add(len)).collect();
    pieces.sort_by_key(|r| r.start);
    let mut merged: Vec<Range<u32>> = Vec::with_capacity(pieces.len());
    for piece in pieces {
        match merged.last_mut() {
            Some(last) if piece.start <= last.end.saturating_add(gap) => {
                last.end = last.end.max(piece.end)
            }
            _ => merged.push(piece),
        }
    }
    merged.into()
}

/// What an image records of the engine besides memory.
#[derive(Clone, Copy)]
struct Status {
    scans: u64,
    mode: Mode,
    error: Option<ErrorKind>,
    switch: Option<SwitchPosition>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_its_ranges_in_order_only_when_asked() {
        let mirror = Mirror::new([4..6, 1..2]);
        let words: Vec<u16> = (0..10).map(|i| i * 10).collect();
        assert!(!mirror.capture(&words, 1, Mode::Run, 5), "nobody asked");
        assert_eq!(mirror.lock().generation, 0);
        mirror.request();
        assert!(mirror.capture(&words, 7, Mode::Run, 9));
        let image = mirror.lock();
        assert_eq!(&*image.words, &[40, 50, 10]);
        assert_eq!((image.generation, image.scans, image.at_ns), (1, 7, 9));
        drop(image);
        assert!(!mirror.is_wanted());
    }

    fn layout(names: &[&str]) -> Arc<RetainedVariables> {
        use crate::value::{Elem, Pointer, Space, Symbol, ValueType};
        let symbols = (0..names.len() as u32)
            .map(|i| Symbol {
                name: names[i as usize].into(),
                ty: ValueType::Signed(Elem::I16),
                at: Pointer { space: Space::Var, offset: 2 * i },
                retain: true,
                constant: false,
            })
            .collect();
        let variables =
            crate::lang::Variables { initial: vec![0; 16].into(), symbols, ..Default::default() };
        Arc::new(RetainedVariables::new(&variables))
    }

    #[test]
    fn copies_the_retained_variables_with_the_words() {
        let mirror = Mirror::with_variables(std::iter::once(1..2));
        let one = layout(&["a", "b"]);
        mirror.prepare(&one, 0);
        let vars: Vec<u8> = (10..26).collect();
        mirror.request();
        assert!(mirror.capture_with_variables(&[5, 6], Some((&one, &vars)), 1, Mode::Run, 1));
        let image = mirror.lock();
        assert_eq!((&*image.words, &image.vars[..]), (&[6][..], &[10, 11, 12, 13][..]));
        assert!(Arc::ptr_eq(image.layout.as_ref().unwrap(), &one));
        assert!(image.replaced.is_none());
        drop(image);
        // A mirror without variables ignores them.
        let plain = Mirror::new(std::iter::once(0..1));
        plain.request();
        assert!(plain.capture_with_variables(&[5], Some((&one, &vars)), 1, Mode::Run, 1));
        assert!(plain.lock().vars.is_empty() && plain.lock().layout.is_none());
    }

    #[test]
    fn a_new_layout_waits_for_the_reader_to_make_room_and_to_drop_the_replaced_one() {
        let mirror = Mirror::with_variables(std::iter::once(0..1));
        let (one, two, three) =
            (layout(&["a"]), layout(&["a", "b", "c", "d", "e"]), layout(&["c"]));
        mirror.prepare(&one, 0);
        let vars: Vec<u8> = (0..16).collect();
        let copy = |l: &Arc<RetainedVariables>| {
            mirror.request();
            mirror.capture_with_variables(&[0], Some((l, &vars)), 1, Mode::Run, 1)
        };
        assert!(copy(&one));
        // Larger than the image's room: not taken, the reader is asked for room.
        assert!(!copy(&two));
        {
            let mut image = mirror.lock();
            assert_eq!((image.room, image.waiting_for_reader), (10, true));
            assert!(image.serve_reader(), "a copy waited");
            assert!(image.vars.capacity() >= 10);
            assert!(!image.serve_reader(), "served");
        }
        assert!(!mirror.is_wanted(), "withdrawn: the scan thread does not spin on it");
        assert!(copy(&two));
        assert_eq!(&mirror.lock().vars[..], &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]);
        assert!(Arc::ptr_eq(mirror.lock().replaced.as_ref().unwrap(), &one));
        // Another layout before the reader took the replaced one: the scan thread would free
        // it, so the copy waits.
        assert!(!copy(&three));
        assert!(mirror.lock().waiting_for_reader);
        assert_eq!(Arc::strong_count(&one), 2, "the test's and the image's");
        assert!(mirror.lock().serve_reader());
        assert_eq!(Arc::strong_count(&one), 1, "dropped by the reader");
        assert!(copy(&three));
        assert_eq!(&mirror.lock().vars[..], &[0, 1]);
    }

    #[test]
    fn a_mirror_of_all_variables_copies_the_whole_memory_and_waits_for_room() {
        let mirror = Mirror::with_all_variables(std::iter::once(0..1));
        let one = layout(&["a"]);
        mirror.prepare(&one, 4);
        let copy = |vars: &[u8]| {
            mirror.request();
            mirror.capture_with_variables(&[7], Some((&one, vars)), 1, Mode::Run, 1)
        };
        assert!(copy(&[1, 2, 3, 4]));
        let image = mirror.lock();
        assert_eq!((&image.vars[..], image.words[0]), (&[1, 2, 3, 4][..], 7));
        drop(image);
        // A larger memory (another engine's) than the room made: the reader makes room first.
        assert!(!copy(&[9; 100]));
        assert_eq!(mirror.lock().room, 100);
        assert!(mirror.lock().serve_reader());
        assert!(copy(&[9; 100]));
        assert_eq!(&mirror.lock().vars[..], &[9; 100]);
    }

    #[test]
    fn a_mirror_of_all_variables_copies_only_the_served_bytes_of_their_engine() {
        let mirror = Mirror::with_all_variables(std::iter::empty());
        let (one, two) = (layout(&["a"]), layout(&["b"]));
        mirror.prepare(&one, 8);
        mirror.serve_only(&one, byte_ranges([(1, 2), (6, 1)], 0));
        let copy = |layout: &Arc<RetainedVariables>, vars: &[u8]| {
            mirror.request();
            mirror.capture_with_variables(&[], Some((layout, vars)), 1, Mode::Run, 1)
        };
        assert!(copy(&one, &[1, 2, 3, 4, 5, 6, 7, 8]));
        assert_eq!(&mirror.lock().vars[..], &[0, 2, 3, 0, 0, 0, 7, 0], "at their own offsets");
        assert!(copy(&one, &[9; 8]));
        assert_eq!(&mirror.lock().vars[..], &[0, 9, 9, 0, 0, 0, 9, 0], "the rest left as it was");
        // Another engine: the whole memory, until the reader says which bytes it reads.
        mirror.lock().serve_reader();
        assert!(copy(&two, &[5; 8]));
        assert_eq!(&mirror.lock().vars[..], &[5; 8]);
    }

    #[test]
    fn an_engine_announced_before_it_runs_is_copied_by_its_served_bytes_from_its_first_copy() {
        let mirror = Mirror::with_all_variables(std::iter::empty());
        let (one, two) = (layout(&["a"]), layout(&["b"]));
        mirror.prepare(&one, 8);
        mirror.serve_only(&one, byte_ranges([(0, 1)], 0));
        mirror.serve_also(&two, byte_ranges([(7, 1)], 0));
        let copy = |layout: &Arc<RetainedVariables>, vars: &[u8]| {
            mirror.request();
            mirror.capture_with_variables(&[], Some((layout, vars)), 1, Mode::Run, 1)
        };
        assert!(copy(&one, &[1; 8]));
        assert_eq!(&mirror.lock().vars[..], &[1, 0, 0, 0, 0, 0, 0, 0], "the served engine's");
        mirror.lock().serve_reader();
        assert!(copy(&two, &[2; 8]));
        assert_eq!(&mirror.lock().vars[..], &[1, 0, 0, 0, 0, 0, 0, 2], "the announced one's");
        // Served now: the engine before it goes, as would older announcements.
        mirror.serve_only(&two, byte_ranges([(7, 1)], 0));
        let served: Vec<_> = mirror.lock().served.iter().map(|(l, _)| Arc::clone(l)).collect();
        assert_eq!(served.len(), 1);
        assert!(Arc::ptr_eq(&served[0], &two));
    }

    #[test]
    fn served_bytes_are_kept_for_the_served_engine_and_the_newest_announcements() {
        let mirror = Mirror::with_all_variables(std::iter::empty());
        let layouts: Vec<_> = (0..8).map(|i| layout(&[&format!("v{i}")])).collect();
        mirror.serve_only(&layouts[0], byte_ranges([(0, 1)], 0));
        for announced in &layouts[1..] {
            mirror.serve_also(announced, byte_ranges([(0, 1)], 0));
        }
        let served: Vec<_> = mirror.lock().served.iter().map(|(l, _)| Arc::clone(l)).collect();
        assert_eq!(served.len(), SERVED_KEPT);
        assert!(Arc::ptr_eq(&served[0], &layouts[0]), "the engine served now stays");
        for (kept, announced) in served[1..].iter().zip(&layouts[4..]) {
            assert!(Arc::ptr_eq(kept, announced), "the newest announcements, in order");
        }
        // Announced again: moved to the newest place, not kept twice.
        mirror.serve_also(&layouts[5], byte_ranges([(0, 1)], 0));
        let served: Vec<_> = mirror.lock().served.iter().map(|(l, _)| Arc::clone(l)).collect();
        assert_eq!(served.len(), SERVED_KEPT);
        assert!(Arc::ptr_eq(&served[SERVED_KEPT - 1], &layouts[5]));
    }

    #[test]
    fn byte_ranges_are_sorted_and_merged_across_small_gaps() {
        let ranges = byte_ranges([(100, 4), (0, 2), (3, 1), (40, 8), (104, 2)], 2);
        assert_eq!(&ranges[..], &[0..4, 40..48, 100..106]);
        assert_eq!(&byte_ranges([(0, 2), (3, 1)], 0)[..], &[0..2, 3..4], "a gap kept");
        assert!(byte_ranges([], 64).is_empty());
    }

    #[test]
    fn a_reader_holding_the_image_defers_the_copy_to_the_next_boundary() {
        let mirror = Mirror::new(std::iter::once(0..1));
        mirror.request();
        let held = mirror.lock();
        assert!(!mirror.capture(&[3], 1, Mode::Run, 1));
        drop(held);
        assert!(mirror.is_wanted(), "the request is still open");
        assert!(mirror.capture(&[3], 2, Mode::Run, 2));
        assert_eq!(mirror.lock().words[0], 3);
    }

    #[test]
    fn wait_newer_returns_the_fresh_image_or_the_old_one_at_the_timeout() {
        let mirror = std::sync::Arc::new(Mirror::new(std::iter::once(0..1)));
        let stale = mirror.wait_newer(0, Duration::from_millis(1));
        assert_eq!(stale.generation, 0);
        drop(stale);
        mirror.request();
        let scan = {
            let mirror = std::sync::Arc::clone(&mirror);
            std::thread::spawn(move || while !mirror.capture(&[42], 1, Mode::Run, 1) {})
        };
        let image = mirror.wait_newer(0, Duration::from_secs(60));
        assert_eq!((image.generation, image.words[0]), (1, 42));
        drop(image);
        scan.join().unwrap();
    }
}
