//! A text Gantt chart of the tasks of a simulation run, like the figure of the XGB manual
//! §5.1.3 item 9 ("Program configuration and processing example"): one row per task, time
//! left to right, so that "why did my task start late?" is answered at a glance.
//!
//! ```text
//!              0s   5ms  10ms 15ms 20ms 25ms 30ms
//! scan        |######==##==########====#.........|
//! 10ms_cycle  |..........##........--##......##..|
//! device_M000 |.........................#####==##|
//! io_P000     |......##............##............|
//! # running  = preempted  - waiting  x request ignored  . idle
//! ```
//!
//! How the chart is drawn:
//! - `[0, end_ns]` is cut into `width` columns; column `c` covers
//!   `[end_ns * c / width, end_ns * (c + 1) / width)` (integer division), the last one also
//!   holds the instant `end_ns`.
//! - A task's states come from its events: the scan program (task 0) executes from
//!   `ScanStart` to `ScanEnd`, every task (the scan program too) from `TaskStart` to `TaskEnd`;
//!   `TaskPreempt` makes `task` preempted until its `TaskResume` (the `by` task gets its own
//!   `TaskStart`); `TaskRequest` of an idle task makes it wait until its `TaskStart`. A request
//!   while the task runs is remembered (the task waits again after its `TaskEnd`) unless a
//!   `TaskIgnored` for the task follows it; `TaskIgnored` cancels the effect of the request just
//!   before it, if any, and marks the column. `Mode(STOP | ERROR)` makes every task idle.
//! - A cell shows the most important state present in its column, however briefly, in the
//!   order executing `#`, preempted `=`, waiting `-`, idle `.`: over a long run a task of a
//!   few microseconds still shows.
//!   A column narrower than 1 ns shows the state at its start instant.
//! - A column with an ignored request of the task shows `x`, unless the cell is `#`.
//! - The axis labels times with [`format_ns`] at the smallest interval of 1, 2 or 5 × 10ⁿ ns
//!   whose labels do not touch; a label starts in the column where its time falls.

use std::collections::BTreeMap;

use crate::duration::format_ns;
use crate::engine::event::{Event, Mode, TaskId, SCAN};

/// The legend printed under the chart.
pub const LEGEND: &str = "# running  = preempted  - waiting  x request ignored  . idle";

/// A task's state, in the order of importance used to break ties in a column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Running = 0,
    Preempted = 1,
    Waiting = 2,
    Idle = 3,
}

impl State {
    const BY_IMPORTANCE: [State; 4] =
        [State::Running, State::Preempted, State::Waiting, State::Idle];

    fn cell(self) -> char {
        match self {
            State::Running => '#',
            State::Preempted => '=',
            State::Waiting => '-',
            State::Idle => '.',
        }
    }
}

/// What the last event of a task, a request, changed (so that a `TaskIgnored` can undo it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RequestEffect {
    /// The task was idle and now waits.
    Waits,
    /// The task was running or preempted; it will wait again after its end.
    Queued,
}

/// One task's history: its non-idle spans and its ignored requests.
#[derive(Debug)]
struct Track {
    state: State,
    since: u64,
    queued: bool,
    last_request: Option<RequestEffect>,
    /// `(start, end, state)`, in time order, not overlapping; gaps are idle.
    spans: Vec<(u64, u64, State)>,
    ignored: Vec<u64>,
}

impl Track {
    fn new() -> Track {
        Track {
            state: State::Idle,
            since: 0,
            queued: false,
            last_request: None,
            spans: Vec::new(),
            ignored: Vec::new(),
        }
    }

    fn set(&mut self, t: u64, state: State) {
        // Events come in time order; a late one is treated as happening now.
        let t = t.max(self.since);
        if state == self.state {
            return;
        }
        if t > self.since && self.state != State::Idle {
            self.spans.push((self.since, t, self.state));
        }
        self.state = state;
        self.since = t;
    }

    fn apply(&mut self, t: u64, event: &Event) {
        let mut request = None;
        match event {
            Event::ScanStart { .. } | Event::TaskStart { .. } | Event::TaskResume { .. } => {
                self.set(t, State::Running);
            }
            Event::ScanEnd { .. } | Event::TaskEnd { .. } => {
                let next = if self.queued { State::Waiting } else { State::Idle };
                self.queued = false;
                self.set(t, next);
            }
            Event::TaskPreempt { .. } => self.set(t, State::Preempted),
            Event::TaskRequest { .. } => match self.state {
                State::Idle => {
                    self.set(t, State::Waiting);
                    request = Some(RequestEffect::Waits);
                }
                State::Running | State::Preempted if !self.queued => {
                    self.queued = true;
                    request = Some(RequestEffect::Queued);
                }
                _ => {}
            },
            Event::TaskIgnored { .. } => {
                match self.last_request {
                    Some(RequestEffect::Waits) => self.set(t, State::Idle),
                    Some(RequestEffect::Queued) => self.queued = false,
                    None => {}
                }
                self.ignored.push(t);
            }
            Event::Mode(_)
            | Event::Set { .. }
            | Event::SetVariable { .. }
            | Event::Error(_)
            | Event::Switch(_) => return,
        }
        self.last_request = request;
    }

