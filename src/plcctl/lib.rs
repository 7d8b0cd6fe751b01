//! `plcctl`: the command-line client of the daemon's control socket.
//!
//! [`client`] is the reusable part: a [`client::Client`] that connects, sends a
//! [`Request`] and returns its [`Reply`] or a [`client::ClientError`]. The rest is the command
//! line: [`Cli`] (clap), socket discovery ([`choose_socket`]), and one module per command
//! group that renders its replies for a human. `main.rs` only parses and calls
//! [`run`].

#![forbid(unsafe_code)]

pub mod client;
pub mod debug;
pub mod devices;
pub mod forces;
pub mod format;
pub mod load;
pub mod mode;
pub mod status;

use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};

use client::{Answer, Client, ClientError};
use plcd_core::duration::parse_duration;
use plcd_ipc::{self as protocol, Reply, Request};

/// The exit statuses, for `--help` and the docs.
pub const EXIT_STATUS_HELP: &str = "\
Exit status:
  0  success
  1  the daemon answered with an error (refused, invalid, busy, denied, ...)
  2  usage error
  3  cannot reach the daemon (no socket, connection refused, permission denied, timeout)
  4  protocol error (not a valid answer, another protocol version, closed before answering)

Socket: --socket, else $PLCD_SOCKET, else the first that exists of /run/plcd/plcd.sock,
$XDG_RUNTIME_DIR/plcd.sock and /tmp/plcd-$UID/plcd.sock.";

/// Success.
pub const EXIT_OK: u8 = 0;
/// The daemon answered with an error.
pub const EXIT_DAEMON_ERROR: u8 = 1;
/// Bad usage (clap's own status).
pub const EXIT_USAGE: u8 = 2;
/// The daemon cannot be reached.
pub const EXIT_UNREACHABLE: u8 = 3;
/// The peer does not speak this protocol.
pub const EXIT_PROTOCOL: u8 = 4;

/// The command line.
#[derive(Debug, Parser)]
#[command(
    name = "plcctl",
    version,
    about = "Control a running plcd through its control socket",
    after_help = EXIT_STATUS_HELP
)]
pub struct Cli {
    /// The daemon's control socket [default: $PLCD_SOCKET, else the first existing of
    /// /run/plcd/plcd.sock, $XDG_RUNTIME_DIR/plcd.sock, /tmp/plcd-$UID/plcd.sock].
    #[arg(long, global = true, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Print the daemon's answer as one JSON line (the `ok` or the `error` object).
    #[arg(long, global = true)]
    pub json: bool,
    /// The longest to wait for the connection, and then for each answer.
    #[arg(long, global = true, value_name = "DURATION", default_value = "5s",
        value_parser = parse_positive_duration)]
    pub timeout: Duration,
    #[command(subcommand)]
    pub command: Command,
}

/// The commands, one [`Request`] each (`watch`: one `get` per sample).
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Mode, error, key switch, scan and task figures, forces, debugger.
    Status,
    /// Go to RUN (also out of DEBUG, keeping device memory).
    Run,
    /// Go to STOP.
    Stop,
    /// Clear a latched error and go to STOP.
    Reset(mode::ResetArgs),
    /// Enter DEBUG mode: the program runs only by `step` and `continue`.
    Debug,
    /// In DEBUG: run to the next line (paused in a program) or through a scan, or to a
    /// breakpoint.
    Step(debug::StepArgs),
    /// In DEBUG: run until a breakpoint is reached.
    Continue,
    /// Set a breakpoint.
    Break(debug::BreakArgs),
    /// Remove a breakpoint, or all of them.
    Unbreak(debug::UnbreakArgs),
    /// Show the force table.
    Forces,
    /// Force a P bit (or a BOOL variable located at one) to a value.
    Force(forces::ForceArgs),
    /// Remove the force of one P bit (or BOOL variable located at one), or of all.
    Unforce(forces::UnforceArgs),
    /// Read devices and variables (as of a scan boundary).
    Get(devices::GetArgs),
    /// Write devices and variables at the next END, all in one request.
    Set(devices::SetArgs),
    /// Read devices and variables every interval, one line per sample, until --count or Ctrl-C.
    Watch(devices::WatchArgs),
    /// Validate a project and swap it in (in STOP, or online in RUN).
    Load(load::LoadArgs),
}

/// What a command does: one request, or `watch`'s series of them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Action<'a> {
    Request(Request),
    Watch(&'a devices::WatchArgs),
}

