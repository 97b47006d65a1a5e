//! Which optional outputs any subscriber of a session wants, so the worker does not broadcast
//! separated audio or measurements that nobody reads (each broadcast wakes every subscriber's
//! task; audio is a message per label and STFT hop).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use tokio::sync::broadcast;

use super::Output;
use crate::protocol::OutputSelection;

/// How many subscribers want each optional output.
#[derive(Debug, Default)]
pub struct Interest {
    audio: AtomicUsize,
    measurements: AtomicUsize,
}

impl Interest {
    /// Whether any subscriber takes separated audio.
    pub fn audio(&self) -> bool {
        self.audio.load(Ordering::Acquire) > 0
    }

    /// Whether any subscriber takes the localiser's measurements.
    pub fn measurements(&self) -> bool {
        self.measurements.load(Ordering::Acquire) > 0
    }

    fn adjust(&self, audio: bool, measurements: bool, up: bool) {
        for (on, n) in [(audio, &self.audio), (measurements, &self.measurements)] {
            if on {
                if up {
                    n.fetch_add(1, Ordering::AcqRel);
                } else {
                    n.fetch_sub(1, Ordering::AcqRel);
                }
            }
        }
    }
}

/// A receiver of a session's outputs with its share of the session's [`Interest`]: everything
/// until [`Subscription::want`] narrows it (so outputs produced before a client's hello is read
/// still reach it, as they did before any selection existed), released when dropped.
pub struct Subscription {
    /// The session's output broadcast.
    pub outputs: broadcast::Receiver<Arc<Output>>,
    interest: Arc<Interest>,
    audio: bool,
    measurements: bool,
}

impl Subscription {
    pub(super) fn new(outputs: broadcast::Receiver<Arc<Output>>, interest: Arc<Interest>) -> Self {
        interest.adjust(true, true, true);
        Self {
            outputs,
            interest,
            audio: true,
            measurements: true,
        }
    }

    /// A claim on `output` in the same session's interest, off until set.
    pub fn claim(&self, output: OptionalOutput) -> Claim {
        Claim::new(self.interest.clone(), output)
    }

    /// Narrows (or widens) what this subscriber wants to `selection`.
    pub fn want(&mut self, selection: &OutputSelection) {
        let (audio, measurements) = (selection.audio.is_some(), selection.measurements);
        self.interest.adjust(self.audio, self.measurements, false);
        self.interest.adjust(audio, measurements, true);
        (self.audio, self.measurements) = (audio, measurements);
    }
}

impl Drop for Subscription {
    fn drop(&mut self) {
        self.interest.adjust(self.audio, self.measurements, false);
    }
}

/// An optional output a [`Claim`] is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OptionalOutput {
    /// Separated audio.
    Audio,
    /// The localiser's measurements.
    Measurements,
}

/// A share of the session's [`Interest`] in one optional output that any thread may switch on
/// and off (a Zenoh matching listener's callback does, as subscribers come and go); off at
/// first, released when dropped.
#[derive(Debug)]
pub struct Claim {
    interest: Arc<Interest>,
    output: OptionalOutput,
    on: AtomicBool,
}

impl Claim {
    /// An unclaimed share of `interest` in `output`.
    pub fn new(interest: Arc<Interest>, output: OptionalOutput) -> Self {
        Self {
            interest,
            output,
            on: AtomicBool::new(false),
        }
    }

    /// Claims the output (`true`) or lets it go; repeating a state changes nothing.
    pub fn set(&self, on: bool) {
        if self.on.swap(on, Ordering::AcqRel) != on {
            let audio = self.output == OptionalOutput::Audio;
            self.interest.adjust(audio, !audio, on);
        }
    }

    /// Whether the output is claimed.
    pub fn is_on(&self) -> bool {
        self.on.load(Ordering::Acquire)
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        self.set(false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_what_subscribers_want_until_they_leave() {
        let interest = Arc::new(Interest::default());
        let (tx, _) = broadcast::channel::<Arc<Output>>(4);
        let mut a = Subscription::new(tx.subscribe(), interest.clone());
        assert!(
            interest.audio() && interest.measurements(),
            "all until told"
        );
        a.want(&OutputSelection::default());
        assert!(!interest.audio() && !interest.measurements());
        let b = Subscription::new(tx.subscribe(), interest.clone());
        assert!(interest.audio());
        a.want(&OutputSelection {
            measurements: true,
            ..OutputSelection::default()
        });
        drop(b);
        assert!(!interest.audio() && interest.measurements());
        drop(a);
        assert!(!interest.measurements());
    }

    #[test]
    fn a_claim_counts_once_while_on_and_not_after_it_is_dropped() {
        let interest = Arc::new(Interest::default());
        let audio = Claim::new(interest.clone(), OptionalOutput::Audio);
        assert!(!interest.audio() && !audio.is_on());
        audio.set(true);
        audio.set(true);
        assert!(interest.audio() && !interest.measurements());
        let measurements = Claim::new(interest.clone(), OptionalOutput::Measurements);
        measurements.set(true);
        audio.set(false);
        assert!(!interest.audio() && interest.measurements());
        audio.set(true);
        drop(audio);
        drop(measurements);
        assert!(!interest.audio() && !interest.measurements());
    }
}
