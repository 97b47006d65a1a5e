//! A pipeline with test hooks, run as a session's engine through the registry.

use avsep::pipeline::{
    ConfigError, EventSink, InputError, Pipeline, PipelineConfig, PipelineEvent,
};
use avsep::scene::{AudioMeasurementFrame, DetectionFrame};
use avsep::server::engine::Engine;
use avsep::server::session::SessionSpec;

use super::{TestServer, settings};

/// A pipeline with test hooks: `on_audio` sees each audio block's first sample before the
/// pipeline does; `on_event` passes each event on to the sink (and may act around it).
pub struct Hooked {
    pub inner: Pipeline,
    pub on_audio: Box<dyn FnMut(u64) + Send>,
    pub on_event: Box<EventHook>,
}

/// What [`Hooked`] does with each event: pass it on to the sink, and act around that.
pub type EventHook = dyn FnMut(PipelineEvent, &mut EventSink<'_>) + Send;

impl Hooked {
    /// The pipeline without hooks.
    pub fn new(inner: Pipeline) -> Self {
        Self {
            inner,
            on_audio: Box::new(|_| {}),
            on_event: Box::new(|e, sink| sink(e)),
        }
    }

    /// The pipeline, stopping after its first step's tracks until the returned sender
    /// sends (or 20 s pass), like a separation that takes long.
    pub fn held_after_first_step(inner: Pipeline) -> (Self, std::sync::mpsc::Sender<()>) {
        let (release, gate) = std::sync::mpsc::channel::<()>();
        let mut held = false;
        let mut engine = Self::new(inner);
        engine.on_event = Box::new(move |e, sink| {
            let tracks = matches!(e, PipelineEvent::Tracks { .. });
            sink(e);
            if tracks && !held {
                held = true;
                let _ = gate.recv_timeout(std::time::Duration::from_secs(20));
            }
        });
        (engine, release)
    }
}

impl Engine for Hooked {
    fn push_audio(
        &mut self,
        first: u64,
        ch: usize,
        s: &[f32],
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        (self.on_audio)(first);
        let on_event = &mut self.on_event;
        self.inner
            .push_audio_to(first, ch, s, &mut |e| on_event(e, &mut *sink))
    }
    fn push_detections(
        &mut self,
        f: DetectionFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        let on_event = &mut self.on_event;
        self.inner
            .push_detections_to(f, &mut |e| on_event(e, &mut *sink))
    }
    fn push_device_measurements(
        &mut self,
        f: AudioMeasurementFrame,
        sink: &mut EventSink<'_>,
    ) -> Result<(), InputError> {
        let on_event = &mut self.on_event;
        self.inner
            .push_device_measurements_to(f, &mut |e| on_event(e, &mut *sink))
    }
    fn set_layout(&mut self, l: avsep::geometry::Layout) -> Result<(), ConfigError> {
        self.inner.set_layout(l)
    }
    fn update_config(&mut self, c: PipelineConfig) -> Result<(), ConfigError> {
        self.inner.update_config(c)
    }
    fn finish(&mut self, sink: &mut EventSink<'_>) {
        let on_event = &mut self.on_event;
        self.inner.finish_to(&mut |e| on_event(e, &mut *sink))
    }
}

/// The registry's description of a session made by hand (for a hooked engine).
pub fn hand_made_spec(
    server: &TestServer,
    id: &str,
    name: &str,
    token: &str,
    sc: &avsep::scene::Scene,
    pipeline: &Pipeline,
) -> SessionSpec {
    SessionSpec {
        id: id.into(),
        name: Some(name.into()),
        token: token.into(),
        step_s: pipeline.clock().step_s(),
        audio_delay_samples: pipeline.audio_delay_samples(),
        layout: sc.layout.clone(),
        settings: settings(8),
        limits: server.registry.config().limits.clone(),
        execution: server.registry.config().execution.clone(),
    }
}
