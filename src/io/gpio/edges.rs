//! The event thread's side: the input request's edge events, read in place into a buffer
//! allocated at open, become [`InputEdge`]s; gaps in each line's sequence numbers count the
//! edges the kernel's FIFO dropped.

use std::os::fd::{AsFd, BorrowedFd};
use std::sync::Arc;

use gpiocdev::line::{EdgeEvent, EdgeKind};
use gpiocdev::Request;

use super::{GpioError, InputWire, IoOp, CONTACTS};
use crate::io::InputEdge;

/// The event thread's side: the input request's edge events, as [`InputEdge`]s.
#[derive(Debug)]
pub struct GpioEdges {
    chip: Arc<str>,
    request: Arc<Request>,
    /// Raw kernel events, read in place.
    buf: Box<[u64]>,
    /// The size of one event in `buf`.
    event_words: usize,
    map: EdgeMap,
}

impl GpioEdges {
    pub(super) fn new(
        chip: Arc<str>,
        request: Arc<Request>,
        map: EdgeMap,
        capacity: usize,
    ) -> GpioEdges {
        let event_words = request.edge_event_u64_size();
        let buf = vec![0; event_words * capacity.max(1)].into_boxed_slice();
        GpioEdges { chip, request, buf, event_words, map }
    }

    /// The input request's fd, readable when edge events are waiting (for epoll).
    pub fn as_fd(&self) -> BorrowedFd<'_> {
        self.request.as_fd()
    }

    /// Reads every edge event available now and hands each to `on_edge`, in the kernel's order.
    /// Call it when the fd is readable: the first read does not check and would block on an
    /// empty FIFO; later reads happen only if the buffer came back full and more are waiting.
    /// No allocation.
    ///
    /// Returns the number of edges handed on. Edges the kernel dropped (its FIFO overflowed)
    /// are added to [`GpioEdges::lost_edges`]; compare it before and after to log them.
    pub fn read(&mut self, on_edge: &mut impl FnMut(InputEdge)) -> Result<usize, GpioError> {
        let error = |op, source| GpioError::Io { chip: self.chip.clone(), op, source };
        let mut delivered = 0;
        loop {
            let words = self
                .request
                .read_edge_events_into_slice(&mut self.buf)
                .map_err(|e| error(IoOp::ReadEdges, e))?;
            for raw in self.buf[..words].chunks_exact(self.event_words) {
                let event = self
                    .request
                    .edge_event_from_slice(raw)
                    .map_err(|e| error(IoOp::ReadEdges, e))?;
                if let Some(edge) = self.map.edge(&event) {
                    on_edge(edge);
                    delivered += 1;
                }
            }
            if words < self.buf.len() {
                break;
            }
            if !self.request.has_edge_event().map_err(|e| error(IoOp::ReadEdges, e))? {
                break;
            }
        }
        Ok(delivered)
    }

    /// Edges the kernel dropped since open, known from gaps in the line sequence numbers.
    pub fn lost_edges(&self) -> u64 {
        self.map.lost
    }
}

/// Turns kernel edge events into [`InputEdge`]s and watches their sequence numbers. Pure.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct EdgeMap {
    /// (line offset, contact) of each edge-detecting line.
    lines: Box<[(u32, u8)]>,
    /// The last line sequence number seen per contact; the kernel counts from 0, so the first
    /// event is 1.
    last_seqno: [u32; CONTACTS],
    lost: u64,
}

impl EdgeMap {
    pub(super) fn new(inputs: &[InputWire]) -> EdgeMap {
        EdgeMap {
            lines: inputs.iter().filter_map(|i| i.edge.map(|(c, _)| (i.line.offset, c))).collect(),
            last_seqno: [0; CONTACTS],
            lost: 0,
        }
    }

    /// The edge an event reports, counting the events lost before it on its line. `None` for
    /// a line that does not detect edges (the kernel never sends one).
    fn edge(&mut self, event: &EdgeEvent) -> Option<InputEdge> {
        let &(_, contact) = self.lines.iter().find(|(offset, _)| *offset == event.offset)?;
        let last = self.last_seqno.get_mut(contact as usize)?;
        match check_seq(*last, event.line_seqno) {
            Seq::InOrder { lost } => {
                *last = event.line_seqno;
                self.lost = self.lost.saturating_add(u64::from(lost));
            }
            // Still an edge the kernel saw; just not one that moves the sequence on.
            Seq::Stale => {}
        }
        Some(InputEdge {
            contact,
            rising: event.kind == EdgeKind::Rising,
            stamp_ns: event.timestamp_ns,
        })
    }
}

