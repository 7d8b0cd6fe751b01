//! The poller's schedule, health and writes on a clock the tests set, and the scan side's
//! copies between the images and device memory.

use super::frame::{Fault, FaultKind};
use super::poller::{Job, LinkState, Notice};
use super::*;
use crate::config::{ModbusTable, OnLoss, RemoteRead, RemoteStatusBit, RemoteWrite, WriteOn};
use crate::device::Address;

const MS: u64 = 1_000_000;

fn table(kind: ModbusTable, address: u16, count: u16, device: &str) -> RemoteTable {
    let device = Address::parse(device).unwrap();
    let first = if kind.is_bits() {
        let bit = device.as_bit().unwrap();
        u32::from(bit.word) * 16 + bit.mask.trailing_zeros()
    } else {
        u32::from(device.as_word().unwrap().0)
    };
    RemoteTable { table: kind, address, count, device, first, swap_bytes: false, swap_words: false }
}

fn device() -> RemoteDevice {
    let status = Address::parse("M0100").unwrap();
    RemoteDevice {
        name: "rack1".into(),
        transport: RemoteTransport::Tcp { address: "127.0.0.1:1502".into() },
        unit_id: 1,
        period_ms: 10,
        timeout_ms: 100,
        on_loss: OnLoss::Clear,
        loss_after: 1,
        reconnect_ms: 100,
        reconnect_max_ms: 500,
        status: Some(RemoteStatusBit { device: status, bit: status.as_bit().unwrap() }),
        reads: vec![
            RemoteRead { table: table(ModbusTable::DiscreteInputs, 0, 20, "P0100"), period_ms: 10 },
            RemoteRead {
                table: table(ModbusTable::HoldingRegisters, 0, 2, "D00010"),
                period_ms: 50,
            },
        ],
        writes: vec![RemoteWrite {
            table: table(ModbusTable::Coils, 0, 4, "P0140"),
            on: WriteOn::Change { refresh_ms: 1000 },
        }],
    }
}

/// Runs the job due at `now` with `result`; a read's answer is `values`.
fn run(poller: &mut Poller, now: u64, values: &[u16], result: Result<(), Fault>) -> Job {
    let job = poller.next_job(now).expect("a job is due");
    let (_, slice) = poller.prepare(job);
    if let Job::Read(_) = job {
        slice[..values.len()].copy_from_slice(values);
    }
    // The link measures a round trip when an answer came (an exception is one).
    let round_trip = matches!(result, Ok(()) | Err(Fault::Exception(_))).then_some(1000);
    poller.finish(job, now, round_trip, result, 0);
    job
}

fn mem() -> Memory {
    Memory::default()
}

fn bit(mem: &Memory, device: &str) -> bool {
    mem.bit(Address::parse(device).unwrap().as_bit().unwrap())
}

fn word(mem: &Memory, device: &str) -> u16 {
    mem.word(Address::parse(device).unwrap().as_word().unwrap())
}

#[test]
fn reads_run_on_their_periods_and_a_missed_period_is_not_made_up() {
    let (_, mut poller) = pair_for_tests(&device());
    assert_eq!(run(&mut poller, 0, &[0, 0], Ok(())), Job::Read(0));
    assert_eq!(run(&mut poller, 0, &[0, 0], Ok(())), Job::Read(1));
    assert_eq!(poller.next_job(MS), Err(10 * MS), "the inputs are due again a period later");
    assert_eq!(run(&mut poller, 10 * MS, &[0, 0], Ok(())), Job::Read(0));
    // 35 ms late: polled once, then a period after that, not three times in a row.
    assert_eq!(run(&mut poller, 55 * MS, &[0, 0], Ok(())), Job::Read(0));
    assert_eq!(run(&mut poller, 55 * MS, &[0, 0], Ok(())), Job::Read(1));
    assert_eq!(poller.next_job(55 * MS), Err(65 * MS));
}

#[test]
fn inputs_reach_memory_whole_with_the_status_bit_once_every_table_was_read() {
    let (mut io, mut poller) = pair_for_tests(&device());
    let mut mem = mem();
    run(&mut poller, 0, &[0b1000_0000_0000_0101, 0b1001], Ok(()));
    io.refresh_inputs(&mut mem);
    assert!(bit(&mem, "P0100") && bit(&mem, "P0102") && bit(&mem, "P010F") && bit(&mem, "P0113"));
    assert!(!bit(&mem, "P0101") && !bit(&mem, "P0111") && bit(&mem, "P0110"));
    assert!(!bit(&mem, "P0114"), "bits past the table's count are not touched");
    assert!(!bit(&mem, "M0100"), "status OFF until every table has been read");
    run(&mut poller, 0, &[0x1234, 0xABCD], Ok(()));
    io.refresh_inputs(&mut mem);
    assert_eq!((word(&mem, "D00010"), word(&mem, "D00011")), (0x1234, 0xABCD));
    assert!(bit(&mem, "M0100"));
    assert!(io.is_input(Address::parse("P0113").unwrap().as_bit().unwrap()));
    assert!(!io.is_input(Address::parse("P0114").unwrap().as_bit().unwrap()));
}

