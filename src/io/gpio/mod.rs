//! The gpiocdev backend: the P image's inputs and outputs, and the RUN/STOP key switch, on the
//! lines of one GPIO chip, through the Linux GPIO character device (uAPI v2).
//!
//! The wiring plan (which line offset is which P bit or the key switch, with which settings,
//! in which request, detecting which edges; the kernel's limits) is the config's:
//! `plcd_core::config::wiring`, checked by `plcd check` with the config's other errors. This
//! module applies a plan to a chip, and owns what needs the chip: finding it ([`chip`]: a
//! path, a `/dev` name or a chip label), the names of its lines (which the plan's line names
//! are looked up among, before anything is requested), a line beyond its line count, a line
//! another consumer holds, the requests and their ioctls. What [`open`] returns is split by thread: [`GpioIo`]
//! for the scan ([`scan`], the [`Io`](crate::io::Io) trait), [`GpioEdges`] for the event thread
//! ([`edges`]), [`GpioOutputs`] for the watchdog ([`watchdog`]); [`error`] says what can fail.
//!
//! What only `plcd run` can find, because it needs the hardware: the chip not found, its label
//! matching several chips, the chip not opening (permissions, not a GPIO chip), a line name the
//! chip does not have (the error names the near ones) or has on several lines, a name and an
//! offset (or two names) that are one line, a line offset at or beyond the chip's line count, a line already held by another consumer (named when the
//! kernel says who), a request the kernel or the chip's driver refuses for what the chip is
//! (a setting its hardware cannot do), and any ioctl that fails while the lines are in use.
//! Everything else about the wiring is the config's and fails `plcd check` too.
//!
//! Why it is built this way:
//! - **One request per direction.** All inputs are one line request, all outputs another, each
//!   with per-line settings (bias, active-low, debounce, edge). The kernel reads or writes every
//!   line of a request in one ioctl, so a refresh costs one syscall whatever the line count, and
//!   every input of a scan is sampled at the same instant (no skew between lines that a
//!   line-by-line loop would have).
//! - **The key switch is one more input line.** `[switch]`'s line is in the input request with
//!   its own bias, active-low and debounce, so the same get-values ioctl reads it; it maps to no
//!   P bit and detects no edges (the engine looks at it at each input refresh, which is as often
//!   as a mode change can take effect). It is read once at open too, so the position is known
//!   before the first scan.
//! - **One ioctl per refresh, no allocation.** The `Values` passed to gpiocdev are built at open
//!   with every requested offset in them: with a non-empty `Values`, gpiocdev converts to and
//!   from the kernel's bitmap on the stack. A failed ioctl is counted with its errno
//!   ([`crate::io::faults`]) for the supervisor to log once per condition; the scan never
//!   panics on I/O and goes on with the inputs it last read.
//! - **Active-low in the kernel.** Lines are requested with the `active_low` flag, so the values
//!   and the edges the kernel reports are already logical (a rising edge is OFF → ON of the
//!   device), as the engine expects.
//! - **Edge detection only where a task needs it.** Each edge-detecting line costs an interrupt
//!   per edge and a slot in the kernel's event FIFO; only the contacts P0000–P0007 that I/O
//!   tasks start on get it, with the kinds those tasks ask for (several tasks on one contact
//!   merge).
//! - **Kernel timestamps.** An edge carries the CLOCK_MONOTONIC time the kernel took in its
//!   interrupt handler, which is when the edge happened, not when the event thread got to it.
//! - **Sequence gaps.** When the event thread falls behind, the kernel's FIFO drops the oldest
//!   events. Each event carries its line's sequence number, so a gap tells how many edges were
//!   lost; they are counted and reported rather than silently missing. The per-line number is
//!   used, not the per-request one: the kernel numbers an edge in the hard interrupt but queues
//!   it from the line's interrupt thread, so events of different lines can be queued out of
//!   request order, while one line's events never are.
//!
//! The plan, the refresh mapping and the sequence check are pure functions with unit tests;
//! everything that needs a chip is tested against the kernel's gpio-sim
//! (`tests/gpiosim_backend.rs`).

