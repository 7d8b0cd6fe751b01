//! Tc2_System's task information and ADS log messages on the engine, in virtual time
//! (docs/ST.md, "System libraries"): what the engine writes into `TwinCAT_SystemInfoVarList`
//! for each task, the index `GETCURTASKINDEX` answers in a task that preempts another, and
//! the messages of `ADSLOGSTR` reaching the trace, at most a cap of them per scan.

mod harness;

use harness::engine::{project, sim, with_native, MS};
use plcd::drivers::virtual_time::{simulate, SimOptions};
use plcd::engine::event::{message_kind, Event, EventSink, TaskId};
use plcd::engine::Engine;
use plcd::project::Project;
use plcd::value::Elem;

/// The value of the variable `name` (an integer or BOOL of `elem`) as the engine ends.
fn value(project: &Project, engine: &Engine, name: &str, elem: Elem) -> u64 {
    let symbol = project.variables.symbols.iter().find(|s| s.name.eq_ignore_ascii_case(name));
    let symbol = symbol.unwrap_or_else(|| panic!("no variable {name}"));
    engine.vm().read_value(symbol.at, elem)
}

const TASKS: &str = r#"
[plc]
scan_period_ms = 10
[st]
system_libraries = ["Tc2_System"]
[[program]]
name = "main"
file = "main.st"
[[program]]
name = "fast"
file = "fast.st"
task = "fast"
[[task]]
name = "fast"
kind = "cycle"
number = 0
priority = 3
interval_ms = 5
"#;

/// The scan program spins long enough for the 5 ms task to preempt it mid-scan: it reads its
/// own index before and after, and the fast task its own.
const MAIN: &str = "PROGRAM Main
VAR
    before : BYTE; after : BYTE; k : DINT; count : UDINT; first : BOOL; period : UDINT;
    fast_period : UDINT; fast_name : STRING;
END_VAR
    before := GETCURTASKINDEXEX();
    FOR k := 1 TO 1000 DO
        count := count;
    END_FOR
    after := GETCURTASKINDEXEX();
    count := TwinCAT_SystemInfoVarList._TaskInfo[after].CycleCount;
    first := _TaskInfo[after].FirstCycle;
    period := _TaskInfo[after].CycleTime;
    fast_period := _TaskInfo[3].CycleTime;
    fast_name := _TaskInfo[3].TaskName;
END_PROGRAM";

const FAST: &str = "PROGRAM Fast
VAR index : GETCURTASKINDEX; mine : BYTE; runs : UDINT; END_VAR
    index();
    mine := index.index;
    runs := _TaskInfo[mine].CycleCount;
END_PROGRAM";

#[test]
fn each_task_reads_its_own_index_and_counts_even_when_preempted() {
    let project = project(TASKS, &[("main.st", MAIN), ("fast.st", FAST)]);
    let (engine, events) = sim(&project, &[], &[], 100 * MS);
    let preempted = events.0.iter().any(|(_, e)| matches!(e, Event::TaskPreempt { task: 0, .. }));
    assert!(preempted, "the fast task never preempted the scan");
    let scans = engine.scan_count();
    assert!(scans >= 3, "{scans} scans");
    // the table's order: 1 the scan task, 2 init, 3 the first [[task]]
    assert_eq!(value(&project, &engine, "main.before", Elem::U8), 1);
    assert_eq!(value(&project, &engine, "main.after", Elem::U8), 1, "after a preemption");
    assert_eq!(value(&project, &engine, "fast.mine", Elem::U8), 3);
    assert_eq!(value(&project, &engine, "main.count", Elem::U32), scans);
    assert_eq!(value(&project, &engine, "main.first", Elem::Bool), 0);
    // CycleTime in 100 ns units: the scan period, the cycle task's interval
    assert_eq!(value(&project, &engine, "main.period", Elem::U32), 100_000);
    assert_eq!(value(&project, &engine, "main.fast_period", Elem::U32), 50_000);
    let fast_runs = engine.task_stats("fast").unwrap().runs;
    assert!(fast_runs >= 2);
    assert_eq!(value(&project, &engine, "fast.runs", Elem::U32), fast_runs);
}

