//! The scan thread never allocates: a counting global allocator watches the scan thread of the
//! real-time driver while it runs a project with a 1 ms cycle task, an I/O task fed with edges,
//! device tasks, timers, counters and DUTY, through mode changes and device writes, until it
//! stops on shutdown. The commands include the control socket's (device and Structured Text
//! variable writes, a STRING and a WSTRING among them) and a two-part Modbus word write; the
//! snapshot reads device words and variables, a STRING's and a WSTRING's characters among them.
//! An ST program converts to and from STRING and WSTRING (numbers, TIME, DT, CHAR) and reads the
//! real-time clock (`SysRtcGetTime`, `RTC`) with the date functions on it, and takes and frees
//! dynamic memory (`__NEW`, `__DELETE`: plcd's heap is variable memory), and uses Tc2_System
//! (the task information the engine writes, `MEMCPY`, ADS log messages on their way to the
//! daemon's log).
//! The main program uses the double-word and real instructions too; and a hand-built program of
//! the typed stack machine (calls, FB instances, strings, an index error, a division by zero)
//! runs scans and RUN starts without allocating. The retain writer's copies of the retained
//! Structured Text variables, through a reload and a load that change their layout, allocate
//! nothing on the scan thread either.
#![allow(unsafe_code)]

mod harness;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use plcd::device::Address;
use plcd::drivers::real_time::io::{FieldIo, FieldSafeOutputs, GatedIo, SafeOutputs};
use plcd::drivers::real_time::mirror::Mirror;
use plcd::drivers::real_time::scan::ScanThread;
use plcd::drivers::real_time::snapshot::Snapshot;
use plcd::drivers::real_time::snapshot::VarRead;
use plcd::drivers::real_time::sys::{self, Timer};
use plcd::drivers::real_time::{
    pending, Command, Completion, ControlCommand, LogMessage, Report, Shared, Source, TextWrite,
    WordWrite, WordWrites, Write, MAX_TEXT_WRITE, WORDS_PER_COMMAND, WRITES_PER_COMMAND,
};
use plcd::engine::debug::Breakpoint;
use plcd::engine::event::Mode;
use plcd::engine::{Engine, ModeRequest};
use plcd::io::gate::OutputGate;
use plcd::io::simulated::SimulatedIo;
use plcd::io::InputEdge;
use plcd::value::Elem;

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counter only reads a
// thread-local flag (const-initialised, so reading it never allocates) and bumps an atomic.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if WATCHED.with(Cell::get) {
            let n = ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            if n < 3 && std::env::var_os("PLCD_ALLOC_TRACE").is_some() {
                WATCHED.with(|w| w.set(false));
                eprintln!("allocation {n}:\n{}", std::backtrace::Backtrace::force_capture());
                WATCHED.with(|w| w.set(true));
            }
        }
        // SAFETY: the caller's layout contract is passed on as is.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if WATCHED.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const CONFIG: &str = r#"
[plc]
scan_period_ms = 1
[st]
system_libraries = ["Tc2_System"]
[[program]]
file = "main.il"
[[program]]
file = "tick.il"
task = "tick"
[[program]]
file = "edge.il"
task = "edge"
[[program]]
file = "full.il"
task = "full"
[[program]]
file = "vars.st"
[[program]]
file = "newer.st"
[[task]]
name = "tick"
kind = "cycle"
number = 0
priority = 3
interval_ms = 1
[[task]]
name = "edge"
kind = "io"
number = 8
priority = 2
contact = "P0000"
edge = "both"
[[task]]
name = "full"
kind = "device"
number = 16
priority = 4
device = "D00000"
condition = ">="
value = 50
"#;

const MAIN: &str = "LOAD _ON\nTON T1500 5\nLOAD T1500\nOUT P0040\nLOAD P0000\nCTU C0000 10\n\
                    LOAD _1ON\nDUTY 2 3 SM420\nLOAD SM420\nOUT P0041\n\
                    LOAD _ON\nDADD D00010 70000 D00010\nRADD D00020 0.5 D00020\n\
                    LOADR> D00020 1e6\nRMOV 0 D00020\nLOADD< D00010 0\nDMOV 0 D00010\n\
                    LOAD P0000\nDINCP D00030\nI2R D00001 D00040\nR2D D00040 D00042\n\
                    DDIV D00010 D00050 D00052\nEND\n";