pub mod chip;
pub mod edges;
pub mod error;
pub mod scan;
pub mod watchdog;

use std::sync::Arc;
use std::time::Duration;

use gpiocdev::line::{Bias as LineBias, EdgeDetection, EventClock, Value, Values};
use gpiocdev::Request;

use crate::config::wiring::{ImageBit, InputSlot, InputWire, OutputWire, CONTACTS};
pub use crate::config::wiring::{LineDirection, Wire};
use crate::config::{Bias, Config, Edge};
use crate::io::faults::FieldFaults;
use chip::{find_chip, FoundChip};
use edges::EdgeMap;
pub use edges::GpioEdges;
pub use error::{ChipSummary, GpioError, IoOp};
pub use scan::GpioIo;
use scan::{switch_position, InputSide, OutputSide};
pub use watchdog::GpioOutputs;
use watchdog::OutputShared;

/// Kernel FIFO slots per edge-detecting line: the kernel's own default per line. The user-space
/// buffer has as many, so one read can drain the whole FIFO.
const EVENTS_PER_EDGE_LINE: usize = 16;

/// What the daemon gets from opening the backend.
#[derive(Debug)]
pub struct Gpio {
    /// The scan's side: input and output refresh.
    pub io: GpioIo,
    /// The event thread's side; `None` when no I/O task needs an edge.
    pub edges: Option<GpioEdges>,
    /// The watchdog's side: forcing every output inactive.
    pub outputs: GpioOutputs,
}

/// Opens the chip `config`'s `io.chip` names and requests the lines of its wiring plan
/// (`Config::wiring`, with the line names looked up among the chip's): the `[[io.input]]` lines
/// and the `[switch]` line as one request, with edge detection on the contacts io tasks start
/// on, the `[[io.output]]` lines as another.
/// `consumer`: the consumer label the kernel shows for the lines ("plcd"); `faults`: where
/// the scan's side counts failed refreshes.
///
/// No line is requested when there is nothing to request in a direction. Outputs start
/// inactive. The switch is read once before this returns.
pub fn open(config: &Config, consumer: &str, faults: Arc<FieldFaults>) -> Result<Gpio, GpioError> {
    let asked = config.io.chip.as_deref().ok_or(GpioError::NoChip)?;
    // Without names the plan needs no chip: a plan the kernel would refuse fails first.
    let by_offsets = match config.uses_line_names() {
        false => Some(config.wiring(&[]).map_err(GpioError::Wiring)?),
        true => None,
    };
    let found = find_chip(asked)?;
    let plan = match by_offsets {
        Some(plan) => plan,
        None => config.wiring(&found.line_names()?).map_err(|errors| found.lines_error(errors))?,
    };
    for (line, wire) in plan.lines() {
        found.check_line(line, wire)?;
    }

    let input_offsets: Vec<u32> = plan.inputs.iter().map(|i| i.line.offset).collect();
    let output_offsets: Vec<u32> = plan.outputs.iter().map(|o| o.line.offset).collect();
    let inputs = if plan.inputs.is_empty() {
        None
    } else {
        Some(Arc::new(request_inputs(&found, &plan.inputs, consumer)?))
    };
    let outputs = if plan.outputs.is_empty() {
        None
    } else {
        Some(Arc::new(OutputShared {
            chip: found.name.clone(),
            request: request_outputs(&found, &plan.outputs, consumer)?,
            inactive: Values::from_offsets(&output_offsets),
        }))
    };

    let edge_lines = plan.edge_lines();
    let edges = match &inputs {
        Some(request) if edge_lines > 0 => Some(GpioEdges::new(
            found.name.clone(),
            request.clone(),
            EdgeMap::new(&plan.inputs),
            EVENTS_PER_EDGE_LINE * edge_lines,
        )),
        _ => None,
    };
    // Values holding every offset of their request: gpiocdev then never grows them, and
    // their order (sorted offsets) is the order of the plan's bits.
    let mut inputs = inputs.map(|request| InputSide {
        request,
        values: Values::from_offsets(&input_offsets),
        slots: plan.inputs.iter().map(|i| i.slot).collect(),
    });
    let mut switch = None;
    if let Some(side) = inputs.as_mut().filter(|_| plan.has_switch()) {
        side.request.values(&mut side.values).map_err(|source| GpioError::Io {
            chip: found.name.clone(),
            op: IoOp::ReadInputs,
            source,
        })?;
        switch = switch_position(&side.slots, &side.values);
    }
    let io = GpioIo {
        inputs,
        switch,
        outputs: outputs.clone().map(|shared| OutputSide {
            shared,
            values: Values::from_offsets(&output_offsets),
            bits: plan.outputs.iter().map(|o| o.bit).collect(),
        }),
        faults,
    };
    Ok(Gpio { io, edges, outputs: GpioOutputs { shared: outputs } })
}

