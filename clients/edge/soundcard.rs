//! Sound-card capture (cpal, `--features soundcard`): the device's input at the session's sample
//! rate and channel count, cut into the feed's blocks as it arrives.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use avsep::protocol::rest::SessionInfo;
use avsep::server::client::FeedItem;
use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
use cpal::{FromSample, SampleFormat, SizedSample};
use tokio::sync::mpsc::{UnboundedReceiver, UnboundedSender, unbounded_channel};

use super::live::LiveFeed;

/// A running capture; dropping it stops the sound card and ends the feed.
pub struct Capture {
    _stream: cpal::Stream,
    _stop: tokio::task::JoinHandle<()>,
}

/// Starts capturing from `device` (a cpal device id, or the default input device); the feed
/// ends after `seconds`, or at ctrl-c.
pub fn start(
    device: Option<&str>,
    info: &SessionInfo,
    seconds: Option<f64>,
    feed: LiveFeed,
) -> Result<(UnboundedReceiver<FeedItem>, Capture), String> {
    let host = cpal::default_host();
    let dev = match device {
        Some(id) => {
            let id = id
                .parse()
                .map_err(|e| format!("--device {id:?} is not a cpal device id: {e}"))?;
            host.device_by_id(&id)
                .ok_or_else(|| format!("no sound card with id {id}"))?
        }
        None => host
            .default_input_device()
            .ok_or("this machine has no default input device")?,
    };
    let config = input_config(&dev, info)?;
    let (channels, rate) = (config.channels(), config.sample_rate());
    let (tx, rx) = unbounded_channel();
    let feed = Arc::new(Mutex::new(Some((feed, tx))));
    let stream = match config.sample_format() {
        SampleFormat::F32 => build::<f32>(&dev, config.config(), feed.clone()),
        SampleFormat::I16 => build::<i16>(&dev, config.config(), feed.clone()),
        SampleFormat::I32 => build::<i32>(&dev, config.config(), feed.clone()),
        f => return Err(format!("{dev}: sample format {f} is not supported here")),
    }?;
    stream.play().map_err(|e| format!("{dev}: {e}"))?;
    eprintln!("capturing {channels} channels at {rate} Hz from {dev}");
    let stop = tokio::spawn(async move {
        match seconds {
            Some(s) => tokio::time::sleep(Duration::from_secs_f64(s.max(0.0))).await,
            None => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
        // The last partial block and the side messages left, then the feed's end (`finish`).
        if let Some((feed, tx)) = feed.lock().ok().and_then(|mut f| f.take()) {
            for item in feed.finish() {
                let _ = tx.send(item);
            }
        }
    });
    Ok((
        rx,
        Capture {
            _stream: stream,
            _stop: stop,
        },
    ))
}

/// The device's input configuration at the session's rate and channel count, in a sample format
/// the callback converts.
fn input_config(
    dev: &cpal::Device,
    info: &SessionInfo,
) -> Result<cpal::SupportedStreamConfig, String> {
    let channels = info.channels as u16;
    let rate = info.sample_rate;
    let ranges: Vec<_> = dev
        .supported_input_configs()
        .map_err(|e| format!("{dev}: {e}"))?
        .collect();
    // The formats the callback converts, best first.
    let rank = |f: SampleFormat| {
        [SampleFormat::F32, SampleFormat::I32, SampleFormat::I16]
            .iter()
            .position(|g| *g == f)
    };
    let range = ranges
        .iter()
        .filter(|r| {
            r.channels() == channels
                && (r.min_sample_rate()..=r.max_sample_rate()).contains(&rate)
                && rank(r.sample_format()).is_some()
        })
        .min_by_key(|r| rank(r.sample_format()))
        .ok_or_else(|| {
            let offered: Vec<String> = ranges
                .iter()
                .map(|r| {
                    format!(
                        "{} ch {}-{} Hz {}",
                        r.channels(),
                        r.min_sample_rate(),
                        r.max_sample_rate(),
                        r.sample_format()
                    )
                })
                .collect();
            format!(
                "{dev} cannot capture {channels} channels at {rate} Hz as f32, i32 or i16 \
                 (session {}); it offers {}",
                info.id,
                offered.join(", ")
            )
        })?;
    Ok(range.with_sample_rate(rate))
}

type Shared = Arc<Mutex<Option<(LiveFeed, UnboundedSender<FeedItem>)>>>;

fn build<T>(
    dev: &cpal::Device,
    config: cpal::StreamConfig,
    feed: Shared,
) -> Result<cpal::Stream, String>
where
    T: SizedSample,
    f32: FromSample<T>,
{
    dev.build_input_stream::<T, _, _>(
        config,
        move |data: &[T], _| {
            let samples: Vec<f32> = data.iter().map(|s| s.to_sample::<f32>()).collect();
            // The callback never blocks on the network: items go to an unbounded channel.
            if let Ok(mut guard) = feed.lock()
                && let Some((feed, tx)) = guard.as_mut()
            {
                for item in feed.push(&samples) {
                    let _ = tx.send(item);
                }
            }
        },
        |e| eprintln!("sound card: {e}"),
        None,
    )
    .map_err(|e| format!("{dev}: {e}"))
}
