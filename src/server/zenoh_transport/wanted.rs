//! Which of a session's optional outputs (separated audio, measurements) some Zenoh subscriber
//! wants. A probe publisher on each output's keys reports, through its matching listener,
//! whether any subscriber on the network intersects them; the session's interest follows, so
//! a session nobody listens to over Zenoh neither broadcasts nor publishes them.

use std::sync::Arc;

use zenoh::Wait;
use zenoh::pubsub::Publisher;

use crate::protocol::zenoh_keys::{output_audio_keys, output_measurement_keys};
use crate::server::session::{Claim, OptionalOutput, Output, Subscription};

/// The fan-out's claims on the optional outputs, kept by the probes' matching listeners.
pub(super) struct Wanted {
    audio: Arc<Claim>,
    measurements: Arc<Claim>,
    /// Undeclaring a probe ends its listener, so they live as long as the fan-out.
    _probes: Vec<Publisher<'static>>,
}

impl Wanted {
    /// Declares the probes of session `id`'s optional outputs, with claims in `subscription`'s
    /// interest. A probe Zenoh refuses leaves its output claimed, published as before probes.
    pub(super) fn declare(z: &zenoh::Session, id: &str, subscription: &Subscription) -> Self {
        let audio = Arc::new(subscription.claim(OptionalOutput::Audio));
        let measurements = Arc::new(subscription.claim(OptionalOutput::Measurements));
        let mut probes = Vec::new();
        for (claim, key) in [
            (&audio, output_audio_keys(id)),
            (&measurements, output_measurement_keys(id)),
        ] {
            let c = claim.clone();
            let probe = z.declare_publisher(key.clone()).wait().and_then(|p| {
                p.matching_listener()
                    .callback(move |status| c.set(status.matching()))
                    .background()
                    .wait()?;
                Ok(p)
            });
            match probe {
                Ok(p) => probes.push(p),
                Err(e) => {
                    tracing::warn!(%key, "no matching listener, publishing regardless: {e}");
                    claim.set(true);
                }
            }
        }
        Self {
            audio,
            measurements,
            _probes: probes,
        }
    }

    /// Whether `out` goes to Zenoh: always, unless it is an optional output nobody wants.
    pub(super) fn wants(&self, out: &Output) -> bool {
        match out {
            Output::Audio { .. } => self.audio.is_on(),
            Output::Measurements(_) => self.measurements.is_on(),
            _ => true,
        }
    }
}
