//! A feed built while the audio arrives (from a sound card): the same messages, in the same
//! order, as `feed_from` makes from a whole recording, so a live device and a recorded one
//! give a session the same input.

use avsep::protocol::{AudioFrame, SampleEncoding};
use avsep::server::client::{FeedItem, FeedMessage};

/// Cuts captured audio into blocks and puts the side messages (camera frames, device
/// measurements) due before each block's end in front of it.
pub struct LiveFeed {
    sample_rate: f64,
    channels: usize,
    block: usize,
    encoding: SampleEncoding,
    side: Vec<(f64, String)>,
    next_side: usize,
    pending: Vec<f32>,
    next_sample: u64,
}

impl LiveFeed {
    /// A feed of `channels`-channel audio at `sample_rate` in blocks of `block` frames, with
    /// `side` messages `(t, JSON)` interleaved by time.
    pub fn new(
        sample_rate: u32,
        channels: usize,
        block: usize,
        encoding: SampleEncoding,
        mut side: Vec<(f64, String)>,
    ) -> Self {
        side.sort_by(|a, b| a.0.total_cmp(&b.0));
        Self {
            sample_rate: f64::from(sample_rate),
            channels: channels.max(1),
            block: block.max(1),
            encoding,
            side,
            next_side: 0,
            pending: Vec::new(),
            next_sample: 0,
        }
    }

    /// Takes interleaved samples as they were captured; returns the items now complete.
    pub fn push(&mut self, samples: &[f32]) -> Vec<FeedItem> {
        self.pending.extend_from_slice(samples);
        let mut items = Vec::new();
        while self.pending.len() >= self.block * self.channels {
            let rest = self.pending.split_off(self.block * self.channels);
            let block = std::mem::replace(&mut self.pending, rest);
            self.emit(block, &mut items);
        }
        items
    }

    /// Ends the capture: the last partial block, then the side messages left.
    pub fn finish(mut self) -> Vec<FeedItem> {
        let mut items = Vec::new();
        let whole = self.pending.len() / self.channels * self.channels;
        let last: Vec<f32> = self.pending.drain(..whole).collect();
        if !last.is_empty() {
            self.emit(last, &mut items);
        }
        self.side_until(f64::INFINITY, &mut items);
        items
    }

    fn emit(&mut self, samples: Vec<f32>, items: &mut Vec<FeedItem>) {
        let frame = AudioFrame {
            first_sample: self.next_sample,
            channels: self.channels,
            samples,
            encoding: self.encoding,
        };
        let end = self.next_sample + frame.frames() as u64;
        let due_s = end as f64 / self.sample_rate;
        self.side_until(due_s, items);
        items.push(FeedItem {
            due_s,
            message: FeedMessage::Audio {
                bytes: frame.encode(),
                end,
            },
        });
        self.next_sample = end;
    }

    fn side_until(&mut self, until: f64, items: &mut Vec<FeedItem>) {
        while let Some((t, text)) = self.side.get(self.next_side) {
            if *t >= until {
                break;
            }
            items.push(FeedItem {
                due_s: t.max(0.0),
                message: FeedMessage::Json(text.clone()),
            });
            self.next_side += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use avsep::scene::Audio;
    use avsep::server::client::feed_from;

    /// Audio captured in uneven callbacks makes the feed a whole recording makes.
    #[test]
    fn captured_chunks_give_the_recorded_feed() {
        let channels = 3;
        let frames = 5000;
        let samples: Vec<f32> = (0..frames * channels)
            .map(|i| ((i * 7919) % 2001) as f32 / 1000.0 - 1.0)
            .collect();
        let audio = Audio {
            sample_rate: 16_000,
            channels,
            samples: samples.clone(),
        };
        let side: Vec<(f64, String)> = [0.0, 0.04, 0.1, 0.1, 0.2, 0.31, 9.0]
            .iter()
            .enumerate()
            .map(|(i, t)| (*t, format!("{{\"n\":{i}}}")))
            .collect();
        for encoding in [SampleEncoding::F32, SampleEncoding::I16] {
            let recorded = feed_from(Some(&audio), side.clone(), 1024, encoding);
            let mut live = LiveFeed::new(16_000, channels, 1024, encoding, side.clone());
            let mut got = Vec::new();
            let mut at = 0;
            for (k, n) in [1usize, 441, 3 * 1024, 5, 2048 * 3 + 1]
                .iter()
                .cycle()
                .enumerate()
            {
                if at >= samples.len() || k > 10_000 {
                    break;
                }
                let end = (at + n).min(samples.len());
                got.extend(live.push(&samples[at..end]));
                at = end;
            }
            got.extend(live.finish());
            assert_eq!(got, recorded, "{encoding:?}");
        }
    }
}