    fn stop(&mut self, t: u64) {
        self.queued = false;
        self.last_request = None;
        self.set(t, State::Idle);
    }

    fn finish(&mut self) {
        if self.state != State::Idle {
            self.spans.push((self.since, u64::MAX, self.state));
        }
    }
}

/// The task an event is about, for the chart (the `by` of a preemption is not: it has its own
/// `TaskStart`).
fn task_of(event: &Event) -> Option<TaskId> {
    match *event {
        Event::ScanStart { .. } | Event::ScanEnd { .. } => Some(SCAN),
        Event::TaskRequest { task }
        | Event::TaskIgnored { task, .. }
        | Event::TaskStart { task }
        | Event::TaskEnd { task }
        | Event::TaskPreempt { task, .. }
        | Event::TaskResume { task } => Some(task),
        Event::Mode(_)
        | Event::Set { .. }
        | Event::SetVariable { .. }
        | Event::Error(_)
        | Event::Switch(_) => None,
    }
}

/// Renders the chart of `events` (in time order) over `[0, end_ns]` in `width` columns: the
/// time axis, one row per task that appears in the events (in [`TaskId`] order, named by
/// `task_names`, `#n` past its end), and the [`LEGEND`]; every line ends with `\n`.
pub fn render(events: &[(u64, Event)], task_names: &[String], end_ns: u64, width: usize) -> String {
    let mut tracks: BTreeMap<TaskId, Track> = BTreeMap::new();
    for (t, event) in events {
        if let Event::Mode(Mode::Stop | Mode::Error) = event {
            for track in tracks.values_mut() {
                track.stop(*t);
            }
        }
        let by = match *event {
            Event::TaskPreempt { by, .. } => Some(by),
            _ => None,
        };
        if let Some(by) = by {
            tracks.entry(by).or_insert_with(Track::new);
        }
        if let Some(task) = task_of(event) {
            tracks.entry(task).or_insert_with(Track::new).apply(*t, event);
        }
    }

    let names: Vec<(String, Track)> = tracks
        .into_iter()
        .map(|(id, mut track)| {
            track.finish();
            let name = match task_names.get(usize::from(id)) {
                Some(name) => name.clone(),
                None => format!("#{id}"),
            };
            (name, track)
        })
        .collect();
    let label_width = names.iter().map(|(name, _)| name.chars().count()).max().unwrap_or(0);
    let columns = Columns { end_ns, width };

    let mut out = String::new();
    out.push_str(&axis(label_width + 2, columns));
    out.push('\n');
    for (name, track) in &names {
        out.push_str(name);
        for _ in name.chars().count()..label_width {
            out.push(' ');
        }
        out.push_str(" |");
        out.extend(row(track, columns));
        out.push_str("|\n");
    }
    out.push_str(LEGEND);
    out.push('\n');
    out
}

/// The column grid over `[0, end_ns]`.
#[derive(Debug, Clone, Copy)]
struct Columns {
    end_ns: u64,
    width: usize,
}

impl Columns {
    /// The start of column `c` (`c == width` gives `end_ns`).
    fn boundary(self, c: usize) -> u64 {
        (u128::from(self.end_ns) * c as u128 / self.width as u128) as u64
    }

    /// The column whose span holds `t` (the last one for `t == end_ns`); `None` past the end.
    fn of(self, t: u64) -> Option<usize> {
        if self.width == 0 || t > self.end_ns {
            return None;
        }
        let mut c = if self.end_ns == 0 {
            0
        } else {
            ((u128::from(t) * self.width as u128 / u128::from(self.end_ns)) as usize)
                .min(self.width - 1)
        };
        while c + 1 < self.width && self.boundary(c + 1) <= t {
            c += 1;
        }
        Some(c)
    }

    /// The character position of time `t` on the axis, relative to the first cell.
    fn position(self, t: u64) -> usize {
        if self.end_ns == 0 {
            0
        } else {
            (u128::from(t) * self.width as u128 / u128::from(self.end_ns)) as usize
        }
    }
}

