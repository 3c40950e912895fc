//! Stopping both devices (seed 001 §5.3: the operator's stop): the stop request that the signal,
//! the console and the e-stop share with the coordinator, and the stop commands themselves.

use std::sync::atomic::Ordering;

use super::*;

/// The stop request the signal, the console and the e-stop share with the coordinator. Making
/// it ([`StopRequest::request`]) sets the flag the coordinator looks at, abandons the exchange
/// under way on both links (their cancel tokens) and wakes the coordinator from its control
/// tick, so that it sends the stop commands at once (seed 001 §5.3: the operator's stop).
#[derive(Debug, Clone)]
pub struct StopRequest {
    flag: Arc<AtomicBool>,
    reason: Arc<std::sync::Mutex<String>>,
    interrupters: Vec<Arc<dyn Interrupt>>,
    pub(super) waiter: Arc<std::sync::Mutex<Option<std::thread::Thread>>>,
}

impl StopRequest {
    /// A request not made, for `devices` (whose exchanges it abandons).
    pub fn new(devices: &Devices) -> Self {
        Self::from_flag(Arc::new(AtomicBool::new(false)), devices)
    }

    /// A request that is made when `flag` is set, too (by whoever holds it).
    pub fn from_flag(flag: Arc<AtomicBool>, devices: &Devices) -> Self {
        StopRequest {
            flag,
            reason: Arc::new(std::sync::Mutex::new("interrupted".into())),
            interrupters: devices.interrupters(),
            waiter: Arc::new(std::sync::Mutex::new(None)),
        }
    }

    /// Asks the coordinator to stop both devices now, saying why.
    pub fn request(&self, reason: &str) {
        if let Ok(mut r) = self.reason.lock() {
            *r = reason.to_string();
        }
        self.flag.store(true, Ordering::SeqCst);
        for i in &self.interrupters {
            i.interrupt();
        }
        if let Ok(w) = self.waiter.lock()
            && let Some(t) = w.as_ref()
        {
            t.unpark();
        }
    }

    /// True once requested.
    pub fn is_requested(&self) -> bool {
        self.flag.load(Ordering::SeqCst)
    }

    /// Why.
    pub fn reason(&self) -> String {
        self.reason
            .lock()
            .map(|r| r.clone())
            .unwrap_or_else(|_| "interrupted".into())
    }

    /// Lets the devices' exchanges run again (the stop commands and their confirmation).
    pub(super) fn clear_interrupts(&self) {
        for i in &self.interrupters {
            i.clear();
        }
    }
}

impl Coordinator<'_> {
    /// Stops both devices (each tried whatever the other did); returns the errors.
    pub(super) fn stop_devices(&mut self) -> Vec<Arc<DeviceError>> {
        // The exchange a stop request abandoned is over: the stops and their confirmations
        // run. The indexer's `S` first, on the wire at once without waiting for its echo; then
        // the robot's STOP session (STOP before any status read); then the indexer's stop
        // again, confirmed by its echo.
        self.stop.clear_interrupts();
        let mut errors = Vec::new();
        let early = self.dev.mandrel.stop_on_wire();
        if let Err(e) = self.dev.robot.stop() {
            errors.push(Arc::new(e));
        }
        if let Err(e) = self.dev.mandrel.stop() {
            errors.push(Arc::new(early.err().unwrap_or(e)));
        }
        let _ = self.dev.sync.set_start(false);
        errors
    }
}
