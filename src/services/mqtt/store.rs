//! Store and forward on disk (`[mqtt] store_forward_dir`): the DATA messages of an outage that
//! the memory store has no room for, first in, first out, bounded by
//! `store_forward_disk_bytes` (the oldest dropped first) (docs/MQTT.md, "Faults").
//!
//! Messages are appended to segment files (`NNNNNNNN.spb`, each at most a sixteenth of the
//! bound) as records: the payload's length and its device (both `u32`, little-endian; the node
//! is `u32::MAX`), then the encoded Sparkplug payload. A whole segment is dropped when the
//! bound is passed, and read whole (then deleted) when its messages are sent. The directory is
//! emptied when the node starts: the aliases of a message belong to the births of the run that
//! stored it. A write that fails drops the message (counted) and is logged once until one
//! succeeds again.

use std::collections::VecDeque;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use prost::Message as _;

use super::edge::{Backlog, Stored};
use super::sparkplug_b::Payload;

/// The smallest segment: a segment never holds less than one message, whatever the bound.
const MIN_SEGMENT_BYTES: u64 = 16 * 1024;
const NODE: u32 = u32::MAX;
const EXTENSION: &str = "spb";

/// One segment file.
#[derive(Debug)]
struct Segment {
    path: PathBuf,
    records: u64,
    bytes: u64,
}

/// The messages on disk.
#[derive(Debug)]
pub struct DiskBacklog {
    dir: PathBuf,
    max_bytes: u64,
    segment_bytes: u64,
    /// Oldest first; the last is the one written.
    segments: VecDeque<Segment>,
    writer: Option<File>,
    next: u64,
    /// The messages of the oldest segment, read and its file deleted, not sent yet.
    reading: VecDeque<Stored>,
    /// A write failed and was logged: not again until one succeeds.
    told: bool,
}

impl DiskBacklog {
    /// The backlog in `dir` (made, 0700, if missing; its segments of an earlier run deleted),
    /// at most `max_bytes` on disk.
    pub fn open(dir: &Path, max_bytes: u64) -> io::Result<DiskBacklog> {
        use std::os::unix::fs::DirBuilderExt;
        fs::DirBuilder::new().recursive(true).mode(0o700).create(dir)?;
        for entry in fs::read_dir(dir)? {
            let path = entry?.path();
            if path.extension().is_some_and(|e| e == EXTENSION) {
                fs::remove_file(&path)?;
            }
        }
        Ok(DiskBacklog {
            dir: dir.to_path_buf(),
            max_bytes,
            segment_bytes: (max_bytes / 16).max(MIN_SEGMENT_BYTES),
            segments: VecDeque::new(),
            writer: None,
            next: 0,
            reading: VecDeque::new(),
            told: false,
        })
    }

    /// Bytes on disk now.
    pub fn bytes(&self) -> u64 {
        self.segments.iter().map(|s| s.bytes).sum()
    }

    fn append(&mut self, record: &[u8]) -> io::Result<()> {
        let full =
            self.segments.back().is_none_or(|s| s.bytes + record.len() as u64 > self.segment_bytes);
        if full || self.writer.is_none() {
            let path = self.dir.join(format!("{:08}.{EXTENSION}", self.next));
            self.next += 1;
            let file = OpenOptions::new().create_new(true).append(true).open(&path)?;
            self.writer = Some(file);
            self.segments.push_back(Segment { path, records: 0, bytes: 0 });
        }
        let (Some(writer), Some(segment)) = (&mut self.writer, self.segments.back_mut()) else {
            return Err(io::Error::other("no segment to write"));
        };
        writer.write_all(record)?;
        segment.records += 1;
        segment.bytes += record.len() as u64;
        Ok(())
    }

    /// Drops the oldest segments past the bound (never the one written); the messages dropped.
    fn bound(&mut self) -> u64 {
        let mut dropped = 0;
        while self.bytes() > self.max_bytes && self.segments.len() > 1 {
            if let Some(oldest) = self.segments.pop_front() {
                let _ = fs::remove_file(&oldest.path);
                dropped += oldest.records;
            }
        }
        dropped
    }

    /// Reads the oldest segment into `reading` and deletes its file.
    fn load_oldest(&mut self) -> io::Result<()> {
        let Some(oldest) = self.segments.pop_front() else { return Ok(()) };
        if self.segments.is_empty() {
            // The one written: a new segment takes the next message.
            self.writer = None;
        }
        let bytes = fs::read(&oldest.path);
        let _ = fs::remove_file(&oldest.path);
        let bytes = bytes?;
        let mut rest = &bytes[..];
        while rest.len() >= 8 {
            let len = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize;
            let device = u32::from_le_bytes([rest[4], rest[5], rest[6], rest[7]]);
            let Some(body) = rest.get(8..8 + len) else { break };
            if let Ok(payload) = Payload::decode(body) {
                let device = (device != NODE).then_some(device as usize);
                self.reading.push_back(Stored { device, payload });
            }
            rest = &rest[8 + len..];
        }
        Ok(())
    }
}

