//! Serving a simulator on pseudo-terminals, for every `windcell sim-*` subcommand: the signals it
//! serves under, the pseudo-terminals whose slave paths it prints, and their slave ends held open
//! while it serves (so that a master never sees a hang-up before a client has opened its slave).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use asea_protocol::link::SerialLink;
use serialport::{SerialPort, TTYPort};

use super::Failure;

/// The master end of a pseudo-terminal, as a link.
pub type Pty = SerialLink<Box<TTYPort>>;

/// The signals a simulator serves under: SIGINT and SIGTERM end it; SIGUSR1 and SIGUSR2 are its
/// fault-injection switches.
#[derive(Debug, Clone, Default)]
pub struct Signals {
    /// Set by SIGINT or SIGTERM.
    pub stop: Arc<AtomicBool>,
    /// Set by SIGUSR1 (when the switches are registered).
    pub usr1: Arc<AtomicBool>,
    /// Set by SIGUSR2 (when the switches are registered).
    pub usr2: Arc<AtomicBool>,
}

impl Signals {
    /// Registers the stop signals and, with `fault_switches`, SIGUSR1 and SIGUSR2, for the
    /// subcommand `cmd` (named in the error).
    pub fn register(cmd: &str, fault_switches: bool) -> Result<Self, Failure> {
        let s = Signals::default();
        let mut wanted = vec![
            (signal_hook::consts::SIGINT, &s.stop),
            (signal_hook::consts::SIGTERM, &s.stop),
        ];
        if fault_switches {
            wanted.push((signal_hook::consts::SIGUSR1, &s.usr1));
            wanted.push((signal_hook::consts::SIGUSR2, &s.usr2));
        }
        for (signal, flag) in wanted {
            signal_hook::flag::register(signal, flag.clone())
                .map_err(|e| Failure::runtime(format!("{cmd}: signal handler: {e}")))?;
        }
        Ok(s)
    }
}

/// Pseudo-terminals a simulator serves on.
#[derive(Debug)]
pub struct Ptys {
    cmd: String,
    masters: Vec<Pty>,
    slaves: Vec<TTYPort>,
}

impl Ptys {
    /// `n` new pseudo-terminals for the subcommand `cmd` (named in the errors).
    pub fn open(cmd: &str, n: usize) -> Result<Self, Failure> {
        let mut ptys = Ptys {
            cmd: cmd.to_string(),
            masters: Vec::with_capacity(n),
            slaves: Vec::with_capacity(n),
        };
        for _ in 0..n {
            let (master, slave) = TTYPort::pair()
                .map_err(|e| Failure::runtime(format!("{cmd}: pseudo-terminal: {e}")))?;
            ptys.masters.push(SerialLink(Box::new(master)));
            ptys.slaves.push(slave);
        }
        Ok(ptys)
    }

    /// The slave device paths, in order, as a client opens them.
    pub fn paths(&self) -> Result<Vec<String>, Failure> {
        self.slaves
            .iter()
            .map(|s| {
                s.name().ok_or_else(|| {
                    Failure::runtime(format!(
                        "{}: the pseudo-terminal has no device path",
                        self.cmd
                    ))
                })
            })
            .collect()
    }

    /// Runs `serve` on the master ends, the slave ends open until it returns; its error is a
    /// runtime failure named after the subcommand.
    pub fn serve<R, E: std::fmt::Display>(
        self,
        serve: impl FnOnce(Vec<Pty>) -> Result<R, E>,
    ) -> Result<R, Failure> {
        let cmd = self.cmd.clone();
        self.serve_failing(|masters| {
            serve(masters).map_err(|e| Failure::runtime(format!("{cmd}: {e}")))
        })
    }

    /// [`Ptys::serve`] for a `serve` whose errors are already failures.
    pub fn serve_failing<R>(
        self,
        serve: impl FnOnce(Vec<Pty>) -> Result<R, Failure>,
    ) -> Result<R, Failure> {
        let served = serve(self.masters);
        drop(self.slaves);
        served
    }
}

/// The log records of the stop commands a tap saw since the last call
/// ([`cell::sim::wiretap::StopTap`]): `{"device", "stop_received": true, "t_s", "unix_s"}`, the
/// simulator's clock time `t_s` and the wall time the command arrived.
pub fn stop_records(
    device: &str,
    stops: &cell::sim::wiretap::StopTimes,
    t_s: f64,
) -> Vec<serde_json::Value> {
    let arrived: Vec<f64> = stops
        .lock()
        .map(|mut s| s.drain(..).collect())
        .unwrap_or_default();
    arrived
        .into_iter()
        .map(|unix_s| {
            serde_json::json!({"device": device, "stop_received": true, "t_s": t_s,
                "unix_s": unix_s})
        })
        .collect()
}
