//! When a session was last in use, so the registry can end the sessions nobody uses
//! (`limits.idle_timeout_s`): a session is in use while a stream client is connected, and each
//! accepted input is a use.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::Session;

/// The last use of a session, and whether it ever accepted input.
pub(super) struct LastUse {
    at: Mutex<Instant>,
    fed: AtomicBool,
}

impl LastUse {
    /// Creation is the first use.
    pub(super) fn new() -> Self {
        Self {
            at: Mutex::new(Instant::now()),
            fed: AtomicBool::new(false),
        }
    }

    /// Records a use now; `fed` when it was accepted input.
    pub(super) fn touch(&self, fed: bool) {
        if let Ok(mut at) = self.at.lock() {
            *at = Instant::now();
        }
        if fed {
            self.fed.store(true, Ordering::Relaxed);
        }
    }
}

impl Session {
    /// How long the session has gone unused: since its last accepted input or its last stream
    /// client leaving. None while a client is connected.
    pub fn unused_for(&self) -> Option<Duration> {
        if self.clients() > 0 {
            return None;
        }
        self.last_use.at.lock().ok().map(|at| at.elapsed())
    }

    /// Whether the session ever accepted input (and so has results to keep).
    pub fn ever_fed(&self) -> bool {
        self.last_use.fed.load(Ordering::Relaxed)
    }
}