/// The cells of one task.
fn row(track: &Track, columns: Columns) -> Vec<char> {
    let mut cells = Vec::with_capacity(columns.width);
    let mut first = 0; // the first span that may reach into the current column
    for c in 0..columns.width {
        let lo = columns.boundary(c);
        let hi = columns.boundary(c + 1);
        while first < track.spans.len() && track.spans[first].1 <= lo {
            first += 1;
        }
        let state = if lo == hi {
            match track.spans.get(first) {
                Some(&(start, _, state)) if start <= lo => state,
                _ => State::Idle,
            }
        } else {
            let mut time = [0u64; 4];
            for &(start, end, state) in &track.spans[first..] {
                if start >= hi {
                    break;
                }
                time[state as usize] += end.min(hi) - start.max(lo);
            }
            time[State::Idle as usize] = (hi - lo) - time.iter().sum::<u64>();
            // Whatever happened in a column shows, however short: a 3 µs task in a 100 ms
            // column is what the reader is looking for.
            State::BY_IMPORTANCE
                .into_iter()
                .find(|&state| time[state as usize] > 0)
                .unwrap_or(State::Idle)
        };
        cells.push(state.cell());
    }
    for &t in &track.ignored {
        if let Some(c) = columns.of(t) {
            if cells[c] != '#' {
                cells[c] = 'x';
            }
        }
    }
    cells
}

/// The axis line: `indent` spaces, then time labels.
fn axis(indent: usize, columns: Columns) -> String {
    let mut labels: Vec<(usize, String)> = vec![(0, format_ns(0))];
    if columns.width > 0 {
        for exponent in 0..=18u32 {
            let mut found = None;
            for mantissa in [1u64, 2, 5] {
                let step = mantissa * 10u64.pow(exponent);
                if let Some(ticks) = ticks(step, columns) {
                    found = Some(ticks);
                    break;
                }
            }
            if let Some(ticks) = found {
                labels = ticks;
                break;
            }
        }
    }
    let mut line = " ".repeat(indent);
    let mut at = 0;
    for (position, label) in labels {
        line.push_str(&" ".repeat(position - at));
        line.push_str(&label);
        at = position + label.len();
    }
    line
}

