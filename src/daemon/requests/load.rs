//! The `load` request: a new project, validated first (any error is answered with every
//! diagnostic, the running project untouched), then swapped in by the scan thread — in STOP or
//! ERROR as a replacement that stays in STOP, in RUN or DEBUG with `--online` as an online
//! change at a scan boundary ([`crate::engine::online`]). The new project is the running one
//! from the moment it is sent; a refusal at the scan thread puts the old one back.

use std::path::Path;

use super::mode::mode_name;
use super::waiting::Then;
use super::{failure, RequestHandler, Running};
use crate::config::ProjectChange;
use crate::drivers::real_time::{Applied, ControlCommand};
use crate::engine::event::Mode;
use crate::engine::{online, Engine};
use crate::files;
use crate::services::control::ClientId;
use plcd_ipc::{ErrorKind as Kind, Failure, Reply, ResponseLine};

impl RequestHandler {
    pub(super) fn load(
        &mut self,
        client: ClientId,
        config: &str,
        online: bool,
    ) -> Option<ResponseLine> {
        let path = Path::new(config);
        if !path.is_absolute() {
            return Some(failure(
                Kind::Invalid,
                format!("`{config}`: give the daemon an absolute path"),
            ));
        }
        let new = match files::project(path) {
            Ok(project) => project,
            Err(diagnostics) => {
                let details = diagnostics.iter().map(ToString::to_string).collect();
                return Some(ResponseLine::failure(
                    Failure::new(
                        Kind::Invalid,
                        format!(
                            "{} errors in {config}; the running project is unchanged",
                            diagnostics.len()
                        ),
                    )
                    .with_details(details),
                ));
            }
        };
        let mut running = self.running();
        let restart: Vec<String> = running
            .project
            .config
            .refused_sections(&new.config, ProjectChange::Load)
            .into_iter()
            .map(|name| format!("{name} changed, which takes a restart of the service"))
            .collect();
        if !restart.is_empty() {
            return Some(ResponseLine::failure(
                Failure::new(Kind::Refused, "load refused; the running project is unchanged")
                    .with_details(restart),
            ));
        }
        let mode = self.links.shared.mode();
        let running_now = matches!(mode, Mode::Run | Mode::Debug);
        if running_now && !online {
            return Some(failure(
                Kind::Refused,
                "the PLC is in RUN: stop it first, or load --online",
            ));
        }
        let watch = new.output_bits();
        let announce = |engine: &Engine| {
            if let Some(announce) = &self.links.announce {
                announce(engine, &new);
            }
        };
        let command = if running_now {
            match online::prepare(&running.project, &new, &watch) {
                Ok(change) => {
                    announce(&change.engine);
                    ControlCommand::Online(Box::new(change))
                }
                Err(reasons) => {
                    return Some(ResponseLine::failure(
                        Failure::new(
                            Kind::Refused,
                            "online change refused; the running project is unchanged",
                        )
                        .with_details(reasons),
                    ))
                }
            }
        } else {
            let engine = Engine::new(&new, &watch);
            announce(&engine);
            ControlCommand::Load(Box::new(engine))
        };
        let (programs, tasks) = (new.programs.len(), new.config.tasks.len());
        // The new project is the running one from now on (the supervisor names the new
        // engine's reports with it); a refusal at the scan thread puts the old one back.
        let previous = std::mem::replace(&mut *running, Running::new(path, new));
        drop(running);
        match self.send(vec![command]) {
            Ok(tickets) => {
                let then = Then::Loaded {
                    online: running_now,
                    programs,
                    tasks,
                    previous: Some(Box::new(previous)),
                };
                self.wait_for(client, tickets, then);
                None
            }
            Err(f) => {
                *self.running() = previous;
                Some(ResponseLine::failure(f))
            }
        }
    }

    /// The answer to an applied load, logged.
    pub(super) fn loaded(
        &self,
        online: bool,
        programs: usize,
        tasks: usize,
        applied: Applied,
    ) -> ResponseLine {
        let running = self.running();
        log::info!(
            "loaded {} ({programs} programs, {tasks} tasks){}",
            running.config_path.display(),
            if online { " as an online change" } else { "" }
        );
        drop(running);
        ResponseLine::ok(Reply::Loaded { online, programs, tasks, mode: mode_name(applied.mode) })
    }
}
