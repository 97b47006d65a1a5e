//! Feeds: a scene (or any audio with side messages) as the wire messages a live client sends, in
//! the offline runner's order.

use crate::geometry::Layout;
use crate::pipeline::PipelineConfig;
use crate::protocol::rest::CreateSession;
use crate::protocol::{AudioFrame, ClientMessage, SampleEncoding};
use crate::scene::convert::{array_to_file, box_to_file, camera_to_file, region_to_file};
use crate::scene::format::{AudioMeasurementLine, DoaFile};
use crate::scene::{Audio, Scene};

/// The body that creates a session for `layout` with `settings`.
pub fn create_body(layout: &Layout, settings: Option<PipelineConfig>) -> CreateSession {
    CreateSession {
        name: None,
        sample_rate: layout.sample_rate,
        speed_of_sound: layout.speed_of_sound,
        arrays: layout.arrays.iter().map(array_to_file).collect(),
        cameras: layout.cameras.iter().map(camera_to_file).collect(),
        region: layout.region.as_ref().map(region_to_file),
        settings,
    }
}

/// One message of a scene feed.
#[derive(Debug, Clone, PartialEq)]
pub struct FeedItem {
    /// When a live source would have it (s from the start): audio when its block is captured,
    /// a camera frame at its time.
    pub due_s: f64,
    /// The message.
    pub message: FeedMessage,
}

/// A wire message of a feed.
#[derive(Debug, Clone, PartialEq)]
pub enum FeedMessage {
    /// An encoded binary audio frame ending at sample `end`.
    Audio {
        /// The frame's bytes.
        bytes: Vec<u8>,
        /// One past its last sample frame.
        end: u64,
    },
    /// A JSON message.
    Json(String),
}

/// The scene as the messages a live client would send, in the offline runner's order: before
/// each audio block of `block` samples, every camera frame and device measurement with t before
/// the block's end.
pub fn scene_feed(scene: &Scene, block: usize, encoding: SampleEncoding) -> Vec<FeedItem> {
    let layout = &scene.layout;
    let mut side: Vec<(f64, String)> = scene
        .detections
        .iter()
        .map(|d| {
            let msg = ClientMessage::Detections {
                t: d.t,
                camera: layout.cameras[d.camera].id.clone(),
                boxes: d.boxes.iter().map(box_to_file).collect(),
            };
            (d.t, serde_json::to_string(&msg).unwrap_or_default())
        })
        .collect();
    side.extend(scene.audio_measurements.iter().map(|m| {
        let line = AudioMeasurementLine {
            t: m.t,
            array: layout.arrays[m.array].id.clone(),
            doas: m
                .doas
                .iter()
                .map(|d| DoaFile {
                    azimuth: d.azimuth.to_degrees(),
                    elevation: d.elevation.map(f64::to_degrees),
                    energy: d.energy,
                })
                .collect(),
            points: m.points.iter().map(|p| [p.x, p.y, p.z]).collect(),
            activity: m.activity,
        };
        let msg = ClientMessage::AudioMeasurements(line);
        (m.t, serde_json::to_string(&msg).unwrap_or_default())
    }));
    feed_from(scene.audio.as_ref(), side, block, encoding)
}

/// `audio` cut into blocks of `block` samples, each preceded by the side messages (`(t, JSON)`,
/// camera frames and device measurements) with t before the block's end, as the offline runner
/// pushes them; side messages past the audio's end follow it.
pub fn feed_from(
    audio: Option<&Audio>,
    mut side: Vec<(f64, String)>,
    block: usize,
    encoding: SampleEncoding,
) -> Vec<FeedItem> {
    side.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut items = Vec::new();
    let mut next = 0;
    let push_side = |items: &mut Vec<FeedItem>, next: &mut usize, until: f64| {
        while *next < side.len() && side[*next].0 < until {
            items.push(FeedItem {
                due_s: side[*next].0.max(0.0),
                message: FeedMessage::Json(side[*next].1.clone()),
            });
            *next += 1;
        }
    };
    if let Some(audio) = audio {
        let sr = f64::from(audio.sample_rate);
        let frames = audio.frames();
        let mut start = 0;
        while start < frames {
            let end = (start + block.max(1)).min(frames);
            push_side(&mut items, &mut next, end as f64 / sr);
            let frame = AudioFrame {
                first_sample: start as u64,
                channels: audio.channels,
                samples: audio.samples[start * audio.channels..end * audio.channels].to_vec(),
                encoding,
            };
            items.push(FeedItem {
                due_s: end as f64 / sr,
                message: FeedMessage::Audio {
                    bytes: frame.encode(),
                    end: end as u64,
                },
            });
            start = end;
        }
    }
    push_side(&mut items, &mut next, f64::INFINITY);
    items
}

/// Where a client resumes a feed after reconnecting: just after the audio frame that ends at
/// the welcome's `next_sample`.
pub fn resume_index(feed: &[FeedItem], next_sample: u64) -> usize {
    if next_sample == 0 {
        return 0;
    }
    feed.iter()
        .position(|i| matches!(i.message, FeedMessage::Audio { end, .. } if end == next_sample))
        .map_or(feed.len(), |i| i + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session computes bit for bit what the offline run computes only if the layout and the
    /// side messages reach it unchanged. -231.29575740048358 (the projection of the uca8
    /// preset's camera) is one the default serde_json parser reads one ulp off.
    #[test]
    fn layouts_and_feed_messages_cross_the_wire_bit_for_bit() {
        use crate::geometry::{Camera, MicArray, Vec3};
        use crate::scene::convert::{geometry_file, layout_from_file};
        use crate::scene::format::BoxFile;
        use nalgebra::Matrix3x4;

        #[rustfmt::skip]
        let p = Matrix3x4::new(
            640.0000000000001, 596.7430540932476, -231.29575740048358, -1482.7585002101262,
            0.0, 104.3722105269681, -726.8469176310197, 1586.538553525007,
            0.0, 0.9324110220206993, -0.3613996209382556, 0.6831898434216785,
        );
        let cam = Camera::from_projection("cam0", 1280.0, 720.0, p, None, None).unwrap();
        let mics = (0..4)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::FRAC_PI_2 + 0.1;
                Vec3::new(3.0 + 0.05 * a.cos(), 2.5 + 0.05 * a.sin(), 0.75)
            })
            .collect();
        let array = MicArray::new("a0", mics, vec![0, 1, 2, 3]).unwrap();
        let layout = Layout::new(16_000, 343.0, vec![array], vec![cam], None).unwrap();
        let text = serde_json::to_string(&create_body(&layout, None)).unwrap();
        let body: CreateSession = serde_json::from_str(&text).unwrap();
        let file = geometry_file(
            body.sample_rate,
            body.speed_of_sound,
            body.arrays,
            body.cameras,
            body.region,
        );
        assert_eq!(layout_from_file(&file).unwrap(), layout);

        let sent = ClientMessage::Detections {
            t: 0.1 + 0.2,
            camera: "cam0".into(),
            boxes: vec![BoxFile {
                x: -231.29575740048358,
                y: 1.0 / 3.0,
                w: 2.0f64.sqrt(),
                h: 1e-7 / 3.0,
                score: Some(0.9324110220206993),
                point: None,
            }],
        };
        let text = serde_json::to_string(&sent).unwrap();
        assert_eq!(ClientMessage::parse(&text).unwrap(), sent);
    }
}
