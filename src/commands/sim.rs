//! `plcd sim --config FILE --for DURATION [--inputs CSV] [--trace FILE|-] [--watch DEVICES]
//! [--step-ns N] [--timeline]`: the engine in virtual time (docs/SIMULATION.md).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use crate::drivers::virtual_time::{self, timeline, trace::TraceWriter, SimOptions};
use crate::engine::event::{message_kind, task_name, Event, EventSink, Recorder, TaskId};
use crate::project::{split_names, Project, Watched};
use crate::symbols::Symbols;
use crate::value::ValueType;
use crate::{duration, files};

/// The command's arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct SimArgs {
    /// The project's TOML config.
    #[arg(long)]
    pub config: PathBuf,
    /// Virtual time to run, e.g. `500ms`, `1.5s`.
    #[arg(long = "for", value_name = "DURATION")]
    pub duration: String,
    /// Input changes: CSV lines `time, device, value`.
    #[arg(long, value_name = "CSV")]
    pub inputs: Option<PathBuf>,
    /// Write the trace (JSON Lines) to FILE, or `-` for standard output.
    #[arg(long, value_name = "FILE|-")]
    pub trace: Option<String>,
    /// Devices and Structured Text variables whose changes are traced, comma separated, and
    /// the option may be repeated (default: every output P bit).
    #[arg(long, value_name = "NAMES", action = clap::ArgAction::Append)]
    pub watch: Vec<String>,
    /// Virtual time an executed instruction costs (default: `[sim] step_ns`).
    #[arg(long, value_name = "N")]
    pub step_ns: Option<u64>,
    /// Print a text Gantt chart of the run, one row per task.
    #[arg(long)]
    pub timeline: bool,
    /// Columns of the timeline.
    #[arg(long, default_value_t = 100, value_name = "COLUMNS")]
    pub timeline_width: usize,
    /// Run every program on the interpreter, without native code (the same results, slower):
    /// to compare the two, or to measure the interpreter itself.
    #[arg(long)]
    pub interpreter: bool,
}

/// Forwards every event to both sinks.
struct Tee<'a, A, B>(&'a mut A, &'a mut B);

impl<A: EventSink, B: EventSink> EventSink for Tee<'_, A, B> {
    fn event(&mut self, t_ns: u64, event: Event) {
        self.0.event(t_ns, event);
        self.1.event(t_ns, event);
    }

    fn text(&mut self, t_ns: u64, watch: u16, text: &[u8]) {
        self.0.text(t_ns, watch, text);
        self.1.text(t_ns, watch, text);
    }

    fn wide_text(&mut self, t_ns: u64, watch: u16, units: &[u8]) {
        self.0.wide_text(t_ns, watch, units);
        self.1.wide_text(t_ns, watch, units);
    }

    fn message(&mut self, t_ns: u64, task: TaskId, mask: u32, text: &[u8]) {
        self.0.message(t_ns, task, mask, text);
        self.1.message(t_ns, task, mask, text);
    }

    fn messages_dropped(&mut self, t_ns: u64, task: TaskId, count: u32) {
        self.0.messages_dropped(t_ns, task, count);
        self.1.messages_dropped(t_ns, task, count);
    }
}

/// Writes the programs' ADS log messages (docs/ST.md, "ADS log messages") to the command's
/// error output as they come, a line each (`message 1.2s scan hint: text`), whether or not a
/// trace is written: what a TwinCAT user reads in the error list.
struct Messages<'a, W> {
    out: &'a mut W,
    task_names: &'a [String],
}

impl<W: Write> EventSink for Messages<'_, W> {
    fn event(&mut self, _: u64, _: Event) {}

    fn message(&mut self, t_ns: u64, task: TaskId, mask: u32, text: &[u8]) {
        let _ = writeln!(
            self.out,
            "message {} {} {}: {}",
            duration::format_ns(t_ns),
            task_name(self.task_names, task),
            message_kind(mask),
            crate::value::decode_str(text)
        );
    }

    fn messages_dropped(&mut self, t_ns: u64, task: TaskId, count: u32) {
        let _ = writeln!(
            self.out,
            "message {} {}: {count} more message(s) of the run dropped",
            duration::format_ns(t_ns),
            task_name(self.task_names, task),
        );
    }
}