impl Backlog for DiskBacklog {
    fn push(&mut self, stored: Stored) -> u64 {
        let body = stored.payload.encode_to_vec();
        let device = stored.device.map_or(NODE, |d| d as u32);
        let mut record = Vec::with_capacity(8 + body.len());
        record.extend_from_slice(&(body.len() as u32).to_le_bytes());
        record.extend_from_slice(&device.to_le_bytes());
        record.extend_from_slice(&body);
        match self.append(&record) {
            Ok(()) => {
                self.told = false;
                self.bound()
            }
            Err(e) => {
                if !self.told {
                    log::warn!(
                        "mqtt: store and forward: cannot write to {}: {e}; messages of the \
                         outage are dropped until a write succeeds",
                        self.dir.display()
                    );
                    self.told = true;
                }
                // A segment that failed half way is not written to again.
                self.writer = None;
                1
            }
        }
    }

    fn pop(&mut self) -> Option<Stored> {
        if self.reading.is_empty() {
            if let Err(e) = self.load_oldest() {
                log::warn!(
                    "mqtt: store and forward: a segment of {} is lost: {e}",
                    self.dir.display()
                );
            }
        }
        self.reading.pop_front()
    }

    fn len(&self) -> usize {
        self.reading.len() + self.segments.iter().map(|s| s.records as usize).sum::<usize>()
    }

    fn clear(&mut self) -> u64 {
        let count = self.len() as u64;
        for segment in self.segments.drain(..) {
            let _ = fs::remove_file(&segment.path);
        }
        self.reading.clear();
        self.writer = None;
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::services::mqtt::sparkplug_b::payload::{metric::Value as Wire, Metric};

    fn message(n: u64, device: Option<usize>) -> Stored {
        let metric =
            Metric { alias: Some(9), value: Some(Wire::LongValue(n)), ..Metric::default() };
        Stored {
            device,
            payload: Payload { timestamp: Some(n), metrics: vec![metric], ..Payload::default() },
        }
    }

    fn dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("plcd-mqtt-store-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn messages_come_back_in_order_and_the_files_go() {
        let dir = dir("order");
        let mut store = DiskBacklog::open(&dir, 1 << 18).unwrap();
        for n in 0..1000 {
            assert_eq!(store.push(message(n, if n % 2 == 0 { None } else { Some(3) })), 0);
        }
        assert_eq!(store.len(), 1000);
        assert!(store.segments.len() > 1, "several segments of 16 KiB");
        for n in 0..1000 {
            let stored = store.pop().unwrap();
            assert_eq!(stored, message(n, if n % 2 == 0 { None } else { Some(3) }), "{n}");
            if n == 500 {
                // Pushed while reading: after the older ones.
                store.push(message(5000, None));
            }
        }
        assert_eq!(store.pop(), Some(message(5000, None)));
        assert_eq!(store.pop(), None);
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 0, "every segment deleted once sent");
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn past_the_bound_the_oldest_segments_are_dropped() {
        let dir = dir("bound");
        let bound = 65_536;
        let mut store = DiskBacklog::open(&dir, bound).unwrap();
        let mut dropped = 0;
        for n in 0..20_000 {
            dropped += store.push(message(n, None));
        }
        assert!(store.bytes() <= bound + MIN_SEGMENT_BYTES, "{}", store.bytes());
        assert_eq!(dropped + store.len() as u64, 20_000, "every message kept or counted");
        let first = store.pop().unwrap().payload.timestamp.unwrap();
        assert_eq!(first, dropped, "the oldest went first");
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn an_earlier_run_s_segments_are_deleted_at_start_and_clear_drops_everything() {
        let dir = dir("start");
        let mut store = DiskBacklog::open(&dir, 1 << 20).unwrap();
        store.push(message(1, None));
        drop(store);
        let mut store = DiskBacklog::open(&dir, 1 << 20).unwrap();
        assert_eq!((store.len(), store.pop()), (0, None));
        store.push(message(2, None));
        store.push(message(3, None));
        assert_eq!(store.clear(), 2);
        assert_eq!(store.pop(), None);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_write_that_fails_drops_the_message() {
        let dir = dir("fail");
        let mut store = DiskBacklog::open(&dir, 1 << 20).unwrap();
        fs::remove_dir_all(&dir).unwrap();
        assert_eq!(store.push(message(1, None)), 1, "counted as dropped");
        fs::create_dir_all(&dir).unwrap();
        assert_eq!(store.push(message(2, None)), 0, "a write succeeds again");
        assert_eq!(store.pop(), Some(message(2, None)));
        let _ = fs::remove_dir_all(&dir);
    }
}
