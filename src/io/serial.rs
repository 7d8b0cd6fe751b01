//! Serial ports for Modbus RTU: a [`SerialLine`] of the config opened with its settings, for
//! the remote I/O pollers ([`super::remote`]) and the Modbus RTU server.
//!
//! The `serialport` crate does the termios work (raw mode, any baud rate through termios2,
//! parity, stop bits, exclusive access, reads with a timeout). A port is opened exclusively
//! (`TIOCEXCL` and `flock`), so two processes, or two threads of this one, never share a line
//! by accident: devices on one port are polled by one thread.

use std::io;
use std::path::PathBuf;
use std::time::Duration;

use serialport::{ClearBuffer, DataBits, SerialPort, StopBits, TTYPort};

use crate::config::{Parity, SerialLine};

/// Why a serial port could not be opened or set up.
#[derive(Debug, thiserror::Error)]
#[error("serial port {}: {source}", port.display())]
pub struct SerialError {
    pub port: PathBuf,
    #[source]
    pub source: serialport::Error,
}

/// An open serial port, set up with a line's settings.
pub struct Port {
    tty: TTYPort,
}

impl Port {
    /// Opens `line.port` exclusively in raw mode with the line's settings.
    pub fn open(line: &SerialLine) -> Result<Port, SerialError> {
        let err = |source| SerialError { port: line.port.clone(), source };
        let parity = match line.parity {
            Parity::None => serialport::Parity::None,
            Parity::Even => serialport::Parity::Even,
            Parity::Odd => serialport::Parity::Odd,
        };
        let stop_bits = if line.stop_bits == 2 { StopBits::Two } else { StopBits::One };
        let builder = serialport::new(line.port.to_string_lossy(), line.baud)
            .data_bits(DataBits::Eight)
            .parity(parity)
            .stop_bits(stop_bits)
            .flow_control(serialport::FlowControl::None)
            .timeout(Duration::from_millis(100));
        let tty = TTYPort::open(&builder).map_err(err)?;
        // Bytes received before the settings applied may be garbled.
        tty.clear(ClearBuffer::All).map_err(err)?;
        Ok(Port { tty })
    }

    /// Reads what has arrived, waiting at most `timeout` for the first byte: `Ok(0)` if
    /// nothing came.
    pub fn read_within(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.tty.set_timeout(timeout).map_err(io::Error::from)?;
        match io::Read::read(&mut self.tty, buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
            Err(e) => Err(e),
        }
    }

    /// Writes a whole frame and waits until it has left the UART (`tcdrain`).
    pub fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.tty.set_timeout(Duration::from_secs(1)).map_err(io::Error::from)?;
        io::Write::write_all(&mut self.tty, frame)?;
        io::Write::flush(&mut self.tty)
    }

    /// Drops every byte received and not yet read (a late answer, line noise).
    pub fn discard_input(&mut self) -> io::Result<()> {
        self.tty.clear(ClearBuffer::Input).map_err(io::Error::from)
    }
}