/// What a run logged: each message as `task kind: text`, and the drop counts.
#[derive(Default)]
struct Messages {
    lines: Vec<(u64, String)>,
    dropped: Vec<(u64, u32)>,
}

impl EventSink for Messages {
    fn event(&mut self, _: u64, _: Event) {}

    fn message(&mut self, t_ns: u64, task: TaskId, mask: u32, text: &[u8]) {
        let text = String::from_utf8_lossy(text);
        self.lines.push((t_ns, format!("{task} {}: {text}", message_kind(mask))));
    }

    fn messages_dropped(&mut self, t_ns: u64, _: TaskId, count: u32) {
        self.dropped.push((t_ns, count));
    }
}

const LOGGING: &str = "PROGRAM Main
VAR n : INT; k : INT; END_VAR
    n := n + 1;
    IF n = 1 THEN
        ADSLOGSTR(ADSLOG_MSGTYPE_HINT, '| Test suite %s |', 'P_Test.fbSuite');
        ADSLOGDINT(ADSLOG_MSGTYPE_ERROR OR ADSLOG_MSGTYPE_STRING, 'Failed tests: %d', -3);
        ADSLOGLREAL(ADSLOG_MSGTYPE_WARN, 'took %f s', 0.25);
        ADSLOGSTR(ADSLOG_MSGTYPE_LOG, 'no placeholder', 'unused');
    ELSIF n = 2 THEN
        FOR k := 1 TO 40 DO
            ADSLOGDINT(ADSLOG_MSGTYPE_HINT, 'line %d', k);
        END_FOR
    ELSIF n = 3 THEN
        ADSLOGSTR(ADSLOG_MSGTYPE_HINT, 'after %s', 'the flood');
    END_IF
END_PROGRAM";

#[test]
fn messages_reach_the_sink_at_the_end_of_the_run_at_most_32_a_run() {
    let config = "[plc]\nscan_period_ms = 10\n[st]\nsystem_libraries = [\"Tc2_System\"]\n\
                  [[program]]\nname = \"main\"\nfile = \"main.st\"\n";
    let project = project(config, &[("main.st", LOGGING)]);
    let mut messages = Messages::default();
    let options = SimOptions { duration_ns: 35 * MS, step_ns: 1000 };
    simulate(&project, &[], &[], options, &mut messages);
    let texts: Vec<&str> = messages.lines.iter().map(|(_, l)| l.as_str()).collect();
    // the first scan: each placeholder replaced as Infosys documents (%s, %d, %f), the kind
    // from the mask's most severe bit; the task is the scan task, 0
    assert_eq!(
        texts[..4],
        [
            "0 hint: | Test suite P_Test.fbSuite |",
            "0 error: Failed tests: -3",
            "0 warning: took 0.25 s",
            "0 log: no placeholder",
        ]
    );
    // the second scan logs 40: the cap of a run, 32, reach the sink, 8 are counted as dropped
    let second: Vec<&str> = texts[4..].iter().copied().filter(|t| t.contains("line")).collect();
    assert_eq!(second.len(), 32);
    assert_eq!(second[0], "0 hint: line 1");
    assert_eq!(second[31], "0 hint: line 32");
    assert_eq!(messages.dropped.len(), 1);
    assert_eq!(messages.dropped[0].1, 8);
    // the queue is empty again for the third scan: its one message comes through
    assert_eq!(texts.last().copied(), Some("0 hint: after the flood"));
    assert_eq!(texts.len(), 4 + 32 + 1);
    // each run's messages come at its end, after the scan's start
    assert!(messages.lines[4].0 >= 10 * MS && messages.lines[4].0 < 20 * MS);
}