const TICK: &str = "INC D00001\nLOAD NOT P0042\nOUT P0042\nEND\n";
const EDGE: &str = "INC D00000\nEND\n";
const FULL: &str = "MOV 0 D00000\nINC D00002\nEND\n";
// With EN/ENO, an edge input, CODESYS's arithmetic on a bit string and its clock, and the
// calendar: the real-time clock, DT arithmetic, its strings and the date functions.
const VARS: &str = "FUNCTION_BLOCK Edge\nVAR_INPUT up : BOOL R_EDGE; END_VAR\n\
                    VAR_OUTPUT k : DINT; END_VAR\n    IF up THEN k := k + 1; END_IF;\n\
                    IF k > 5 THEN ENO := FALSE; END_IF;\nEND_FUNCTION_BLOCK\n\
                    FUNCTION Half : DINT\nVAR_INPUT x : DINT; END_VAR\n    Half := x / 2;\n\
                    END_FUNCTION\n\
                    PROGRAM Vars\nVAR\n    n : DINT;\n    r : REAL;\n    s : STRING[10] := 'ab';\n\
                    pos AT %D00300 : DINT;\n    t : STRING;\n    x : REAL;\n    m : DINT;\n\
                    e : Edge;\n    ok : BOOL;\n    h : DINT;\n    w : WORD;\n    clock_now : TIME;\n\
                    now : DT;\n    day : INT;\n    clock : RTC;\n    ws : WSTRING[10] := \"äb\";\n\
                    wt : WSTRING;\n    c : CHAR;\n    cpu : GETCPUCOUNTER;\n    task : BYTE;\n\
                    buf : ARRAY [0..15] OF BYTE;\nEND_VAR\n\
                    n := n + 1;\n    t := REAL_TO_STRING(x + 0.5);\n    x := STRING_TO_REAL(t);\n\
                    t := TIME_TO_STRING(DINT_TO_TIME(n));\n    m := STRING_TO_DINT(DINT_TO_STRING(n));\n\
                    e(EN := n MOD 3 <> 0, up := n MOD 2 = 0, ENO => ok);\n\
                    h := Half(EN := ok, x := n) + Half(EN := NOT ok, x := n);\n\
                    w := w + DINT_TO_WORD(n) * 3;\n    clock_now := TIME();\n\
                    now := SysRtcGetTime(TRUE) + T#1s;\n    clock(IN := n > 3, PDT := now);\n\
                    t := DT_TO_STRING(now);\n    now := STRING_TO_DT(t);\n\
                    wt := CONCAT(ws, DINT_TO_WSTRING(n MOD 100));\n    t := WSTRING_TO_STRING(wt);\n\
                    wt := MID(STRING_TO_WSTRING(t), 3, 1);\n    m := m + LEN(wt) + WSTRING_TO_DINT(RIGHT(wt, 1));\n\
                    IF wt < ws AND FIND(wt, \"b\") > 0 THEN m := m + 1; END_IF;\n\
                    c := STRING_TO_CHAR(t);\n    wt := WCHAR_TO_WSTRING(WORD_TO_WCHAR(CHAR_TO_WORD(c)));\n\
                    SPLIT_DATE(IN := DT_TO_DATE(now), DAY => day);\n    day := DAY_OF_WEEK(DT_TO_DATE(now));\n\
                    cpu();\n    task := GETCURTASKINDEXEX();\n    MEMCPY(ADR(buf), ADR(n), SIZEOF(n));\n\
                    IF n MOD 20 = 0 THEN ADSLOGDINT(ADSLOG_MSGTYPE_HINT, 'n %d', n); END_IF;\n\
                    END_PROGRAM\n";

// The constructs of issue 29: a method called through an interface and on the instance (its
// VAR_INST, a property), EXTENDS with SUPER, an action, a chart with timed qualifiers,
// references and pointers (moved, compared, an alias), a union, a jump, AND_THEN / OR_ELSE,
// TOD/DATE arithmetic, and instances as values (a method's instance result, an assignment).
const NEWER: &str = "TYPE U : UNION dw : DWORD; b : ARRAY [0..3] OF BYTE; END_UNION END_TYPE
INTERFACE ICount
METHOD Add : DINT
VAR_INPUT delta : DINT; END_VAR
END_METHOD
END_INTERFACE
FUNCTION_BLOCK Base IMPLEMENTS ICount
VAR n : DINT; END_VAR
METHOD Add : DINT
VAR_INPUT delta : DINT; END_VAR
VAR_INST calls : DINT; END_VAR
    calls := calls + 1; n := n + delta; Add := n;
END_METHOD
PROPERTY Count : DINT
GET Count := n; END_GET
END_PROPERTY
METHOD Snapshot : Base
    Snapshot := THIS^;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Twice EXTENDS Base
METHOD Add : DINT
VAR_INPUT delta : DINT; END_VAR
    Add := SUPER^.Add(2 * delta);
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Newer
VAR
    b : Base; t : Twice; i : ICount; k : DINT; total : DINT;
    buf : ARRAY [0..7] OF DINT; p : POINTER TO DINT; r : REF_TO DINT; alias : REFERENCE TO DINT;
    u : U; go : BOOL; lamp : BOOL; bumps : DINT; hit : BOOL;
    tod1 : TOD := TOD#23:59:59; day : DATE; stamp : DT := DT#2024-02-28-12:00:00; span : TIME;
    heap : POINTER TO DINT; names : POINTER TO STRING(20); counters : POINTER TO Base;
    snap, copy : Base;
