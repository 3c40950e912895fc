//! Clocks for the simulator: real time, or a virtual clock the test advances.

use std::sync::{Arc, Mutex};
use std::time::Instant;

/// A monotonic clock in seconds.
pub trait Clock: Send + Sync + std::fmt::Debug {
    /// Seconds since the clock's epoch.
    fn now_s(&self) -> f64;
}

/// Wall-clock time since creation.
#[derive(Debug, Clone, Copy)]
pub struct RealClock {
    epoch: Instant,
}

impl RealClock {
    /// A clock starting at 0 now.
    pub fn new() -> Self {
        RealClock {
            epoch: Instant::now(),
        }
    }
}

impl Default for RealClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for RealClock {
    fn now_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }
}

/// A simulated clock, shared by its clones, that only moves when told to.
#[derive(Debug, Clone, Default)]
pub struct VirtualClock {
    now_s: Arc<Mutex<f64>>,
}

impl VirtualClock {
    /// A clock at 0 s.
    pub fn new() -> Self {
        Self::default()
    }

    /// Moves the clock forward by `dt_s` (negative values are ignored).
    pub fn advance(&self, dt_s: f64) {
        if let Ok(mut t) = self.now_s.lock()
            && dt_s > 0.0
        {
            *t += dt_s;
        }
    }
}

impl Clock for VirtualClock {
    fn now_s(&self) -> f64 {
        self.now_s.lock().map(|t| *t).unwrap_or(0.0)
    }
}