/// Every function and block of the libraries, with values that change from scan to scan.
const EVERYTHING: &str = "TYPE Rec : STRUCT a : DINT; b : LREAL; END_STRUCT END_TYPE
PROGRAM Main
VAR
    n : DINT; src : ARRAY [0..40] OF BYTE; dst : ARRAY [0..40] OF BYTE; k : INT;
    copied : UDINT; cmp : DINT; moved : UDINT; filled : UDINT;
    hex : STRING; trimmed : STRING; lower : STRING;
    ring : FB_MemRingBuffer; buffer : ARRAY [0..63] OF BYTE; r : Rec; got : Rec; sum : LREAL;
    cpu : GETCPUCOUNTER; ticks : UDINT; idx : BYTE; count : UDINT;
    handle : RTS_IEC_HANDLE; result : RTS_IEC_RESULT;
    fmt : FB_FormatString; formatted : STRING; real : LREAL; wide : WSTRING; wlength : INT;
END_VAR
    n := n + 1;
    FOR k := 0 TO 40 DO
        src[k] := DINT_TO_BYTE(n * 7 + k);
    END_FOR
    copied := MEMCPY(ADR(dst), ADR(src), DINT_TO_UDINT(n MOD 41));
    cmp := MEMCMP(ADR(dst), ADR(src), 41);
    moved := MEMMOVE(ADR(src) + 3, ADR(src), 20);
    filled := MEMSET(ADR(dst) + 30, DINT_TO_USINT(n), 11);
    hex := LWORD_TO_HEXSTR(DINT_TO_LWORD(n * 1000003), 12, n MOD 2 = 0);
    trimmed := F_RTrim(F_LTrim(CONCAT('  x', INT_TO_STRING(DINT_TO_INT(n)))));
    lower := F_ToLCase(CONCAT('ABC', hex));
    r.a := n; r.b := DINT_TO_LREAL(n) / 4.0;
    ring.A_AddTail(pWrite := ADR(r), cbWrite := SIZEOF(r), pBuffer := ADR(buffer), cbBuffer := SIZEOF(buffer));
    IF n MOD 3 = 0 THEN
        ring.A_RemoveHead(pRead := ADR(got), cbRead := SIZEOF(got), pBuffer := ADR(buffer), cbBuffer := SIZEOF(buffer));
        sum := sum + got.b + DINT_TO_LREAL(got.a);
    END_IF
    cpu();
    ticks := cpu.cpuCntLoDW;
    idx := GETCURTASKINDEXEX();
    count := _TaskInfo[idx].CycleCount;
    handle := SysFileOpen('f', AM_READ, ADR(result));
    real := DINT_TO_LREAL(n) / 3.0;
    fmt(sFormat := '%+08.3f %-5d|%X %s', arg1 := F_LREAL(real), arg2 := F_DINT(n),
        arg3 := F_UDINT(ticks), arg4 := F_STRING(hex));
    formatted := fmt.sOut;
    wide := STRING_TO_WSTRING(formatted);
    wlength := WLEN(wide);
    IF n MOD 4 = 0 THEN
        ADSLOGSTR(ADSLOG_MSGTYPE_HINT, 'hex %s', hex);
        ADSLOGLREAL(ADSLOG_MSGTYPE_WARN, 'sum %f', sum);
    END_IF
END_PROGRAM";

#[test]
fn native_code_runs_the_libraries_as_the_interpreter_does() {
    let config = "[plc]\nscan_period_ms = 10\n\
                  [st]\nsystem_libraries = [\"Tc2_Utilities\", \"Tc2_Standard\", \"SysFile\"]\n\
                  [[program]]\nname = \"main\"\nfile = \"main.st\"\n";
    let names = [
        "main.copied",
        "main.cmp",
        "main.moved",
        "main.filled",
        "main.hex",
        "main.trimmed",
        "main.lower",
        "main.sum",
        "main.ticks",
        "main.idx",
        "main.count",
        "main.result",
        "main.dst[35]",
        "main.src[10]",
        "main.ring.nCount",
        "main.ring.cbSize",
    ];
    let run = |native: bool| {
        let project = with_native(project(config, &[("main.st", EVERYTHING)]), native);
        let watch: Vec<_> = names.iter().flat_map(|n| project.watched(n).unwrap()).collect();
        let mut messages = Messages::default();
        let options = SimOptions { duration_ns: 200 * MS, step_ns: 1000 };
        let engine = simulate(&project, &[], &watch, options, &mut messages);
        let values: Vec<String> = project
            .variables
            .symbols
            .iter()
            .filter(|s| s.name.starts_with("main."))
            .map(|s| format!("{} = {}", s.name, engine.vm().read_value(s.at, s.ty.elem())))
            .collect();
        assert!(engine.last_operation_error().is_none(), "{:?}", engine.last_operation_error());
        (values, messages.lines)
    };
    let (interpreted, interpreted_messages) = run(false);
    let (native, native_messages) = run(true);
    assert_eq!(interpreted, native);
    assert_eq!(interpreted_messages, native_messages);
    assert_eq!(interpreted_messages.len(), 2 * 5, "20 scans, two messages every fourth");
}