#[test]
fn a_lost_device_clears_its_inputs_backs_off_and_comes_back() {
    let (mut io, mut poller) = pair_for_tests(&device());
    let stats = poller.stats();
    let mut mem = mem();
    run(&mut poller, 0, &[0xFFFF, 0xF], Ok(()));
    run(&mut poller, 0, &[7, 8], Ok(()));
    io.refresh_inputs(&mut mem);
    assert!(bit(&mem, "M0100") && bit(&mem, "P0100"));
    assert_eq!(run(&mut poller, 10 * MS, &[], Err(Fault::Timeout)), Job::Read(0));
    io.refresh_inputs(&mut mem);
    assert!(!bit(&mem, "M0100") && !bit(&mem, "P0100"));
    assert_eq!(word(&mem, "D00010"), 0, "on_loss = clear clears every table");
    assert_eq!(stats.lock().unwrap().state, LinkState::Lost);
    // Tried again after 100 ms, then 200, 400, and 500 (the most), one exchange each.
    let mut at = 10 * MS;
    for wait in [100, 200, 400, 500, 500] {
        assert_eq!(poller.next_job(at), Err(at + wait * MS));
        at += wait * MS;
        assert_eq!(run(&mut poller, at, &[], Err(Fault::Timeout)), Job::Read(0));
    }
    let notices = poller.take_notices();
    assert_eq!(
        notices,
        [
            Notice::Fault {
                ask: frame::Ask::read(&device().reads[0].table),
                fault: Fault::Timeout
            },
            Notice::Lost { failures: 1, on_loss: OnLoss::Clear },
        ],
        "one line for the fault and one for the loss, not one a poll"
    );
    // Back: every table is read again at once, and the status waits for all of them.
    assert_eq!(run(&mut poller, at + 600 * MS, &[1, 0], Ok(())), Job::Read(0));
    io.refresh_inputs(&mut mem);
    assert!(!bit(&mem, "M0100"));
    assert_eq!(run(&mut poller, at + 601 * MS, &[5, 6], Ok(())), Job::Read(1));
    io.refresh_inputs(&mut mem);
    assert!(bit(&mem, "M0100") && bit(&mem, "P0100"));
    assert!(matches!(poller.take_notices()[..], [Notice::Back { failures: 6, lost_ms: Some(_) }]));
    let stats = stats.lock().unwrap().clone();
    assert_eq!((stats.requests, stats.failures, stats.losses), (10, 6, 1));
    assert_eq!(
        stats.by_kind[FaultKind::ALL.iter().position(|&k| k == FaultKind::Timeout).unwrap()],
        6
    );
    assert_eq!(stats.state, LinkState::Online);
    assert_eq!(stats.round_trip.count(), 4, "round trips of answered exchanges only");
}

#[test]
fn held_inputs_keep_their_values_and_loss_waits_for_loss_after_failures() {
    let mut config = device();
    config.on_loss = OnLoss::Hold;
    config.loss_after = 3;
    let (mut io, mut poller) = pair_for_tests(&config);
    let mut mem = mem();
    run(&mut poller, 0, &[1, 0], Ok(()));
    run(&mut poller, 0, &[42, 0], Ok(()));
    for (n, at) in [10, 20].into_iter().enumerate() {
        run(&mut poller, at * MS, &[], Err(Fault::Exception(4)));
        io.refresh_inputs(&mut mem);
        assert!(bit(&mem, "M0100"), "still online after {} failure(s)", n + 1);
    }
    run(&mut poller, 30 * MS, &[], Err(Fault::Exception(4)));
    io.refresh_inputs(&mut mem);
    assert!(!bit(&mem, "M0100"));
    assert!(bit(&mem, "P0100") && word(&mem, "D00010") == 42, "on_loss = hold");
    let notices = poller.take_notices();
    assert_eq!(notices.len(), 2, "{notices:?}");
    assert_eq!(notices[1], Notice::Lost { failures: 3, on_loss: OnLoss::Hold });
}

