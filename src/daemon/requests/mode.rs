//! Mode requests: `run`, `stop`, `reset [--cold]` and `debug`, each a remote mode request the
//! engine decides on at a scan boundary (the key switch and a latched error may refuse it). The
//! answer is the mode after it; `debug` answers with the debugger's state once execution is
//! paused, since from RUN the current scan ends first.

use super::waiting::Then;
use super::RequestHandler;
use crate::drivers::real_time::{Applied, ControlCommand};
use crate::engine::event::Mode;
use crate::engine::ModeRequest;
use crate::services::control::ClientId;
use plcd_ipc::{ModeName, Reply, ResponseLine};

impl RequestHandler {
    pub(super) fn mode(&mut self, client: ClientId, request: ModeRequest) -> Option<ResponseLine> {
        let then = match request {
            // From RUN the current scan ends first: answered once paused.
            ModeRequest::Debug => Then::Debug { unbroken: None, devices: None, until_paused: true },
            ModeRequest::Run | ModeRequest::Stop | ModeRequest::Reset { .. } => Then::Mode,
        };
        self.park(client, vec![ControlCommand::Mode(request)], then)
    }
}

/// The answer to an applied mode request.
pub(super) fn applied(applied: Applied) -> ResponseLine {
    ResponseLine::ok(Reply::Mode { mode: mode_name(applied.mode) })
}

pub(super) fn mode_name(mode: Mode) -> ModeName {
    match mode {
        Mode::Run => ModeName::Run,
        Mode::Stop => ModeName::Stop,
        Mode::Error => ModeName::Error,
        Mode::Debug => ModeName::Debug,
    }
}