/// Where a sequence number stands against the last one seen on its line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seq {
    /// Newer than `last`; `lost` events were dropped in between.
    InOrder { lost: u32 },
    /// Not newer than `last` (a repeat, or older): nothing to count.
    Stale,
}

/// Checks a line sequence number against the last one seen (0 before the first event: the
/// kernel's numbering starts at 1). The numbers are u32 and wrap; a step of more than half the
/// range is taken as going backwards.
fn check_seq(last: u32, seqno: u32) -> Seq {
    let step = seqno.wrapping_sub(last);
    if step == 0 || step > u32::MAX / 2 {
        Seq::Stale
    } else {
        Seq::InOrder { lost: step - 1 }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn event(offset: u32, line_seqno: u32, kind: EdgeKind, timestamp_ns: u64) -> EdgeEvent {
        EdgeEvent { timestamp_ns, kind, offset, seqno: line_seqno, line_seqno }
    }

    #[test]
    fn sequence_numbers() {
        // The first event of a line is 1.
        assert_eq!(check_seq(0, 1), Seq::InOrder { lost: 0 });
        // The FIFO overflowed before the first read.
        assert_eq!(check_seq(0, 4), Seq::InOrder { lost: 3 });
        assert_eq!(check_seq(7, 8), Seq::InOrder { lost: 0 });
        assert_eq!(check_seq(7, 10), Seq::InOrder { lost: 2 });
        // Wrapping around u32.
        assert_eq!(check_seq(u32::MAX, 0), Seq::InOrder { lost: 0 });
        assert_eq!(check_seq(u32::MAX - 1, 1), Seq::InOrder { lost: 2 });
        // A repeat or an older number.
        assert_eq!(check_seq(7, 7), Seq::Stale);
        assert_eq!(check_seq(7, 6), Seq::Stale);
        assert_eq!(check_seq(1, u32::MAX), Seq::Stale);
    }

    #[test]
    fn events_become_input_edges_and_gaps_count_per_line() {
        let text = "[[program]]\nfile = \"main.il\"\n\
                    [[task]]\nname = \"a\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
                    contact = \"P0000\"\nedge = \"both\"\n\
                    [[task]]\nname = \"b\"\nkind = \"io\"\nnumber = 9\npriority = 2\n\
                    contact = \"P0002\"\nedge = \"rising\"\n\
                    [io]\nbackend = \"gpiocdev\"\nchip = \"gpiochip0\"\n\
                    [[io.input]]\ndevice = \"P0000\"\nline = 10\n\
                    [[io.input]]\ndevice = \"P0002\"\nline = 12\n\
                    [[io.input]]\ndevice = \"P0010\"\nline = 3\n";
        let plan = crate::config::parse(text, Path::new("plcd.toml")).unwrap().wiring(&[]).unwrap();
        assert_eq!(&*EdgeMap::new(&plan.inputs).lines, &[(10, 0), (12, 2)]);
        let mut map = EdgeMap::new(&plan.inputs);

        let edge = map.edge(&event(10, 1, EdgeKind::Rising, 1_000)).unwrap();
        assert_eq!(edge, InputEdge { contact: 0, rising: true, stamp_ns: 1_000 });
        let edge = map.edge(&event(10, 2, EdgeKind::Falling, 2_000)).unwrap();
        assert_eq!(edge, InputEdge { contact: 0, rising: false, stamp_ns: 2_000 });
        assert_eq!(map.lost, 0);

        // Line 12 starts its own count: its first event is not a gap after line 10's.
        map.edge(&event(12, 1, EdgeKind::Rising, 3_000)).unwrap();
        assert_eq!(map.lost, 0);
        // Two of line 12's edges were dropped.
        let edge = map.edge(&event(12, 4, EdgeKind::Rising, 4_000)).unwrap();
        assert_eq!(edge.contact, 2);
        assert_eq!(map.lost, 2);
        // A late event of line 10 is still delivered, and counts nothing.
        assert!(map.edge(&event(10, 2, EdgeKind::Falling, 2_500)).is_some());
        assert_eq!(map.lost, 2);
        // A line without edge detection, or unknown: nothing.
        assert_eq!(map.edge(&event(3, 1, EdgeKind::Rising, 5_000)), None);
        assert_eq!(map.last_seqno, [2, 0, 4, 0, 0, 0, 0, 0]);
    }
}