END_VAR
    INITIAL_STEP Idle: Work(N); END_STEP
    STEP Fill: lamp(N); Work(N); Bump(L, T#2ms); END_STEP
    TRANSITION FROM Idle TO Fill := go; END_TRANSITION
    TRANSITION FROM Fill TO Idle := NOT go AND Fill.T >= T#1ms; END_TRANSITION
ACTION Work:
    k := k + 1;
    IF k MOD 2 = 0 THEN i := b; ELSE i := t; END_IF;
    total := i.Add(k) + t.Add(1) + b.Count;
    snap := t.Snapshot(); copy := b; total := total + snap.Count - copy.Count;
    p := ADR(buf[0]); p := p + 4 * (k MOD 8); p^ := k; r := REF(buf[1]);
    IF r <> NULL AND_THEN r^ >= 0 THEN r^ := r^ + 1; END_IF;
    alias REF= buf[2]; alias := alias + p^;
    u.dw := DINT_TO_DWORD(k); hit := u.b[0] = 0 OR_ELSE u.b[1] > 0;
    go := k MOD 4 < 2;
    IF k > 1000 THEN JMP done; END_IF;
    tod1 := tod1 + T#1s; stamp := stamp + T#1d; day := DT_TO_DATE(stamp);
    span := stamp - DT#2024-02-28-00:00:00;
    heap := __NEW(DINT, 3); names := __NEW(STRING(20), 2); counters := __NEW(Base, 2);
    IF heap <> 0 THEN heap[2] := k; END_IF;
    IF names <> 0 THEN names[1] := 'n'; END_IF;
    IF counters <> 0 THEN total := total + counters[1].Add(1); END_IF;
    __DELETE(heap); __DELETE(names); __DELETE(counters); __DELETE(heap);
done:
    Bump();
END_ACTION
ACTION Bump:
    bumps := bumps + 1;
END_ACTION
END_PROGRAM
";

/// A scan thread serving `engine` on its own thread, counting allocations, and the other ends
/// of its queues.
struct Rig {
    field: Arc<plcd::io::simulated::SimulatedField>,
    shared: Arc<Shared>,
    edges: rtrb::Producer<InputEdge>,
    commands: rtrb::Producer<Command>,
    reports: rtrb::Consumer<Report>,
    messages: rtrb::Consumer<LogMessage>,
    completions: rtrb::Consumer<Completion>,
    snapshot: Arc<Mutex<Box<Snapshot>>>,
    handle: std::thread::JoinHandle<Box<Engine>>,
    /// The poller thread of the remote device the scan thread refreshes too.
    _remote: plcd::io::remote::RemoteService,
}

/// A remote TCP device nobody answers for (its port refuses), read into P0100–P010F and
/// D00500–D00503 and written from P0040–P0043 (outputs that change every scan), so that the
/// scan thread's remote refreshes and wake-ups run at every scan.
fn remote_device() -> plcd::config::RemoteDevice {
    use plcd::config::{
        ModbusTable, OnLoss, RemoteDevice, RemoteRead, RemoteTable, RemoteTransport, RemoteWrite,
        WriteOn,
    };
    let refused = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let table = |table: ModbusTable, device: &str, count: u16| {
        let device = Address::parse(device).unwrap();
        let first = match device.as_bit() {
            Ok(bit) if table.is_bits() => u32::from(bit.word) * 16 + bit.mask.trailing_zeros(),
            _ => u32::from(device.as_word().unwrap().0),
        };
        RemoteTable { table, address: 0, count, device, first, swap_bytes: false, swap_words: true }
    };
    RemoteDevice {
        name: "refused".into(),
        transport: RemoteTransport::Tcp { address: refused.to_string() },
        unit_id: 1,
        period_ms: 1,
        timeout_ms: 10,
        on_loss: OnLoss::Clear,
        loss_after: 1,
        reconnect_ms: 10,
        reconnect_max_ms: 20,
        status: None,
        reads: vec![
            RemoteRead { table: table(ModbusTable::DiscreteInputs, "P0100", 16), period_ms: 1 },
            RemoteRead { table: table(ModbusTable::InputRegisters, "D00500", 4), period_ms: 1 },
        ],
        writes: vec![RemoteWrite {
            table: RemoteTable { swap_words: false, ..table(ModbusTable::Coils, "P0040", 4) },
            on: WriteOn::Change { refresh_ms: 5 },
        }],
    }
}

impl Rig {
    fn start(engine: Box<Engine>, io: SimulatedIo, mirror: &Arc<Mirror>) -> Rig {
        let field = io.field();
        let shared = Arc::new(Shared::new().unwrap());
        let (edges, edge_rx) = rtrb::RingBuffer::<InputEdge>::new(256);
        let (commands, command_rx) = rtrb::RingBuffer::<Command>::new(64);
        let (report_tx, reports) = rtrb::RingBuffer::<Report>::new(4096);
        let (message_tx, messages) = rtrb::RingBuffer::<LogMessage>::new(64);
        let (completion_tx, completions) = rtrb::RingBuffer::<Completion>::new(64);
        let snapshot = Arc::new(Mutex::new(Snapshot::new()));
        let (remote, remote_service) = plcd::io::remote::start(&[remote_device()]).unwrap();
        let safe = SafeOutputs {
            field: FieldSafeOutputs::Simulated(Arc::clone(&field)),
            remote: remote.safe_state(),
        };
        let scan = ScanThread {
            engine,
            io: GatedIo {
                field: FieldIo::Simulated(io),
                remote,
                gate: Arc::new(OutputGate::default()),
                safe,
                clear_on_trip: true,
            },
            shared: Arc::clone(&shared),
            edges: edge_rx,
            commands: command_rx,
            reports: report_tx,
            messages: message_tx,
            completions: completion_tx,
            snapshot: Arc::clone(&snapshot),
            timer: Timer::new().unwrap(),
            mirrors: vec![Arc::clone(mirror)],
        };
        let handle = std::thread::spawn(move || {
            let mut scan = scan;
            WATCHED.with(|w| w.set(true));
            scan.serve();
            WATCHED.with(|w| w.set(false));
            scan.into_engine()
        });
        Rig {
            field,
            shared,
            edges,
            commands,
            reports,
            messages,
            completions,
            snapshot,
            handle,
            _remote: remote_service,
        }
    }
}

#[test]
fn typed_programs_do_not_allocate() {
    use plcd::lang::ops::{CmpOp, Op::*, Place, StrOp};
    use plcd::lang::Variables;
    use plcd::vm::{ExecState, Exit, StepClock, Vm};
    use plcd_core::device::RetainSet;
    use plcd_core::value::BinOp;

    let d = |text: &str| Place::Word(Address::parse(text).unwrap().as_word().unwrap());
    let code = vec![
        // 0: a FUNCTION call and an FB call.
        PushInt(20),
        Store { elem: Elem::I16, at: Place::Frame(8 + 2) },
        CallFn { target: 47, frame: 8 },
        Fetch { elem: Elem::I16, at: Place::Frame(8) },
        Store { elem: Elem::I16, at: Place::Var(0) },
        AddrOf(Place::Var(10)),
        CallFb { target: 52, frame: 8 },
        // 7: an index out of range, a division by zero, a REAL into a device, a string.
        AddrOf(Place::Var(16)),
        PushInt(9),
        Index { lo: 0, len: 4, stride: 1 },
        FetchInd(Elem::U8),
        PushInt(0),
        Bin { op: BinOp::Div, elem: Elem::U8 },
        Drop,
        PushConst(0),
        Store { elem: Elem::F32, at: d("D00100") },
        AddrOf(Place::Var(32)),
        AddrOf(Place::Var(32)),
        AddrOf(Place::Var(32)),
        Str { op: StrOp::Concat, cap: 16, wide: false },
        // 20: a reference to buf[0] moved to buf[2] and read through; a read through NULL
        // (2822H); a member read past the end of variable memory (2820H); the distance
        // between two NULLs (2820H).
        AddrOf(Place::Var(16)),
        PushConst(1),
        Bin { op: BinOp::Add, elem: Elem::U64 },
        PushInt(2),
        RefAdd,
        Deref { size: 1 },
        FetchInd(Elem::U8),
        Drop,
        PushInt(0),
        Deref { size: 2 },
        FetchInd(Elem::I16),
        Drop,
        AddrOf(Place::Var(16)),
        PushConst(1),
        Bin { op: BinOp::Add, elem: Elem::U64 },
        PushInt(44),
        RefAdd,
        Deref { size: 0 },
        Offset(3),
        CheckRef(2),
        FetchInd(Elem::I16),
        Drop,
        PushInt(0),
        PushInt(0),
        RefDiff,
        Drop,
        End,
        // 47: a FUNCTION: result := x * 2.
        Fetch { elem: Elem::I16, at: Place::Frame(2) },
        PushInt(2),
        Bin { op: BinOp::Mul, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::Frame(0) },
        Return,
        // 52: an FB: count += 1 while count < 1000.
        Fetch { elem: Elem::I16, at: Place::This(0) },
        PushInt(1000),
        Cmp { op: CmpOp::Lt, elem: Elem::I16 },
        GotoIf { target: 60, when: false },
        Fetch { elem: Elem::I16, at: Place::This(0) },
        PushInt(1),
        Bin { op: BinOp::Add, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::This(0) },
        Return,
    ];
    let program = harness::vm::typed_program(
        "typed",
        code,
        vec![u64::from(1.5f32.to_bits()), plcd::value::REF_TAG],
        16,
    );
    let mut vm = Vm::for_programs([&program]);
    let mut initial = vec![0u8; 64];
    initial[32..35].copy_from_slice(&[2, b'a', b'b']);
    vm.set_variables(&Variables {
        initial: initial.into(),
        retained: vec![(10, 2)].into(),
        persistent: vec![].into(),
        located_init: vec![(d("D00102"), Elem::I32, 7)].into(),
        symbols: Default::default(),
        referents: vec![],
        access: vec![],
    });
    let mut state = ExecState::with_frame(program.frame_bytes);
    let retain = RetainSet::default();
    let clock = StepClock { origin_ns: 0, origin_steps: 0, step_ns: 1000 };
    let mut errors = 0;
    WATCHED.with(|w| w.set(true));
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for run in 0..4 {
        vm.reset_for_run(&retain, run % 2 == 1);
        for scan in 0..50 {
            vm.begin_scan(scan == 0, 0);
            state.restart();
            loop {
                match vm.run(&program, &mut state, &clock, 7) {
                    Exit::End => break,
                    Exit::OperationError { .. } => errors += 1,
                    _ => {}
                }
            }
        }
    }
    let count = ALLOCATIONS.load(Ordering::Relaxed) - before;
    WATCHED.with(|w| w.set(false));
    assert_eq!(count, 0, "the typed program allocated or freed {count} times");
    assert_eq!(
        errors,
        4 * 50 * 5,
        "an index error, a division by zero and three reference errors each scan"
    );
    assert_eq!(
        vm.read_value(
            plcd_core::value::Pointer { space: plcd_core::value::Space::Var, offset: 0 },
            Elem::I16
        ),
        40
    );
    // Cold, warm, cold, warm: 50 + 50 counted over the last warm start.
    assert_eq!(vm.vars()[10], 100, "the FB's retained count");
}

#[test]
fn the_scan_thread_does_not_allocate() {
    let project = harness::engine::project(
        CONFIG,
        &[
            ("main.il", MAIN),
            ("tick.il", TICK),
            ("edge.il", EDGE),
            ("full.il", FULL),
            ("vars.st", VARS),
            ("newer.st", NEWER),
        ],
    );
    let at = |name: &str| project.variable(name).unwrap().at;
    let (n, r, s_at, pos) = (at("vars.n"), at("vars.r"), at("vars.s"), at("vars.pos"));
    let ws_at = at("vars.ws");
    let (newer_k, newer_calls, newer_bumps) =
        (at("newer.k"), at("newer.b.Add.calls"), at("newer.bumps"));
    let io = SimulatedIo::new(&[Address::parse("P0000").unwrap()], &[0], None);
    let watch = project.output_bits();
    let d0 = Address::parse("D00000").unwrap().as_word().unwrap().0;
    // The OPC UA server's kind: the words and the whole variable memory, made room for at start.
    let mirror = Arc::new(Mirror::with_all_variables(std::iter::once(d0..d0 + 3)));
    let engine = Box::new(Engine::new(&project, &watch));
    mirror.prepare(engine.retained_variables(), engine.vm().vars().len());
    // And the bytes it serves, for this engine: copying those alone is a scan-thread path too
    // (the engines of the online changes below are copied whole).
    let served = plcd::drivers::real_time::mirror::byte_ranges([(n.offset, 8), (pos.offset, 8)], 0);
    mirror.serve_only(engine.retained_variables(), served);
    let Rig {
        field,
        shared,
        mut edges,
        mut commands,
        mut reports,
        mut messages,
        mut completions,
        snapshot,
        handle,
        _remote,
    } = Rig::start(engine, io, &mirror);
    let command = |commands: &mut rtrb::Producer<Command>, c: Command| {
        assert!(commands.push(c).is_ok());
        shared.signal(pending::COMMAND);
    };
    command(&mut commands, Command::Mode(Mode::Run, Source::Startup));
    let p0000 = Address::parse("P0000").unwrap();
    let mut answered = Vec::new();
    let mut logged = 0;
    for i in 0..300u32 {
        for edge in field.set_input(&p0000, (i % 2) as i32) {
            let edge =
                InputEdge { contact: edge.contact, rising: edge.rising, stamp_ns: sys::now_ns() };
            assert!(edges.push(edge).is_ok());
        }
        shared.signal(pending::EDGE);
        if i == 100 {
            command(&mut commands, Command::Mode(Mode::Stop, Source::Signal));
        }
        if i == 120 {
            command(&mut commands, Command::Mode(Mode::Run, Source::Signal));
        }
        if i == 150 {
            command(&mut commands, Command::Write(Address::parse("D00100").unwrap(), 7));
        }
        // The control socket's commands and snapshot reads, as the control thread sends them.
        let p0043 = Address::parse("P0043").unwrap().as_bit().unwrap();
        let control = match i {
            160 => Some(ControlCommand::Force(p0043, true)),
            170 => Some(ControlCommand::Unforce(p0043)),
            180 => Some(ControlCommand::Mode(ModeRequest::Debug)),
            181 => Some(ControlCommand::Break(Breakpoint { program: 0, pc: 2 })),
            182 => Some(ControlCommand::Continue),
            190 => Some(ControlCommand::Step { scan: false }),
            200 => Some(ControlCommand::Mode(ModeRequest::Run)),
            210 => {
                let mut items = [Write::default(); WRITES_PER_COMMAND];
                items[0] = Write::Device(Address::parse("D00101").unwrap(), 9);
                items[1] = Write::Value { at: r, elem: Elem::F32, slot: 2.5f32.to_bits().into() };
                items[2] = Write::Value { at: pos, elem: Elem::I32, slot: 0x1234_5678 };
                Some(ControlCommand::Writes { items, len: 3 })
            }
            211 => {
                let mut chars = [0; MAX_TEXT_WRITE];
                chars[..3].copy_from_slice(b"xyz");
                Some(ControlCommand::WriteText(TextWrite {
                    at: s_at,
                    cap: 10,
                    len: 3,
                    chars,
                    wide: false,
                }))
            }
            212 => {
                // a WSTRING: "Ωx", code units little-endian
                let mut chars = [0; MAX_TEXT_WRITE];
                chars[..4].copy_from_slice(&[0xA9, 0x03, b'x', 0]);
                Some(ControlCommand::WriteText(TextWrite {
                    at: ws_at,
                    cap: 10,
                    len: 2,
                    chars,
                    wide: true,
                }))
            }
            _ => None,
        };
        if let Some(c) = control {
            command(&mut commands, Command::Control(u64::from(i), c));
        }
        if i == 220 {
            // A Modbus write of 40 words (D00200..D00239) in two parts, pushed as one chunk.
            let d200 = Address::parse("D00200").unwrap().as_word().unwrap().0;
            let parts = (0..2).map(|part| {
                let mut items = [WordWrite::default(); WORDS_PER_COMMAND];
                for (n, item) in items.iter_mut().enumerate() {
                    let k = (part * WORDS_PER_COMMAND + n) as u16;
                    *item = WordWrite { word: d200 + k, mask: 0xFFFF, value: 1000 + k };
                }
                let len = if part == 0 { WORDS_PER_COMMAND } else { 40 - WORDS_PER_COMMAND };
                Command::Words(WordWrites { seq: 5, last: part == 1, len: len as u8, items })
            });
            assert_eq!(commands.write_chunk_uninit(2).unwrap().fill_from_iter(parts), 2);
            shared.signal(pending::COMMAND);
        }
        if i % 10 == 5 {
            let mut s = snapshot.lock().unwrap();
            s.want[0] = Address::parse("D00001").unwrap().as_word().unwrap().0;
            s.want_len = 1;
            s.want_vars[0] = VarRead::Value { at: n, elem: Elem::I32 };
            s.want_vars[1] = VarRead::Text { at: s_at, cap: 10 };
            s.want_vars[2] = VarRead::WideText { at: ws_at, cap: 10 };
            s.want_vars_len = 3;
            drop(s);
            shared.snapshot_wanted.store(true, Ordering::Release);
            shared.signal(pending::COMMAND);
        }
        if i % 10 == 7 {
            // The retain writer, the Modbus and the OPC UA server ask for their mirrors so.
            mirror.request();
            shared.signal(pending::MIRROR);
        }
        std::thread::sleep(Duration::from_millis(1));
        while reports.pop().is_ok() {}
        while let Ok(m) = messages.pop() {
            logged += usize::from(m.bytes().starts_with(b"n "));
        }
        while let Ok(c) = completions.pop() {
            answered.push(c);
        }
    }
    shared.request_shutdown();
    let engine = handle.join().unwrap();
    let count = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(count, 0, "the scan thread allocated or freed {count} times");
    assert!(logged > 0, "the program's ADSLOGDINT messages reached the message queue");
    // Shutdown stopped it, and it did run: scans since its last RUN (STOP keeps the count), the
    // cycle task, the io task (one run per edge at most), the device task.
    assert_eq!(engine.mode(), Mode::Stop, "shutdown leaves the PLC in STOP");
    assert!(engine.scan_stats().count > 0, "no scan since the last RUN");
    let runs = |name: &str| engine.task_stats(name).unwrap().runs;
    assert!(runs("tick") > 10, "tick ran {}", runs("tick"));
    assert!(runs("edge") > 10, "edge ran {}", runs("edge"));
    assert!(runs("full") >= 1, "full ran {}", runs("full"));
    assert_eq!(engine.vm().mem.read(&Address::parse("D00100").unwrap()), 7);
    assert_eq!(engine.vm().mem.read(&Address::parse("D00101").unwrap()), 9);
    assert_eq!(engine.vm().mem.read(&Address::parse("D00200").unwrap()), 1000);
    assert_eq!(engine.vm().mem.read(&Address::parse("D00239").unwrap()), 1039);
    assert_eq!(engine.vm().mem.read(&Address::parse("D00240").unwrap()), 0, "only `len` items");
    assert_eq!(shared.words_applied.load(Ordering::Relaxed), 5, "the last part was applied");
    let tickets: Vec<u64> = answered.iter().map(|c| c.ticket).collect();
    assert_eq!(
        tickets,
        [160, 170, 180, 181, 182, 190, 200, 210, 211, 212],
        "every command answered"
    );
    assert!(answered.iter().all(|c| c.result.is_ok()), "{answered:?}");
    assert_eq!(f32::from_bits(engine.vm().read_value(r, Elem::F32) as u32), 2.5);
    assert_eq!(engine.vm().mem.read(&Address::parse("D00300").unwrap()), 0x5678);
    assert_eq!(engine.vm().mem.read(&Address::parse("D00301").unwrap()), 0x1234);
    let captured = snapshot.lock().unwrap();
    assert!(captured.generation > 10, "snapshots were captured");
    assert!(captured.value(n, Elem::I32).is_some_and(|n| n > 0), "the ST program counts");
    let read = |at| engine.vm().read_value(at, Elem::I32) as i32;
    assert!(read(newer_k) > 10, "the program of issue 29's constructs ran");
    assert!(read(newer_calls) > 2, "the method was called through the interface");
    assert!(read(newer_bumps) > read(newer_k), "the action ran, by call and from the chart");
    assert_eq!(captured.text(s_at, 10), Some(&b"xyz"[..]), "the STRING written, read back");
    assert_eq!(
        captured.wide_text(ws_at, 10),
        Some(&[0xA9, 0x03, b'x', 0][..]),
        "the WSTRING written, read back"
    );
    drop(captured);
    let image = mirror.lock();
    assert!(image.generation > 10, "mirrors were copied: {}", image.generation);
    assert!(image.words[1] > 0, "D00001 counts the tick task's runs: {:?}", image.words);
    let offset = match n.space {
        plcd::value::Space::Var => n.offset as usize,
        other => panic!("vars.n is in variable memory, not {other:?}"),
    };
    let counted = i32::from_le_bytes(image.vars[offset..offset + 4].try_into().unwrap());
    assert!(counted > 0, "the whole variable memory was copied: vars.n = {counted}");
    assert_eq!(image.vars.len(), engine.vm().vars().len());
}

const ST_CONFIG: &str =
    "[plc]\nscan_period_ms = 1\n[[program]]\nname = \"main\"\nfile = \"main.st\"\n";

/// Counts scans in a retained variable, in an element of a retained array and in a member of
/// an element of a retained array of structs whose other member, a reference, is not saved
/// (the retained bytes not contiguous in memory); a retained STRING too.
const ST_SMALL: &str = "TYPE Slot : STRUCT n : DINT; p : POINTER TO DINT; END_STRUCT; END_TYPE
PROGRAM Main
VAR RETAIN count : DINT; label : STRING[10] := 'abc'; extra : ARRAY [1..3] OF LINT;
    ks : ARRAY [1..2] OF Slot; END_VAR
    count := count + 1; extra[1] := extra[1] + 1; ks[2].n := ks[2].n + 1;
END_PROGRAM";

/// The same, with many more retained bytes: a new layout the mirror has no room for; the
/// arrays of other bounds (their common elements kept by index).
const ST_LARGE: &str = "TYPE Slot : STRUCT n : DINT; p : POINTER TO DINT; END_STRUCT; END_TYPE
PROGRAM Main
VAR RETAIN extra : ARRAY [1..40] OF LINT; count : DINT; ks : ARRAY [0..3] OF Slot; END_VAR
    count := count + 1; extra[1] := extra[1] + 1; ks[2].n := ks[2].n + 1;
END_PROGRAM";

/// The retain writer's copies of the retained ST variables: the scan thread copies them at scan
/// boundaries, and takes over a reloaded project's (a larger layout: room to make) and a loaded
/// one's (a smaller layout again: the replaced one to drop) without allocating or freeing —
/// the writer thread makes the room and drops the layouts. The files hold the variables of
/// each layout, and `count`, `extra[1]` and `ks[2].n` count on through both replacements.
#[test]
fn retained_variables_are_copied_and_taken_over_without_allocating() {
    use plcd::device::RetainSet;
    use plcd::services::retain::writer::{Writer, WriterThread};
    use plcd::services::retain::{newest_in, Generation, Store};

    let small = harness::engine::project(ST_CONFIG, &[("main.st", ST_SMALL)]);
    let large = harness::engine::project(ST_CONFIG, &[("main.st", ST_LARGE)]);
    let dir = harness::tempdir::TempDir::new("scan-no-alloc-retain");
    let set = RetainSet::k_only();
    let mirror = Arc::new(Mirror::with_variables(set.words.iter().map(|w| w.range())));
    let engine = Box::new(Engine::new::<Address>(&small, &[]));
    mirror.prepare(engine.retained_variables(), 0);
    let io = SimulatedIo::new(&[], &[], None);
    let Rig { shared, mut commands, mut reports, mut completions, handle, .. } =
        Rig::start(engine, io, &mirror);
    let writer = Writer::new(Store::open(dir.path()).unwrap(), &set.words, 0, 1, None);
    let writer = WriterThread::spawn(
        writer,
        Arc::clone(&mirror),
        Arc::clone(&shared),
        Duration::from_millis(2),
    )
    .unwrap();
    let mut command = |c: Command| {
        assert!(commands.push(c).is_ok());
        shared.signal(pending::COMMAND);
    };
    // Waits for a generation on disk; drops the engines the scan thread retired meanwhile.
    let mut wait_for = |what: &str, done: &dyn Fn(&Generation) -> bool| -> Generation {
        let mut found = None;
        harness::log::wait_until(harness::log::PATIENCE, what, String::new, || {
            while reports.pop().is_ok() {}
            while completions.pop().is_ok() {}
            found = newest_in(dir.path()).filter(|g| done(g));
            found.is_some()
        });
        found.unwrap()
    };
    let bytes = |g: &Generation, name: &str, at: usize, len: usize| {
        let v = g.variables.iter().find(|v| v.name == name).expect("saved");
        let mut number = [0u8; 8];
        number[..len].copy_from_slice(&v.bytes[at..at + len]);
        i64::from_le_bytes(number)
    };
    let count = |g: &Generation| bytes(g, "main.count", 0, 4);
    // extra[1], and ks[2].n: of the second element of ARRAY[1..2], the third of ARRAY[0..3]
    let extra = |g: &Generation| bytes(g, "main.extra", 0, 8);
    let kept = |g: &Generation, second: usize| bytes(g, "main.ks", 4 * second, 4);
    let has = |g: &Generation, name: &str| g.variables.iter().any(|v| v.name == name);

    command(Command::Mode(Mode::Run, Source::Startup));
    let first = wait_for("the small layout counting", &|g| has(g, "main.label") && count(g) > 5);
    assert_eq!(
        first.variables[1].bytes[..4],
        [b'a', b'b', b'c', 0],
        "the STRING's characters and their NUL"
    );
    command(Command::Replace(Box::new(Engine::new::<Address>(&large, &[]))));
    let large_layout = |g: &Generation| {
        g.variables.iter().any(|v| v.name == "main.extra" && v.ty == "ARRAY[1..40] OF LINT")
    };
    let reloaded = wait_for("the large layout", &|g| large_layout(g) && count(g) > 0);
    assert!(count(&reloaded) > count(&first), "count kept over the reload and counting on");
    assert!(extra(&reloaded) > extra(&first), "an array's element kept by index");
    assert!(kept(&reloaded, 2) > kept(&first, 1), "a struct's member kept by index");
    assert!(first.variables.iter().any(|v| v.ty == "ARRAY[1..2] OF {.n@0:DINT;@4}"));
    command(Command::Mode(Mode::Stop, Source::Signal));
    let load = ControlCommand::Load(Box::new(Engine::new::<Address>(&small, &[])));
    command(Command::Control(1, load));
    command(Command::Mode(Mode::Run, Source::Signal));
    let loaded =
        wait_for("the small layout again", &|g| g.seq > reloaded.seq && has(g, "main.label"));
    assert!(count(&loaded) >= count(&reloaded), "count kept over the load");
    assert!(extra(&loaded) >= extra(&reloaded));
    assert!(kept(&loaded, 1) >= kept(&reloaded, 2));
    assert_eq!(loaded.variables.len(), 4);

    shared.request_shutdown();
    handle.join().unwrap();
    writer.stop().unwrap();
    let count = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(count, 0, "the scan thread allocated or freed {count} times");
}