#[test]
fn each_condition_is_noticed_once_until_an_exchange_succeeds() {
    let mut config = device();
    config.loss_after = 100;
    let (_, mut poller) = pair_for_tests(&config);
    let faults = [
        Fault::Timeout,
        Fault::Timeout,
        Fault::Exception(2),
        Fault::Exception(2),
        Fault::Exception(4),
        Fault::BadCrc,
        Fault::BadCrc,
    ];
    let mut at = 0;
    for fault in faults {
        let job = poller.next_job(at).unwrap_or_else(|due| {
            at = due;
            poller.next_job(due).unwrap()
        });
        poller.prepare(job);
        poller.finish(job, at, None, Err(fault), 0);
    }
    let kinds: Vec<String> = poller
        .take_notices()
        .iter()
        .map(|n| match n {
            Notice::Fault { fault, .. } => fault.to_string(),
            other => format!("{other:?}"),
        })
        .collect();
    assert_eq!(
        kinds,
        [
            "no answer in time",
            "exception 02 (illegal data address)",
            "exception 04 (server device failure)",
            "an answer with a bad CRC"
        ]
    );
    let job = poller.next_job(u64::MAX / 2).unwrap();
    poller.prepare(job);
    poller.finish(job, u64::MAX / 2, None, Ok(()), 2);
    let notices = poller.take_notices();
    assert_eq!(notices, [Notice::Late, Notice::Back { failures: 7, lost_ms: None }]);
    assert_eq!(poller.stats().lock().unwrap().late, 2);
    // Within one episode, late answers are counted, not noticed again.
    let at = u64::MAX / 2 + 100 * MS;
    for late in [1, 1] {
        let job = poller.next_job(at).unwrap();
        poller.prepare(job);
        poller.finish(job, at, None, Err(Fault::Timeout), late);
    }
    let notices = poller.take_notices();
    assert_eq!(notices.iter().filter(|n| **n == Notice::Late).count(), 1, "{notices:?}");
    assert_eq!(poller.stats().lock().unwrap().late, 4);
}

#[test]
fn writes_wait_for_a_capture_then_follow_changes_refreshes_and_retries() {
    let mut config = device();
    config.reads.clear();
    let (mut io, mut poller) = pair_for_tests(&config);
    let mut mem = mem();
    assert_eq!(poller.next_job(0), Err(u64::MAX), "nothing to write before the first capture");
    mem.set_bit(Address::parse("P0141").unwrap().as_bit().unwrap(), true);
    io.refresh_outputs(&mem);
    let job = poller.next_job(0).unwrap();
    assert_eq!(job, Job::Write(0));
    let (ask, values) = poller.prepare(job);
    assert!(ask.write);
    assert_eq!(values, [0b0010]);
    poller.finish(job, 0, None, Ok(()), 0);
    io.refresh_outputs(&mem);
    assert_eq!(poller.next_job(MS), Err(1000 * MS), "unchanged: only the refresh is due");
    mem.set_bit(Address::parse("P0143").unwrap().as_bit().unwrap(), true);
    io.refresh_outputs(&mem);
    let job = poller.next_job(2 * MS).unwrap();
    assert_eq!(poller.prepare(job).1, [0b1010]);
    poller.finish(job, 2 * MS, None, Err(Fault::Timeout), 0);
    // Lost (loss_after 1): retried after reconnect_ms, with the values wanted now.
    assert_eq!(poller.next_job(3 * MS), Err(102 * MS));
    let job = poller.next_job(102 * MS).unwrap();
    assert_eq!(poller.prepare(job).1, [0b1010]);
    poller.finish(job, 102 * MS, None, Ok(()), 0);
    assert_eq!(poller.next_job(103 * MS), Err(1102 * MS));
    assert_eq!(poller.next_job(1102 * MS), Ok(Job::Write(0)), "the refresh");
    assert_eq!(poller.stats().lock().unwrap().writes, 2);
}

#[test]
fn a_watchdog_trip_writes_zeros_until_the_scan_publishes_again() {
    let mut config = device();
    config.reads.clear();
    let (mut io, mut poller) = pair_for_tests(&config);
    let mut mem = mem();
    mem.set_bit(Address::parse("P0140").unwrap().as_bit().unwrap(), true);
    io.refresh_outputs(&mem);
    let job = poller.next_job(0).unwrap();
    poller.prepare(job);
    poller.finish(job, 0, None, Ok(()), 0);
    io.safe_state().apply();
    let job = poller.next_job(MS).unwrap();
    assert_eq!(poller.prepare(job).1, [0]);
    poller.finish(job, MS, None, Ok(()), 0);
    assert!(poller.next_job(2 * MS).is_err(), "zeros written: nothing more until the refresh");
    io.refresh_outputs(&mem);
    let job = poller.next_job(3 * MS).unwrap();
    assert_eq!(poller.prepare(job).1, [1], "the scan's outputs again");
}