impl Command {
    /// The request of a command, or `watch`; a usage error the parser could not see (a `set`
    /// name without its value).
    pub fn action(&self) -> Result<Action<'_>, String> {
        Ok(Action::Request(match self {
            Command::Status => Request::Status,
            Command::Run => Request::Run,
            Command::Stop => Request::Stop,
            Command::Reset(args) => Request::Reset { cold: args.cold },
            Command::Debug => Request::Debug,
            Command::Step(args) => Request::Step { scan: args.scan },
            Command::Continue => Request::Continue,
            Command::Break(args) => Request::Break { at: args.at() },
            Command::Unbreak(args) => Request::Unbreak { at: args.at() },
            Command::Forces => Request::Forces,
            Command::Force(args) => args.request()?,
            Command::Unforce(args) => args.request(),
            Command::Get(args) => args.request(),
            Command::Set(args) => args.request()?,
            Command::Watch(args) => return Ok(Action::Watch(args)),
            Command::Load(args) => args.request(),
        }))
    }
}

/// Where `--socket` came from, for the hint when it cannot be connected to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SocketSource {
    Flag,
    Env,
    /// The first default path that exists.
    Found,
    /// None of these default paths exists; the first is used.
    Default(Vec<PathBuf>),
}

/// The socket to connect to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SocketChoice {
    pub path: PathBuf,
    pub source: SocketSource,
}

/// `--socket`, else `$PLCD_SOCKET` (when not empty), else the first of
/// [`protocol::default_socket_paths`] that `exists`, else the first of them.
pub fn choose_socket(
    flag: Option<&Path>,
    env: Option<&OsStr>,
    uid: u32,
    xdg_runtime_dir: Option<&str>,
    exists: impl Fn(&Path) -> bool,
) -> SocketChoice {
    if let Some(path) = flag {
        return SocketChoice { path: path.to_path_buf(), source: SocketSource::Flag };
    }
    if let Some(path) = env.filter(|p| !p.is_empty()) {
        return SocketChoice { path: PathBuf::from(path), source: SocketSource::Env };
    }
    let candidates: Vec<PathBuf> = protocol::default_socket_paths(uid, xdg_runtime_dir)
        .into_iter()
        .map(PathBuf::from)
        .collect();
    match candidates.iter().find(|p| exists(p)) {
        Some(path) => SocketChoice { path: path.clone(), source: SocketSource::Found },
        None => {
            SocketChoice { path: candidates[0].clone(), source: SocketSource::Default(candidates) }
        }
    }
}

/// The socket of this process: its flag, environment and effective uid.
pub fn socket_from_env(flag: Option<&Path>) -> SocketChoice {
    let env = std::env::var_os("PLCD_SOCKET");
    let xdg = std::env::var("XDG_RUNTIME_DIR").ok();
    choose_socket(flag, env.as_deref(), nix::unistd::geteuid().as_raw(), xdg.as_deref(), |p| {
        p.exists()
    })
}

/// Runs a parsed command line; returns the exit status.
pub fn run(cli: &Cli, out: &mut dyn Write, err: &mut dyn Write) -> ExitCode {
    let mut session = Session {
        json: cli.json,
        socket: socket_from_env(cli.socket.as_deref()),
        timeout: cli.timeout,
        out,
        err,
    };
    let status = match cli.command.action() {
        Ok(Action::Request(request)) => session.one_shot(&request),
        Ok(Action::Watch(args)) => devices::watch(&mut session, args),
        Err(usage) => {
            // As clap reports the errors it finds.
            let _ = writeln!(session.err, "error: {usage}\n\nFor more information, try '--help'.");
            EXIT_USAGE
        }
    };
    ExitCode::from(status)
}

/// What a command needs: where to connect, how to print.
pub struct Session<'a> {
    pub json: bool,
    pub socket: SocketChoice,
    pub timeout: Duration,
    pub out: &'a mut dyn Write,
    pub err: &'a mut dyn Write,
}