/// The labels of ticks every `step` ns, if they fit without touching (at least one space
/// between labels; the last may reach into the closing `|` column, later ones are left out).
fn ticks(step: u64, columns: Columns) -> Option<Vec<(usize, String)>> {
    // Every label is at least two characters and needs a space after it.
    if columns.end_ns / step > columns.width as u64 / 3 + 1 {
        return None;
    }
    let mut labels: Vec<(usize, String)> = Vec::new();
    let mut next_free = 0;
    let mut t = 0u64;
    loop {
        let position = columns.position(t);
        let label = format_ns(t);
        if position + label.len() > columns.width + 1 {
            break;
        }
        if position < next_free {
            return None;
        }
        next_free = position + label.len() + 1;
        labels.push((position, label));
        match t.checked_add(step) {
            Some(next) if next <= columns.end_ns => t = next,
            _ => break,
        }
    }
    Some(labels)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::event::{Ignored, INIT};

    const MS: u64 = 1_000_000;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    /// The XGB manual §5.1.3 item 9: tasks 2 = P1 (10 ms cycle, priority 3), 3 = P2 (device
    /// M000, priority 5), 4 = P3 (I/O P000, priority 2); scan program 17 ms, P1 2 ms, P2 7 ms,
    /// P3 2 ms.
    fn xgb_example() -> Vec<(u64, Event)> {
        const P1: TaskId = 2;
        const P2: TaskId = 3;
        const P3: TaskId = 4;
        use Event::*;
        vec![
            (0, Mode(crate::engine::event::Mode::Run)),
            (0, ScanStart { n: 1 }),
            // 6: P000 rises, P3 interrupts the scan program.
            (6 * MS, TaskRequest { task: P3 }),
            (6 * MS, TaskPreempt { task: SCAN, by: P3 }),
            (6 * MS, TaskStart { task: P3 }),
            // 7: a new request of P3 while it runs is ignored.
            (7 * MS, TaskRequest { task: P3 }),
            (7 * MS, TaskIgnored { task: P3, why: Ignored::Running }),
            (8 * MS, TaskEnd { task: P3 }),
            (8 * MS, TaskResume { task: SCAN }),
            // 10: the 10 ms cycle interrupts.
            (10 * MS, TaskRequest { task: P1 }),
            (10 * MS, TaskPreempt { task: SCAN, by: P1 }),
            (10 * MS, TaskStart { task: P1 }),
            (12 * MS, TaskEnd { task: P1 }),
            (12 * MS, TaskResume { task: SCAN }),
            // 20: both at once, P3 (priority 2) first, P1 waits.
            (20 * MS, TaskRequest { task: P1 }),
            (20 * MS, TaskRequest { task: P3 }),
            (20 * MS, TaskPreempt { task: SCAN, by: P3 }),
            (20 * MS, TaskStart { task: P3 }),
            (22 * MS, TaskEnd { task: P3 }),
            (22 * MS, TaskStart { task: P1 }),
            (24 * MS, TaskEnd { task: P1 }),
            (24 * MS, TaskResume { task: SCAN }),
            // 25: END of the scan program; the M000 condition starts P2.
            (25 * MS, ScanEnd { n: 1 }),
            (25 * MS, TaskRequest { task: P2 }),
            (25 * MS, TaskStart { task: P2 }),
            // 30: the 10 ms cycle interrupts P2.
            (30 * MS, TaskRequest { task: P1 }),
            (30 * MS, TaskPreempt { task: P2, by: P1 }),
            (30 * MS, TaskStart { task: P1 }),
            (32 * MS, TaskEnd { task: P1 }),
            (32 * MS, TaskResume { task: P2 }),
            (34 * MS, TaskEnd { task: P2 }),
            (34 * MS, ScanStart { n: 2 }),
        ]
    }

    fn xgb_names() -> Vec<String> {
        names(&["scan", "init", "10ms_cycle", "device_M000", "io_P000"])
    }

    #[test]
    fn xgb_manual_example_at_one_ms_per_column() {
        // Written from the manual's table, one character a millisecond:
        // scan: runs 0-6, stopped 6-8 (P3), runs 8-10, stopped 10-12 (P1), runs 12-20,
        //       stopped 20-24 (P3 then P1), runs 24-25, idle until the new scan at 34.
        // P1:   runs 10-12, waits 20-22, runs 22-24, runs 30-32.
        // P2:   runs 25-30, stopped 30-32 (P1), runs 32-34.
        // P3:   runs 6-8 (the ignored request at 7 falls in a running column), runs 20-22.
        let expected = "             0s   5ms  10ms 15ms 20ms 25ms 30ms\n\
                        scan        |######==##==########====#.........|\n\
                        10ms_cycle  |..........##........--##......##..|\n\
                        device_M000 |.........................#####==##|\n\
                        io_P000     |......##............##............|\n\
                        # running  = preempted  - waiting  x request ignored  . idle\n";
        let chart = render(&xgb_example(), &xgb_names(), 34 * MS, 34);
        assert_eq!(chart, expected, "\n{chart}");
    }

    #[test]
    fn xgb_manual_example_at_two_ms_per_column() {
        // Columns of 2 ms; all changes are on even milliseconds except the scan end at 25,
        // where column 12 (24-26) is half running, half idle: running wins the tie.
        let expected = "             0s   10ms 20ms\n\
                        scan        |###=#=####==#....|\n\
                        10ms_cycle  |.....#....-#...#.|\n\
                        device_M000 |............###=#|\n\
                        io_P000     |...#......#......|\n\
                        # running  = preempted  - waiting  x request ignored  . idle\n";
        let chart = render(&xgb_example(), &xgb_names(), 34 * MS, 17);
        assert_eq!(chart, expected, "\n{chart}");
    }

    #[test]
    fn ignored_requests_show_unless_executing() {
        use Event::*;
        let events = vec![
            // Task 2 is idle and its request is dropped (not in RUN): x on idle.
            (MS, TaskIgnored { task: 2, why: Ignored::Stop }),
            // Task 2 waits from 3, a second request is dropped as pending: x on waiting.
            (3 * MS, TaskRequest { task: 2 }),
            (4 * MS, TaskRequest { task: 2 }),
            (4 * MS, TaskIgnored { task: 2, why: Ignored::Pending }),
            (5 * MS, TaskStart { task: 2 }),
            // Running: the ignored request does not hide the run.
            (5 * MS, TaskRequest { task: 2 }),
            (5 * MS, TaskIgnored { task: 2, why: Ignored::Running }),
            // Preempted by task 3 from 6 to 8; a request at 7 is ignored: x on preempted.
            (6 * MS, TaskPreempt { task: 2, by: 3 }),
            (6 * MS, TaskStart { task: 3 }),
            (7 * MS, TaskIgnored { task: 2, why: Ignored::Running }),
            (8 * MS, TaskEnd { task: 3 }),
            (8 * MS, TaskResume { task: 2 }),
            (9 * MS, TaskEnd { task: 2 }),
        ];
        let expected = "   0s   5ms\n\
                        a |.x.-x#=x#.|\n\
                        b |......##..|\n\
                        # running  = preempted  - waiting  x request ignored  . idle\n";
        let chart = render(&events, &names(&["scan", "init", "a", "b"]), 10 * MS, 10);
        assert_eq!(chart, expected, "\n{chart}");
    }

    #[test]
    fn a_request_while_running_that_is_kept_waits_after_the_end() {
        use Event::*;
        let events = vec![
            (0, TaskRequest { task: INIT }),
            (0, TaskStart { task: INIT }),
            (MS, TaskRequest { task: INIT }),
            (2 * MS, TaskEnd { task: INIT }),
            (4 * MS, TaskStart { task: INIT }),
            (5 * MS, TaskEnd { task: INIT }),
        ];
        let chart = render(&events, &names(&["scan", "init"]), 6 * MS, 6);
        assert_eq!(chart.lines().nth(1), Some("init |##--#.|"));
    }

    #[test]
    fn stop_mode_idles_every_task_and_unknown_tasks_get_numbers() {
        use Event::*;
        let events = vec![
            (0, ScanStart { n: 1 }),
            (0, TaskStart { task: 12 }),
            (2 * MS, Mode(crate::engine::event::Mode::Stop)),
            (3 * MS, Mode(crate::engine::event::Mode::Run)),
            (3 * MS, ScanStart { n: 1 }),
        ];
        let chart = render(&events, &names(&["scan"]), 4 * MS, 4);
        let rows: Vec<&str> = chart.lines().skip(1).take(2).collect();
        assert_eq!(rows, vec!["scan |##.#|", "#12  |##..|"]);
    }

    #[test]
    fn the_most_important_state_present_wins_a_column() {
        use Event::*;
        // 10 columns of 1 ms; task 2 runs 0.3-1.0 (column 0: 0.3 idle, 0.7 running), waits
        // 1.0-1.6 then runs to 2.0 (column 1: 0.6 waiting, 0.4 running: running shows).
        let events = vec![
            (300_000, TaskStart { task: 2 }),
            (MS, TaskEnd { task: 2 }),
            (MS, TaskRequest { task: 2 }),
            (1_600_000, TaskStart { task: 2 }),
            (2 * MS, TaskEnd { task: 2 }),
            // column 2: 0.5 preempted, 0.5 idle: preempted shows.
            (2 * MS, TaskStart { task: 2 }),
            (2 * MS, TaskPreempt { task: 2, by: 3 }),
            (2_500_000, TaskResume { task: 2 }),
            (2_500_000, TaskEnd { task: 2 }),
        ];
        let chart = render(&events, &names(&["scan", "init", "t"]), 10 * MS, 10);
        assert_eq!(chart.lines().nth(1), Some("t  |##=.......|"));
    }

    #[test]
    fn degenerate_sizes() {
        let events = vec![(0, Event::ScanStart { n: 1 })];
        let scan = names(&["scan"]);
        assert_eq!(
            render(&events, &scan, 0, 3),
            "      0s\nscan |###|\n".to_string() + LEGEND + "\n"
        );
        assert_eq!(
            render(&events, &scan, 10, 0),
            "      0s\nscan ||\n".to_string() + LEGEND + "\n"
        );
        // 2 ns over 4 columns: columns 0 and 2 are narrower than 1 ns.
        let events = vec![(0, Event::ScanStart { n: 1 }), (1, Event::ScanEnd { n: 1 })];
        assert_eq!(render(&events, &scan, 2, 4).lines().nth(1), Some("scan |##..|"));
        assert_eq!(render(&[], &scan, 10 * MS, 10), "  0s   5ms\n".to_string() + LEGEND + "\n");
    }

    #[test]
    fn axis_scales_with_the_run() {
        let events = vec![(0, Event::ScanStart { n: 1 })];
        let chart = render(&events, &names(&["scan"]), 10_000_000_000, 60);
        assert_eq!(
            chart.lines().next(),
            Some("      0s    1s    2s    3s    4s    5s    6s    7s    8s    9s")
        );
        let chart = render(&events, &names(&["scan"]), 1_500, 30);
        assert_eq!(chart.lines().next(), Some("      0s        500ns     1us"));
    }

    #[test]
    fn deterministic() {
        let a = render(&xgb_example(), &xgb_names(), 40 * MS, 80);
        let b = render(&xgb_example(), &xgb_names(), 40 * MS, 80);
        assert_eq!(a, b);
    }
}