fn request_inputs(
    found: &FoundChip,
    inputs: &[InputWire],
    consumer: &str,
) -> Result<Request, GpioError> {
    let mut builder = Request::builder();
    builder.on_chip(found.path.as_path()).with_consumer(consumer);
    let edge_lines = inputs.iter().filter(|i| i.edge.is_some()).count();
    if edge_lines > 0 {
        builder.with_kernel_event_buffer_size((EVENTS_PER_EDGE_LINE * edge_lines) as u32);
    }
    for input in inputs {
        // with_line selects just this line: what follows configures it alone.
        // `bias = "disabled"` is asked for explicitly, so that a pull left on by firmware or
        // a previous user does not linger on a line the config says has none.
        builder.with_line(input.line.offset).as_input().with_bias(line_bias(input.line.bias));
        if input.line.active_low {
            builder.as_active_low();
        }
        if input.line.debounce_us > 0 {
            builder.with_debounce_period(Duration::from_micros(input.line.debounce_us.into()));
        }
        if let Some((_, edge)) = input.edge {
            // Monotonic is the kernel's default; named because InputEdge::stamp_ns is defined
            // on it.
            builder
                .with_edge_detection(edge_detection(edge))
                .with_event_clock(EventClock::Monotonic);
        }
    }
    builder.request().map_err(|source| {
        found.request_error(
            LineDirection::Input,
            inputs.iter().map(|i| (i.line.offset, i.wire())),
            source,
        )
    })
}

fn request_outputs(
    found: &FoundChip,
    outputs: &[OutputWire],
    consumer: &str,
) -> Result<Request, GpioError> {
    let mut builder = Request::builder();
    builder.on_chip(found.path.as_path()).with_consumer(consumer);
    for output in outputs {
        builder.with_line(output.line.offset).as_output(Value::Inactive);
        if output.line.active_low {
            builder.as_active_low();
        }
    }
    builder.request().map_err(|source| {
        found.request_error(
            LineDirection::Output,
            outputs.iter().map(|o| (o.line.offset, Wire::Device(o.device))),
            source,
        )
    })
}

fn line_bias(bias: Bias) -> LineBias {
    match bias {
        Bias::Disabled => LineBias::Disabled,
        Bias::PullUp => LineBias::PullUp,
        Bias::PullDown => LineBias::PullDown,
    }
}

fn edge_detection(edge: Edge) -> EdgeDetection {
    match edge {
        Edge::Rising => EdgeDetection::RisingEdge,
        Edge::Falling => EdgeDetection::FallingEdge,
        Edge::Both => EdgeDetection::BothEdges,
    }
}