impl Session<'_> {
    pub fn connect(&self) -> Result<Client, ClientError> {
        Client::connect(&self.socket.path, self.timeout)
    }

    /// Connects, sends `request`, prints the answer; the exit status.
    pub fn one_shot(&mut self, request: &Request) -> u8 {
        let answer = self.connect().and_then(|mut client| client.exchange(request));
        match answer {
            Ok(answer) => {
                self.print_answer(request, &answer);
                EXIT_OK
            }
            Err(e) => self.fail(&e),
        }
    }

    /// The answer on stdout: its `ok` object with `--json`, else for a human.
    fn print_answer(&mut self, request: &Request, answer: &Answer) {
        let text = if self.json { json_line(&answer.raw) } else { render(request, &answer.reply) };
        let _ = self.out.write_all(text.as_bytes());
        let _ = self.out.flush();
    }

    /// Reports `error` and returns its exit status. With `--json`, an error answer is printed
    /// as its `error` object on stdout; everything else goes to stderr as
    /// `plcctl: message` and the details, one per line.
    pub fn fail(&mut self, error: &ClientError) -> u8 {
        if let (true, ClientError::Daemon { raw, .. }) = (self.json, error) {
            let _ = self.out.write_all(json_line(raw).as_bytes());
            let _ = self.out.flush();
            return error.exit_code();
        }
        let mut text = format!("plcctl: {error}\n");
        for detail in error.details() {
            text.push_str(&detail);
            text.push('\n');
        }
        if let ClientError::Connect { .. } | ClientError::ConnectTimeout { .. } = error {
            text.push_str(&socket_hint(&self.socket));
        }
        let _ = self.err.write_all(text.as_bytes());
        error.exit_code()
    }
}

/// Where the socket path came from, when it could not be connected to.
fn socket_hint(socket: &SocketChoice) -> String {
    match &socket.source {
        SocketSource::Flag => String::new(),
        SocketSource::Env => "(the socket named by $PLCD_SOCKET)\n".to_string(),
        SocketSource::Found => String::new(),
        SocketSource::Default(candidates) => {
            let list: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
            format!(
                "looked for {}; name the socket with --socket or $PLCD_SOCKET\n",
                list.join(", ")
            )
        }
    }
}

/// A reply for a human, by its kind. The request gives context (the file a `load` named).
pub fn render(request: &Request, reply: &Reply) -> String {
    match reply {
        Reply::Status(s) => status::render(s),
        Reply::Mode { mode } => mode::render(*mode),
        Reply::Values { values, .. } => devices::render_values(values),
        Reply::Written { scan, count } => devices::render_written(*scan, *count),
        Reply::Forces { forces } => forces::render(forces),
        Reply::Loaded { online, programs, tasks, mode } => {
            let config = match request {
                Request::Load { config, .. } => Some(config.as_str()),
                _ => None,
            };
            load::render(config, *online, *programs, *tasks, *mode)
        }
        Reply::Debug(state) => debug::render(state),
    }
}

/// One line of JSON.
pub fn json_line(value: &serde_json::Value) -> String {
    let mut line = value.to_string();
    line.push('\n');
    line
}

/// A duration as `parse_duration` reads it, more than zero.
pub fn parse_positive_duration(text: &str) -> Result<Duration, String> {
    match parse_duration(text)? {
        0 => Err("must be more than 0".to_string()),
        ns => Ok(Duration::from_nanos(ns)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn socket_discovery_order() {
        let flag = Path::new("/x/flag.sock");
        let env = OsStr::new("/x/env.sock");
        let none = |_: &Path| false;
        let c = choose_socket(Some(flag), Some(env), 1000, Some("/run/user/1000"), none);
        assert_eq!(c, SocketChoice { path: flag.into(), source: SocketSource::Flag });
        let c = choose_socket(None, Some(env), 1000, Some("/run/user/1000"), none);
        assert_eq!(c, SocketChoice { path: env.into(), source: SocketSource::Env });
        let c = choose_socket(None, Some(OsStr::new("")), 1000, Some("/run/user/1000"), |p| {
            p == Path::new("/tmp/plcd-1000/plcd.sock")
        });
        assert_eq!(c.path, Path::new("/tmp/plcd-1000/plcd.sock"));
        assert_eq!(c.source, SocketSource::Found);
        let c = choose_socket(None, None, 1000, Some("/run/user/1000"), none);
        assert_eq!(c.path, Path::new("/run/plcd/plcd.sock"));
        assert!(matches!(c.source, SocketSource::Default(ref all) if all.len() == 3));
    }

    #[test]
    fn the_command_line_parses() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
        let cli = Cli::try_parse_from(["plcctl", "get", "D10", "--json", "--timeout", "1s"]);
        let cli = cli.unwrap();
        assert!(cli.json);
        assert_eq!(cli.timeout, Duration::from_secs(1));
        assert!(Cli::try_parse_from(["plcctl", "--timeout", "0s", "status"]).is_err());
    }
}