#[test]
fn nt_get_time_answers_at_once_from_the_real_time_clock() {
    let config = "[plc]\nscan_period_ms = 500\n[sim]\nstart = \"2026-11-30-08:15:42\"\n\
                  [st]\nsystem_libraries = [\"Tc2_Utilities\"]\n\
                  [[program]]\nname = \"main\"\nfile = \"main.st\"\n";
    let main = "PROGRAM Main
VAR clock : NT_GetTime; n : INT; seen : DT; busy : BOOL; END_VAR
    n := n + 1;
    clock(NETID := '', START := n = 3);
    busy := busy OR clock.BUSY;
    seen := SYSTEMTIME_TO_DT(clock.TIMESTR);
END_PROGRAM";
    let project = project(config, &[("main.st", main)]);
    let (engine, _) = sim(&project, &[], &[], 2_000 * MS);
    // the third scan starts 1 s after the start: the clock reads 08:15:43 then, and holds it
    let seen = value(&project, &engine, "main.seen", Elem::U32);
    let ty = plcd::value::ValueType::Calendar(plcd::value::Calendar::Dt);
    assert_eq!(plcd::value::format(&ty, seen), "DT#2026-11-30-08:15:43");
    assert_eq!(value(&project, &engine, "main.busy", Elem::Bool), 0);
    assert_eq!(value(&project, &engine, "main.clock.TIMESTR.wDayOfWeek", Elem::U16), 1, "Monday");
}

/// A test runner written the way TcUnit writes its own (github.com/tcunit/TcUnit, MIT; this is
/// plcd's own code, not TcUnit's): assertions queue messages in an FB_MemRingBuffer, one
/// message a cycle goes out through ADSLOGSTR, the duration comes from GETCPUCOUNTER, and the
/// first cycle is found through GETCURTASKINDEX and `_TaskInfo`.
const TCUNIT_STYLE: &str = "TYPE ST_Message : STRUCT mask : DWORD; format : T_MaxString; arg : T_MaxString; END_STRUCT END_TYPE

FUNCTION_BLOCK FB_MessageQueue
VAR
    ring : FB_MemRingBuffer;
    buffer : ARRAY [0..4095] OF BYTE;
    message : ST_Message;
END_VAR
METHOD Add
VAR_INPUT mask : DWORD; format : T_MaxString; arg : T_MaxString; END_VAR
    message.mask := mask; message.format := format; message.arg := arg;
    ring.A_AddTail(pWrite := ADR(message), cbWrite := SIZEOF(message), pBuffer := ADR(buffer),
                   cbBuffer := SIZEOF(buffer));
END_METHOD
METHOD SendOne
VAR out : ST_Message; END_VAR
    IF ring.nCount > 0 THEN
        ring.A_RemoveHead(pRead := ADR(out), cbRead := SIZEOF(out), pBuffer := ADR(buffer),
                          cbBuffer := SIZEOF(buffer));
        IF ring.bOk THEN
            ADSLOGSTR(msgCtrlMask := out.mask, msgFmtStr := out.format, strArg := out.arg);
        END_IF
    END_IF
END_METHOD
END_FUNCTION_BLOCK