#[test]
fn period_writes_go_every_period_changed_or_not() {
    let mut config = device();
    config.reads.clear();
    config.writes[0].on = WriteOn::Period { period_ms: 20 };
    let (mut io, mut poller) = pair_for_tests(&config);
    let mut mem = mem();
    io.refresh_outputs(&mem);
    assert_eq!(run(&mut poller, 0, &[], Ok(())), Job::Write(0));
    mem.set_bit(Address::parse("P0140").unwrap().as_bit().unwrap(), true);
    io.refresh_outputs(&mem);
    assert_eq!(poller.next_job(MS), Err(20 * MS), "a change waits for the period");
    assert_eq!(run(&mut poller, 20 * MS, &[], Ok(())), Job::Write(0));
    assert_eq!(poller.next_job(21 * MS), Err(40 * MS));
}

#[test]
fn register_tables_swap_bytes_and_words_both_ways() {
    let mut config = device();
    config.reads = vec![RemoteRead {
        table: RemoteTable {
            swap_bytes: true,
            swap_words: true,
            ..table(ModbusTable::InputRegisters, 0, 2, "D00020")
        },
        period_ms: 10,
    }];
    config.writes = vec![RemoteWrite {
        table: RemoteTable {
            swap_words: true,
            ..table(ModbusTable::HoldingRegisters, 0, 2, "D00030")
        },
        on: WriteOn::Change { refresh_ms: 0 },
    }];
    let (mut io, mut poller) = pair_for_tests(&config);
    let mut mem = mem();
    mem.set_word(Address::parse("D00030").unwrap().as_word().unwrap(), 0x5678);
    mem.set_word(Address::parse("D00031").unwrap().as_word().unwrap(), 0x1234);
    io.refresh_outputs(&mem);
    let job = poller.next_job(0).unwrap();
    assert_eq!(poller.prepare(job).1, [0x1234, 0x5678], "a DINT goes high word first");
    poller.finish(job, 0, None, Ok(()), 0);
    run(&mut poller, 0, &[0x1234, 0x5678], Ok(()));
    io.refresh_inputs(&mut mem);
    assert_eq!((word(&mem, "D00020"), word(&mem, "D00021")), (0x7856, 0x3412));
}

#[test]
fn a_device_that_reads_well_and_refuses_a_write_is_lost_once_until_the_write_goes_through() {
    let mut config = device();
    config.loss_after = 2;
    let (mut io, mut poller) = pair_for_tests(&config);
    let mut mem = mem();
    io.refresh_outputs(&mem);
    let refused = Err(Fault::Exception(2));
    assert_eq!(run(&mut poller, 0, &[], refused.clone()), Job::Write(0));
    // The reads go on and succeed, but the device stays unhealthy: no "answering again".
    assert_eq!(run(&mut poller, 0, &[1, 0], Ok(())), Job::Read(0));
    assert_eq!(run(&mut poller, 0, &[2, 0], Ok(())), Job::Read(1));
    io.refresh_inputs(&mut mem);
    assert!(bit(&mem, "M0100"), "one refused write of two allowed: still online");
    assert_eq!(run(&mut poller, 10 * MS, &[], refused.clone()), Job::Write(0));
    io.refresh_inputs(&mut mem);
    assert!(!bit(&mem, "M0100"), "the write failed twice in a row: lost");
    // Lost: the write is what is tried, with backoff; the reads wait.
    let mut at = 10 * MS;
    for wait in [100, 200, 400] {
        at += wait * MS;
        assert_eq!(poller.next_job(at - 1), Err(at));
        assert_eq!(run(&mut poller, at, &[], refused.clone()), Job::Write(0));
    }
    let notices = poller.take_notices();
    assert_eq!(notices.len(), 2, "one fault, one loss: {notices:?}");
    assert!(matches!(notices[1], Notice::Lost { failures: 2, .. }));
    at += 500 * MS;
    assert_eq!(run(&mut poller, at, &[], Ok(())), Job::Write(0));
    assert!(matches!(poller.take_notices()[..], [Notice::Back { failures: 5, lost_ms: Some(_) }]));
    // Back: the reads come at once, and the status with them.
    assert_eq!(run(&mut poller, at, &[1, 0], Ok(())), Job::Read(0));
    assert_eq!(run(&mut poller, at, &[2, 0], Ok(())), Job::Read(1));
    io.refresh_inputs(&mut mem);
    assert!(bit(&mem, "M0100"));
    assert_eq!(poller.stats().lock().unwrap().losses, 1);
}