/// Exit 0 when the run completed, 1 for an invalid config, program or inputs file, 2 for bad
/// usage. PLC errors are events, not failures.
pub fn run(args: &SimArgs, err: &mut impl Write) -> ExitCode {
    let duration_ns = match duration::parse_duration(&args.duration) {
        Ok(ns) => ns,
        Err(e) => return usage(err, &format!("--for {}: {e}", args.duration)),
    };
    let load = if args.interpreter { files::interpreted_project } else { files::project };
    let project = match load(&args.config) {
        Ok(p) => p,
        Err(diags) => {
            let _ = write!(err, "{diags}");
            return ExitCode::from(1);
        }
    };
    let stimuli = match &args.inputs {
        Some(path) => match files::stimulus_for(path, &project.config) {
            Ok(s) => s,
            Err(diags) => {
                let _ = write!(err, "{diags}");
                return ExitCode::from(1);
            }
        },
        None => Vec::new(),
    };
    let watch = if args.watch.is_empty() {
        project.output_bits().into_iter().map(Watched::Device).collect()
    } else {
        match parse_watch(&project, &args.watch) {
            Ok(w) => w,
            Err(e) => return usage(err, &format!("--watch: {e}")),
        }
    };
    let step_ns = args.step_ns.unwrap_or(project.config.sim.step_ns);
    if step_ns == 0 {
        return usage(err, "--step-ns must be at least 1");
    }
    let options = SimOptions { duration_ns, step_ns };

    let out: Box<dyn Write> = match args.trace.as_deref() {
        None => Box::new(std::io::sink()),
        Some("-") => Box::new(std::io::stdout().lock()),
        Some(path) => match File::create(path) {
            Ok(f) => Box::new(f),
            Err(e) => {
                let _ = writeln!(err, "{path}: cannot create the trace file: {e}");
                return ExitCode::from(1);
            }
        },
    };
    let names = crate::engine::task_names(&project.config);
    let watch_names = watch.iter().map(Watched::name).collect();
    let program_lines =
        project.programs.iter().map(|p| (p.name.clone(), p.lines.to_vec())).collect();
    let watch_types: Vec<Option<ValueType>> = watch.iter().map(watched_type).collect();
    // The trace reads the symbols only to name a watched reference's target: one symbol per
    // scalar element is most of what a large array costs (BENCHMARKS.md, "Large variables"),
    // so they are copied only when a reference is watched.
    let watches_reference =
        watch_types.iter().flatten().any(|ty| matches!(ty, ValueType::Reference { .. }));
    let symbols =
        if watches_reference { project.variables.symbols.clone() } else { Symbols::default() };
    let mut writer =
        TraceWriter::new(BufWriter::new(out), names.clone(), watch_names, program_lines)
            .with_types(watch_types)
            .with_symbols(symbols);
    let mut recorder = Recorder::default();
    let started = Instant::now();
    let mut messages = Messages { out: err, task_names: &names };
    let engine = if args.timeline {
        let mut with_messages = Tee(&mut writer, &mut messages);
        virtual_time::simulate(
            &project,
            &stimuli,
            &watch,
            options,
            &mut Tee(&mut with_messages, &mut recorder),
        )
    } else {
        virtual_time::simulate(
            &project,
            &stimuli,
            &watch,
            options,
            &mut Tee(&mut writer, &mut messages),
        )
    };
    let elapsed = started.elapsed();
    if let Err(e) = writer.finish() {
        let _ = writeln!(err, "writing the trace: {e}");
        return ExitCode::from(1);
    }
    if args.timeline {
        let chart = timeline::render(&recorder.0, &names, duration_ns, args.timeline_width);
        print!("{chart}");
        if !chart.ends_with('\n') {
            println!();
        }
    }
    let scans = engine.scan_stats();
    let _ = writeln!(
        err,
        "sim: {} of virtual time in {:.3} s: {} scans (max {}), {} steps, mode {}",
        duration::format_ns(duration_ns),
        elapsed.as_secs_f64(),
        scans.count,
        duration::format_ns(scans.max_ns),
        engine.steps(),
        engine.mode().as_str()
    );
    ExitCode::SUCCESS
}

/// Every `--watch` list, split at the commas outside `[…]`, each name resolved.
fn parse_watch(project: &Project, lists: &[String]) -> Result<Vec<Watched>, String> {
    let mut watch = Vec::new();
    for list in lists {
        for name in split_names(list) {
            watch.extend(project.watched(name)?);
        }
    }
    Ok(watch)
}

/// How the trace writes a watched value: a device's as a number, a variable's by its type.
fn watched_type(watched: &Watched) -> Option<ValueType> {
    match watched {
        Watched::Device(_) => None,
        Watched::Variable(symbol) => Some(symbol.ty.clone()),
        Watched::Through(through) => Some(through.target.ty.clone()),
    }
}

fn usage(err: &mut impl Write, message: &str) -> ExitCode {
    let _ = writeln!(err, "plcd sim: {message}");
    ExitCode::from(2)
}