FUNCTION_BLOCK FB_Suite
VAR_INPUT name : T_MaxString; END_VAR
VAR
    queue : REFERENCE TO FB_MessageQueue;
    tests : INT; failed : INT; finished : BOOL;
    cpu : GETCPUCOUNTER; started : ULINT; duration : LREAL;
END_VAR
METHOD Bind
VAR_IN_OUT q : FB_MessageQueue; END_VAR
    queue REF= q;
END_METHOD
METHOD AssertEquals_DINT
VAR_INPUT expected : DINT; actual : DINT; message : T_MaxString; END_VAR
    tests := tests + 1;
    IF expected <> actual THEN
        failed := failed + 1;
        queue.Add(ADSLOG_MSGTYPE_ERROR, CONCAT('FAILED TEST, EXP: ', CONCAT(DINT_TO_STRING(expected),
            CONCAT(', ACT: ', CONCAT(DINT_TO_STRING(actual), ', MSG: %s')))), message);
    END_IF
END_METHOD
METHOD Finish
VAR summary : T_MaxString; END_VAR
    IF finished THEN RETURN; END_IF
    finished := TRUE;
    cpu();
    duration := ULINT_TO_LREAL(SHL(UDINT_TO_ULINT(cpu.cpuCntHiDW), 32) + UDINT_TO_ULINT(cpu.cpuCntLoDW) - started) / 1.0E7;
    summary := CONCAT('| Test suite %s | Tests: ', CONCAT(INT_TO_STRING(tests),
        CONCAT(' | Failed tests: ', CONCAT(INT_TO_STRING(failed), CONCAT(' | Duration: ',
        LREAL_TO_FMTSTR(duration, 3, TRUE))))));
    queue.Add(ADSLOG_MSGTYPE_HINT, summary, name);
END_METHOD
    IF started = 0 THEN
        cpu();
        started := SHL(UDINT_TO_ULINT(cpu.cpuCntHiDW), 32) + UDINT_TO_ULINT(cpu.cpuCntLoDW);
    END_IF
END_FUNCTION_BLOCK

PROGRAM Main
VAR
    queue : FB_MessageQueue;
    suite : FB_Suite := (name := 'Main.suite');
    task : GETCURTASKINDEX;
    cycle : UDINT;
END_VAR
    task();
    cycle := TwinCAT_SystemInfoVarList._TaskInfo[task.index].CycleCount;
    IF _TaskInfo[task.index].FirstCycle THEN
        suite.Bind(queue);
    END_IF
    suite();
    IF cycle = 1 THEN
        suite.AssertEquals_DINT(expected := 4, actual := 2 + 2, message := 'adds');
        suite.AssertEquals_DINT(expected := 5, actual := 2 + 2, message := 'adds wrongly');
    ELSIF cycle = 3 THEN
        suite.Finish();
    END_IF
    queue.SendOne();
END_PROGRAM";

#[test]
fn a_tcunit_style_runner_reports_its_results_through_adslogstr() {
    let config = "[plc]\nscan_period_ms = 10\n[st]\nsystem_libraries = [\"Tc2_Utilities\"]\n\
                  [[program]]\nname = \"main\"\nfile = \"main.st\"\n";
    for native in [false, true] {
        let project = with_native(project(config, &[("main.st", TCUNIT_STYLE)]), native);
        let mut messages = Messages::default();
        let options = SimOptions { duration_ns: 100 * MS, step_ns: 1000 };
        simulate(&project, &[], &[], options, &mut messages);
        let texts: Vec<&str> = messages.lines.iter().map(|(_, l)| l.as_str()).collect();
        // one message a cycle, in the order queued: the failed assertion in the first cycle,
        // the summary queued in the third goes out in the third; the duration: 2 scans of
        // 10 ms between the first cycle's reading and the third's
        assert_eq!(
            texts,
            [
                "0 error: FAILED TEST, EXP: 5, ACT: 4, MSG: adds wrongly",
                "0 hint: | Test suite Main.suite | Tests: 2 | Failed tests: 1 | Duration: 0.020",
            ],
            "native: {native}"
        );
    }
}