// The scan, event and watchdog threads each own one part; the watchdog's is shared.
const _: fn() = || {
    fn send<T: Send>() {}
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Request>();
    send_sync::<GpioOutputs>();
    send::<GpioIo>();
    send::<GpioEdges>();
    send::<GpioError>();
};

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::config::LineRef;

    /// A gpiocdev config on `chip` with an io task on P0000 and the wiring `io`.
    fn config(chip: &str, io: &str) -> Config {
        let text = format!(
            "[[program]]\nfile = \"main.il\"\n[[task]]\nname = \"edge\"\nkind = \"io\"\n\
             number = 8\npriority = 2\ncontact = \"P0000\"\nedge = \"rising\"\n\
             [io]\nbackend = \"gpiocdev\"\nchip = \"{chip}\"\n\
             [[io.input]]\ndevice = \"P0000\"\nline = 1\n{io}"
        );
        crate::config::parse(&text, Path::new("plcd.toml")).unwrap()
    }

    #[test]
    fn a_chip_is_required() {
        let mut cfg = config("gpiochip0", "");
        cfg.io.chip = None;
        assert!(matches!(open(&cfg, "plcd", Arc::default()), Err(GpioError::NoChip)));
    }

    #[test]
    fn a_missing_chip_path_names_what_was_asked() {
        let cfg =
            config("/dev/gpiochip-does-not-exist", "[[io.output]]\ndevice = \"P0040\"\nline = 2\n");
        let err = open(&cfg, "plcd", Arc::default()).unwrap_err();
        let GpioError::ChipNotFound { asked, .. } = &err else { panic!("{err:?}") };
        assert_eq!(asked, "/dev/gpiochip-does-not-exist");
        assert!(err
            .to_string()
            .starts_with("GPIO chip `/dev/gpiochip-does-not-exist` not found; "));
    }

    #[test]
    fn a_label_that_matches_no_chip_names_what_was_asked() {
        let err = open(&config("plcd-no-such-chip-label", ""), "plcd", Arc::default()).unwrap_err();
        let GpioError::ChipNotFound { asked, .. } = &err else { panic!("{err:?}") };
        assert_eq!(asked, "plcd-no-such-chip-label");
        assert!(err.to_string().starts_with("GPIO chip `plcd-no-such-chip-label` not found; "));
    }

    #[test]
    fn a_path_that_is_not_a_chip_is_an_open_error() {
        let err = open(&config("/dev/null", ""), "plcd", Arc::default()).unwrap_err();
        assert!(
            matches!(&err, GpioError::ChipOpen { chip, .. } if &**chip == "/dev/null"),
            "{err:?}"
        );
        assert!(err.to_string().starts_with("cannot open GPIO chip `/dev/null`: "), "{err}");
    }

    #[test]
    fn a_plan_by_line_names_needs_the_chip_first() {
        // The names are looked up on the chip: without it, the chip is the error, even for a
        // plan the kernel would refuse.
        let mut cfg = config("/dev/gpiochip-does-not-exist", "");
        let line = cfg.io.inputs[0].clone();
        cfg.io.inputs = (0..65)
            .map(|n| crate::config::IoLine { line: LineRef::Name(format!("L{n}")), ..line.clone() })
            .collect();
        assert!(cfg.uses_line_names());
        let err = open(&cfg, "plcd", Arc::default()).unwrap_err();
        assert!(matches!(err, GpioError::ChipNotFound { .. }), "{err:?}");
    }

    #[test]
    fn a_plan_the_kernel_would_refuse_fails_before_the_chip() {
        // Only a config that did not come from parsing can have one: parsing reports it.
        let mut cfg = config("/dev/gpiochip-does-not-exist", "");
        let line = cfg.io.inputs[0].clone();
        cfg.io.inputs = (0..65)
            .map(|n| crate::config::IoLine { line: LineRef::Offset(n), ..line.clone() })
            .collect();
        let err = open(&cfg, "plcd", Arc::default()).unwrap_err();
        assert_eq!(
            err.to_string(),
            "65 input lines configured, but one GPIO line request holds at most 64"
        );
    }
}
